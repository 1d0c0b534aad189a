"""Relative-motion calibration of odometry and sensor pose (Censi et al. 2013): calibration.censi
(the .tuple reader, io.tuples, is tested in tests/io/test_tuples.py).

Tiers: exact noise-free round trips; seeded noisy round trips with tolerances from the predicted
standard errors; outlier rejection; degenerate data; the authors' published results on their real
data.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

from odocal.calibration.censi import (
    PARAMETERS,
    closed_form_censi,
    fit_censi,
    predict_sensor_motion,
    relative_motion,
)
from odocal.core.model import ModelError, WheelGeometry
from odocal.errors import CalibrationError
from odocal.io.tuples import read_tuples

# A Khepera-like robot (the authors' real robot) with a sensor mounted off-centre and rotated, as
# a motion-capture marker body or a laser would be.
TRUTH_GEOMETRY = WheelGeometry(0.0416, 0.0411, 0.0885)
TRUTH_POSE = np.array([0.021, -0.013, 0.7])
TRUTH = np.array([0.0416, 0.0411, 0.0885, *TRUTH_POSE])
# Scan-matching noise of the order the authors' data show (m, m, rad)
NOISE = np.array([7e-4, 5e-4, 2e-3])


def synthetic(rng, n, pose=TRUTH_POSE, noise=None):
    """Random intervals mixing forward motion and turns of both signs, as in the paper's data:
    per interval a forward wheel rotation ~ N(0.2, 0.2) rad and a turning part ~ N(0, 0.3) rad."""
    fwd = rng.normal(0.2, 0.2, n)
    turn = rng.normal(0.0, 0.3, n)
    phi_r, phi_l = fwd + turn, fwd - turn
    sm = predict_sensor_motion(TRUTH_GEOMETRY, pose, phi_r, phi_l)
    if noise is not None:
        sm = sm + rng.normal(0.0, 1.0, sm.shape) * noise
    return phi_r, phi_l, sm


# --------------------------------------------------------------------------------------------
# (a) exact round trips


def test_noise_free_round_trip_is_exact():
    rng = np.random.default_rng(1000)
    phi_r, phi_l, sm = synthetic(rng, 200)
    # The arc model is exact, so both steps recover the truth up to floating point: the closed
    # form's eigen step loses a few digits (eigenvector of a near-zero eigenvalue), hence 1e-9
    # relative (lengths ~0.04 m -> 4e-11 m) rather than machine epsilon.
    p = closed_form_censi(phi_r, phi_l, sm)
    np.testing.assert_allclose(p, TRUTH, rtol=1e-9, atol=1e-12)
    fit = fit_censi(phi_r, phi_l, sm)
    np.testing.assert_allclose(fit.parameters, TRUTH, rtol=1e-9, atol=1e-12)
    assert fit.tuples_used + fit.tuples_dropped == fit.tuples_total == 200


def test_noise_free_with_known_sensor_pose_at_the_base():
    # the "sensor" is the robot base itself (e.g. SLAM poses of base_link): pose fixed at zero
    rng = np.random.default_rng(1001)
    phi_r, phi_l, sm = synthetic(rng, 100, pose=np.zeros(3))
    fit = fit_censi(phi_r, phi_l, sm, sensor_pose=[0.0, 0.0, 0.0])
    np.testing.assert_allclose(fit.parameters[:3], TRUTH[:3], rtol=1e-9)
    assert fit.sensor_pose_fixed and np.all(fit.sensor_pose == 0.0)
    d = fit.as_dict()
    assert d["stderr"]["sensor_x_m"] is None and d["stderr"]["wheelbase_m"] is not None


def test_relative_motion_of_absolute_poses_feeds_the_fit():
    # SLAM / motion capture: absolute poses of a body off the robot centre -> relative motions
    rng = np.random.default_rng(1002)
    phi_r, phi_l, sm = synthetic(rng, 150)
    poses = np.zeros((151, 3))
    for k in range(150):  # integrate the sensor motion in a world frame
        c, s = np.cos(poses[k, 2]), np.sin(poses[k, 2])
        poses[k + 1] = poses[k] + [
            c * sm[k, 0] - s * sm[k, 1],
            s * sm[k, 0] + c * sm[k, 1],
            sm[k, 2],
        ]
    np.testing.assert_allclose(relative_motion(poses), sm, atol=1e-12)


# --------------------------------------------------------------------------------------------
# (b) noisy round trip


def test_noisy_round_trip_within_predicted_standard_errors():
    rng = np.random.default_rng(2024)
    phi_r, phi_l, sm = synthetic(rng, 600, noise=NOISE)
    fit = fit_censi(phi_r, phi_l, sm, nominal=WheelGeometry(0.041, 0.041, 0.09))
    se = np.array([fit.stderr[k] for k in PARAMETERS])
    assert np.all(np.isfinite(se)) and np.all(se > 0)
    # 4 standard errors: a fixed seed, so this is deterministic; 4 sigma leaves room for the
    # standard errors being ~10 % optimistic after trimming (see the Monte-Carlo test below)
    err = fit.parameters - TRUTH
    err[5] = (err[5] + np.pi) % (2 * np.pi) - np.pi
    assert np.all(np.abs(err) < 4 * se), err / se
    # the noise estimate sees the injected noise (trimming cuts the tails, so a little lower)
    np.testing.assert_allclose(fit.noise_std, NOISE, rtol=0.2)
    assert fit.warnings == ()


def test_standard_errors_match_monte_carlo_spread():
    # 30 seeded trials: the spread of (estimate - truth) / stderr must be near 1. The sample
    # standard deviation of 30 unit normals is 1 +- 0.13 (1 sigma); [0.6, 1.6] allows > 3 sigma
    # plus the ~10 % optimism of standard errors computed after trimming.
    rng = np.random.default_rng(77)
    z = []
    for _ in range(30):
        phi_r, phi_l, sm = synthetic(rng, 200, noise=NOISE)
        fit = fit_censi(phi_r, phi_l, sm)
        se = np.array([fit.stderr[k] for k in PARAMETERS])
        z.append((fit.parameters - TRUTH) / se)
    spread = np.std(z, axis=0, ddof=1)
    assert np.all((spread > 0.6) & (spread < 1.6)), spread


# --------------------------------------------------------------------------------------------
# (c) outliers


def test_outlier_rejection_drops_injected_gross_outliers():
    rng = np.random.default_rng(31)
    phi_r, phi_l, sm = synthetic(rng, 400, noise=NOISE)
    bad = rng.choice(400, size=6, replace=False)
    # scan-matching failures: centimetres and degrees off, i.e. > 20 sigma
    sm[bad] += rng.choice([-1.0, 1.0], (6, 3)) * rng.uniform([0.02, 0.02, 0.1], [0.05, 0.05, 0.3])
    fit = fit_censi(phi_r, phi_l, sm)
    assert set(bad.tolist()) <= set(fit.dropped_indices)
    assert fit.tuples_dropped == sum(fit.dropped_per_round) and len(fit.dropped_per_round) == 4
    se = np.array([fit.stderr[k] for k in PARAMETERS])
    assert np.all(np.abs(fit.parameters - TRUTH) < 4 * se)
    # without rejection the same data give a biased result
    naive = fit_censi(phi_r, phi_l, sm, outlier_iterations=0)
    assert naive.tuples_dropped == 0
    assert np.max(np.abs(naive.parameters - TRUTH) / se) > 4


# --------------------------------------------------------------------------------------------
# (d) degenerate data and bad arguments


@pytest.mark.parametrize(
    ("kind", "needle"),
    [
        ("straight", "no turning"),
        ("spin", "no forward motion"),
        ("one_radius", "same curvature"),
        ("sensor_blind", "no rotation"),
        ("sensor_dim", "no rotation"),
        ("swapped", "swapped"),
        ("left_reversed", "left wheel's rotation sign"),
        ("few", "at least 10"),
    ],
)
def test_degenerate_data_refused(kind, needle):
    rng = np.random.default_rng(5)
    n = 5 if kind == "few" else 100
    a = rng.uniform(0.05, 0.4, n)
    phi_r, phi_l = {
        "straight": (a, a),
        "spin": (a, -a),
        "one_radius": (2 * a, a),
    }.get(kind, (a + rng.normal(0, 0.3, n), a - rng.normal(0, 0.3, n)))
    sm = predict_sensor_motion(TRUTH_GEOMETRY, TRUTH_POSE, phi_r, phi_l)
    sm += rng.normal(0.0, 1.0, sm.shape) * NOISE
    if kind == "sensor_blind":
        sm[:, 2] = rng.normal(0.0, NOISE[2], n)
    if kind == "sensor_dim":  # 1 % of the turning seen: 4.4 standard errors from 0, not 10
        sm[:, 2] -= 0.99 * predict_sensor_motion(TRUTH_GEOMETRY, TRUTH_POSE, phi_r, phi_l)[:, 2]
    if kind == "swapped":
        phi_r, phi_l = phi_l, phi_r
    if kind == "left_reversed":
        phi_l = -phi_l
    with pytest.raises(CalibrationError, match=needle):
        fit_censi(phi_r, phi_l, sm)


def test_bad_arguments_refused():
    rng = np.random.default_rng(6)
    phi_r, phi_l, sm = synthetic(rng, 50)
    with pytest.raises(ModelError, match="shape"):
        fit_censi(phi_r, phi_l[:-1], sm)
    with pytest.raises(ModelError, match=r"shape \(50, 3\)"):
        fit_censi(phi_r, phi_l, sm[:, :2])
    bad = sm.copy()
    bad[7, 1] = np.nan
    with pytest.raises(ModelError, match="tuple 7"):
        fit_censi(phi_r, phi_l, bad)
    with pytest.raises(ModelError, match="outlier_fraction"):
        fit_censi(phi_r, phi_l, sm, outlier_fraction=0.6)
    with pytest.raises(ModelError, match="sensor_pose"):
        fit_censi(phi_r, phi_l, sm, sensor_pose=[0.0, 0.0])


def test_json_contract():
    rng = np.random.default_rng(7)
    fit = fit_censi(*synthetic(rng, 120, noise=NOISE))
    d = fit.as_dict()
    json.dumps(d, allow_nan=False)  # no NaN/inf as numbers
    assert d["method"] == "relative"
    for k in PARAMETERS:
        assert isinstance(d[k], float) and isinstance(d["stderr"][k], float)
    assert d["tuples_used"] + d["tuples_dropped"] == d["tuples_total"] == 120
    assert len(d["covariance"]) == 6 and len(d["covariance_paper"]) == 6


# --------------------------------------------------------------------------------------------
# (e) the authors' real data and published results

FILES = [f"{s}{k}" for s in ("l90", "lmov", "lstraight") for k in ("", "_0", "_1", "_2")]


def _published(folder: Path, name: str):
    """Published (D_R, D_L, b, x, y, yaw) and covariance converted to odocal's order: their
    covariance is of (r_L, r_R, axle, l_x, l_y, l_theta), RADII (verified, docs/censi.md)."""
    pub = json.loads((folder / f"{name}_results.json").read_text())
    values = np.array(
        [pub["r_diam"], pub["l_diam"], pub["axle"], pub["l_x"], pub["l_y"], pub["l_theta"]]
    )
    to_ours = np.zeros((6, 6))
    to_ours[0, 1] = to_ours[1, 0] = 2.0  # D_R = 2 r_R, D_L = 2 r_L
    to_ours[2, 2] = to_ours[3, 3] = to_ours[4, 4] = to_ours[5, 5] = 1.0
    cov = to_ours @ np.array(pub["covariance"]) @ to_ours.T
    return values, cov


@pytest.fixture(scope="module")
def censi_folder(realdata):
    folder = realdata / "censi_calibration"
    if not folder.is_dir():  # the shared real data hold it beside optiodom_diff/
        pytest.fail(f"{folder} missing: the shared real-data folder is incomplete")
    return folder


@pytest.mark.parametrize("name", FILES)
def test_real_data_reproduce_published_results(censi_folder, name):
    data = read_tuples(censi_folder / f"{name}.tuple")
    values, cov = _published(censi_folder, name)
    std = np.sqrt(np.diag(cov))
    fit = fit_censi(data.phi_right_rad, data.phi_left_rad, data.sensor_motion)
    # requirement: every parameter within the authors' own standard deviation
    z = np.abs(fit.parameters - values) / std
    assert np.all(z < 1.0), dict(zip(PARAMETERS, z.round(3), strict=True))
    # the closed-form estimate IS the authors' estimator: equal to their 6 printed digits
    # (relative 5e-6 of each value, far below 1e-2 std)
    np.testing.assert_allclose(fit.closed_form, values, rtol=5e-6)
    # the authors' covariance, recomputed at our estimate: their order and units verified
    np.testing.assert_allclose(np.sqrt(np.diag(fit.covariance_paper)), std, rtol=0.01)
    assert not fit.warnings


def test_the_increments_jacobian_is_the_derivative_of_the_residual():
    """The analytic Jacobian for wheel increments (zero-padded rows of different lengths)
    against central differences of the residual itself, with a sensor off the axle and
    yawed, and with per-tuple weights."""
    from odocal.calibration import censi

    rng = np.random.default_rng(7)
    n, k = 40, 30
    inc_r, inc_l = np.zeros((n, k)), np.zeros((n, k))
    for i, m in enumerate(rng.integers(1, k + 1, n)):
        inc_r[i, :m] = rng.uniform(-0.2, 0.6, m)
        inc_l[i, :m] = rng.uniform(-0.2, 0.6, m)
    p = np.array([0.071, 0.069, 0.29, 0.05, -0.03, 0.4])
    sm = censi._predict(p, inc_r, inc_l) + rng.normal(0.0, 0.01, (n, 3))
    weight = rng.uniform(0.5, 2.0, (n, 3))
    free = [0, 1, 2, 3, 4, 5]
    got = censi._increments_jacobian(p, free, inc_r, inc_l, weight)
    for col, j in enumerate(free):
        h = 1e-7 * max(abs(p[j]), 0.05)
        up, dn = p.copy(), p.copy()
        up[j] += h
        dn[j] -= h
        fd = (censi._residual(up, inc_r, inc_l, sm) - censi._residual(dn, inc_r, inc_l, sm)) / (
            2 * h
        )
        np.testing.assert_allclose(got[:, col], (fd * weight).ravel(), rtol=1e-6, atol=1e-7)
    assert censi._jacobian(p, [2, 0], inc_r, inc_l, sm, weight).shape == (3 * n, 2)


# --------------------------------------------------------------------------------------------
# (d) the uncertainty's parts


def _residuals(fit, phi_r, phi_l, sm):
    e = predict_sensor_motion(fit.geometry, fit.sensor_pose, phi_r, phi_l) - sm
    e[:, 2] = (e[:, 2] + np.pi) % (2 * np.pi) - np.pi
    return e


@pytest.mark.parametrize("rounds", [0, 4])
def test_the_noise_is_the_larger_of_the_kept_rms_and_the_mad_of_all(rounds):
    # per component: RMS over the tuples used (6 parameters spread over 3 components: n - 2
    # degrees of freedom), or 1.4826 MAD of every tuple's residual when that is larger
    phi_r, phi_l, sm = synthetic(np.random.default_rng(31), 60, noise=NOISE)
    fit = fit_censi(phi_r, phi_l, sm, outlier_iterations=rounds)
    e = _residuals(fit, phi_r, phi_l, sm)
    kept = np.setdiff1d(np.arange(60), fit.dropped_indices)
    rms = np.sqrt((e[kept] ** 2).sum(axis=0) / (len(kept) - 2))
    mad = 1.4826 * np.median(np.abs(e - np.median(e, axis=0)), axis=0)
    np.testing.assert_allclose(fit.noise_std, np.maximum(rms, mad), rtol=1e-9)
    assert (rms > mad).tolist() == [False, True, True]  # both rules at work on this seed


def test_the_cluster_robust_covariance_of_white_noise_is_near_the_formal_one():
    # independent noise: 20 blocks of 15 tuples give about the formal standard errors
    # (sampling error of a 20-cluster sandwich: some 20 %); the sensor frame's weights apply
    phi_r, phi_l, sm = synthetic(np.random.default_rng(32), 300, noise=NOISE)
    fit = fit_censi(phi_r, phi_l, sm, clusters=np.arange(300) // 15)
    assert fit.uncertainty == "cluster-robust over 20 time blocks" and fit.dof == 19
    ratio = np.sqrt(np.diag(fit.covariance) / np.diag(fit.covariance_formal))
    assert np.all((ratio > 0.5) & (ratio < 1.5)), ratio


def test_a_refinement_far_from_the_closed_form_is_reported():
    from odocal.calibration.censi import _far_from_closed_form

    closed = TRUTH.copy()
    cov = np.diag(np.full(6, 1e-6))  # standard errors of 1 mm (1 mrad)
    near, far = closed.copy(), closed.copy()
    near[2] += 2.9e-3
    far[2] += 3.1e-3
    assert _far_from_closed_form(near, closed, cov, [0, 1, 2, 3, 4, 5]) == []
    (w,) = _far_from_closed_form(far, closed, cov, [0, 1, 2, 3, 4, 5])
    assert "wheelbase_m" in w and "3 standard errors" in w
    # yaw compared across the wrap: -pi + 1e-4 is 2e-4 from pi - 1e-4
    a, b = closed.copy(), closed.copy()
    a[5], b[5] = np.pi - 1e-4, -np.pi + 1e-4
    assert _far_from_closed_form(a, b, cov, [5]) == []
