"""``odocal.app.simulate.simulate`` on its typed result: the simulated end errors of model.md,
the same runs for the same seed, the first-order prediction, RUNS.csv written with its track."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.common import make_robot
from odocal.app.simulate import simulate
from odocal.core.covariance import predict
from odocal.core.tracks import polygon
from odocal.io.runs_csv import read_run_sheet
from odocal.presets import PRESETS

# the ROBOT.yaml of tests/cli/test_simulate.py, as values
ROBOT = make_robot(
    0.15, 0.385, E_b=1.028, E_d=0.999, k_r_m=1.69e-6, sigma_xy_m=0.001, sigma_theta_deg=0.1
)


def test_a_cw_square_ends_with_the_heading_error_of_model_md():
    res = simulate(ROBOT, sides=4, side_m=4.0, directions=("cw",), runs=7, seed=3)
    assert res.runs.directions == ("cw",) * 7 and res.runs.errors.shape == (7, 3)
    assert (res.track, res.runs_per_direction, res.seed) == ("4-gon, side 4 m", 7, 3)
    # a CW square ends with heading error 4 alpha + 4 beta (model.md; 7 runs, sigma ~ 0.4 deg)
    alpha = math.pi / 2 - (math.pi / 2) / 1.028
    beta = 2 * 4.0 * (0.999 - 1) / (1.999 * 1.028 * 0.385)
    theta = math.degrees(res.runs.errors[:, 2].mean())
    assert theta == pytest.approx(math.degrees(4 * (alpha + beta)), abs=1.0)
    assert res.as_dict()["mean"]["theta_deg"] == pytest.approx(theta, rel=1e-12)
    # same seed, same runs
    again = simulate(ROBOT, sides=4, side_m=4.0, directions=("cw",), runs=7, seed=3)
    np.testing.assert_array_equal(again.runs.errors, res.runs.errors)


def test_the_prediction_is_the_covariance_propagation_of_the_track():
    res = simulate(
        "paper-experiment", runs=50, max_step_m=0.05, predict_covariance=True, directions=("ccw",)
    )
    assert res.predicted is not None and set(res.predicted) == {"ccw"}  # not "cw"
    expected = predict(polygon(4, 4.0, "ccw"), PRESETS["paper-experiment"], max_step_m=0.05)
    np.testing.assert_array_equal(res.predicted["ccw"].error_mean, expected.error_mean)
    np.testing.assert_array_equal(
        res.predicted["ccw"].measured_covariance, expected.measured_covariance
    )
    doc = res.as_dict()
    pred = doc["predicted"]["ccw"]
    assert pred["std"]["theta_deg"] == pytest.approx(math.degrees(expected.std()[2]))
    assert set(pred["correlation"]) == {"x_y", "x_theta", "y_theta"}
    assert np.shape(doc["monte_carlo_covariance"]["ccw"]) == (3, 3)


def test_the_run_sheet_written_holds_the_track_and_the_runs(tmp_path):
    out = tmp_path / "runs.csv"
    res = simulate(ROBOT, runs=3, seed=1, out=out)
    assert res.written == (out,)
    sheet = read_run_sheet(out)
    assert (sheet.sides, sheet.side_m) == (4, 4.0)
    assert sheet.runs.directions == res.runs.directions == ("cw",) * 3 + ("ccw",) * 3
    # nine significant digits in the sheet
    np.testing.assert_allclose(sheet.runs.errors, res.runs.errors, rtol=1e-8, atol=1e-12)
