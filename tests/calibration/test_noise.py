"""k_r, k_l from repeated straight runs (calibration.noise): estimators, intervals, checks."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.noise import estimate_k
from odocal.core.model import MeasurementNoise
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import simulate
from odocal.core.tracks import out_and_back, straight_line
from odocal.errors import CalibrationError
from tests.support.noise_runs import fwd_runs, noise_robot

B = 0.385


@pytest.mark.parametrize(
    ("kind", "make"), [("out-and-back", out_and_back), ("straight", straight_line)]
)
def test_recovers_k_within_the_chi_square_interval(kind, make):
    robot = noise_robot(3e-6, 1e-6, MeasurementNoise.from_degrees(0.001, 0.05))
    est = estimate_k(fwd_runs(robot, make(10.0), 30, seed=7), kind, 10.0, B, robot.measurement)
    lo, hi = est.k_sum_ci95_m
    assert lo < 4e-6 < hi
    # the interval is the chi-square one: for 29 degrees of freedom it spans a factor 2.85
    assert 2.0 < hi / lo < 3.2
    assert est.runs == 30 and est.warnings == ()


def test_interval_coverage_over_many_seeds():
    # (N - 1) s^2 / sigma^2 is exactly chi-square here (the heading is linear in the noise), so
    # 400 independent experiments cover the truth 95 % of the time: binomial sd 1.1 %, 4 sd
    robot = noise_robot()
    rng = np.random.default_rng(3)
    res = simulate(out_and_back(5.0), robot, 400 * 12, rng, max_step_m=0.5)
    e = res.errors.reshape(400, 12, 3)
    hits = 0
    for i in range(400):
        est = estimate_k(EndPoseRuns(("fwd",) * 12, e[i]), "out-and-back", 5.0, B, strict=False)
        hits += est.k_sum_ci95_m[0] <= 4e-6 <= est.k_sum_ci95_m[1]
    assert abs(hits / 400 - 0.95) < 0.045


def test_worked_example_and_units():
    # methods-notes 3.5(b): s_theta^2 = 4.0e-5 rad^2, b = 0.5 m, d = 10 m -> k_r + k_l = 5.0e-7 m,
    # i.e. k = 2.5e-7 m per wheel = 5.0e-4 m^0.5 in Chong & Kleeman's units (k_CK = sqrt(k)).
    z = np.array([-1.5, -1.0, -0.5, 0.0, 0.5, 1.0, 1.5, 0.2, -0.2, 0.0])
    th = z / np.std(z, ddof=1) * math.sqrt(4.0e-5)
    err = np.column_stack([np.zeros(10), np.zeros(10), th])
    est = estimate_k(EndPoseRuns(("fwd",) * 10, err), "out-and-back", 10.0, 0.5)
    assert est.k_sum_m == pytest.approx(5.0e-7, rel=1e-12)
    assert math.sqrt(est.k_sum_m / 2) == pytest.approx(5.0e-4, rel=1e-12)
    assert est.as_dict()["k_each_m"] == pytest.approx(2.5e-7)
    assert est.as_dict()["k_each_chong_kleeman_m05"] == pytest.approx(5.0e-4)
    # the same spread from one-way runs means twice the k (half the travel)
    est1 = estimate_k(EndPoseRuns(("fwd",) * 10, err), "straight", 10.0, 0.5)
    assert est1.k_sum_m == pytest.approx(1.0e-6, rel=1e-12)


def test_instrument_noise_is_subtracted():
    robot = noise_robot(meas=MeasurementNoise.from_degrees(0.0, 0.3))
    runs = fwd_runs(robot, out_and_back(10.0), 20, seed=1)
    raw = estimate_k(runs, "out-and-back", 10.0, B)
    sub = estimate_k(runs, "out-and-back", 10.0, B, robot.measurement)
    expected = raw.k_sum_m - B**2 * math.radians(0.3) ** 2 / 20.0
    assert sub.k_sum_m == pytest.approx(expected, rel=1e-12)
    with pytest.raises(CalibrationError, match="instrument"):
        estimate_k(runs, "out-and-back", 10.0, B, MeasurementNoise.from_degrees(0.0, 5.0))


def _curvature(robot):
    t, b = robot.true_geometry, robot.believed_geometry
    f_r = t.diameter_right_m / b.diameter_right_m
    f_l = t.diameter_left_m / b.diameter_left_m
    return (f_r - f_l) / t.wheelbase_m


@pytest.mark.parametrize(
    ("kind", "make"), [("out-and-back", out_and_back), ("straight", straight_line)]
)
def test_k_r_and_k_l_separately_when_the_runs_allow_it(kind, make):
    # E_d = 1.004 curves the path enough to flip the sign of s_xtheta over 10 m: the split must
    # use the propagated coefficients, not the straight-path closed forms
    robot = noise_robot(3e-6, 1e-6)
    runs = fwd_runs(robot, make(10.0), 600, seed=5)
    est = estimate_k(runs, kind, 10.0, B, curvature_rad_per_m=_curvature(robot))
    assert est.k_r_m is not None and est.k_l_m is not None
    # k_r = (K+ + K-)/2: 4 standard errors of K-/2, plus 4 of K+/2 (chi-square, 600 runs: 5.8 %)
    tol = 4 * est.k_diff_se_m / 2 + 4 * 0.058 * 4e-6 / 2
    assert est.k_r_m == pytest.approx(3e-6, abs=tol)
    assert est.k_l_m == pytest.approx(1e-6, abs=tol)
    # with few runs the split is refused, with the reason (8 runs: refused for every one of 30
    # seeds tried; at 15 runs the rule, standard error > 25 % of k_r + k_l, holds for ~90 %)
    few = estimate_k(
        EndPoseRuns(runs.directions[:8], runs.errors[:8]),
        kind,
        10.0,
        B,
        curvature_rad_per_m=_curvature(robot),
    )
    assert few.k_r_m is None and "not identifiable" in few.split_note


def test_too_few_runs_is_an_error_and_few_runs_a_warning():
    robot = noise_robot()
    runs = fwd_runs(robot, out_and_back(10.0), 5, seed=2)
    with pytest.raises(CalibrationError, match="at least 3"):
        estimate_k(EndPoseRuns(("fwd",) * 2, runs.errors[:2]), "out-and-back", 10.0, B)
    est = estimate_k(runs, "out-and-back", 10.0, B)
    assert any("only 5 runs" in w for w in est.warnings)


def test_systematic_part_that_did_not_cancel_is_an_error():
    robot = noise_robot()
    runs = fwd_runs(robot, out_and_back(10.0), 15, seed=4)
    shifted = runs.errors + [0.0, 0.0, math.radians(2.0)]  # e.g. turned between the legs
    bad = EndPoseRuns(runs.directions, shifted)
    with pytest.raises(CalibrationError, match="standard errors from zero"):
        estimate_k(bad, "out-and-back", 10.0, B)
    forced = estimate_k(bad, "out-and-back", 10.0, B, strict=False)
    assert any("standard errors from zero" in w for w in forced.warnings)


def test_drift_with_run_order_is_an_error():
    robot = noise_robot()
    runs = fwd_runs(robot, straight_line(10.0), 15, seed=6)
    drift = runs.errors.copy()
    drift[:, 2] += np.radians(0.4) * np.arange(15)  # e.g. a tyre warming up
    with pytest.raises(CalibrationError, match="drift with run order"):
        estimate_k(EndPoseRuns(runs.directions, drift), "straight", 10.0, B)


def test_lateral_spread_from_a_misaligned_start_is_a_warning():
    robot = noise_robot()
    runs = fwd_runs(robot, straight_line(10.0), 20, seed=8)
    e = runs.errors.copy()
    # start heading misaligned by ~1 deg (random per run): y grows by d * delta
    delta = np.radians(1.0) * np.random.default_rng(9).standard_normal(20)
    e[:, 1] += 10.0 * delta
    est = estimate_k(EndPoseRuns(runs.directions, e), "straight", 10.0, B)
    assert any("lateral spread" in w for w in est.warnings)


def test_the_statistics_without_scipy_stats_are_scipy_stats_numbers():
    """The trend (linregress) and the chi^2 quantiles are computed without importing
    scipy.stats (0.6 s of every command's start-up): the same numbers. (The t quantile of the
    effective wheelbase is core.stats.student_t_quantile, tested in test_stats.py.)"""
    from scipy import stats

    from odocal.calibration.noise import _chi2_quantiles, _trend

    for dof in range(1, 200):
        assert np.array_equal(_chi2_quantiles(dof), stats.chi2.ppf([0.975, 0.025], dof))
    rng = np.random.default_rng(8)
    for n in (5, 6, 19, 200):
        for drift in (0.0, 1e-3, 1.0):
            y = drift * np.arange(n) + rng.normal(0.0, 1e-3, n)
            ref = stats.linregress(np.arange(n, dtype=float), y)
            slope, t, r2 = _trend(y)
            assert slope == pytest.approx(ref.slope, rel=1e-12)
            # linregress's stderr loses digits on a near-exact line (drift 1: 1 - r^2 ~ 1e-12);
            # 1e-3 still tells n - 2 from n - 1 degrees of freedom (0.25 % at n = 200)
            assert t == pytest.approx(ref.slope / ref.stderr, rel=1e-3)
            assert r2 == pytest.approx(ref.rvalue**2, rel=1e-9, abs=1e-15)
    assert _trend(np.full(6, 0.3)) == (0.0, 0.0, 0.0)  # no spread: no trend
    slope, t, r2 = _trend(2.0 * np.arange(6.0))  # an exact line
    assert slope == 2.0 and r2 == 1.0 and t == math.inf


def test_few_runs_whose_interval_reaches_zero_say_so_instead_of_an_absurd_factor():
    """4 runs whose heading spread is barely above the protractor's: the interval's lower end
    is 0 after the instrument's noise is taken off, and the warning gives the two ends (it once
    said 'spans a factor 1.47e+294', the upper end over 1e-300)."""
    z = np.array([-1.0, -0.3, 0.4, 0.9])
    th = z / np.std(z, ddof=1) * math.sqrt(4.0e-5)
    err = np.column_stack([np.zeros(4), np.zeros(4), th])
    meas = MeasurementNoise.from_degrees(0.0, 0.3)
    est = estimate_k(EndPoseRuns(("fwd",) * 4, err), "out-and-back", 10.0, 0.5, meas)
    assert est.k_sum_ci95_m[0] == 0.0 and est.k_sum_m > 0
    (said,) = [w for w in est.warnings if w.startswith("only 4 runs")]
    assert "factor" not in said and "e+" not in said
    assert f"runs from 0 to {est.k_sum_ci95_m[1]:.3g} m" in said
