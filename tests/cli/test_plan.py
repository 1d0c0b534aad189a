"""``odocal plan``: the protocol and predictions it prints, its JSON, the run sheet it writes,
bad inputs (the numbers: tests/app/test_plan.py)."""

from __future__ import annotations

import json
import math

import odocal.app.plan as app_plan
from tests.support.printed import as_printed


def test_plan_writes_an_alternating_template_and_predicts(cli, tmp_path, returned):
    results = returned(app_plan, "plan")
    out = tmp_path / "sheet.csv"
    status, text, err = cli(
        "plan",
        "--robot",
        "paper-experiment",
        "--sides",
        "4",
        "--side-length",
        "4",
        "--runs-per-direction",
        "3",
        "--out",
        out,
    )
    assert status == 0, err
    rows = [ln for ln in out.read_text().splitlines() if ln and not ln.startswith("#")]
    assert rows[0] == "direction,x_m,y_m,theta_deg,run"
    assert [r.split(",")[0] for r in rows[1:]] == ["cw", "ccw"] * 3
    assert "alternate CW and CCW" in text and "start frame" in text.lower()
    assert f"odocal calibrate {out}" in text
    # the printed expectation is the plan's prediction (the covariance propagation of the
    # robot's errors: tests/app/test_plan.py)
    fp = results[0].floor_plan
    p = fp.predictions["cw"]
    assert f"{math.degrees(p.error_mean[2]):+.3f} ± {math.degrees(p.std()[2]):.3f}" in text
    assert f"E_b {fp.calibration.E_b_mean:.4f} ±" in text and "uncalibrated" in text
    assert "E_b 1.0255 ±" in text


def test_plan_json_is_the_app_result(cli, tmp_path, returned):
    results = returned(app_plan, "plan")
    out = tmp_path / "k.csv"
    status, text, err = cli(
        "plan", "--robot", "paper-experiment", "--track", "out-and-back:10", "--out", out, "--json"
    )
    assert status == 0, err
    assert json.loads(text) == as_printed(results[0].as_dict())
    (res,) = results
    assert res.sheet == out and res.floor_plan.kind == "out-and-back"
    assert len(res.floor_plan.order) == 20  # the default number of k runs


def test_unfilled_template_is_a_clear_error_in_calibrate(cli, tmp_path):
    out = tmp_path / "runs-template.csv"
    assert cli("plan", "--out", out)[0] == 0
    status, text, err = cli("calibrate", out, "--robot", "paper-fig5")
    assert status == 2 and text == ""
    assert err.startswith("odocal: error:") and len(err.strip().splitlines()) == 1
    assert str(out) in err and "field 'theta_deg'" in err and "not filled in" in err


def test_straight_plan_explains_the_odometric_offset(cli, tmp_path):
    status, text, err = cli(
        "plan", "--track", "straight:5", "--runs-per-direction", "12", "--out", tmp_path / "s.csv"
    )
    assert status == 0, err
    assert "x_m = measured x - 5" in text and "12 runs" in text


def test_plan_bad_inputs_leave_no_file(cli, tmp_path):
    out = tmp_path / "nodir" / "sheet.csv"
    status, _, err = cli("plan", "--out", out)
    assert status == 2 and "output folder does not exist" in err and not out.exists()
    status, _, err = cli("plan", "--sides", "2", "--out", tmp_path / "a.csv")
    assert status == 2 and "at least 3 sides" in err
    status, _, err = cli("plan", "--track", "zigzag:3", "--out", tmp_path / "a.csv")
    assert status == 2 and "out-and-back:D" in err
    status, _, err = cli("plan", "--robot", tmp_path / "none.yaml", "--out", tmp_path / "a.csv")
    assert status == 2 and "none.yaml" in err
    assert not (tmp_path / "a.csv").exists()


def test_a_robot_without_errors_gets_a_spread_table_that_does_not_contradict_its_typical_ends(
    cli, tmp_path
):
    """The typical robots end up to |theta| ~24 deg on average, so the table beside cannot
    show a mean of 0 and call values far outside +-1 deg mistakes: it shows the spread alone,
    and a mistake is an end far beyond the typical ones."""
    robot = tmp_path / "robot.yaml"
    robot.write_text(
        "wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n"
        "measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1.0}\n"
    )
    status, out, err = cli(
        "plan", "--robot", robot, "--side-length", "1.8", "--out", tmp_path / "runs.csv"
    )
    assert status == 0, err
    assert "|theta| 24." in out  # the typical ends
    assert "+0.0000 ±" not in out and "+0.000 ±" not in out  # no mean of 0 beside them
    assert "cw         ± 0.0100  ± 0.0100    ± 1.000" in out
    assert "values far outside these usually mean" not in out
    assert "far beyond the typical ones above usually means a frame or sign mistake" in out
