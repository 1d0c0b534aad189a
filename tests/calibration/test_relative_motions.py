"""Relative motions of several sources: stacked on one clock, and one recording given twice told
from two recordings (calibration.relative_motions)."""

from dataclasses import replace

import numpy as np

from odocal.calibration.relative_motions import overlapping_sources, stack_motions
from tests.support.relative_intervals import motions


def test_stacked_sources_follow_each_other_with_a_one_second_gap():
    # two bags on their own clocks (the second's from 1000 s): the second is moved to start
    # 1 s after the first ends, so no time block holds intervals of both
    a, b = motions(n=5, seed=0), motions(n=4, seed=1)
    b = replace(b, start_s=b.start_s + 1000.0, end_s=b.end_s + 1000.0)
    both = stack_motions([a, b])
    np.testing.assert_array_equal(both.start_s, [0, 1, 2, 3, 4, 6, 7, 8, 9])
    np.testing.assert_array_equal(both.end_s, both.start_s + 1.0)


def test_bags_on_their_own_origins_given_twice_are_found():
    # each bag's intervals from its own start (0 s), the bags' starts since the epoch apart
    a = motions(n=60, seed=0)
    t0 = 1.7e9
    assert overlapping_sources([a, a], [t0, t0]) == (0, 1, t0, t0 + 60.0)
    # b's first 30 s are a's last 30 s: the half shared
    half = replace(
        a,
        **{f: getattr(a, f)[30:] for f in ("phi_right_rad", "phi_left_rad", "sensor_motion")},
        start_s=a.start_s[30:] - 30.0,
        end_s=a.end_s[30:] - 30.0,
        increments=None,
    )
    assert overlapping_sources([a, half], [t0, t0 + 30.0]) == (0, 1, t0 + 30.0, t0 + 60.0)
    assert overlapping_sources([a, half], [t0, t0 + 60.0]) is None  # the next hour's


def test_sources_sharing_a_minority_of_their_motions_are_two_recordings():
    # on one clock, b repeats 40 % of a's sensor motions (a quantised sensor, a robot parked
    # between moves): fewer than half of the moving intervals are shared
    a, b = motions(n=60, seed=0), motions(n=60, seed=1)
    same = np.random.default_rng(2).random(60) < 0.4
    mixed = replace(b, sensor_motion=np.where(same[:, None], a.sensor_motion, b.sensor_motion))
    assert overlapping_sources([a, mixed]) is None
    most = np.random.default_rng(2).random(60) < 0.6
    mostly = replace(b, sensor_motion=np.where(most[:, None], a.sensor_motion, b.sensor_motion))
    assert overlapping_sources([a, mostly]) == (0, 1, 0.0, 60.0)
