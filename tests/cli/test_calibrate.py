"""`odocal simulate` and `odocal calibrate`: contracts, composition and every bad input."""

import json
import math
import subprocess
import sys

import pytest

ROBOT = """\
wheel_diameter_m: 0.15
wheelbase_m: 0.385
systematic: {E_b: 1.028, E_d: 0.999}
nonsystematic: {k_r_m: 1.69e-6, k_l_m: 1.69e-6}
measurement: {sigma_xy_m: 0.001, sigma_theta_deg: 0.1}
"""
GOOD_RUNS = "direction,x_m,y_m,theta_deg\ncw,-0.25,-0.27,7.5\nccw,-0.39,0.46,-12.1\n"


@pytest.fixture
def robot(tmp_path):
    p = tmp_path / "robot.yaml"
    p.write_text(ROBOT)
    return p


def test_simulate_json_contract(cli, robot):
    status, out, err = cli(
        "simulate",
        "--robot",
        robot,
        "--sides",
        4,
        "--side-length",
        4,
        "--direction",
        "cw",
        "--runs",
        7,
        "--seed",
        3,
        "--json",
    )
    assert status == 0, err
    data = json.loads(out)
    assert data["runs"] == 7
    assert set(data["mean"]) == {"x_m", "y_m", "theta_deg"} == set(data["std"])
    # a CW square ends with heading error 4 alpha + 4 beta (model.md; 7 runs, sigma ~ 0.4 deg)
    alpha = math.pi / 2 - (math.pi / 2) / 1.028
    beta = 2 * 4.0 * (0.999 - 1) / (1.999 * 1.028 * 0.385)
    assert data["mean"]["theta_deg"] == pytest.approx(math.degrees(4 * (alpha + beta)), abs=1.0)
    # same seed, same numbers
    assert (
        cli("simulate", "--robot", robot, "--direction", "cw", "--runs", 7, "--seed", 3, "--json")[
            1
        ]
        == out
    )


def test_simulate_then_calibrate_composes(cli, robot, tmp_path):
    runs = tmp_path / "runs.csv"
    status, _, err = cli("simulate", "--robot", robot, "--runs", 20, "--seed", 1, "--out", runs)
    assert status == 0, err
    # the track is data of the sheet (read back by calibrate), then the header
    lines = runs.read_text().splitlines()
    assert lines[:2] == ["# sides: 4", "# side_m: 4"]
    assert lines[2].startswith("direction,x_m,y_m,theta_deg")
    for method in ("heading", "umbmark"):
        status, out, err = cli(
            "calibrate",
            runs,
            "--robot",
            robot,
            "--sides",
            4,
            "--side-length",
            4,
            "--method",
            method,
            "--json",
        )
        assert status == 0, err
        data = json.loads(out)
        assert set(data) >= {
            "method",
            "E_b",
            "E_d",
            "wheel_diameter_right_m",
            "wheel_diameter_left_m",
            "wheelbase_m",
        }
        assert data["method"] == method
        # 20 noisy runs per direction: E_b within about 0.5 % and E_d within 0.1 % of the truth
        assert data["E_b"] == pytest.approx(1.028, abs=0.006)
        assert data["E_d"] == pytest.approx(0.999, abs=0.001)
        assert data["wheelbase_m"] == pytest.approx(0.385 * data["E_b"])


def test_calibrate_writes_params_that_simulate_accepts(cli, robot, tmp_path):
    runs, params = tmp_path / "runs.csv", tmp_path / "params.yaml"
    cli("simulate", "--robot", robot, "--runs", 10, "--out", runs)
    status, out, err = cli("calibrate", runs, "--robot", robot, "--out", params)
    assert status == 0 and params.exists(), err
    assert "E_b" in out and "wheelbase_m" in out
    status, out, err = cli(
        "simulate", "--robot", robot, "--params", params, "--direction", "ccw", "--json"
    )
    assert status == 0, err
    # the calibrated robot ends far closer to its start than the uncalibrated one (0.6 m)
    m = json.loads(out)["mean"]
    assert math.hypot(m["x_m"], m["y_m"]) < 0.2


def test_table_output_and_python_dash_m(robot, tmp_path):
    runs = tmp_path / "r.csv"
    runs.write_text(GOOD_RUNS)
    proc = subprocess.run(
        [sys.executable, "-m", "odocal", "calibrate", str(runs), "--robot", str(robot)]
        + ["--side-length", "4"],
        capture_output=True,
        text=True,
        check=False,
    )
    assert proc.returncode == 0, proc.stderr
    assert "E_b" in proc.stdout and "calibrated" in proc.stdout


def test_default_robot_is_builtin(cli):
    status, out, _ = cli("simulate", "--runs", 2, "--json")
    assert status == 0 and json.loads(out)["runs"] == 4


BAD_RUNS = {
    "short row": ("direction,x_m,y_m,theta_deg\ncw,0.1,0.2\nccw,0,0,0\n", ["line 2"]),
    "long row": ("direction,x_m,y_m,theta_deg\ncw,0.1,0.2,1,9\nccw,0,0,0\n", ["line 2"]),
    "missing column": ("direction,x_m,y_m\ncw,0.1,0.2\n", ["theta_deg", "line 1"]),
    "non-numeric": (GOOD_RUNS + "cw,abc,0,0\n", ["line 4", "x_m", "abc"]),
    "nan": (GOOD_RUNS + "ccw,0,nan,0\n", ["line 4", "y_m"]),
    "inf": (GOOD_RUNS + "ccw,0,0,inf\n", ["line 4", "theta_deg"]),
    "unknown direction": (GOOD_RUNS + "left,0,0,0\n", ["line 4", "direction", "left"]),
    "one direction": ("direction,x_m,y_m,theta_deg\ncw,0,0,1\ncw,0,0,2\n", ["CCW"]),
    "empty": ("", ["empty"]),
    "header only": ("direction,x_m,y_m,theta_deg\n", ["no runs"]),
    # a heading error no run of a square can have (radians multiplied out, ...): refused
    "implausible heading": (
        "direction,x_m,y_m,theta_deg\ncw,0,0,150\nccw,0,0,-4\n",
        ["line 2", "theta_deg", "deviation"],
    ),
    # an end 12 m from the start after 16 m of travel: centimetres in a metre column
    "implausible end": (
        "direction,x_m,y_m,theta_deg\ncw,12,-3,4\nccw,0.1,0.1,-4\n",
        ["line 2", "x_m", "centimetres"],
    ),
}


@pytest.mark.parametrize("case", sorted(BAD_RUNS))
def test_bad_runs_csv(cli, robot, tmp_path, case):
    text, needles = BAD_RUNS[case]
    p = tmp_path / "runs.csv"
    p.write_text(text)
    out_params = tmp_path / "params.yaml"
    result = cli("calibrate", p, "--robot", robot, "--side-length", 4, "--out", out_params)
    result.expect_error(*needles)
    assert not out_params.exists()
    err = result[2]
    if case not in ("one direction", "empty", "header only"):
        assert str(p) in err


def test_binary_garbage_and_missing_file(cli, robot, tmp_path):
    p = tmp_path / "garbage.csv"
    p.write_bytes(bytes(range(256)) * 4)
    cli("calibrate", p, "--robot", robot).expect_error("binary")
    cli("calibrate", tmp_path / "nope.csv", "--robot", robot).expect_error("no such file")
    latin = tmp_path / "latin.csv"
    latin.write_bytes(b"direction,x_m,y_m,theta_deg\ncw,\xe9,0,0\n")
    cli("calibrate", latin, "--robot", robot).expect_error("UTF-8", "line 2")


BAD_ROBOTS = {
    "missing wheelbase": ("wheel_diameter_m: 0.15\n", ["wheelbase_m"]),
    "negative diameter": (
        "wheel_diameter_m: -0.15\nwheelbase_m: 0.4\n",
        ["wheel_diameter_m", "line 1", "> 0"],
    ),
    "string value": ("wheel_diameter_m: 0.15\nwheelbase_m: wide\n", ["wheelbase_m", "line 2"]),
    "bool value": ("wheel_diameter_m: 0.15\nwheelbase_m: true\n", ["wheelbase_m"]),
    "nan": ("wheel_diameter_m: .nan\nwheelbase_m: 0.4\n", ["wheel_diameter_m", "finite"]),
    "unknown key": (
        "wheel_diameter_m: 0.15\nwheelbase_m: 0.4\nsystematic: {E_B: 1.0}\n",
        ["systematic.E_B", "line 3", "unknown key"],
    ),
    "zero E_b": (
        "wheel_diameter_m: 0.15\nwheelbase_m: 0.4\nsystematic:\n  E_b: 0\n",
        ["systematic.E_b", "line 4"],
    ),
    "negative k": (
        "wheel_diameter_m: 0.15\nwheelbase_m: 0.4\nnonsystematic: {k_r_m: -1}\n",
        ["nonsystematic.k_r_m", ">= 0"],
    ),
    "section not mapping": (
        "wheel_diameter_m: 0.15\nwheelbase_m: 0.4\nmeasurement: 3\n",
        ["measurement", "mapping"],
    ),
    "invalid yaml": ("wheel_diameter_m: [0.15\nwheelbase_m: 0.4\n", ["invalid YAML", "line"]),
    "not a mapping": ("- 1\n- 2\n", ["mapping"]),
    "empty": ("", ["empty"]),
}


@pytest.mark.parametrize("case", sorted(BAD_ROBOTS))
def test_bad_robot_yaml(cli, tmp_path, case):
    text, needles = BAD_ROBOTS[case]
    robot = tmp_path / "robot.yaml"
    robot.write_text(text)
    out = tmp_path / "runs.csv"
    cli("simulate", "--robot", robot, "--out", out).expect_error(str(robot), *needles)
    assert not out.exists()


@pytest.mark.parametrize(
    "args,needle",
    [
        (["simulate", "--sides", "2"], "--sides"),
        (["simulate", "--side-length", "-1"], "--side-length"),
        (["simulate", "--side-length", "nan"], "--side-length"),
        (["simulate", "--runs", "0"], "--runs"),
        (["simulate", "--direction", "up"], "--direction"),
        (["simulate", "--seed", "x"], "--seed"),
        (["calibrate"], "RUNS.csv"),
        (["calibrate", "r.csv", "--method", "magic"], "--method"),
        (["frobnicate"], "frobnicate"),
    ],
)
def test_bad_arguments(cli, args, needle):
    cli(*args).expect_error(needle)


def test_umbmark_needs_a_square(cli, robot, tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(GOOD_RUNS)
    result = cli("calibrate", p, "--robot", robot, "--method", "umbmark", "--sides", 5)
    result.expect_error("--side-length")
    result = cli(
        "calibrate", p, "--robot", robot, "--method", "umbmark", "--sides", 5, "--side-length", 4
    )
    result.expect_error("squares")


def test_output_into_missing_folder_leaves_nothing(cli, robot, tmp_path):
    target = tmp_path / "no" / "such" / "dir" / "runs.csv"
    cli("simulate", "--robot", robot, "--out", target).expect_error("does not exist")
    assert not target.parent.exists()


def test_failed_write_keeps_previous_file(cli, robot, tmp_path, monkeypatch):
    out = tmp_path / "runs.csv"
    out.write_text("previous\n")
    import odocal.app.simulate as app_simulate

    def boom(*a, **k):
        raise OSError("disk full")

    monkeypatch.setattr(app_simulate, "runs_csv_text", boom)
    with pytest.raises(OSError):
        cli("simulate", "--robot", robot, "--out", out)
    assert out.read_text() == "previous\n"
    assert [p.name for p in tmp_path.iterdir() if p.name.endswith(".tmp")] == []


def test_track_file(cli, tmp_path):
    track = tmp_path / "track.yaml"
    track.write_text(
        "name: L\nsegments:\n  - straight_m: 2\n  - turn_deg: 90\n"
        "  - arc: {radius_m: 1, angle_deg: 90}\n"
    )
    status, out, err = cli("simulate", "--track", track, "--runs", 3, "--json")
    assert status == 0, err
    assert json.loads(out)["by_direction"].keys() == {"ccw"}
    track.write_text("segments:\n  - jump: 2\n")
    cli("simulate", "--track", track).expect_error(str(track), "jump")


def test_outputs_get_the_usual_file_mode(cli, robot, tmp_path):
    import os
    import stat

    out = tmp_path / "runs.csv"
    old = os.umask(0o022)
    try:
        assert cli("simulate", "--robot", robot, "--out", out)[0] == 0
    finally:
        os.umask(old)
    assert stat.S_IMODE(out.stat().st_mode) == 0o644


def test_heading_method_needs_only_headings_and_blank_cells_say_so(cli, robot, tmp_path):
    p = tmp_path / "runs.csv"
    p.write_text("direction,x_m,y_m,theta_deg\ncw,,,7.5\nccw,,,-12.1\n")
    track = ("--side-length", 4)
    status, out, err = cli("calibrate", p, "--robot", robot, *track, "--json")
    assert status == 0, err
    assert json.loads(out)["E_b"] > 1
    # UMBmark needs the positions: an empty one is reported as not filled in
    cli("calibrate", p, "--robot", robot, *track, "--method", "umbmark").expect_error(
        "line 2",
        "x_m",
        "not filled in",
    )
    p.write_text("direction,x_m,y_m,theta_deg\ncw,0.1,0.2,\nccw,0,0,1\n")
    cli("calibrate", p, "--robot", robot, *track).expect_error(
        "line 2", "theta_deg", "not filled in"
    )


def test_help_is_complete_and_imports_no_command_module():
    # 'odocal --help' lists every command with its line without importing any command module
    # (nor numpy); every module still builds its own parser under its name
    import subprocess
    import sys

    from odocal.cli.main import COMMANDS, build_parser

    code = (
        "import sys, contextlib, io\n"
        "from odocal.cli.main import main\n"
        "buf = io.StringIO()\n"
        "with contextlib.redirect_stdout(buf):\n"
        "    try:\n"
        "        main(['--help'])\n"
        "    except SystemExit:\n"
        "        pass\n"
        "print(buf.getvalue())\n"
        "print('LOADED', sorted(m for m in sys.modules if m.startswith('odocal.cli.') "
        "or m == 'numpy'))\n"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True).stdout
    assert all(name in out for name in COMMANDS)
    assert "LOADED ['odocal.cli.main']" in out
    sub = next(a for a in build_parser()._actions if hasattr(a, "choices") and a.choices)
    assert list(sub.choices) == list(COMMANDS)
