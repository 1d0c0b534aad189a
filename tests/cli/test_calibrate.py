"""``odocal calibrate``: its JSON and text, composed with ``simulate``, every bad run sheet,
``python -m odocal``, and the BCPT circles."""

import json
import subprocess
import sys

import pytest

import odocal.app.calibrate as app_calibrate
import odocal.app.simulate as app_simulate
from tests.support.printed import as_printed

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


def test_simulate_then_calibrate_composes(cli, robot, tmp_path, returned):
    results = returned(app_calibrate, "calibrate")
    runs = tmp_path / "runs.csv"
    status, _, err = cli("simulate", "--robot", robot, "--runs", 20, "--seed", 1, "--out", runs)
    assert status == 0, err
    # the track is data of the sheet (read back by calibrate), then the header
    lines = runs.read_text().splitlines()
    assert lines[:2] == ["# sides: 4", "# side_m: 4"]
    assert lines[2].startswith("# odocal simulate: simulated runs, not measurements (robot ")
    assert lines[3].startswith("direction,x_m,y_m,theta_deg")
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
        # the app's typed result, printed (its numbers: tests/app/test_calibrate.py)
        assert data == as_printed(results[-1].as_dict())


def test_a_sheet_saved_in_the_european_dialect_with_padded_lines(cli, robot, tmp_path):
    """Issue 27 item 19: a spreadsheet with a note in a wider column ends every line in ';;';
    the README promises the European dialect, the sheet was refused (an empty column name)."""
    runs, eu = tmp_path / "runs.csv", tmp_path / "runs-eu.csv"
    assert cli("simulate", "--robot", robot, "--runs", 5, "--seed", 1, "--out", runs)[0] == 0
    lines = runs.read_text().splitlines()
    eu.write_text(
        "".join(
            (
                line.replace(".", ",")
                if line.startswith("#")
                else line.replace(",", ";").replace(".", ",")
            )
            + ";;\n"
            for line in lines
        )  # fmt: skip
    )
    status, out, err = cli("calibrate", eu, "--robot", robot, "--json")
    assert status == 0, err
    assert (
        json.loads(out)["E_b"]
        == json.loads(cli("calibrate", runs, "--robot", robot, "--json")[1])["E_b"]
    )


def test_calibrate_writes_params_that_simulate_accepts(cli, robot, tmp_path, returned):
    simulated = returned(app_simulate, "simulate")
    runs, params = tmp_path / "runs.csv", tmp_path / "params.yaml"
    cli("simulate", "--robot", robot, "--runs", 10, "--out", runs)
    status, out, err = cli("calibrate", runs, "--robot", robot, "--out", params)
    assert status == 0 and params.exists(), err
    assert "E_b" in out and "wheelbase_m" in out
    status, out, err = cli(
        "simulate", "--robot", robot, "--params", params, "--direction", "ccw", "--json"
    )
    assert status == 0, err
    # simulated with the parameters written (how close they end: tests/app/test_calibrate.py)
    assert json.loads(out) == as_printed(simulated[-1].as_dict())
    assert json.loads(out)["runs"] == 5


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


def test_umbmark_needs_a_square(cli, robot, tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(GOOD_RUNS)
    result = cli("calibrate", p, "--robot", robot, "--method", "umbmark", "--sides", 5)
    result.expect_error("--side-length")
    result = cli(
        "calibrate", p, "--robot", robot, "--method", "umbmark", "--sides", 5, "--side-length", 4
    )
    result.expect_error("squares")


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


# --- BCPT: circles of a commanded radius ------------------------------------------------------


def _write(path, text):
    path.write_text(text)
    return path


def test_cli_bcpt_json(cli, tmp_path, returned):
    results = returned(app_calibrate, "calibrate")
    robot = _write(tmp_path / "robot.yaml", "wheel_diameter_m: 0.15\nwheelbase_m: 0.34\n")
    runs = _write(tmp_path / "runs.csv", "direction,radius_m,run\ncw,1.015798,1\nccw,1.004270,2\n")
    out = tmp_path / "params.yaml"
    status, stdout, stderr = cli(
        "calibrate",
        runs,
        "--method",
        "bcpt",
        "--radius",
        1.0,
        "--robot",
        robot,
        "--json",
        "--out",
        out,
    )
    assert status == 0, stderr
    doc = json.loads(stdout)
    assert doc["method"] == "bcpt"
    assert doc == as_printed(results[-1].as_dict())  # its numbers: tests/app/test_calibrate.py
    assert out.exists()
    status, stdout, _ = cli("calibrate", runs, "--method", "bcpt", "--radius", 1, "--robot", robot)
    assert status == 0 and "first order" in stdout


@pytest.mark.parametrize(
    "text, args, message",
    [
        ("direction,radius_m\ncw,1.01\nccw,1.0\n", [], "--radius"),
        ("direction,radius_m\ncw,abc\nccw,1.0\n", ["--radius", "1"], "line 2, field 'radius_m'"),
        ("direction,radius_m\ncw,-1\nccw,1.0\n", ["--radius", "1"], "line 2, field 'radius_m'"),
        ("direction,radius_m\nup,1.0\nccw,1.0\n", ["--radius", "1"], "line 2, field 'direction'"),
        ("direction,r\ncw,1.0\n", ["--radius", "1"], "missing column(s) radius_m"),
        ("direction,radius_m\ncw,1.0,9\n", ["--radius", "1"], "line 2"),
        ("direction,radius_m\n", ["--radius", "1"], "no runs"),
        ("direction,radius_m\ncw,1.0\ncw,1.1\n", ["--radius", "1"], "no CCW runs"),
        ("direction,radius_m\ncw,0.11\nccw,0.1\n", ["--radius", "0.1"], "half the wheelbase"),
        ("direction,radius_m\ncw,1.0\nccw,1.0\n", ["--radius", "0.1"], "a diameter for a radius"),
        ("direction,radius_m\ncw,1.0\nccw,1.0\n", ["--radius", "-2"], "--radius"),
    ],
)
def test_cli_bcpt_bad_input(cli, tmp_path, text, args, message):
    runs = _write(tmp_path / "runs.csv", text)
    out = tmp_path / "params.yaml"
    status, stdout, stderr = cli(
        "calibrate", runs, "--robot", "paper-fig5", "--method", "bcpt", *args, "--out", out
    )
    assert status == 2
    assert stderr.startswith("odocal: error:") and stderr.count("\n") == 1
    assert message in stderr
    assert "Traceback" not in stderr
    assert not out.exists()
    if "line" in message or "column" in message or "no runs" in message:
        assert str(runs) in stderr


def test_cli_radius_without_bcpt_is_an_error(cli, tmp_path):
    runs = _write(
        tmp_path / "runs.csv", "direction,x_m,y_m,theta_deg\ncw,0.1,0.1,1\nccw,0.1,-0.1,-1\n"
    )
    status, _, err = cli("calibrate", runs, "--robot", "paper-fig5", "--radius", 1.0)
    assert status == 2 and err.count("\n") == 1
    assert "--radius is only used with --method bcpt" in err


def test_cli_names_the_robot_and_has_no_default(cli, robot, tmp_path):
    runs = _write(tmp_path / "runs.csv", "# sides: 4\n# side_m: 4\n" + GOOD_RUNS)
    status, _, err = cli("calibrate", runs, "--ros2", tmp_path / "ros2.yaml")
    assert status == 2 and err.count("\n") == 1 and "--robot" in err
    assert not (tmp_path / "ros2.yaml").exists()
    status, out, err = cli("calibrate", runs, "--robot", robot)
    assert status == 0, err
    assert f"robot {robot}: ran with wheel diameters 0.15 / 0.15 m" in out
    assert "wheelbase 0.385 m" in out


def test_a_heading_with_the_wrong_sign_is_refused(cli, tmp_path):
    # issue 20.2: theta read with the protractor the other way gave the inverse correction
    # (E_b 0.98 instead of 1.02); the positions on the same sheet contradict it
    robot = _write(
        tmp_path / "tb3.yaml",
        "wheel_diameter_m: 0.066\nwheelbase_m: 0.16\nsystematic: {E_b: 1.019, E_d: 1.003}\n"
        "nonsystematic: {k_r_m: 2.0e-6, k_l_m: 2.0e-6}\n"
        "measurement: {sigma_xy_m: 0.002, sigma_theta_deg: 0.3}\n",
    )
    sheet = tmp_path / "runs.csv"
    args = ("--robot", robot, "--side-length", 1, "--runs", 5, "--seed", 3)
    assert cli("simulate", *args, "--out", sheet)[0] == 0
    lines = sheet.read_text().splitlines()
    start = next(i for i, ln in enumerate(lines) if ln.startswith("direction")) + 1
    for i in range(start, len(lines)):
        f = lines[i].split(",")
        f[3] = repr(-float(f[3]))
        lines[i] = ",".join(f)
    flipped = _write(tmp_path / "flipped.csv", "\n".join(lines) + "\n")
    plain = _write(tmp_path / "plain.yaml", "wheel_diameter_m: 0.066\nwheelbase_m: 0.16\n")
    status, out, err = cli("calibrate", sheet, "--robot", plain, "--json")
    assert status == 0, err
    assert json.loads(out)["E_b"] == pytest.approx(1.019, abs=0.004)
    cli("calibrate", flipped, "--robot", plain).expect_error(
        str(flipped), "the headings contradict the positions", "counter-clockwise positive",
        "--force",
    )  # fmt: skip
    status, out, err = cli("calibrate", flipped, "--robot", plain, "--force", "--json")
    assert status == 0 and "contradict the positions" in err
    assert json.loads(out)["E_b"] < 1.0  # as written, with the warning
