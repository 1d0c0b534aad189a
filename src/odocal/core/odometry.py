"""Dead reckoning: wheel rotations -> believed pose, with the midpoint update (model.md eq. 8)."""

from __future__ import annotations

import numpy as np

from .model import WheelGeometry

__all__ = ["dead_reckon", "dead_reckon_rows", "final_error", "position_errors", "evaluate"]


def dead_reckon(angle_right_rad, angle_left_rad, geometry: WheelGeometry) -> np.ndarray:
    """Integrate cumulative wheel angles (rad, shape (K,)) into poses, shape (K, 3).

    ds_i = dphi_i D_i / 2; ds = (ds_R + ds_L)/2; dtheta = (ds_R - ds_L)/b;
    x += ds cos(theta + dtheta/2), y += ds sin(theta + dtheta/2). Starts at (0, 0, 0).
    """
    dr = np.diff(np.asarray(angle_right_rad, dtype=float)) * (0.5 * geometry.diameter_right_m)
    dl = np.diff(np.asarray(angle_left_rad, dtype=float)) * (0.5 * geometry.diameter_left_m)
    ds = 0.5 * (dr + dl)
    dth = (dr - dl) / geometry.wheelbase_m
    theta = np.concatenate([[0.0], np.cumsum(dth)])
    mid = theta[:-1] + 0.5 * dth
    x = np.concatenate([[0.0], np.cumsum(ds * np.cos(mid))])
    y = np.concatenate([[0.0], np.cumsum(ds * np.sin(mid))])
    return np.column_stack([x, y, theta])


def dead_reckon_rows(
    increment_right_rad, increment_left_rad, geometry: WheelGeometry
) -> np.ndarray:
    """:func:`dead_reckon` of many runs at once, bit for bit: one run per row.

    The increments (rad, shape (R, L)) are each row's ``np.diff`` of its cumulative wheel
    angles, zero-padded at its end (padding leaves the row's earlier poses untouched: the sums
    run along each row, element after element, as for one run). Returns the poses, shape
    (3, R, L + 1) (x, y, theta; column k = sample k, column 0 the start (0, 0, 0)), with the
    operations of :func:`dead_reckon` in the same order on every element, so that row r up to
    its own length equals ``dead_reckon`` of that run exactly.
    """
    dr = np.asarray(increment_right_rad, dtype=float) * (0.5 * geometry.diameter_right_m)
    dl = np.asarray(increment_left_rad, dtype=float) * (0.5 * geometry.diameter_left_m)
    ds = 0.5 * (dr + dl)
    dth = (dr - dl) / geometry.wheelbase_m
    poses = np.empty((3, dr.shape[0], dr.shape[1] + 1))
    poses[:, :, 0] = 0.0
    np.cumsum(dth, axis=1, out=poses[2, :, 1:])
    mid = poses[2, :, :-1] + 0.5 * dth
    np.cumsum(ds * np.cos(mid), axis=1, out=poses[0, :, 1:])
    np.cumsum(ds * np.sin(mid), axis=1, out=poses[1, :, 1:])
    return poses


def final_error(ground_truth: np.ndarray, odometry: np.ndarray) -> np.ndarray:
    """Final pose error actual - odometric in the start frame, shape (3,) (theta unwrapped)."""
    return np.asarray(ground_truth[-1], dtype=float) - np.asarray(odometry[-1], dtype=float)


def position_errors(ground_truth: np.ndarray, odometry: np.ndarray) -> np.ndarray:
    """Position error norm ||p_true - p_odo|| (m) at every sample, shape (K,)."""
    return np.hypot(ground_truth[:, 0] - odometry[:, 0], ground_truth[:, 1] - odometry[:, 1])


def evaluate(recording, geometry: WheelGeometry) -> dict:
    """Dead-reckon ``recording`` with ``geometry`` and compare with its ground truth.

    Returns final and maximum position error (m) and final and maximum heading error (rad, abs).
    Where the ground truth is valid only at some samples (``meta['truth_samples']``, e.g. a
    SLAM pose at its update instants), only those are compared.
    """
    odo = dead_reckon(recording.wheel_angle_right_rad, recording.wheel_angle_left_rad, geometry)
    gt = recording.ground_truth
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
