"""UMBmark: the worked example (TV1), its known small-angle error, the E_d coupling of its x- and
y-forms."""

import numpy as np
import pytest

from odocal.calibration.heading import calibrate_heading
from odocal.calibration.umbmark import calibrate_umbmark, umbmark_factors
from odocal.core.model import Robot, SystematicError, WheelGeometry
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import simulate
from odocal.core.tracks import polygon

NOMINAL = WheelGeometry.symmetric(0.15, 0.385)


def _noise_free_runs(robot, sides, side_m):
    errs = [simulate(polygon(sides, side_m, d), robot, 1, None).errors[0] for d in ("cw", "ccw")]
    return EndPoseRuns(("cw", "ccw"), np.array(errs))


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


def test_umbmark_default_form_is_the_mean_and_headings_do_not_count():
    # UMBmark reads positions only: its default is the mean form, and neither its factors nor
    # their standard errors depend on the measured headings
    rng = np.random.default_rng(3)
    robot = Robot(WheelGeometry.symmetric(0.15, 0.34), SystematicError(1.0, 1.004))
    ends = _noise_free_runs(robot, 4, 4.0).errors
    err = np.repeat(ends, 4, axis=0) + rng.normal(0.0, 0.01, (8, 3))
    runs = EndPoseRuns(("cw",) * 4 + ("ccw",) * 4, err)
    geo = WheelGeometry.symmetric(0.15, 0.34)
    default = calibrate_umbmark(runs, 4.0, geo)
    mean = calibrate_umbmark(runs, 4.0, geo, "mean")
    assert (default.E_b, default.E_d) == (mean.E_b, mean.E_d)
    assert default.E_b != calibrate_umbmark(runs, 4.0, geo, "x").E_b
    other = err.copy()
    other[:, 2] = rng.normal(0.0, 0.5, 8)
    moved = calibrate_umbmark(EndPoseRuns(runs.directions, other), 4.0, geo)
    assert default.uncertainty is not None and moved.uncertainty is not None
    assert (moved.E_b, moved.E_d) == (default.E_b, default.E_d)
    np.testing.assert_allclose(
        moved.uncertainty.covariance, default.uncertainty.covariance, rtol=1e-9, atol=0
    )
