"""Skid-steer kinematics (core/skid_steer): the ideal case is the differential drive of
core/odometry exactly; the centres of rotation act as rigid-body kinematics says; the turn-rate
table interpolates as documented."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.skid_steer import (
    SkidSteerModel,
    TurnRateTable,
    body_motion_end,
    dead_reckon_skid,
    integrate_body_increments,
    skid_body_increments,
)
from odocal.errors import ModelError

NOMINAL = WheelGeometry(0.61, 0.59, 1.08)


def _angles(rng, k=400):
    rates = np.repeat(rng.uniform(-4, 4, size=(2, k // 50)), 50, axis=1)
    return np.cumsum(rates * 0.05, axis=1)


def test_the_ideal_model_is_the_differential_drive_of_core_odometry():
    rng = np.random.default_rng(3)
    right, left = _angles(rng)
    model = SkidSteerModel.from_geometry(NOMINAL)
    ours = dead_reckon_skid(model, right, left)
    theirs = dead_reckon(right, left, NOMINAL)
    assert np.max(np.abs(ours - theirs)) < 1e-12


def test_a_track_multiplier_divides_the_turn_and_keeps_the_forward_motion():
    model = SkidSteerModel.from_geometry(NOMINAL, track_multiplier=1.6)
    dx, dy, dth = skid_body_increments(model, [1.0, 2.0], [0.5, -2.0])
    r_r, r_l = 0.305, 0.295
    assert dth == pytest.approx(
        [(r_r * 1.0 - r_l * 0.5) / (1.6 * 1.08), (2 * r_r + 2 * r_l) / 1.728]
    )
    assert dx == pytest.approx([0.5 * (r_r + 0.5 * r_l), 0.5 * (2 * r_r - 2 * r_l)])
    assert np.all(dy == 0)
    assert model.track_m == pytest.approx(1.728)
    mult = model.ros2_multipliers(NOMINAL)
    assert mult["wheel_separation_multiplier"] == pytest.approx(1.6)
    assert mult["left_wheel_radius_multiplier"] == pytest.approx(1.0)


def test_the_centres_of_rotation_follow_rigid_body_kinematics():
    # a spot turn (v_L = -v_R) about centres y_L = 0.5, y_R = -0.7: omega = 2 v / 1.2, the
    # reference point moves forward by omega (y_L + y_R) / 2, and sideways by -x_icr omega
    model = SkidSteerModel(0.3, 0.3, 0.5, -0.7, x_icr_m=-0.15)
    dx, dy, dth = skid_body_increments(model, 1.0, -1.0)
    w = 0.6 / 1.2
    assert float(dth) == pytest.approx(w)
    assert float(dx) == pytest.approx(w * (0.5 - 0.7) / 2)
    assert float(dy) == pytest.approx(0.15 * w)
    # every point of the left side's contact line at y_L moves with its own wheel speed
    # relative to the ground: v_x(y) = v_x - omega y, so v_x(y_L) = v_L
    assert float(dx) - w * 0.5 == pytest.approx(-0.3)
    assert float(dx) - w * (-0.7) == pytest.approx(0.3)


def test_a_constant_turn_rate_table_is_the_constant_track():
    rng = np.random.default_rng(4)
    right, left = _angles(rng)
    t = 0.05 * np.arange(right.shape[0])
    plain = SkidSteerModel.from_geometry(NOMINAL, 1.7)
    table = SkidSteerModel.from_geometry(NOMINAL).with_turn_rate(
        TurnRateTable((0.1, 0.5, 1.0), (1.7, 1.7, 1.7))
    )
    assert (
        np.max(
            np.abs(dead_reckon_skid(plain, right, left) - dead_reckon_skid(table, right, left, t))
        )
        < 1e-12
    )


def test_the_table_interpolates_in_the_wheel_yaw_rate_and_holds_beyond_its_ends():
    table = TurnRateTable((0.2, 0.4), (2.0, 1.6))
    assert table.at([0.0, 0.2, 0.3, -0.3, 0.4, 5.0]) == pytest.approx(
        [2.0, 2.0, 1.8, 1.8, 1.6, 1.6]
    )
    assert table.true_rate_rad_s() == pytest.approx([0.1, 0.25])
    model = SkidSteerModel(0.3, 0.3, 0.5, -0.5, turn_rate=table)
    # v_R - v_L = 0.3 m over 1 s: wheel yaw rate 0.3 rad/s, multiplier 1.8
    _, _, dth = skid_body_increments(model, 0.5, -0.5, 1.0)
    assert float(dth) == pytest.approx(0.3 / 1.8)
    with pytest.raises(ModelError, match="durations"):
        skid_body_increments(model, 0.5, -0.5)


def test_integration_uses_the_mid_heading_and_the_end_form_agrees():
    rng = np.random.default_rng(5)
    dx, dy, dth = rng.normal(size=(3, 4, 30)) * [[[0.1]], [[0.02]], [[0.05]]]
    poses = integrate_body_increments(dx, dy, dth)
    assert poses.shape == (4, 31, 3)
    assert np.max(np.abs(poses[:, -1] - body_motion_end(dx, dy, dth))) < 1e-12
    # one increment by hand
    mid = dth[0, 0] / 2
    first = [dx[0, 0] * math.cos(mid) - dy[0, 0] * math.sin(mid),
             dx[0, 0] * math.sin(mid) + dy[0, 0] * math.cos(mid), dth[0, 0]]  # fmt: skip
    assert poses[0, 1] == pytest.approx(first)


def test_a_circle_closes():
    # constant wheel speeds: an arc; 2000 increments around a full turn come back to the start
    model = SkidSteerModel(0.3, 0.3, 0.8, -0.8)
    k = 2000
    dth = 2 * math.pi / k
    # v_R - v_L = dth * 1.6; choose v_R + v_L = 2 * 0.5 * dth * 5 (radius 5 m)
    vr, vl = 0.5 * (5 * 2 * dth + 1.6 * dth), 0.5 * (5 * 2 * dth - 1.6 * dth)
    end = body_motion_end(*skid_body_increments(model, np.full(k, vr / 0.3), np.full(k, vl / 0.3)))
    assert end[:2] == pytest.approx([0, 0], abs=1e-9)
    assert end[2] == pytest.approx(2 * math.pi)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (
            dict(radius_right_m=0.0, radius_left_m=0.3, y_icr_left_m=0.5, y_icr_right_m=-0.5),
            "radii",
        ),
        (dict(radius_right_m=0.3, radius_left_m=0.3, y_icr_left_m=-0.5, y_icr_right_m=0.5), "left"),
        (
            dict(
                radius_right_m=0.3,
                radius_left_m=0.3,
                y_icr_left_m=0.5,
                y_icr_right_m=-0.5,
                x_icr_m=math.nan,
            ),
            "finite",
        ),  # fmt: skip
    ],
)
def test_impossible_models_are_refused(kwargs, match):
    with pytest.raises(ModelError, match=match):
        SkidSteerModel(**kwargs)


def test_bad_tables_are_refused():
    with pytest.raises(ModelError, match="increasing"):
        TurnRateTable((0.4, 0.2), (1.0, 1.0))
    with pytest.raises(ModelError, match="as many"):
        TurnRateTable((0.2, 0.4), (1.0,))
    with pytest.raises(ModelError, match="> 0"):
        TurnRateTable((0.2,), (0.0,))
