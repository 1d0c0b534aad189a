"""Planar poses (x_m, y_m, theta_rad): composition along constant-curvature motion and the start
frame (docs/conventions.md: +x the start heading, +y to the left, theta CCW positive)."""

from __future__ import annotations

import numpy as np
from numpy.typing import ArrayLike

from .odometry import arc_step
from .transforms import se2_relative

__all__ = ["compose", "start_frame"]


def compose(pose: ArrayLike, distance: ArrayLike, angle: ArrayLike) -> np.ndarray:
    """Exact pose after a constant-curvature motion (distance m, heading change rad).

    ``pose`` has shape (..., 3); ``distance`` and ``angle`` broadcast against pose[..., 0]. The
    exact-arc step of the dead-reckoning kernel (:func:`odocal.core.odometry.arc_step`).
    """
    return arc_step(pose, distance, angle)


def start_frame(x: ArrayLike, y: ArrayLike, theta_rad: ArrayLike) -> np.ndarray:
    """Poses re-expressed relative to the first one: shape (K, 3), first row (0, 0, 0).

    ``x``, ``y`` (m) and ``theta_rad`` (rad, unwrapped) have shape (K,); the heading keeps its
    unwrapping (only the first heading is subtracted).
    """
    poses = np.column_stack([np.asarray(v, dtype=float) for v in (x, y, theta_rad)])
    return se2_relative(poses[0], poses, wrap=False)
