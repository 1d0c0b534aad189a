"""``odocal plan``: protocol, predictions, run sheet that calibrate / noise read once filled in."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from odocal.core.covariance import predict
from odocal.core.simulate import measure, simulate
from odocal.core.tracks import out_and_back, polygon
from odocal.design.plan import build_plan
from odocal.io.runs_csv import read_runs
from odocal.presets import PRESETS


def _fill(template: str, errors_by_row) -> str:
    """Fill the blank rows of a run sheet in order with (x_m, y_m, theta_rad) per row."""
    out, i = [], 0
    for line in template.splitlines():
        if line.startswith("#") or line.startswith("direction"):
            out.append(line)
            continue
        d, _, _, _, run = line.split(",")
        x, y, th = errors_by_row[i]
        out.append(f"{d},{x:.6f},{y:.6f},{math.degrees(th):.6f},{run}")
        i += 1
    return "\n".join(out) + "\n"


def test_plan_writes_an_alternating_template_and_predicts(cli, tmp_path):
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
    # the printed expectation is the covariance propagation of the robot's errors
    p = predict(polygon(4, 4.0, "cw"), PRESETS["paper-experiment"], max_step_m=0.02)
    assert f"{math.degrees(p.error_mean[2]):+.3f} ± {math.degrees(p.std()[2]):.3f}" in text
    assert "E_b 1.0255 ±" in text and "uncalibrated" in text


def test_unfilled_template_is_a_clear_error_in_calibrate(cli, tmp_path):
    out = tmp_path / "runs-template.csv"
    assert cli("plan", "--out", out)[0] == 0
    status, text, err = cli("calibrate", out)
    assert status == 2 and text == ""
    assert err.startswith("odocal: error:") and len(err.strip().splitlines()) == 1
    assert str(out) in err and "field 'theta_deg'" in err and "not filled in" in err


def test_filled_template_calibrates(cli, tmp_path):
    robot = PRESETS["paper-fig5"]
    plan = build_plan(robot, sides=4, side_m=2.0, runs_per_direction=5)
    rng = np.random.default_rng(0)
    # simulate each row's run in the plan's order and write it into the sheet
    errs = [
        measure(simulate(polygon(4, 2.0, d), robot, 1, rng, max_step_m=0.05).errors, robot, rng)[0]
        for d in plan.order
    ]
    sheet = tmp_path / "filled.csv"
    sheet.write_text(_fill(plan.template_csv(), errs))
    runs = read_runs(sheet)
    assert runs.directions == plan.order
    status, text, err = cli("calibrate", sheet, "--side-length", "2", "--json")
    assert status == 0, err
    doc = json.loads(text)
    # 5 runs per direction on a 2 m square: E_b within a few of its predicted standard deviations
    assert doc["E_b"] == pytest.approx(1.028, abs=0.005)


def test_noise_plan_and_template_read_by_noise(cli, tmp_path):
    out = tmp_path / "k.csv"
    status, text, err = cli(
        "plan", "--robot", "paper-experiment", "--track", "out-and-back:10", "--out", out, "--json"
    )
    assert status == 0, err
    doc = json.loads(text)
    assert doc["kind"] == "out-and-back" and doc["runs"] == 20 and set(doc["order"]) == {"fwd"}
    assert "odocal noise" in doc["next_command"]
    robot = PRESETS["paper-experiment"]
    # out-and-back: the predicted heading std is sqrt(2 (k_r + k_l) d) / b exactly
    b = robot.true_geometry.wheelbase_m
    expected = math.degrees(math.sqrt(2 * 2 * 2.89e-6 * 10) / b)
    assert doc["predicted"]["fwd"]["std"]["theta_deg"] == pytest.approx(expected, rel=1e-6)
    assert doc["predicted"]["fwd"]["mean"]["theta_deg"] == pytest.approx(0.0, abs=1e-9)
    rng = np.random.default_rng(5)
    e = simulate(out_and_back(10.0), robot, 20, rng, max_step_m=0.1).errors
    out.write_text(_fill(out.read_text(), e))
    status, text, err = cli(
        "noise", out, "--robot", "paper-experiment", "--track", "out-and-back:10", "--json"
    )
    assert status == 0, err
    lo, hi = json.loads(text)["k_sum_ci95"]
    assert lo < 2 * 2.89e-6 < hi


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
