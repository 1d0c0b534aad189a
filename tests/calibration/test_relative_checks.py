"""The checks of a relative-motion fit from a bag (calibration.relative_checks)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from odocal.calibration.censi import fit_censi
from odocal.calibration.heldout import ModelScore, fit_base_motion
from odocal.calibration.relative_checks import (
    check_relative_fit,
    interval_blocks,
    preferred_answer,
    slam_chains,
    with_offset_error,
)
from odocal.calibration.relative_motions import RelativeMotions, wheel_increments
from odocal.calibration.time_offset import TimeOffset, time_blocks
from odocal.core.odometry import dead_reckon_rows
from tests.support.relative_intervals import NOMINAL, TRUE, motions


def fitted(m: RelativeMotions):
    return fit_censi(m.phi_right_rad, m.phi_left_rad, m.sensor_motion, sensor_pose=(0, 0, 0),
                     wheel_increments=m.increments)  # fmt: skip


def test_the_checks_of_a_good_calibration():
    m = motions()
    result = fitted(m)
    usable = np.ones(len(m.phi_right_rad), dtype=bool)
    checks = check_relative_fit(m, usable, np.zeros(3), result, NOMINAL, source="SLAM")
    assert checks.heldout is not None and checks.heldout.preferred == "full"
    assert checks.noise is not None and checks.noise.intervals == 300
    assert checks.heldout_problem is None and checks.notes == ()
    # the answer is the full fit's
    answer = preferred_answer(result, checks.heldout)
    assert answer.model == "full" and answer.geometry == result.geometry
    assert answer.stderr == (result.stderr["wheel_diameter_right_m"],
                             result.stderr["wheel_diameter_left_m"],
                             result.stderr["wheelbase_m"])  # fmt: skip
    # a restricted model preferred by the check is the answer, with its own errors
    fit = fit_base_motion("scale", *m.increments, m.sensor_motion, NOMINAL, m.start_s)
    extra = ModelScore("scale", fit.geometry, 0.0, True, fit)
    scale = replace(checks.heldout, preferred="scale", models=(*checks.heldout.models, extra))
    answer = preferred_answer(result, scale)
    score = next(s for s in scale.models if s.model == "scale")
    assert answer.model == "scale" and answer.geometry == score.geometry
    assert answer.stderr[2] is not None or score.fit is None


def test_what_is_not_checked_is_said():
    m = motions(n=100)  # what is checked does not depend on the length (a short log: below)
    result = fitted(m)
    usable = np.ones(len(m.phi_right_rad), dtype=bool)
    without = check_relative_fit(m, usable, np.zeros(3), result, None, source="SLAM")
    assert without.heldout is None and without.heldout_problem is None
    assert without.notes == ("no held-out check: it needs the nominal geometry (--robot)",)
    assert without.noise is not None  # the noise needs no nominal geometry
    untimed = RelativeMotions(m.phi_right_rad, m.phi_left_rad, m.sensor_motion)
    checks = check_relative_fit(untimed, usable, np.zeros(3), result, NOMINAL, source="SLAM")
    assert checks.notes == ("no held-out check: the intervals carry no times",)
    # a log too short for the check: the problem, for the caller to refuse without --force
    short = motions(n=12)
    usable = np.ones(12, dtype=bool)
    checks = check_relative_fit(short, usable, np.zeros(3), fitted(short), NOMINAL, source="x")
    assert checks.heldout is None and "too short" in str(checks.heldout_problem)
    assert checks.notes[0] == f"no held-out check: {checks.heldout_problem}"
    assert checks.notes[1].startswith("no noise estimate: too few intervals")


def test_interval_blocks():
    m = motions(n=120)
    assert np.array_equal(interval_blocks(m), time_blocks(m.start_s))
    untimed = interval_blocks(RelativeMotions(m.phi_right_rad, m.phi_left_rad, m.sensor_motion))
    assert untimed[0] == 0 and np.all(np.diff(untimed) >= 0) and untimed[-1] > 0


def test_slam_chains_mark_what_the_fit_used():
    a, b = motions(n=4, seed=1), motions(n=2, seed=2)
    # bag a gave intervals 0, 2, 3 to the fit, bag b both; the fit dropped its 2nd and 4th
    every, usable = slam_chains(
        [(a, np.array([True, False, True, True])), (b, np.array([True, True]))], (1, 3)
    )
    assert usable.tolist() == [True, False, False, True, False, True]
    assert len(every.phi_right_rad) == 6
    assert np.array_equal(every.start_s[:4], a.start_s)  # (the bags strung on one clock)
    assert np.array_equal(every.sensor_motion, np.r_[a.sensor_motion, b.sensor_motion])


def test_the_offset_s_own_uncertainty_widens_the_covariance():
    rng = np.random.default_rng(3)
    t = np.arange(0.0, 300.0, 0.02)
    right = np.cumsum(rng.uniform(0.0, 0.2, size=len(t)))
    left = np.cumsum(rng.uniform(0.0, 0.2, size=len(t)))
    start, end = np.arange(1.0, 298.0, 1.0), np.arange(2.0, 299.0, 1.0)
    inc_r, inc_l = wheel_increments(t, right, left, start, end)
    motion = dead_reckon_rows(inc_r, inc_l, TRUE)[:, :, -1].T
    motion = motion + rng.standard_normal(motion.shape) * 0.002
    result = fit_censi(inc_r.sum(axis=1), inc_l.sum(axis=1), motion, sensor_pose=(0, 0, 0),
                       wheel_increments=(inc_r, inc_l))  # fmt: skip
    given = TimeOffset.given("slam", 0.0)
    assert with_offset_error(result, given, t, right, left, start, end, motion) is result
    est = TimeOffset("slam", 0.0, 0.02, "estimated", applied=False)
    wider = with_offset_error(result, est, t, right, left, start, end, motion)
    assert wider.uncertainty.endswith("and the clock offset's own uncertainty")
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        assert wider.stderr[key] >= result.stderr[key]
    assert wider.stderr["sensor_x_m"] is None  # fixed parameters stay unestimated
    assert wider.geometry == result.geometry
    assert np.isnan(wider.covariance[3, 3])
    assert wider.stderr["wheelbase_m"] == pytest.approx(np.sqrt(wider.covariance[2, 2]))
