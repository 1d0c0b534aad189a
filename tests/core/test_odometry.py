"""The dead-reckoning kernel (core/odometry) and every copy of it elsewhere.

``core.odometry`` is the one home of the midpoint update (model.md eq. 8). Its forms are checked
against a plain per-increment loop and against each other; the copies kept outside it for speed
(the simulator's segment loop, the trajectory fit's batched poses and derivatives, the real
experiment's held-out final positions) and the callers that build on it (censi's interval
model, the covariance propagation, the replay) are equated to it here. Where two computations do
the same floating-point operations in the same order the test is np.array_equal; where they are
one rounding apart per increment (theta_before + dtheta/2 against theta_after - dtheta/2, a
pairwise sum against a cumulative one) the tolerance is 1e-12 m or rad, far above those
roundings over a few thousand increments and far below anything printed.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core import odometry
from odocal.core.model import NonSystematicError, WheelGeometry
from odocal.core.odometry import (
    arc_displacement,
    arc_step,
    body_increments,
    chord_factor,
    chord_factor_series,
    dead_reckon,
    dead_reckon_rows,
    midpoint_end,
    midpoint_end_padded,
    midpoint_headings,
    midpoint_path,
    midpoint_poses,
    wheel_jacobian,
    wheel_travel,
)

GEOMETRY = WheelGeometry(0.0703, 0.0698, 0.2934)
TOL = 1e-12


def _angles(seed: int = 3, n: int = 2000) -> tuple[np.ndarray, np.ndarray]:
    """Cumulative wheel angles (rad) of a drive with arcs, spins, stops and reversals."""
    rng = np.random.default_rng(seed)
    t = np.arange(n) * 0.05
    v_r = 0.1 + 0.08 * np.sin(0.3 * t) + 0.15 * (np.sin(0.11 * t) > 0.9)
    v_l = 0.1 - 0.05 * np.sin(0.23 * t) - 0.15 * (np.sin(0.11 * t) > 0.9)
    v_r[rng.random(n) < 0.05] = 0.0
    v_l[n // 2 : n // 2 + 40] *= -1.0
    return np.r_[0, np.cumsum(v_r * 0.05)] / 0.035, np.r_[0, np.cumsum(v_l * 0.05)] / 0.035


def _loop(angle_r: np.ndarray, angle_l: np.ndarray, g: WheelGeometry) -> np.ndarray:
    """Eq. 8 written out, one increment at a time (the definition)."""
    pose = [np.zeros(3)]
    x = y = th = 0.0
    for dpr, dpl in zip(np.diff(angle_r), np.diff(angle_l), strict=True):
        s_r, s_l = dpr * g.diameter_right_m / 2, dpl * g.diameter_left_m / 2
        ds, dth = (s_r + s_l) / 2, (s_r - s_l) / g.wheelbase_m
        x += ds * math.cos(th + dth / 2)
        y += ds * math.sin(th + dth / 2)
        th += dth
        pose.append(np.array([x, y, th]))
    return np.array(pose)


def test_dead_reckon_is_the_midpoint_update():
    r, left = _angles()
    np.testing.assert_allclose(dead_reckon(r, left, GEOMETRY), _loop(r, left, GEOMETRY), atol=TOL)


def test_dead_reckon_is_built_from_the_steps():
    r, left = _angles()
    dr, dl = wheel_travel(np.diff(r), np.diff(left), GEOMETRY)
    ds, dth = body_increments(dr, dl, GEOMETRY.wheelbase_m)
    poses = midpoint_poses(ds, dth)
    assert np.array_equal(dead_reckon(r, left, GEOMETRY), poses.T)
    theta, mid = midpoint_headings(dth)
    assert np.array_equal(theta, poses[2, 1:])
    assert np.array_equal(mid, poses[2, :-1] + 0.5 * dth)
    assert dead_reckon(r, left, GEOMETRY).flags.c_contiguous


def test_the_end_forms_agree():
    """theta_after - dtheta/2 summed pairwise (midpoint_end, midpoint_path) against
    theta_before + dtheta/2 summed cumulatively (midpoint_poses): one rounding apart."""
    r, left = _angles()
    ds, dth = body_increments(*wheel_travel(np.diff(r), np.diff(left), GEOMETRY), 0.2934)
    ref = midpoint_poses(ds, dth)[:, -1]
    np.testing.assert_allclose(midpoint_end(ds, dth), ref, atol=TOL)
    x, y, theta, c, s = midpoint_path(ds, dth)
    np.testing.assert_allclose([x[-1], y[-1], theta[-1]], ref, atol=TOL)
    _, mid = midpoint_headings(dth)
    np.testing.assert_allclose(c, np.cos(mid), atol=TOL)
    np.testing.assert_allclose(s, np.sin(mid), atol=TOL)
    # batched rows: each row is the same increments alone
    rows = np.stack([ds, 2 * ds]), np.stack([dth, 2 * dth])
    assert np.array_equal(midpoint_end(*rows)[0], midpoint_end(ds, dth))


def test_no_increments_end_at_the_origin():
    assert np.array_equal(midpoint_end(np.zeros((2, 0)), np.zeros((2, 0))), np.zeros((2, 3)))


def test_padded_rows_end_where_the_plain_form_ends():
    """midpoint_end_padded (rows of different lengths, zero-padded) against midpoint_end: a
    short row, an empty row, a full row, a row whose last increments are a pure turn or a pure
    stop inside the row, and the little-padding fallback."""
    rng = np.random.default_rng(4)
    k = 40
    ds, dth = np.zeros((6, k)), np.zeros((6, k))
    for row, n in zip(range(6), (3, 0, k, 17, 25, 1), strict=True):
        ds[row, :n] = rng.uniform(0.0, 0.02, n)
        dth[row, :n] = rng.normal(0.0, 0.05, n)
    ds[3, 16] = 0.0  # the row ends on a turn in place
    ds[4, 10:12] = dth[4, 10:12] = 0.0  # a stop inside the row
    np.testing.assert_allclose(midpoint_end_padded(ds, dth), midpoint_end(ds, dth), atol=TOL)
    full = rng.uniform(0.0, 0.02, (3, k)), rng.normal(0.0, 0.05, (3, k))
    np.testing.assert_allclose(midpoint_end_padded(*full), midpoint_end(*full), atol=TOL)
    assert midpoint_end_padded(np.zeros((0, k)), np.zeros((0, k))).shape == (0, 3)


def test_wheel_heading_speed_is_the_centre_speed():
    # both wheels at 0.3 m/s and then the right one only: centre speed 0.3, then 0.15 m/s
    t = np.arange(41) * 0.05
    s_r = 0.3 * t
    s_l = np.where(t <= 1.0, 0.3 * t, 0.3)
    right = s_r / (0.5 * GEOMETRY.diameter_right_m)
    left = s_l / (0.5 * GEOMETRY.diameter_left_m)
    heading, speed = odometry.wheel_heading(t, right, left, GEOMETRY)
    assert speed is not None
    np.testing.assert_allclose(speed[:20], 0.3, atol=1e-9)
    np.testing.assert_allclose(speed[22:], 0.15, atol=1e-9)
    np.testing.assert_allclose(heading, (s_r - s_l) / GEOMETRY.wheelbase_m, atol=1e-12)


def test_end_derivatives_are_the_derivatives_of_the_end():
    """midpoint_end_derivatives against central differences of midpoint_end_padded, with the
    increments depending on two parameters (one scaling ds, one scaling dtheta and ds)."""
    rng = np.random.default_rng(5)
    k = 12
    ds0, dth0 = np.zeros((3, k)), np.zeros((3, k))
    for row, n in zip(range(3), (k, 5, 9), strict=True):
        ds0[row, :n] = rng.uniform(-0.02, 0.05, n)
        dth0[row, :n] = rng.normal(0.0, 0.3, n)

    def increments(p: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return p[0] * ds0 + p[1] ** 2 * dth0, p[1] * dth0

    p0 = np.array([1.1, 0.9])
    d_ds = np.stack([ds0, 2.0 * p0[1] * dth0])  # (q, n, K)
    d_dth = np.stack([np.zeros_like(dth0), dth0])
    end, jac = odometry.midpoint_end_derivatives(*increments(p0), d_ds, d_dth)
    np.testing.assert_allclose(end, midpoint_end_padded(*increments(p0)), atol=TOL)
    h = 1e-6
    num = np.stack(
        [
            (
                midpoint_end_padded(*increments(p0 + h * e))
                - midpoint_end_padded(*increments(p0 - h * e))
            )
            / (2 * h)
            for e in np.eye(2)
        ],
        axis=-1,
    )  # (n, 3, q)
    np.testing.assert_allclose(jac, num, atol=1e-8)


def test_exact_arcs():
    """The chord factor makes each increment an exact arc: one increment of a constant-curvature
    motion ends where arc_step and arc_displacement put it, however long it is."""
    rng = np.random.default_rng(8)
    ds = rng.uniform(-2.0, 2.0, 50)
    dth = rng.uniform(-3.0, 3.0, 50)
    dth[:5] = 0.0
    step = arc_step(np.zeros(3), ds, dth)
    np.testing.assert_allclose(
        midpoint_end(ds[:, None], dth[:, None], chord="exact"), step, atol=TOL
    )
    np.testing.assert_allclose(arc_displacement(ds, dth), step, atol=TOL)
    # the series chord factor: to 1e-10 (its stated accuracy), exact beyond 0.5 rad
    small = np.linspace(-0.5, 0.5, 101)
    np.testing.assert_allclose(chord_factor_series(small), chord_factor(small), atol=1e-10)
    big = np.array([0.6, -1.0, 3.0])
    assert np.array_equal(chord_factor_series(big), np.sin(big / 2) / (big / 2))
    # many short exact arcs: the same end as one long one
    n = 400
    many = midpoint_end(np.full(n, 1.5 / n), np.full(n, 2.0 / n), chord="series")
    np.testing.assert_allclose(many, arc_step(np.zeros(3), 1.5, 2.0), atol=TOL)


def test_wheel_jacobian_is_the_derivative_of_one_step():
    rng = np.random.default_rng(9)
    b = 0.29
    for _ in range(5):
        th0, s_r, s_l = rng.uniform(-3, 3), rng.uniform(-0.05, 0.05), rng.uniform(-0.05, 0.05)

        def step(sr: float, sl: float, th0: float = th0) -> np.ndarray:
            ds, dth = body_increments(np.array([sr]), np.array([sl]), b)
            p = midpoint_poses(ds, dth)[:, -1]
            c, s = math.cos(th0), math.sin(th0)  # the step starts at heading th0
            return np.array([c * p[0] - s * p[1], s * p[0] + c * p[1], p[2]])

        ds, dth = body_increments(np.array(s_r), np.array(s_l), b)
        mid = th0 + 0.5 * dth
        jac = wheel_jacobian(ds, np.cos(mid), np.sin(mid), b)
        h = 1e-7
        num = np.column_stack(
            [
                (step(s_r + h, s_l) - step(s_r - h, s_l)) / (2 * h),
                (step(s_r, s_l + h) - step(s_r, s_l - h)) / (2 * h),
            ]
        )
        np.testing.assert_allclose(jac, num, atol=1e-7)


# ------------------------------------------------------------------ copies kept for speed


def test_trajectory_fit_poses_are_the_kernel_bit_for_bit():
    """calibration/trajectory.py's _dead_reckon_trials (every Monte-Carlo trial at once, with
    exact derivatives) does dead_reckon's operations in the same order."""
    from odocal.calibration.trajectory import _dead_reckon_trials

    r, left = _angles(n=600)
    x = np.array([[0.0703, 0.0698, 0.2934], [0.07, 0.07, 0.29], [0.081, 0.062, 0.21]])
    poses, jac = _dead_reckon_trials(np.diff(r), np.diff(left), x, True)
    for m, g in enumerate(x):
        want = dead_reckon(r, left, WheelGeometry.unchecked(*g))
        assert np.array_equal(poses[:, m].T, want[1:])
    # the derivatives: central differences of the kernel (lengths relative to their value)
    assert jac is not None
    for p in range(3):
        h = 1e-6 * x[0, p]
        up, dn = x[0].copy(), x[0].copy()
        up[p] += h
        dn[p] -= h
        num = (
            dead_reckon(r, left, WheelGeometry.unchecked(*up))[1:]
            - dead_reckon(r, left, WheelGeometry.unchecked(*dn))[1:]
        ) / (2 * h)
        np.testing.assert_allclose(jac[p, :, 0].T, num, rtol=1e-5, atol=1e-5)


def test_trajectory_relative_poses_are_se2_relative():
    """calibration/trajectory.py's relative_poses is core.transforms.se2_relative (unwrapped)
    bit for bit."""
    from odocal.calibration.trajectory import relative_poses
    from odocal.core.transforms import se2_relative

    r, left = _angles()
    poses = dead_reckon(r, left, GEOMETRY)
    i0, i1 = np.arange(0, 1900, 100), np.arange(100, 2000, 100)
    want = se2_relative(poses[i0], poses[i1], wrap=False)
    assert np.array_equal(relative_poses(poses, i0, i1), want)


def test_real_experiment_final_positions_are_the_kernel():
    """design/real_experiment.py's _final_positions (many geometries at once): midpoint_end's
    operations, bit for bit, and dead_reckon's end to 1e-12."""
    from odocal.core.recording import Recording
    from odocal.design.real_experiment import _final_positions

    r, left = _angles()
    rec = Recording("run", np.arange(len(r)) * 0.05, r, left, np.zeros((len(r), 3)))
    d_r = np.array([0.0703, 0.07, 0.081])
    d_l = np.array([0.0698, 0.07, 0.062])
    b = np.array([0.2934, 0.29, 0.21])
    got = _final_positions(rec, d_r, d_l, b)
    batch = WheelGeometry.unchecked(d_r[:, None], d_l[:, None], b[:, None])
    dr, dl = wheel_travel(np.diff(r), np.diff(left), batch)
    assert np.array_equal(got, midpoint_end(*body_increments(dr, dl, batch.wheelbase_m))[:, :2])
    for i in range(3):
        want = dead_reckon(r, left, WheelGeometry(d_r[i], d_l[i], b[i]))[-1, :2]
        np.testing.assert_allclose(got[i], want, atol=TOL)


@pytest.mark.parametrize("integration", ["midpoint", "exact"])
def test_simulator_is_the_kernel(integration):
    """core/simulate.py's segment loop (Taylor polynomials, sums by segment, rotated once per
    run) drives the true path the kernel integrates from the same wheel rotations."""
    from odocal.core.simulate import commanded_wheel_angles, drive
    from odocal.core.tracks import polygon

    believed = WheelGeometry(0.07, 0.07, 0.29)
    track = polygon(4, 2.0, "ccw")
    n, angles = commanded_wheel_angles(track, believed, 0.01)
    res = drive(
        track,
        GEOMETRY,
        believed,
        NonSystematicError(),
        2,
        None,
        steps_per_segment=n,
        integration=integration,
        trajectory=True,
    )
    assert res.trajectory is not None
    if integration == "midpoint":
        want = dead_reckon(angles[:, 0], angles[:, 1], GEOMETRY)
    else:
        dr, dl = wheel_travel(np.diff(angles[:, 0]), np.diff(angles[:, 1]), GEOMETRY)
        ds, dth = body_increments(dr, dl, GEOMETRY.wheelbase_m)
        ends = [midpoint_end(ds[:k], dth[:k], chord="exact") for k in range(1, len(ds) + 1)]
        want = np.vstack([np.zeros(3), ends])
    for run in res.trajectory:
        np.testing.assert_allclose(run, want, atol=TOL)


# ------------------------------------------------------------------ callers built on it


def test_censi_interval_model_is_the_kernel():
    from odocal.calibration.censi import _arc

    p = np.array([0.0703, 0.0698, 0.2934, 0.1, -0.05, 0.2])
    r, left = _angles(n=300)
    # two intervals of 150 increments each, one per row
    inc = np.diff(r).reshape(2, 150), np.diff(left).reshape(2, 150)
    got = _arc(p, *inc)
    for k in range(2):
        g = WheelGeometry.unchecked(*p[:3])
        want = dead_reckon(np.r_[0, np.cumsum(inc[0][k])], np.r_[0, np.cumsum(inc[1][k])], g)
        np.testing.assert_allclose(got[k], want[-1], atol=TOL)
    # one total rotation per interval: the exact arc
    total = _arc(p, inc[0].sum(axis=1), inc[1].sum(axis=1))
    dr, dl = wheel_travel(inc[0].sum(axis=1), inc[1].sum(axis=1), WheelGeometry.unchecked(*p[:3]))
    ds, dth = body_increments(dr, dl, p[2])
    np.testing.assert_allclose(total, arc_step(np.zeros(3), ds, dth), atol=TOL)


def test_covariance_mean_is_the_kernel():
    from odocal.core.covariance import propagate_increments

    r, left = _angles()
    dr, dl = wheel_travel(np.diff(r), np.diff(left), GEOMETRY)
    mean, _ = propagate_increments(dr, dl, GEOMETRY.wheelbase_m, NonSystematicError(1e-6, 1e-6))
    np.testing.assert_allclose(mean, dead_reckon(r, left, GEOMETRY)[-1], atol=TOL)


def test_module_lists_its_kernel():
    for name in ("dead_reckon", "dead_reckon_rows", "midpoint_end", "midpoint_path", "arc_step"):
        assert name in odometry.__all__
    assert dead_reckon_rows is odometry.dead_reckon_rows
