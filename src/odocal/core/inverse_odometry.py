"""Wheel rotations from a robot's own odometry poses: the controller's dead reckoning, undone.

Most real bags carry no wheel joint states, only the controller's ``nav_msgs/Odometry`` (or
``odom -> base_link`` on ``/tf``). That pose was integrated from the wheel rotations through the
geometry the controller ran with (its nominal diameters and wheelbase times any multipliers),
so the rotations can be recovered exactly, step by step, as long as the controller integrated
each step as an arc (the exact integration of diff_drive_controller's ``integrateExact``) or as
a midpoint/Runge-Kutta step (the same to second order over a 10-100 Hz step):

    step k: (dx, dy, dtheta) = odom_k^-1 (+) odom_{k+1}       (in the base frame at k)
    chord c = hypot(dx, dy), signed by the direction of travel (dx < 0: backwards)
    arc length ds = c (dtheta / 2) / sin(dtheta / 2)           (c where dtheta -> 0)
    wheel travel s_R = ds + b dtheta / 2,  s_L = ds - b dtheta / 2
    wheel rotation phi = 2 s / D

with D_R, D_L, b the geometry the controller ran with. A lateral step (|dy| far above what the
arc allows) cannot come from a differential drive: those steps are counted, so that the caller
can say the topic is not a wheel odometry (a fused or a SLAM pose).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .model import WheelGeometry

__all__ = ["wheel_angles_from_poses", "InvertedOdometry"]


@dataclass(frozen=True)
class InvertedOdometry:
    """Cumulative wheel angles recovered from odometry poses.

    Attributes
    ----------
    angle_right_rad, angle_left_rad : ndarray, shape (K,)
        Cumulative wheel rotations (rad), starting at 0, one per pose.
    lateral_steps : int
        Steps whose sideways motion is inconsistent with an arc (more than 1 mm and more than a
        tenth of the step): not a differential drive's own odometry there.
    moving_steps : int
        Steps that move at all (translation above 1e-9 m or rotation above 1e-9 rad).
    """

    angle_right_rad: np.ndarray
    angle_left_rad: np.ndarray
    lateral_steps: int
    moving_steps: int


def wheel_angles_from_poses(poses: np.ndarray, ran_with: WheelGeometry) -> InvertedOdometry:
    """Invert odometry poses (x_m, y_m, yaw_rad), shape (K, 3), integrated by a controller that
    ran with ``ran_with`` (its diameters and wheelbase, multipliers included) into wheel angles
    (module docstring)."""
    p = np.asarray(poses, dtype=float)
    th = np.unwrap(p[:, 2])
    dxw, dyw = np.diff(p[:, 0]), np.diff(p[:, 1])
    c0, s0 = np.cos(th[:-1]), np.sin(th[:-1])
    dx = c0 * dxw + s0 * dyw  # in the base frame at the step's start
    dy = -s0 * dxw + c0 * dyw
    dth = np.diff(th)
    chord = np.hypot(dx, dy)
    # the chord of an arc points at dtheta/2 from the heading: forward or backward along it
    along = dx * np.cos(0.5 * dth) + dy * np.sin(0.5 * dth)
    signed = np.where(along < 0, -chord, chord)
    half = 0.5 * dth
    small = np.abs(half) < 1e-9
    ratio = np.where(small, 1.0, half / np.where(small, 1.0, np.sin(half)))
    ds = signed * ratio
    b = ran_with.wheelbase_m
    s_r, s_l = ds + 0.5 * b * dth, ds - 0.5 * b * dth
    right = np.concatenate([[0.0], np.cumsum(2.0 * s_r / ran_with.diameter_right_m)])
    left = np.concatenate([[0.0], np.cumsum(2.0 * s_l / ran_with.diameter_left_m)])
    # sideways motion an arc cannot make: the component across the chord's expected direction
    across = np.abs(-dx * np.sin(0.5 * dth) + dy * np.cos(0.5 * dth))
    lateral = int(np.sum((across > 1e-3) & (across > 0.1 * chord)))
    moving = int(np.sum((chord > 1e-9) | (np.abs(dth) > 1e-9)))
    return InvertedOdometry(right, left, lateral, moving)
