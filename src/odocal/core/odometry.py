"""Dead reckoning: wheel rotations -> believed pose, with the midpoint update (model.md eq. 8)."""

from __future__ import annotations

import numpy as np

from .model import WheelGeometry

__all__ = ["dead_reckon", "final_error", "position_errors", "evaluate"]


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
