"""The synthetic room and the simulated 2D lidar (tests/support/room.py): exact ranges on simple
geometry, batches, misses, seeded noise, bad input."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.errors import ModelError
from tests.support.room import Room, box_segments, ray_cast

# A 4 m x 2 m room, nothing inside: exact ranges are easy to write down.
EMPTY = Room.rectangle(4.0, 2.0)


def test_ranges_to_the_walls_are_exact():
    # sensor at (1, 0.5) facing +x: walls at x = 4 (3 m ahead), y = 2 (1.5 m left),
    # y = 0 (0.5 m right), x = 0 (1 m behind); at 45 deg it meets y = 2 at x = 2.5
    angles = np.array([0.0, math.pi / 2, -math.pi / 2, math.pi, math.pi / 4])
    r = ray_cast(EMPTY, (1.0, 0.5, 0.0), angles, 10.0)
    np.testing.assert_allclose(r, [3.0, 1.5, 0.5, 1.0, 1.5 * math.sqrt(2)], rtol=0, atol=1e-12)


def test_the_sensor_heading_turns_the_rays():
    # facing +y (CCW 90 deg), the ray at angle 0 goes left in the room: 1.5 m to y = 2
    r = ray_cast(EMPTY, (1.0, 0.5, math.pi / 2), [0.0, -math.pi / 2], 10.0)
    np.testing.assert_allclose(r, [1.5, 3.0], atol=1e-12)


def test_a_box_hides_the_wall_behind_it():
    room = Room.rectangle(4.0, 2.0, boxes=(((3.0, 1.0), (0.4, 0.6), 0.0),))
    # the box's near face is at x = 2.8: 1.8 m from x = 1; rays that pass it see the wall
    r = ray_cast(room, (1.0, 1.0, 0.0), [0.0, math.atan2(0.9, 3.0)], 10.0)
    assert r[0] == pytest.approx(1.8, abs=1e-12)
    assert r[1] == pytest.approx(math.hypot(3.0, 0.9), abs=1e-12)


def test_box_segments_are_a_closed_rotated_rectangle():
    seg = box_segments((1.0, 2.0), (2.0, 1.0), math.pi / 2)
    np.testing.assert_allclose(seg[:, 2:], np.roll(seg[:, :2], -1, axis=0))
    # turned by 90 deg the 2 m side runs along y
    assert np.ptp(seg[:, 1]) == pytest.approx(2.0) and np.ptp(seg[:, 0]) == pytest.approx(1.0)


def test_misses_and_ranges_beyond_the_maximum_are_inf():
    # outside the room looking away: nothing to hit
    assert np.isinf(ray_cast(EMPTY, (-1.0, 1.0, math.pi), [0.0], 100.0)).all()
    # the wall 3 m ahead is beyond a 2.5 m sensor
    r = ray_cast(EMPTY, (1.0, 0.5, 0.0), [0.0, math.pi / 2], 2.5)
    assert np.isinf(r[0]) and r[1] == pytest.approx(1.5)


def test_a_batch_of_poses_equals_one_pose_at_a_time():
    room = Room.default()
    rng = np.random.default_rng(3)
    poses = np.column_stack(
        [rng.uniform(2, 6, 20), rng.uniform(1.5, 4.5, 20), rng.uniform(-3, 3, 20)]
    )
    angles = np.linspace(-math.pi, math.pi, 90, endpoint=False)
    batch = ray_cast(room, poses, angles, 12.0)
    assert batch.shape == (20, 90)
    for pose, row in zip(poses, batch, strict=True):
        np.testing.assert_array_equal(ray_cast(room, pose, angles, 12.0), row)
    assert np.all(np.isfinite(batch))  # a closed room: every ray hits something


def test_range_noise_is_seeded_and_has_the_requested_spread():
    angles = np.linspace(-math.pi, math.pi, 2000, endpoint=False)
    poses = np.tile([2.0, 1.0, 0.3], (10, 1))
    exact = ray_cast(EMPTY, poses, angles, 10.0)
    a = ray_cast(EMPTY, poses, angles, 10.0, np.random.default_rng(5), 0.01)
    b = ray_cast(EMPTY, poses, angles, 10.0, np.random.default_rng(5), 0.01)
    np.testing.assert_array_equal(a, b)
    # 20000 samples: the sample std is within 3 % of sigma with overwhelming probability
    # (its relative standard error is 1/sqrt(2 n) = 0.5 %)
    assert np.std(a - exact) == pytest.approx(0.01, rel=0.03)
    assert abs(np.mean(a - exact)) < 4 * 0.01 / math.sqrt(a.size)


def test_noise_keeps_misses_as_inf():
    r = ray_cast(EMPTY, (1.0, 0.5, 0.0), [0.0, math.pi / 2], 2.5, np.random.default_rng(1), 0.01)
    assert np.isinf(r[0]) and np.isfinite(r[1])


def test_distance_to_walls():
    d = EMPTY.distance_to_walls([[1.0, 0.5], [2.0, 1.0], [5.0, 1.0]])
    np.testing.assert_allclose(d, [0.5, 1.0, 1.0])


@pytest.mark.parametrize(
    ("call", "message"),
    [
        (lambda: ray_cast(EMPTY, (1, 1, 0), [0.0], 5.0, None, 0.01), "Generator"),
        (lambda: ray_cast(EMPTY, (1, 1), [0.0], 5.0), "shape"),
        (lambda: ray_cast(EMPTY, (1, np.nan, 0), [0.0], 5.0), "finite"),
        (lambda: ray_cast(EMPTY, (1, 1, 0), [0.0], 0.0), "max_range_m"),
        (lambda: ray_cast(EMPTY, (1, 1, 0), [0.0], 5.0, np.random.default_rng(), -1), "sigma"),
        (lambda: Room(np.zeros((2, 3))), "shape"),
        (lambda: Room([[0, 0, 0, 0]]), "zero length"),
        (lambda: Room([[0, 0, np.inf, 0]]), "finite"),
        (lambda: Room.rectangle(-1.0, 2.0), "width"),
    ],
)
def test_bad_input_is_a_clear_model_error(call, message):
    with pytest.raises(ModelError, match=message):
        call()


def test_room_segments_are_a_read_only_copy():
    seg = np.array([[0.0, 0.0, 1.0, 0.0]])
    room = Room(seg)
    seg[0, 0] = 5.0
    assert room.segments_m[0, 0] == 0.0
    with pytest.raises(ValueError):
        room.segments_m[0, 0] = 1.0
