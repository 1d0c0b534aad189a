"""Independent re-derivations of the reference model (review of the math against model.md and
methods-notes.md). Each test recomputes a published test vector or a DERIVED relation by a route
that does not share code with the function under test (brute-force Monte Carlo, the model's own
closed forms, scipy), so a sign, frame, unit or factor-of-2 slip in either shows up.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.bcpt import bcpt_factors, bcpt_first_order
from odocal.calibration.circle_fit import fit_circle
from odocal.calibration.gyro import gyro_calibration, rotation_from_rpy
from odocal.calibration.heading import heading_factors
from odocal.calibration.ivanjko import ivanjko_from_end_poses
from odocal.calibration.linear import fit_linear
from odocal.calibration.noise import estimate_k
from odocal.calibration.trajectory import fit_trajectory
from odocal.calibration.umbmark import umbmark_factors
from odocal.core.covariance import propagate, straight_line_covariance
from odocal.core.model import NonSystematicError, SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import drive
from odocal.core.stats import ttest_samples
from odocal.core.tracks import (
    Segment,
    Track,
    circle,
    out_and_back,
    polygon,
    spot_turn,
    straight_line,
)
from odocal.design.metrics import leg_heading_curve
from odocal.design.result import ValidationTrack
from odocal.design.sweep import simulate_candidates
from odocal.presets import PRESETS

NO_NOISE = NonSystematicError()


def _exact(track, true, believed):
    """Noise-free true final pose error, one exact arc per segment, shape (3,)."""
    r = drive(track, true, believed, NO_NOISE, 1, None, steps_per_segment=1, integration="exact")
    return r.errors[0]


# --- systematic relations ------------------------------------------------------------------


def test_derived_per_turn_and_per_leg_relations_with_the_1cm_midpoint_simulation():
    # model.md: a spot turn of psi really turns psi / E_b; a leg of L curves by
    # beta = 2 L (E_d - 1) / ((E_d + 1) E_b b_n); both exact (the midpoint update is exact for a
    # spot turn, and a straight leg's heading is the sum of increments whatever their size)
    nom = WheelGeometry.symmetric(0.1, 0.4)
    E_b, E_d, L = 1.03, 1.004, 3.0
    true = nom.with_systematic(SystematicError(E_b, E_d, 1.02))
    turn = drive(Track("t", (spot_turn(1.0),)), true, nom, NO_NOISE, 1, None).true_final[0, 2]
    # E_s = 1.02 scales the turn too (alpha measures E_b / E_s: methods-notes 2.2)
    assert turn == pytest.approx(1.02 / E_b, rel=1e-12)
    true = nom.with_systematic(SystematicError(E_b, E_d))
    leg = drive(straight_line(L), true, nom, NO_NOISE, 1, None).true_final[0, 2]
    assert leg == pytest.approx(2 * L * (E_d - 1) / ((E_d + 1) * E_b * 0.4), rel=1e-12)


def test_heading_method_is_exact_for_random_polygons_and_non_nominal_believed_parameters():
    # The robot already runs with a previous calibration (mean diameter kept). The heading method
    # is exact up to a common scale of (D_R, D_L, b), which no closed track can see: the
    # corrected diameter ratio and b / D_R must equal the true ones.
    rng = np.random.default_rng(1)
    for _ in range(25):
        n = int(rng.integers(3, 9))
        L, b_n, d_n = rng.uniform(0.5, 6), rng.uniform(0.2, 0.8), rng.uniform(0.05, 0.3)
        nom = WheelGeometry.symmetric(d_n, b_n)
        ran = nom.corrected(rng.uniform(0.97, 1.03), rng.uniform(0.99, 1.01))
        true = nom.with_systematic(
            SystematicError(rng.uniform(0.95, 1.05), rng.uniform(0.99, 1.01))
        )
        th = {d: _exact(polygon(n, L, d), true, ran)[2] for d in ("cw", "ccw")}
        E_b, E_d = heading_factors(th["cw"], th["ccw"], n, L, ran.wheelbase_m)
        c = ran.corrected(E_b, E_d)
        assert c.diameter_ratio == pytest.approx(true.diameter_ratio, rel=1e-12)
        assert c.wheelbase_m / c.diameter_right_m == pytest.approx(
            true.wheelbase_m / true.diameter_right_m, rel=1e-12
        )


def test_heading_method_tv3():
    E_b, E_d = heading_factors(math.radians(-1.8118), math.radians(6.3912), 4, 4.0, 0.340)
    assert float(E_b) == pytest.approx(0.988735, abs=1e-6)
    assert float(E_b) * 340 == pytest.approx(336.170, abs=1e-3)
    assert float(E_d) == pytest.approx(1.000840, abs=1e-6)


def test_umbmark_tv1_and_approximation_table():
    cw, ccw = np.array([0.0634, 0.0626]), np.array([0.2300, -0.2094])
    expect = {"x": (0.9884607, 1.000885), "y": (0.9892933, 1.000780), "mean": (0.9888768, 1.000833)}
    for form, (eb, ed) in expect.items():
        E_b, E_d = umbmark_factors(cw, ccw, 4.0, 0.340, form, "nominal")
        assert float(E_b) == pytest.approx(eb, abs=1e-7)
        assert float(E_d) == pytest.approx(ed, abs=1e-6)
    # methods-notes 1.7 (E_b 1.01, E_d 1.002, b 0.34 m, L = 4 m), from simulated squares
    nom = WheelGeometry.symmetric(0.1, 0.34)
    true = nom.with_systematic(SystematicError(1.01, 1.002))
    e = {d: _exact(polygon(4, 4.0, d), true, nom)[:2] for d in ("cw", "ccw")}
    for form, d_eb in (("x", -7.4e-4), ("y", 1.2e-3), ("mean", 2.2e-4)):
        E_b, _ = umbmark_factors(e["cw"], e["ccw"], 4.0, 0.34, form, "nominal")
        assert float(E_b) - 1.01 == pytest.approx(d_eb, abs=0.06e-3)
    # a pure E_d error: spurious E_b 0.9979 (x) and 1.0035 (y)
    true = nom.with_systematic(SystematicError(1.0, 1.004))
    e = {d: _exact(polygon(4, 4.0, d), true, nom)[:2] for d in ("cw", "ccw")}
    assert float(umbmark_factors(e["cw"], e["ccw"], 4.0, 0.34, "x")[0]) == pytest.approx(
        0.9979, abs=1e-4
    )
    assert float(umbmark_factors(e["cw"], e["ccw"], 4.0, 0.34, "y")[0]) == pytest.approx(
        1.0035, abs=1e-4
    )


def test_bcpt_tv5_and_simulated_circles_with_a_scale_error():
    E_b, E_d = bcpt_factors(1.015798, 1.004270, 1.0, 0.340)
    assert float(E_b) == pytest.approx(1.010000, abs=2e-6)
    assert float(E_d) == pytest.approx(1.002000, abs=2e-7)
    lin = bcpt_first_order(1.015798, 1.004270, 1.0, 0.340)
    assert float(lin[0]) == pytest.approx(1.010034, abs=1e-6)
    assert float(lin[1]) == pytest.approx(1.001960, abs=1e-6)
    nom = WheelGeometry.symmetric(0.1, 0.34)
    true = nom.with_systematic(SystematicError(1.01, 1.002, 1.03))  # E_s cancels
    radius = {}
    for d in ("cw", "ccw"):
        r = drive(circle(1.0, d), true, nom, NO_NOISE, 1, None, integration="exact",
                  trajectory=True)  # fmt: skip
        radius[d] = fit_circle(r.trajectory[0, :, :2]).radius_m
    E_b, E_d = bcpt_factors(radius["cw"], radius["ccw"], 1.0, 0.34)
    assert float(E_b) == pytest.approx(1.01, abs=1e-9)
    assert float(E_d) == pytest.approx(1.002, abs=1e-9)


# --- statistics ----------------------------------------------------------------------------


def test_ttest_tv6_student_and_welch():
    from scipy import stats

    a = [12.1, 15.3, 9.8, 14.2, 11.0]
    b = [18.4, 21.0, 16.7, 25.3, 19.9]
    s = ttest_samples(a, b, equal_var=True)
    assert (s.t, s.df) == (pytest.approx(-4.396112, abs=1e-6), 8.0)
    assert s.p_two_sided == pytest.approx(0.00229867, abs=1e-8)
    assert s.p_less == pytest.approx(0.00114934, abs=1e-8)
    w = ttest_samples(a, b, equal_var=False)
    assert w.df == pytest.approx(7.136864, abs=1e-6)
    assert w.p_two_sided == pytest.approx(0.00302735, abs=1e-8)
    ref = stats.ttest_ind(a, b, equal_var=False, alternative="less")
    assert w.p_less == pytest.approx(ref.pvalue, rel=1e-10)


# --- non-systematic errors -----------------------------------------------------------------


def test_covariance_tv4_closed_form_propagation_and_one_step():
    g = WheelGeometry.symmetric(0.1, 0.5)
    expect = np.array([[0.01, 0, 0], [0, 0.213333, 0.16], [0, 0.16, 0.16]])
    assert 1e4 * straight_line_covariance(2.0, 0.5, 1e-6, 1e-6) == pytest.approx(expect, abs=1e-6)
    p = propagate(straight_line(2.0), g, g, NonSystematicError(1e-6, 1e-6), steps_per_segment=2000)
    assert 1e4 * p.covariance == pytest.approx(expect, abs=1e-6)
    p10 = propagate(straight_line(2.0), g, g, NonSystematicError(1e-6, 1e-6), steps_per_segment=10)
    assert 1e4 * p10.covariance[1, 1] == pytest.approx(0.2128, abs=1e-6)
    # TV4-b: one step, ds_R = 0.0105, ds_L = 0.0095 (d = 0.01 m, dtheta = 0.002 rad)
    one = propagate(Track("step", (Segment(0.01, 0.002),)), g, g, NonSystematicError(1e-4, 1e-4),
                    steps_per_segment=1)  # fmt: skip
    assert one.mean == pytest.approx([9.999995e-3, 9.999998e-6, 2.0e-3], rel=1e-6)
    tv4b = [
        [4.999985e-7, 9.997987e-10, 9.995995e-8],
        [9.997987e-10, 2.014998e-10, 4.009998e-8],
        [9.995995e-8, 4.009998e-8, 8.000000e-6],
    ]
    assert one.covariance == pytest.approx(np.array(tv4b), rel=2e-6)


def test_straight_line_covariance_with_unequal_k_against_monte_carlo():
    kr, kl, d, b = 3e-6, 1e-6, 3.0, 0.4
    g = WheelGeometry.symmetric(0.1, b)
    closed = straight_line_covariance(d, b, kr, kl)
    prop = propagate(straight_line(d), g, g, NonSystematicError(kr, kl), steps_per_segment=2000)
    assert prop.covariance == pytest.approx(closed, rel=1e-5)
    n = 40_000
    e = drive(straight_line(d), g, g, NonSystematicError(kr, kl), n, np.random.default_rng(2),
              steps_per_segment=60, integration="exact").errors  # fmt: skip
    mc = np.cov(e.T)
    # sample covariances of n Gaussian draws: relative s.e. of var ~ sqrt(2/n) = 0.7 %, of a
    # covariance sqrt((1 + rho^-2)/n) <= 1.3 % for these correlations (|rho| >= 0.3); allow 5 s.e.
    assert np.diag(mc) == pytest.approx(np.diag(closed), rel=0.035)
    off = [(0, 1), (0, 2), (1, 2)]
    assert [mc[i, j] for i, j in off] == pytest.approx([closed[i, j] for i, j in off], rel=0.065)


@pytest.mark.parametrize("track", ["out-and-back", "straight"])
def test_noise_estimator_chi_square_coverage_and_k_difference(track):
    # 600 sets of 10 runs: coverage of the 95 % interval has s.e. sqrt(.95 .05 / 600) = 0.9 %;
    # the mean k_sum estimate has s.e. sqrt(2/9)/sqrt(600) = 1.9 %; k_diff about 2 % (measured).
    rng = np.random.default_rng(11)
    b, kr, kl, d, N, M = 0.4, 3e-6, 1e-6, 5.0, 10, 600
    nom = WheelGeometry.symmetric(0.15, b)
    E_b, E_d = 1.02, 1.004
    true = nom.with_systematic(SystematicError(E_b, E_d))
    tr = out_and_back(d) if track == "out-and-back" else straight_line(d)
    e = drive(tr, true, nom, NonSystematicError(kr, kl), N * M, rng, steps_per_segment=40,
              integration="exact").errors.reshape(M, N, 3)  # fmt: skip
    curvature = 2 * (E_d - 1) / ((E_d + 1) * E_b * b)
    ests = [
        estimate_k(EndPoseRuns(("fwd",) * N, e[m]), track, d, b * E_b,
                   curvature_rad_per_m=curvature, strict=False)
        for m in range(M)
    ]  # fmt: skip
    cover = np.mean([lo <= kr + kl <= hi for lo, hi in (x.k_sum_ci95_m for x in ests)])
    assert 0.95 - 0.04 < cover < 0.95 + 0.04
    assert np.mean([x.k_sum_m for x in ests]) == pytest.approx(kr + kl, rel=0.08)
    assert np.mean([x.k_diff_m for x in ests]) == pytest.approx(kr - kl, rel=0.10)


# --- recorded-run and other calibrations: exact without noise ------------------------------


def _recording(name, true, ran_with, dphi_r, dphi_l, label=None):
    pr = np.concatenate([[0.0], np.cumsum(dphi_r)])
    pl = np.concatenate([[0.0], np.cumsum(dphi_l)])
    gt = dead_reckon(pr, pl, true)
    return Recording(name, np.arange(len(pr)) * 0.1, pr, pl, gt, None, ran_with, label)


def test_linear_and_trajectory_recover_the_methods_notes_example_exactly():
    # methods-notes 5.5: r_R = 0.1010, r_L = 0.0995, b = 0.52 m (radii; diameters are twice)
    true = WheelGeometry(0.2020, 0.1990, 0.52)
    nom = WheelGeometry.symmetric(0.2, 0.5)
    k = 400
    recs = [
        _recording("ccw", true, nom, np.full(k, 0.10), np.full(k, 0.07)),
        _recording("cw", true, nom, np.full(k, 0.07), np.full(k, 0.10)),
        _recording("spin", true, nom, np.full(k, 0.05), np.full(k, -0.05)),
        _recording("line", true, nom, np.full(k, 0.10), np.full(k, 0.10)),
    ]
    for fit in (fit_linear(recs), fit_trajectory(recs, nominal=nom)):
        g = fit.geometry
        got = [g.diameter_right_m, g.diameter_left_m, g.wheelbase_m]
        assert got == pytest.approx([0.2020, 0.1990, 0.52], rel=1e-9)


def test_ivanjko_recovers_scale_ratio_and_wheelbase_exactly():
    nom = WheelGeometry.symmetric(0.15, 0.385)
    true = nom.with_systematic(SystematicError(1.02, 1.003, 1.01))

    def final(track):  # measured TRUE final pose (not the error)
        return drive(track, true, nom, NO_NOISE, 1, None, steps_per_segment=1,
                     integration="exact").true_final[0]  # fmt: skip

    straight = final(straight_line(3.0))
    cw = final(Track("cw", (spot_turn(-math.pi),)))
    ccw = final(Track("ccw", (spot_turn(math.pi),)))
    fit = ivanjko_from_end_poses(
        straight[None, None], 3.0, cw[None, None], ccw[None, None], math.pi, nom, tolerance=1e-10
    )
    g = fit.geometry.take(0)
    got = [g.diameter_right_m, g.diameter_left_m, g.wheelbase_m]
    assert got == pytest.approx(
        [true.diameter_right_m, true.diameter_left_m, true.wheelbase_m], rel=1e-9
    )


def test_gyro_ratio_with_a_tilted_upside_down_imu_and_a_bias():
    t = np.arange(0.0, 60.0, 0.01)
    rate = np.where((t > 5) & (t < 55), 0.5 * np.sin(0.1 * (t - 5)) ** 2 + 0.3, 0.0)
    R = rotation_from_rpy(0.3, math.pi, 0.7)  # base <- imu
    w_imu = np.column_stack([0 * t, 0 * t, rate]) @ R + R.T @ [0.0, 0.0, 0.002]
    w_imu += np.random.default_rng(0).normal(0.0, 0.001, w_imu.shape)
    odo = np.concatenate([[0], np.cumsum(0.5 * (rate[1:] + rate[:-1]) * np.diff(t))]) / 1.02
    r = gyro_calibration(t, w_imu, t, odom_yaw_rad=odo, rotation=R, bias="still")
    # white noise 1e-3 rad/s at 100 Hz over 60 s moves the ratio by ~1e-4 (and the bias s.e.)
    assert r.rotation_ratio == pytest.approx(1.02, abs=5e-4)
    assert r.wheelbase_multiplier == pytest.approx(1 / 1.02, abs=5e-4)
    assert r.bias_rad_s == pytest.approx(0.002, abs=1e-4)


# --- design --------------------------------------------------------------------------------


def test_systematic_share_at_4m_is_the_papers_91_percent():
    curve = leg_heading_curve(PRESETS["paper-fig3"], [4.0], runs_per_direction=5)
    assert curve.share[0] == pytest.approx(0.91, abs=0.005)
    # and independently from model.md's closed forms
    b = 0.385 * 1.025
    beta = 2 * 4.0 * (0.999 - 1) / (1.999 * b)
    sigma = math.sqrt(2e-6 * 4.0) / b
    assert curve.share[0] == pytest.approx(beta**2 / (beta**2 + sigma**2 / 5), rel=2e-3)


def test_design_candidate_statistics_do_not_depend_on_batching():
    from scipy import stats

    robot, val, trials = PRESETS["paper-fig5"], ValidationTrack(4, 4.0, "ccw"), 1500
    alone = simulate_candidates(
        robot, 4, [2.0], 5, trials, "heading", val, np.random.default_rng(7)
    )
    swept = simulate_candidates(
        robot, 4, [0.5, 2.0, 6.0], 5, trials, "heading", val, np.random.default_rng(8)
    )[1]
    a, b = alone[0], swept
    # independent samples of one distribution: Welch test of the post-calibration errors, and
    # the calibrated factors' means within 4 standard errors
    assert stats.ttest_ind(a.post_errors_m, b.post_errors_m, equal_var=False).pvalue > 1e-4
    for m1, s1, m2, s2 in ((a.E_b_mean, a.E_b_std, b.E_b_mean, b.E_b_std),
                           (a.E_d_mean, a.E_d_std, b.E_d_mean, b.E_d_std)):  # fmt: skip
        assert abs(m1 - m2) < 4 * math.hypot(s1, s2) / math.sqrt(trials)
        assert s1 == pytest.approx(s2, rel=0.15)  # s.e. of a std ratio ~ sqrt(1/trials) = 2.6 %


@pytest.mark.parametrize(
    "argv",
    [
        ("simulate", "--runs", "3", "--json"),
        ("design", "--trials", "20", "--side-lengths", "1:2:1", "--json", "--quiet"),
    ],
)
def test_seed_reproducibility(cli, argv):
    s1, out1, _ = cli(*argv, "--seed", "5")
    s2, out2, _ = cli(*argv, "--seed", "5")
    s3, out3, _ = cli(*argv, "--seed", "6")
    assert s1 == s2 == s3 == 0
    assert out1 == out2
    assert out1 != out3
    assert '"seed": 5' in out1
