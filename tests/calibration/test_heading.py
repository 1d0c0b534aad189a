"""The heading-error method (calibration.heading): exactness, composition with the parameters
the robot ran with, the worked example (TV3), undefined equations."""

import math

import numpy as np
import pytest

from odocal.calibration.heading import calibrate_heading, heading_factors
from odocal.calibration.umbmark import umbmark_factors
from odocal.core.model import ModelError, Robot, SystematicError, WheelGeometry
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import simulate
from odocal.core.tracks import polygon
from odocal.errors import CalibrationError

NOMINAL = WheelGeometry.symmetric(0.15, 0.385)


def _noise_free_runs(robot, sides, side_m):
    errs = [simulate(polygon(sides, side_m, d), robot, 1, None).errors[0] for d in ("cw", "ccw")]
    return EndPoseRuns(("cw", "ccw"), np.array(errs))


def test_heading_method_noise_free_round_trip_is_exact():
    rng = np.random.default_rng(20140201)
    for sides in range(3, 9):
        for _ in range(3):
            E_b = rng.uniform(0.93, 1.07)
            E_d = rng.uniform(0.992, 1.008)
            L = rng.uniform(0.5, 10.0)
            robot = Robot(NOMINAL, SystematicError(E_b, E_d))
            res = calibrate_heading(_noise_free_runs(robot, sides, L), sides, L, NOMINAL)
            assert res.E_b == pytest.approx(E_b, rel=1e-9), (sides, L)
            assert res.E_d == pytest.approx(E_d, rel=1e-9), (sides, L)
            # the corrected geometry is the true one (E_s = 1)
            t = robot.true_geometry
            assert res.corrected.wheelbase_m == pytest.approx(t.wheelbase_m, rel=1e-9)
            assert res.corrected.diameter_right_m == pytest.approx(t.diameter_right_m, rel=1e-9)
            assert res.corrected.diameter_left_m == pytest.approx(t.diameter_left_m, rel=1e-9)


def test_calibrated_robot_re_driven_has_no_error_and_recalibrates_to_one():
    robot = Robot(NOMINAL, SystematicError(1.045, 0.995))
    first = calibrate_heading(_noise_free_runs(robot, 4, 4.0), 4, 4.0, NOMINAL)
    fixed = robot.with_believed(first.corrected)
    runs = _noise_free_runs(fixed, 4, 4.0)
    np.testing.assert_allclose(runs.errors, 0.0, atol=1e-9)
    again = calibrate_heading(runs, 4, 4.0, first.corrected)
    assert again.E_b == pytest.approx(1.0, abs=1e-10)
    assert again.E_d == pytest.approx(1.0, abs=1e-10)


def test_results_compose_with_the_parameters_the_robot_ran_with():
    # the robot ran with a wrong non-nominal belief; composing must still land on the truth
    robot = Robot(NOMINAL, SystematicError(1.03, 1.004))
    ran_with = WheelGeometry(0.1512, 0.1495, 0.39)
    runs = _noise_free_runs(robot.with_believed(ran_with), 6, 2.0)
    res = calibrate_heading(runs, 6, 2.0, ran_with)
    t = robot.true_geometry
    c = res.corrected
    # a closed track cannot see a common scale: compare the ratio and b relative to the scale
    m = c.mean_diameter_m / t.mean_diameter_m
    assert c.diameter_ratio == pytest.approx(t.diameter_ratio, rel=1e-9)
    assert c.wheelbase_m / m == pytest.approx(t.wheelbase_m, rel=1e-9)


def test_tv3_heading_worked_example():
    # methods-notes.md section 2.3 (TV3): L = 4 m, b = 0.340 m
    E_b, E_d = heading_factors(math.radians(-1.8118), math.radians(6.3912), 4, 4.0, 0.340)
    assert E_b == pytest.approx(0.988735, abs=2e-6)
    assert E_d == pytest.approx(1.000840, abs=2e-6)


def test_both_directions_required_and_undefined_equations_raise():
    one = EndPoseRuns(("cw", "cw"), np.zeros((2, 3)))
    with pytest.raises(CalibrationError, match="no CCW runs"):
        calibrate_heading(one, 4, 4.0, NOMINAL)
    # a per-turn under-rotation of a whole turn angle makes E_b undefined
    bad = EndPoseRuns(("cw", "ccw"), np.array([[0, 0, 7.0], [0, 0, -7.0]]))
    with pytest.raises(CalibrationError, match="undefined"):
        calibrate_heading(bad, 4, 4.0, NOMINAL)
    with pytest.raises(ModelError):
        umbmark_factors((0, 0), (0, 0), 4.0, 0.3, "z")


def test_headings_a_full_turn_apart_are_the_same_heading():
    # a run's heading written a full turn off (0.014 + 2 pi) changes neither the factors nor
    # their standard errors: the spread is taken about the circular mean, deviations wrapped
    geo = WheelGeometry.symmetric(0.15, 0.34)
    err = np.zeros((6, 3))
    err[:, 2] = [0.010, 0.014, 0.011, -0.030, -0.034, -0.031]
    directions = ("cw",) * 3 + ("ccw",) * 3
    plain = calibrate_heading(EndPoseRuns(directions, err), 4, 2.0, geo)
    err[1, 2] += 2 * np.pi
    err[4, 2] -= 2 * np.pi
    turned = calibrate_heading(EndPoseRuns(directions, err), 4, 2.0, geo)
    assert turned.E_b == pytest.approx(plain.E_b, abs=1e-12)
    assert turned.E_d == pytest.approx(plain.E_d, abs=1e-12)
    assert plain.uncertainty is not None and turned.uncertainty is not None
    np.testing.assert_allclose(
        turned.uncertainty.covariance, plain.uncertainty.covariance, rtol=1e-6, atol=1e-15
    )
