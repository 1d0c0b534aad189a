"""``odocal.app.plan.plan`` on its typed result: the floor plan predicts what the covariance
propagation and the analytic design predict, the side it suggests, the noise plan whose sheet
``noise`` reads."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.noise import noise
from odocal.app.plan import plan
from odocal.core.covariance import predict
from odocal.core.simulate import simulate
from odocal.core.tracks import out_and_back, polygon
from odocal.design.analytic import analytic_design_result
from odocal.design.spec import DesignSpec
from odocal.io.runs_csv import read_run_sheet
from odocal.presets import PRESETS
from tests.support.run_sheets import fill


def test_the_plan_predicts_the_covariance_propagation_of_its_track(tmp_path):
    out = tmp_path / "sheet.csv"
    res = plan("paper-experiment", sides=4, side_m=4.0, runs_per_direction=3, out=out)
    fp = res.floor_plan
    assert res.sheet == out and fp.order == ("cw", "ccw") * 3 and fp.track == (4, 4.0)
    assert fp.next_command.startswith(f"odocal calibrate {out}")
    for d in ("cw", "ccw"):
        expected = predict(polygon(4, 4.0, d), PRESETS["paper-experiment"], max_step_m=0.02)
        np.testing.assert_array_equal(fp.predictions[d].error_mean, expected.error_mean)
        np.testing.assert_array_equal(fp.predictions[d].std(), expected.std())
    # the heading method's prediction from these runs: unbiased E_b (the robot's own)
    assert fp.calibration is not None
    assert fp.calibration.E_b_mean == pytest.approx(PRESETS["paper-experiment"].systematic.E_b)
    sheet = read_run_sheet(out, required=())
    assert (sheet.sides, sheet.side_m) == (4, 4.0)


def test_without_a_side_the_plan_takes_the_analytic_recommendation(tmp_path):
    res = plan(out=tmp_path / "sheet.csv")  # the default robot, a square
    spec = DesignSpec(sides=(4,)).for_wheelbase(float(PRESETS["paper-fig5"].nominal.wheelbase_m))
    side = analytic_design_result(PRESETS["paper-fig5"], spec).recommended.side_m
    assert res.floor_plan.track == (4, side)
    assert any("odocal design --analytic" in n for n in res.notes)


def test_noise_plan_and_template_read_by_noise(tmp_path):
    out = tmp_path / "k.csv"
    res = plan("paper-experiment", noise_track=("out-and-back", 10.0), out=out)
    doc = res.as_dict()
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
    out.write_text(fill(out.read_text(), e))
    est = noise(out, "paper-experiment", track="out-and-back", distance_m=10.0)
    lo, hi = est.k_sum_ci95_m
    assert lo < 2 * 2.89e-6 < hi
