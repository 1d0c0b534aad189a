"""Dead reckoning: wheel rotations -> believed pose, with the midpoint update (model.md eq. 8)."""

from __future__ import annotations

import numpy as np

from .model import WheelGeometry

__all__ = ["dead_reckon", "final_error"]


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
