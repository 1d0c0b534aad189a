"""Heading-error method and UMBmark: exactness, known approximation errors, test vectors."""

import math

import numpy as np
import pytest

from odocal.calibration.heading import calibrate_heading, heading_factors
from odocal.calibration.umbmark import calibrate_umbmark, umbmark_factors
from odocal.core.model import ModelError, Robot, SystematicError, WheelGeometry
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import simulate
from odocal.core.stats import circular_mean
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


@pytest.mark.parametrize(
    "form,E_b,E_d",
    [("x", 0.9884607, 1.000885), ("y", 0.9892933, 1.000780), ("mean", 0.9888768, 1.000833)],
)
def test_tv1_umbmark_worked_example(form, E_b, E_d):
    # methods-notes.md section 1.6 (TV1) uses the book's E_d with the nominal wheelbase
    cw, ccw = (0.0634, 0.0626), (0.2300, -0.2094)
    got_b, got_d = umbmark_factors(cw, ccw, 4.0, 0.340, form, ed_wheelbase="nominal")
    assert got_b == pytest.approx(E_b, abs=1e-6)
    assert got_d == pytest.approx(E_d, abs=1e-6)


def test_umbmark_small_angle_error_mean_form_is_best():
    """UMBmark's x- and y-forms err in opposite directions by a small-angle error that grows with
    L (methods-notes.md 1.7); their mean cancels most of it."""
    rng = np.random.default_rng(7)
    worse = 0
    for _ in range(20):
        E_b, E_d = rng.uniform(0.97, 1.03), rng.uniform(0.996, 1.004)
        L = rng.uniform(1.0, 8.0)
        robot = Robot(NOMINAL, SystematicError(E_b, E_d))
        runs = _noise_free_runs(robot, 4, L)
        err = {}
        for form in ("x", "y", "mean"):
            r = calibrate_umbmark(runs, L, NOMINAL, form)
            err[form] = abs(r.E_b - E_b)
            # the known small-angle error: well under 1 % of E_b for these error sizes
            assert abs(r.E_b - E_b) < 0.01
            assert abs(r.E_d - E_d) < 1e-3
        assert err["mean"] <= max(err["x"], err["y"])
        worse += err["mean"] > min(err["x"], err["y"])
    # the mean form is better than both single forms in most cases
    assert worse <= 4


def test_umbmark_table_1_7_pure_E_d_coupling():
    # methods-notes.md 1.7: a pure E_d error produces a spurious E_b (x-form below 1, y-form above)
    robot = Robot(WheelGeometry.symmetric(0.15, 0.34), SystematicError(1.0, 1.004))
    runs = _noise_free_runs(robot, 4, 4.0)
    geo = WheelGeometry.symmetric(0.15, 0.34)
    assert (
        calibrate_umbmark(runs, 4.0, geo, "x").E_b
        < 1.0
        < calibrate_umbmark(runs, 4.0, geo, "y").E_b
    )
    # the heading method has no such coupling: E_b stays exactly 1
    assert calibrate_heading(runs, 4, 4.0, geo).E_b == pytest.approx(1.0, abs=1e-12)


def test_circular_mean_keeps_unwrapped_scale():
    a = np.array([-2 * math.pi + 0.01, -2 * math.pi - 0.01, -2 * math.pi + 0.03])
    assert circular_mean(a) == pytest.approx(-2 * math.pi + 0.01, abs=1e-4)
    # samples either side of the +-pi cut: the mean is pi, not 0
    assert circular_mean(np.array([3.1, -3.1])) == pytest.approx(math.pi, abs=1e-12)


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
