"""``odocal.app.calibrate.calibrate`` on its typed result: simulated runs calibrate to the truth,
the calibrated parameters close the square, a filled-in plan calibrates, BCPT circles."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.calibrate import calibrate
from odocal.app.common import make_robot
from odocal.app.simulate import simulate as simulate_runs
from odocal.core.simulate import measure, simulate
from odocal.core.tracks import polygon
from odocal.design.plan import build_plan
from odocal.errors import InputError
from odocal.io.robot_file import load_params
from odocal.io.runs_csv import read_runs
from odocal.presets import PRESETS
from tests.support.recorded_runs import values
from tests.support.run_sheets import fill

# the ROBOT.yaml of tests/cli/test_calibrate.py, as values
ROBOT = make_robot(
    0.15, 0.385, E_b=1.028, E_d=0.999, k_r_m=1.69e-6, sigma_xy_m=0.001, sigma_theta_deg=0.1
)


def test_simulated_runs_calibrate_to_the_truth(tmp_path):
    runs = tmp_path / "runs.csv"
    simulate_runs(ROBOT, runs=20, seed=1, out=runs)
    for method in ("heading", "umbmark"):
        res = calibrate(runs, ROBOT, sides=4, side_m=4.0, method=method)
        c = res.calibration
        assert c.method == method and res.track == "4-gon side 4 m"
        assert res.track_source == "both"  # the arguments and the sheet's '# sides/side_m' agree
        # 20 noisy runs per direction: E_b within about 0.5 % and E_d within 0.1 % of the truth
        assert c.E_b == pytest.approx(1.028, abs=0.006)
        assert c.E_d == pytest.approx(0.999, abs=0.001)
        assert c.corrected.wheelbase_m == pytest.approx(0.385 * c.E_b)
        assert res.nominal == ROBOT.nominal and res.written == ()


def test_the_calibrated_parameters_close_the_square(tmp_path):
    runs, params = tmp_path / "runs.csv", tmp_path / "params.yaml"
    simulate_runs(ROBOT, runs=10, out=runs)
    res = calibrate(runs, ROBOT, out=params)  # the track from the sheet
    assert res.written == (params,) and res.track_source == "run sheet"
    # PARAMS.yaml keeps nine significant digits
    np.testing.assert_allclose(
        values(load_params(params)), values(res.calibration.corrected), rtol=1e-8
    )
    before = simulate_runs(ROBOT, directions=("ccw",)).runs.errors[:, :2].mean(axis=0)
    after = simulate_runs(ROBOT, params=params, directions=("ccw",)).runs.errors[:, :2].mean(axis=0)
    # the calibrated robot ends far closer to its start than the uncalibrated one (0.6 m)
    assert math.hypot(*before) > 0.5
    assert math.hypot(*after) < 0.2


def test_filled_template_calibrates(tmp_path):
    robot = PRESETS["paper-fig5"]
    plan = build_plan(robot, sides=4, side_m=2.0, runs_per_direction=5)
    rng = np.random.default_rng(0)
    # simulate each row's run in the plan's order and write it into the sheet
    errs = [
        measure(simulate(polygon(4, 2.0, d), robot, 1, rng, max_step_m=0.05).errors, robot, rng)[0]
        for d in plan.order
    ]
    sheet = tmp_path / "filled.csv"
    sheet.write_text(fill(plan.template_csv(), errs))
    runs = read_runs(sheet)
    assert runs.directions == plan.order
    res = calibrate(sheet, "paper-fig5", side_m=2.0)
    # 5 runs per direction on a 2 m square: E_b within a few of its predicted standard deviations
    assert res.calibration.E_b == pytest.approx(1.028, abs=0.005)


def test_bcpt_circles_give_the_worked_example(tmp_path):
    # methods-notes.md TV5: R_c = 1 m, b_n = 0.34 m, truth E_b = 1.01 (radii printed to 1e-6 m)
    runs = tmp_path / "runs.csv"
    runs.write_text("direction,radius_m,run\ncw,1.015798,1\nccw,1.004270,2\n")
    out = tmp_path / "params.yaml"
    res = calibrate(runs, make_robot(0.15, 0.34), method="bcpt", radius_m=1.0, out=out)
    c = res.calibration
    assert c.method == "bcpt" and res.track == "circles of commanded radius 1 m"
    assert c.E_b == pytest.approx(1.01, abs=2e-6)
    assert c.corrected.wheelbase_m == pytest.approx(0.34 * 1.01, abs=1e-6)
    assert res.written == (out,)
    np.testing.assert_allclose(values(load_params(out)), values(c.corrected), rtol=1e-8)


def test_a_second_round_that_needs_no_correction_says_so(tmp_path):
    """Runs of a robot already running with its true parameters: E_b and E_d within their
    95 % intervals of 1, and the report says that no further correction is needed; a robot with
    a real error is told nothing of the kind."""
    from odocal.presets import PRESETS

    robot = PRESETS["paper-fig5"]
    calibrated = robot.with_believed(robot.true_geometry)
    sheet = tmp_path / "second.csv"
    simulate_runs(calibrated, sides=4, side_m=2.0, runs=5, seed=3, out=sheet)
    res = calibrate(sheet, calibrated)
    assert res.correction_needed is False
    assert "no further correction needed" in str(res)
    assert res.as_dict()["correction_needed"] is False
    first = tmp_path / "first.csv"
    simulate_runs(robot, sides=4, side_m=2.0, runs=5, seed=3, out=first)
    res = calibrate(first, robot)
    assert res.correction_needed is True and "no further correction" not in str(res)


def test_no_default_robot_and_the_result_names_its_robot(tmp_path):
    # issue 20.1: without a robot, the built-in 0.385 m robot was calibrated without a word
    sheet = tmp_path / "runs.csv"
    sheet.write_text(
        "# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg\n"
        "cw,,,1.0\ncw,,,1.1\nccw,,,-0.8\nccw,,,-0.9\n"
    )
    ros2 = tmp_path / "ros2.yaml"
    with pytest.raises(InputError, match="which robot drove the runs.*--robot.*paper-fig5"):
        calibrate(sheet, ros2=ros2)
    assert not ros2.exists()
    res = calibrate(sheet, "paper-fig5")
    assert res.robot == "paper-fig5" and res.as_dict()["robot"] == "paper-fig5"
