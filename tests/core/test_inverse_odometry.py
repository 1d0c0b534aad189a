"""Wheel rotations from odometry poses (core.inverse_odometry)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.core.inverse_odometry import wheel_angles_from_poses
from odocal.core.model import WheelGeometry

RAN_WITH = WheelGeometry(0.2 * 1.01, 0.2, 0.55 * 0.97)  # nominal times multipliers


def arcs(phi_r, phi_l, g: WheelGeometry):
    """Poses integrated as exact arcs (diff_drive_controller's integrateExact)."""
    poses = [np.zeros(3)]
    for a, b in zip(phi_r, phi_l, strict=True):
        sr, sl = 0.5 * g.diameter_right_m * a, 0.5 * g.diameter_left_m * b
        ds, dth = 0.5 * (sr + sl), (sr - sl) / g.wheelbase_m
        x, y, th = poses[-1]
        if abs(dth) < 1e-12:
            step = (ds * np.cos(th), ds * np.sin(th))
        else:
            r = ds / dth
            step = (r * (np.sin(th + dth) - np.sin(th)), -r * (np.cos(th + dth) - np.cos(th)))
        poses.append(np.array([x + step[0], y + step[1], th + dth]))
    return np.array(poses)


def test_round_trip_through_the_controllers_geometry():
    rng = np.random.default_rng(1)
    # forward, backward, spot turns both ways, arcs, standing still
    phi_r = np.r_[rng.uniform(-0.5, 1.0, 300), np.full(20, 0.3), np.zeros(10), -np.ones(5)]
    phi_l = np.r_[rng.uniform(-0.5, 1.0, 300), np.full(20, -0.3), np.zeros(10), -np.ones(5)]
    poses = arcs(phi_r, phi_l, RAN_WITH)
    poses[:, 2] = np.angle(np.exp(1j * poses[:, 2]))  # as a bag gives it: wrapped
    inv = wheel_angles_from_poses(poses, RAN_WITH)
    assert np.diff(inv.angle_right_rad) == pytest.approx(phi_r, abs=1e-9)
    assert np.diff(inv.angle_left_rad) == pytest.approx(phi_l, abs=1e-9)
    assert inv.lateral_steps == 0
    assert inv.moving_steps == len(phi_r) - 10
    # through another geometry the rotations are wrong by its ratios: the multipliers matter
    other = wheel_angles_from_poses(poses, WheelGeometry(0.2, 0.2, 0.55))
    assert not np.allclose(np.diff(other.angle_right_rad), phi_r, atol=1e-3)


def test_sideways_steps_are_counted():
    poses = np.zeros((11, 3))
    poses[:, 1] = np.linspace(0.0, 1.0, 11)  # a robot sliding to its left: not a diff drive
    assert wheel_angles_from_poses(poses, RAN_WITH).lateral_steps == 10


def test_a_turn_through_the_wrapped_heading_round_trips():
    # two full turns on a circle: the bag's yaw jumps from +pi to -pi twice; unwrapped, each
    # step is the same small arc
    phi_r, phi_l = np.full(200, 0.5), np.full(200, 0.1)
    poses = arcs(phi_r, phi_l, RAN_WITH)
    assert poses[-1, 2] > 4 * np.pi
    poses[:, 2] = np.angle(np.exp(1j * poses[:, 2]))
    inv = wheel_angles_from_poses(poses, RAN_WITH)
    assert np.diff(inv.angle_right_rad) == pytest.approx(phi_r, abs=1e-9)
    assert np.diff(inv.angle_left_rad) == pytest.approx(phi_l, abs=1e-9)


def test_sideways_steps_above_a_millimetre_are_counted():
    # 2 mm sideways per 2 mm step: counted (above 1 mm and a tenth of the step); 0.5 mm: not
    for step_m, expected in ((0.002, 10), (0.0005, 0)):
        poses = np.zeros((11, 3))
        poses[:, 1] = np.arange(11) * step_m
        assert wheel_angles_from_poses(poses, RAN_WITH).lateral_steps == expected


def test_straight_steps_and_spins_are_moving():
    # a pure translation (no rotation) and a pure rotation (no translation) both move
    poses = np.zeros((9, 3))
    poses[:5, 0] = np.arange(5) * 0.01
    poses[5:, 0] = poses[4, 0]
    poses[5:, 2] = np.arange(1, 5) * 0.1
    inv = wheel_angles_from_poses(poses, RAN_WITH)
    assert inv.moving_steps == 8
    assert inv.lateral_steps == 0
