"""Dead reckoning: wheel rotations -> believed pose, with the midpoint update (model.md eq. 8).

This module is the one home of the midpoint update

    ds_i = dphi_i D_i / 2,  ds = (ds_R + ds_L) / 2,  dtheta = (ds_R - ds_L) / b,
    x += ds cos(theta + dtheta/2),  y += ds sin(theta + dtheta/2),  theta += dtheta

and of its exact-arc form (``ds`` times the chord factor sin(dtheta/2) / (dtheta/2), exact for
constant wheel speeds within an increment). Every caller builds on the steps below:

- :func:`wheel_travel` (wheel rotations to wheel travel) and :func:`body_increments` (wheel travel
  to the centre's travel ``ds`` and heading change ``dtheta``);
- :func:`midpoint_headings`, :func:`midpoint_poses` (every pose along the way; the core of
  :func:`dead_reckon` and :func:`dead_reckon_rows`), :func:`midpoint_end` (the end pose only) and
  :func:`midpoint_path` (headings, mid-heading cosines and positions, for covariance propagation);
- :func:`arc_step` (one exact arc from a given pose) and :func:`arc_displacement` (one exact arc
  from the origin); :func:`wheel_jacobian` (the update's derivative with respect to the wheel
  travel, Siegwart's F_d).

Two floating-point forms of the mid heading exist, one rounding apart: theta_before + dtheta/2
(:func:`midpoint_headings`, :func:`midpoint_poses`) and theta_after - dtheta/2
(:func:`midpoint_end`, :func:`midpoint_path`); and the end pose is summed pairwise
(:func:`midpoint_end`) where the path is a cumulative sum. Both are kept, each where it was
written, so that every printed number stays the same bit for bit; tests equate them to 1e-12.

Speed-critical copies stay where they are, each with a test equating it to this kernel and a
comment pointing here: the simulator's segment loop (``core/simulate.py``, Taylor polynomials
per run), the trajectory fit's batched poses and derivatives (``calibration/trajectory.py``) and
the real experiment's held-out final positions (``design/real_experiment.py``).
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Literal

import numpy as np
from numpy.typing import ArrayLike

from .model import ModelError, WheelGeometry

if TYPE_CHECKING:
    from .recording import Recording

__all__ = [
    "wheel_travel",
    "body_increments",
    "midpoint_headings",
    "midpoint_poses",
    "midpoint_end",
    "midpoint_end_padded",
    "midpoint_end_derivatives",
    "midpoint_path",
    "chord_factor",
    "chord_factor_series",
    "arc_step",
    "arc_position",
    "arc_displacement",
    "wheel_jacobian",
    "dead_reckon",
    "dead_reckon_rows",
    "final_error",
    "position_errors",
    "evaluate",
]

Chord = Literal["none", "exact", "series"]


def wheel_travel(
    increment_right_rad: ArrayLike, increment_left_rad: ArrayLike, geometry: WheelGeometry
) -> tuple[np.ndarray, np.ndarray]:
    """Wheel travel (m) of wheel-rotation increments (rad): ds_i = dphi_i D_i / 2.

    The increments broadcast against the geometry's values (a batch of geometries of shape
    (M, 1) with increments of shape (K,) gives shape (M, K)).
    """
    dr = np.asarray(increment_right_rad, dtype=float) * (0.5 * geometry.diameter_right_m)
    dl = np.asarray(increment_left_rad, dtype=float) * (0.5 * geometry.diameter_left_m)
    return dr, dl


def body_increments(
    travel_right_m: np.ndarray,
    travel_left_m: np.ndarray,
    wheelbase_m: float | np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """The centre's travel ds = (ds_R + ds_L) / 2 (m) and heading change
    dtheta = (ds_R - ds_L) / b (rad) of each increment (shapes broadcast)."""
    return 0.5 * (travel_right_m + travel_left_m), (travel_right_m - travel_left_m) / wheelbase_m


def midpoint_headings(dtheta_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Heading after each increment (cumulative sum along the last axis, from 0) and the mid
    heading of each increment, theta_before + dtheta / 2 (rad); both of the input's shape."""
    theta = np.cumsum(dtheta_rad, axis=-1)
    before = np.zeros_like(theta)
    before[..., 1:] = theta[..., :-1]
    return theta, before + 0.5 * dtheta_rad


def midpoint_poses(ds_m: np.ndarray, dtheta_rad: np.ndarray) -> np.ndarray:
    """Every pose of the midpoint update over increments along the last axis (shape (..., K)),
    from (0, 0, 0): shape (3, ..., K + 1) (x_m, y_m, theta_rad; column 0 the start).

    Sums run along the last axis element after element, so that each row of a batch equals the
    same increments integrated alone, bit for bit (zero padding at a row's end leaves its
    earlier poses untouched)."""
    ds = np.asarray(ds_m, dtype=float)
    dth = np.asarray(dtheta_rad, dtype=float)
    poses = np.empty((3, *ds.shape[:-1], ds.shape[-1] + 1))
    poses[..., 0] = 0.0
    np.cumsum(dth, axis=-1, out=poses[2, ..., 1:])
    # mid = theta_before + dtheta / 2, ds cos(mid), ds sin(mid), in place (the same sums and
    # products: they commute exactly)
    mid = np.multiply(dth, 0.5)
    mid += poses[2, ..., :-1]
    part = np.cos(mid)
    part *= ds
    np.cumsum(part, axis=-1, out=poses[0, ..., 1:])
    np.sin(mid, out=part)
    part *= ds
    np.cumsum(part, axis=-1, out=poses[1, ..., 1:])
    return poses


def chord_factor(dtheta_rad: np.ndarray) -> np.ndarray:
    """sin(dtheta/2) / (dtheta/2): an exact arc's chord over its length (1 at dtheta = 0)."""
    return np.sinc(dtheta_rad / (2.0 * math.pi))


def chord_factor_series(dtheta_rad: np.ndarray) -> np.ndarray:
    """:func:`chord_factor` without np.sinc's cost: its Taylor series to x^6 where
    |dtheta| < 0.5 rad (error below 1e-10), else exact."""
    x2 = 0.25 * dtheta_rad * dtheta_rad
    out = 1.0 - x2 / 6.0 + x2 * x2 / 120.0 - x2 * x2 * x2 / 5040.0
    big = np.abs(dtheta_rad) >= 0.5
    if np.any(big):
        half = 0.5 * dtheta_rad[big]
        out[big] = np.sin(half) / half
    return out


def _chord(ds_m: np.ndarray, dtheta_rad: np.ndarray, chord: Chord) -> np.ndarray:
    if chord == "exact":
        return ds_m * chord_factor(dtheta_rad)
    if chord == "series":
        return ds_m * chord_factor_series(dtheta_rad)
    return ds_m


def midpoint_end(ds_m: np.ndarray, dtheta_rad: np.ndarray, *, chord: Chord = "none") -> np.ndarray:
    """End pose (x_m, y_m, theta_rad) of consecutive increments along the last axis, from the
    origin: shape (..., 3). Mid heading theta_after - dtheta/2, positions summed pairwise
    (np.sum). ``chord``: 'exact' or 'series' integrates each increment as an exact arc
    (:func:`chord_factor`, :func:`chord_factor_series`); 'none' is eq. 8."""
    theta = np.cumsum(dtheta_rad, axis=-1)
    mid = theta - 0.5 * dtheta_rad
    ds = _chord(ds_m, dtheta_rad, chord)
    x = np.sum(ds * np.cos(mid), axis=-1)
    y = np.sum(ds * np.sin(mid), axis=-1)
    end = theta[..., -1] if theta.shape[-1] else np.zeros(theta.shape[:-1])
    return np.stack([x, y, end], axis=-1)


def _padded_trig(ds: np.ndarray, dth: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Heading after each increment, and cos, sin of the mid headings, of zero-padded rows
    (n, K); the sines and cosines computed on each row's own length only (zeros beyond it),
    where the padding is more than 30 % of the array."""
    n, k = ds.shape
    theta = np.cumsum(dth, axis=1)  # per row, as midpoint_end sums them (no cancellation)
    mid = theta - 0.5 * dth
    moving = (ds != 0.0) | (dth != 0.0)
    length = np.where(moving.any(axis=1), k - np.argmax(moving[:, ::-1], axis=1), 0)
    if int(length.sum()) > 0.7 * n * k:  # little padding: the plain form
        return theta, np.cos(mid), np.sin(mid)
    keep = np.arange(k)[None, :] < length[:, None]
    c, s = np.zeros((n, k)), np.zeros((n, k))
    used = mid[keep]
    c[keep], s[keep] = np.cos(used), np.sin(used)
    return theta, c, s


def midpoint_end_padded(ds_m: np.ndarray, dtheta_rad: np.ndarray) -> np.ndarray:
    """:func:`midpoint_end` of zero-padded rows (n, K) (each row's increments, then zeros),
    shape (n, 3): the same end poses, the sines and cosines computed on the rows' own lengths
    only (a log's intervals between SLAM updates vary in length, and padding them to the
    longest would triple the sines and cosines)."""
    ds = np.asarray(ds_m, dtype=float)
    dth = np.asarray(dtheta_rad, dtype=float)
    if ds.size == 0:
        return midpoint_end(ds, dth)
    theta, c, s = _padded_trig(ds, dth)
    return np.stack([np.sum(ds * c, axis=1), np.sum(ds * s, axis=1), theta[:, -1]], axis=-1)


def midpoint_end_derivatives(
    ds_m: np.ndarray, dtheta_rad: np.ndarray, d_ds: np.ndarray, d_dtheta: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """:func:`midpoint_end_padded` of rows (n, K) and its derivatives with respect to q
    parameters, given the increments' derivatives ``d_ds``, ``d_dtheta`` of shape (q, n, K):
    end poses (n, 3) and their derivatives (n, 3, q). With mid_i = theta_i - dtheta_i / 2:
    dx = sum d_ds cos(mid) - ds sin(mid) dmid, dy = sum d_ds sin(mid) + ds cos(mid) dmid,
    dtheta_end = sum d_dtheta, dmid = cumsum(d_dtheta) - d_dtheta / 2."""
    ds = np.asarray(ds_m, dtype=float)
    dth = np.asarray(dtheta_rad, dtype=float)
    a = np.asarray(d_ds, dtype=float)
    b = np.asarray(d_dtheta, dtype=float)
    theta, c, s = _padded_trig(ds, dth)
    end = np.stack([np.sum(ds * c, axis=1), np.sum(ds * s, axis=1), theta[:, -1]], axis=-1)
    dmid = np.cumsum(b, axis=2) - 0.5 * b
    sc, ss = ds * c, ds * s
    jac = np.stack(
        [
            np.sum(a * c - ss * dmid, axis=2),
            np.sum(a * s + sc * dmid, axis=2),
            np.sum(b, axis=2),
        ],
        axis=1,
    )  # (q, 3, n)
    return end, np.transpose(jac, (2, 1, 0))


def midpoint_path(
    ds_m: np.ndarray, dtheta_rad: np.ndarray, *, chord: Chord = "none"
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The path of consecutive increments along the last axis, from the origin: x, y, theta
    after each increment and cos, sin of each increment's mid heading theta_after - dtheta/2
    (all of the input's shape), as covariance propagation needs them. ``chord`` as in
    :func:`midpoint_end`."""
    theta = np.cumsum(dtheta_rad, axis=-1)
    mid = theta - 0.5 * dtheta_rad
    c, s = np.cos(mid), np.sin(mid)
    ds = _chord(ds_m, dtheta_rad, chord)
    return np.cumsum(ds * c, axis=-1), np.cumsum(ds * s, axis=-1), theta, c, s


def arc_step(pose: ArrayLike, distance_m: ArrayLike, angle_rad: ArrayLike) -> np.ndarray:
    """Exact pose after a constant-curvature motion (distance m, heading change rad) from
    ``pose`` (shape (..., 3)); ``distance_m`` and ``angle_rad`` broadcast against pose[..., 0]."""
    pose = np.asarray(pose, dtype=float)
    distance = np.asarray(distance_m, dtype=float)
    angle = np.asarray(angle_rad, dtype=float)
    chord = distance * chord_factor(angle)  # d sin(a/2)/(a/2)
    mid = pose[..., 2] + 0.5 * angle
    return np.stack(
        np.broadcast_arrays(
            pose[..., 0] + chord * np.cos(mid),
            pose[..., 1] + chord * np.sin(mid),
            pose[..., 2] + angle,
        ),
        axis=-1,
    )


def arc_position(distance_m: np.ndarray, angle_rad: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Exact constant-curvature position change from the origin: (d sin(a)/a, d (1 - cos a)/a)
    (m), written with sin(a)/a and (1 - cos a)/a = (a/2) sinc(a/2)^2 so that it is stable at
    a = 0; shapes of the inputs."""
    sinc = np.sinc(angle_rad / np.pi)
    half = np.sinc(angle_rad / (2 * np.pi))
    return distance_m * sinc, distance_m * 0.5 * angle_rad * half * half


def arc_displacement(distance_m: np.ndarray, angle_rad: np.ndarray) -> np.ndarray:
    """:func:`arc_position` and the heading change, shape (n, 3) (x_m, y_m, theta_rad)."""
    return np.column_stack([*arc_position(distance_m, angle_rad), angle_rad])


def wheel_jacobian(
    ds_m: np.ndarray, cos_mid: np.ndarray, sin_mid: np.ndarray, wheelbase_m: float | np.ndarray
) -> np.ndarray:
    """Derivative of one midpoint step (dx, dy, dtheta; start frame) with respect to the wheel
    travel (ds_R, ds_L): Siegwart's F_d (eq. 5.11), shape (..., 3, 2) for inputs of shape (...)
    (``cos_mid``, ``sin_mid`` of the mid heading)."""
    b = wheelbase_m
    h = ds_m / (2.0 * b)
    g = np.empty(np.shape(ds_m) + (3, 2))
    g[..., 0, 0] = 0.5 * cos_mid - h * sin_mid
    g[..., 0, 1] = 0.5 * cos_mid + h * sin_mid
    g[..., 1, 0] = 0.5 * sin_mid + h * cos_mid
    g[..., 1, 1] = 0.5 * sin_mid - h * cos_mid
    g[..., 2, 0] = 1.0 / b
    g[..., 2, 1] = -1.0 / b
    return g


def dead_reckon(
    angle_right_rad: ArrayLike, angle_left_rad: ArrayLike, geometry: WheelGeometry
) -> np.ndarray:
    """Integrate cumulative wheel angles (rad, shape (K,)) into poses, shape (K, 3).

    ds_i = dphi_i D_i / 2; ds = (ds_R + ds_L)/2; dtheta = (ds_R - ds_L)/b;
    x += ds cos(theta + dtheta/2), y += ds sin(theta + dtheta/2). Starts at (0, 0, 0).
    """
    dr, dl = wheel_travel(
        np.diff(np.asarray(angle_right_rad, dtype=float)),
        np.diff(np.asarray(angle_left_rad, dtype=float)),
        geometry,
    )
    return np.ascontiguousarray(midpoint_poses(*body_increments(dr, dl, geometry.wheelbase_m)).T)


def dead_reckon_rows(
    increment_right_rad: ArrayLike, increment_left_rad: ArrayLike, geometry: WheelGeometry
) -> np.ndarray:
    """:func:`dead_reckon` of many runs at once, bit for bit: one run per row.

    The increments (rad, shape (R, L)) are each row's ``np.diff`` of its cumulative wheel
    angles, zero-padded at its end (padding leaves the row's earlier poses untouched: the sums
    run along each row, element after element, as for one run). Returns the poses, shape
    (3, R, L + 1) (x, y, theta; column k = sample k, column 0 the start (0, 0, 0)), with the
    operations of :func:`dead_reckon` in the same order on every element, so that row r up to
    its own length equals ``dead_reckon`` of that run exactly.
    """
    dr, dl = wheel_travel(increment_right_rad, increment_left_rad, geometry)
    return midpoint_poses(*body_increments(dr, dl, geometry.wheelbase_m))


def final_error(ground_truth: np.ndarray, odometry: np.ndarray) -> np.ndarray:
    """Final pose error actual - odometric in the start frame, shape (3,) (theta unwrapped)."""
    return np.asarray(ground_truth[-1], dtype=float) - np.asarray(odometry[-1], dtype=float)


def position_errors(ground_truth: np.ndarray, odometry: np.ndarray) -> np.ndarray:
    """Position error norm ||p_true - p_odo|| (m) at every sample, shape (K,)."""
    return np.hypot(ground_truth[:, 0] - odometry[:, 0], ground_truth[:, 1] - odometry[:, 1])


def evaluate(recording: Recording, geometry: WheelGeometry) -> dict:
    """Dead-reckon ``recording`` with ``geometry`` and compare with its ground truth.

    Returns final and maximum position error (m) and final and maximum heading error (rad, abs).
    Where the ground truth is valid only at some samples (``meta['truth_samples']``, e.g. a
    SLAM pose at its update instants), only those are compared.
    """
    odo = dead_reckon(recording.wheel_angle_right_rad, recording.wheel_angle_left_rad, geometry)
    gt = recording.ground_truth
    if gt is None:
        raise ModelError(f"{recording.name}: evaluating a geometry needs ground truth")
    valid = recording.meta.get("truth_samples") if recording.meta else None
    if valid is not None:
        gt, odo = gt[valid], odo[valid]
    pos = position_errors(gt, odo)
    head = np.abs(gt[:, 2] - odo[:, 2])
    return {
        "final_error_m": float(pos[-1]),
        "max_error_m": float(pos.max()),
        "final_heading_error_rad": float(head[-1]),
        "max_heading_error_rad": float(head.max()),
    }


def wheel_heading(
    time_s: np.ndarray,
    angle_right_rad: np.ndarray,
    angle_left_rad: np.ndarray,
    geometry: WheelGeometry,
    *,
    invert_right: bool = False,
    invert_left: bool = False,
) -> tuple[np.ndarray, np.ndarray | None]:
    """The heading (rad) the wheel angles give, and the forward speed (m/s), shape (K,) each.

    With the wheel travel s = angle D / 2 (a joint negated with ``invert_*``): heading =
    (s_R - s_L) / b (the heading of :func:`dead_reckon`, summed at once instead of per
    increment), speed = the time derivative of (s_R + s_L) / 2 (``numpy.gradient`` over
    ``time_s``, s; None with fewer than 3 samples). Cumulative angles (rad) at ``time_s``."""
    s_r = angle_right_rad * (0.5 * geometry.diameter_right_m * (-1.0 if invert_right else 1.0))
    s_l = angle_left_rad * (0.5 * geometry.diameter_left_m * (-1.0 if invert_left else 1.0))
    heading = (s_r - s_l) / geometry.wheelbase_m
    speed = np.gradient(0.5 * (s_r + s_l), time_s) if len(time_s) > 2 else None
    return heading, speed
