"""``odocal simulate``: its JSON and text, the default robot, track files, bad ROBOT.yaml files,
outputs written all or none with the usual file mode."""

import json

import pytest

import odocal.app.simulate as app_simulate
from tests.support.printed import as_printed

ROBOT = """\
wheel_diameter_m: 0.15
wheelbase_m: 0.385
systematic: {E_b: 1.028, E_d: 0.999}
nonsystematic: {k_r_m: 1.69e-6, k_l_m: 1.69e-6}
measurement: {sigma_xy_m: 0.001, sigma_theta_deg: 0.1}
"""


@pytest.fixture
def robot(tmp_path):
    p = tmp_path / "robot.yaml"
    p.write_text(ROBOT)
    return p


def test_simulate_json_contract(cli, robot, returned):
    results = returned(app_simulate, "simulate")
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
    # the app's typed result, printed (its numbers: tests/app/test_simulate.py)
    assert data == as_printed(results[0].as_dict())
    # same seed, same numbers
    assert (
        cli("simulate", "--robot", robot, "--direction", "cw", "--runs", 7, "--seed", 3, "--json")[
            1
        ]
        == out
    )


def test_default_robot_is_builtin(cli):
    status, out, _ = cli("simulate", "--runs", 2, "--json")
    assert status == 0 and json.loads(out)["runs"] == 4


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
        cli("simulate", "--robot", robot, "--out", out, "--force")
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


def test_simulate_predict_cli(cli, returned):
    results = returned(app_simulate, "simulate")
    status, out, err = cli(
        "simulate", "--robot", "paper-experiment", "--runs", "50", "--max-step", "0.05", "--predict"
    )
    assert status == 0, err
    assert "predicted" in out and "MC (50 runs)" in out
    status, out, err = cli(
        "simulate",
        "--robot",
        "paper-experiment",
        "--runs",
        "50",
        "--max-step",
        "0.05",
        "--predict",
        "--json",
        "--direction",
        "ccw",
    )
    assert status == 0, err
    doc = json.loads(out)
    # the prediction of the app's typed result (tests/app/test_simulate.py checks its numbers)
    assert doc == as_printed(results[-1].as_dict())
    pred = doc["predicted"]["ccw"]
    assert set(pred["correlation"]) == {"x_y", "x_theta", "y_theta"}
    assert len(doc["monte_carlo_covariance"]["ccw"]) == 3
    assert "cw" not in doc["predicted"]


def test_direction_in_any_case(cli):
    # issue 20, hostile inputs: --direction CW was refused though the files accept upper case
    status, out, err = cli("simulate", "--direction", "CW", "--runs", 2, "--side-length", 1)
    assert status == 0, err
    rows = [line.split() for line in out.splitlines() if line.split()[:1] in (["cw"], ["ccw"])]
    assert [r[0] for r in rows] == ["cw"]


def test_out_never_replaces_measurements_without_force(cli, tmp_path):
    # issue 20.3: simulate --out runs.csv replaced a sheet of real measurements without a word
    sheet = tmp_path / "runs.csv"
    measured = "# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg\ncw,0.01,0.02,1.5\n"
    sheet.write_text(measured)
    args = ("simulate", "--runs", 2, "--side-length", 1, "--out", sheet)
    cli(*args).expect_error("--out", "already holds measured runs", "--force")
    assert sheet.read_text() == measured
    # a blank sheet from plan is not simulate's either: refused too
    blank = tmp_path / "blank.csv"
    assert cli("plan", "--side-length", 1, "--out", blank)[0] == 0
    cli("simulate", "--out", blank).expect_error("already holds")
    # simulate replaces its own sheet; --force replaces anything
    assert cli(*args, "--force")[0] == 0
    first = sheet.read_text()
    assert "# odocal simulate: simulated runs, not measurements" in first
    assert cli(*args, "--seed", 7)[0] == 0 and sheet.read_text() != first
    # and plan will not replace a simulated sheet (not its own)
    cli("plan", "--side-length", 1, "--out", sheet).expect_error("already holds")
