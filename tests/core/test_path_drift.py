"""KITTI-style drift over pieces of the truth's path (core/path_drift) on hand-made trajectories
with known answers, and its piece choice against a re-statement of evo's pair filters."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.path_drift import path_drift, path_length
from odocal.errors import ModelError


def _straight(length_m=100.0, step_m=0.1):
    x = np.arange(0.0, length_m + 1e-9, step_m)
    return np.column_stack([x, np.zeros_like(x), np.zeros_like(x)])


def test_a_straight_path_driven_in_a_direction_off_by_alpha_drifts_2_sin_alpha_over_2():
    truth = _straight()
    alpha = 0.1
    est = truth.copy()
    est[:, 0], est[:, 1] = math.cos(alpha) * truth[:, 0], math.sin(alpha) * truth[:, 0]
    d = path_drift(truth, est, length_m=10.0)
    assert d.pieces == 10
    assert d.piece_length_m == pytest.approx(np.full(10, 10.0))
    assert d.error_pct == pytest.approx(np.full(10, 200 * math.sin(alpha / 2)))
    assert d.median_pct == pytest.approx(9.9958, abs=1e-4)
    assert d.heading_error_rad == pytest.approx(np.zeros(10))


def test_a_heading_that_drifts_k_rad_per_metre_bends_every_piece_into_an_arc():
    truth = _straight(50.0, 0.01)
    k = 0.01  # rad/m: the estimate drives an arc of radius 100 m
    s = truth[:, 0]
    est = np.column_stack([np.sin(k * s) / k, (1 - np.cos(k * s)) / k, k * s])
    d = path_drift(truth, est, length_m=10.0)
    # each piece, re-anchored at its start, is the same arc of 10 m against a 10 m line
    expect = math.hypot(10 - math.sin(0.1) / k, (1 - math.cos(0.1)) / k)
    assert d.error_m == pytest.approx(np.full(d.pieces, expect), rel=1e-6)
    assert d.median_pct == pytest.approx(10 * expect, rel=1e-6)  # about 5 %
    assert d.median_heading_deg_per_10m == pytest.approx(math.degrees(0.1), rel=1e-6)


def test_a_distance_scale_error_of_ten_percent_is_ten_percent():
    truth = _straight()
    est = truth * [0.9, 1.0, 1.0]
    d = path_drift(truth, est, length_m=10.0)
    assert d.error_pct == pytest.approx(np.full(d.pieces, 10.0))


def test_frames_do_not_matter_only_relative_motion():
    rng = np.random.default_rng(0)
    truth = np.cumsum(rng.normal(size=(500, 3)) * [0.1, 0.1, 0.05], axis=0)
    c, s = math.cos(1.0), math.sin(1.0)
    x = 3 + c * truth[:, 0] - s * truth[:, 1]
    y = -2 + s * truth[:, 0] + c * truth[:, 1]
    moved = np.column_stack([x, y, truth[:, 2] + 1.0])
    assert path_drift(truth, moved, length_m=5.0).error_m == pytest.approx(0.0, abs=1e-9)


def test_consecutive_pieces_follow_each_other_and_reach_the_length():
    rng = np.random.default_rng(1)
    truth = np.cumsum(rng.uniform(0, 0.2, size=(800, 3)) * [1, 1, 0.1], axis=0)
    d = path_drift(truth, truth, length_m=7.0)
    assert d.start[0] == 0 and np.array_equal(d.start[1:], d.end[:-1])
    dist = path_length(truth)
    assert np.all(d.piece_length_m >= 7.0)
    assert np.all(dist[d.end - 1] - dist[d.start] < 7.0)  # the first sample that reaches it
    assert d.pieces == len(d.start) and d.median_pct == 0.0


def _evo_pairs(dist, delta, tol):
    """evo's filter_pairs_by_path with all_pairs (evo/core/filters.py), restated as a loop."""
    pairs = []
    for i in range(len(dist) - 1):
        d = dist[i + 1 :] - dist[i]
        c = int(np.argmin(np.abs(d - delta)))
        if abs(d[c] - delta) <= tol:
            pairs.append((i, c + i + 1))
    return pairs


def test_all_pairs_are_evo_s_pairs_with_standstills_and_the_end_of_the_path():
    rng = np.random.default_rng(2)
    steps = rng.uniform(0, 0.3, size=600)
    steps[rng.random(600) < 0.3] = 0.0  # standstills: equal distances, argmin takes the first
    xy = np.cumsum(np.column_stack([steps, np.zeros(600)]), axis=0)
    truth = np.column_stack([xy, np.zeros(600)])
    d = path_drift(truth, truth, length_m=10.0, mode="all-pairs", tolerance=0.1)
    expect = _evo_pairs(path_length(truth), 10.0, 1.0)
    assert list(zip(d.start.tolist(), d.end.tolist(), strict=True)) == expect


def test_pieces_never_span_a_break():
    truth = _straight(40.0, 0.5)
    d = path_drift(truth, truth, length_m=5.0, breaks=[30])
    assert not np.any((d.start < 30) & (d.end >= 30))
    assert d.start[d.start >= 30][0] == 30
    with pytest.raises(ModelError, match="breaks"):
        path_drift(truth, truth, breaks=[0])


def test_no_pieces_when_the_path_is_shorter_than_the_length():
    truth = _straight(5.0)
    d = path_drift(truth, truth, length_m=10.0)
    assert d.pieces == 0 and math.isnan(d.median_pct)


@pytest.mark.parametrize(
    "kwargs,match",
    [
        (dict(length_m=0.0), "length_m"),
        (dict(mode="pairs"), "mode"),
        (dict(tolerance=-1.0), "tolerance"),
    ],
)
def test_bad_arguments_are_refused(kwargs, match):
    truth = _straight(20.0)
    with pytest.raises(ModelError, match=match):
        path_drift(truth, truth, **kwargs)
    with pytest.raises(ModelError, match="shape"):
        path_drift(truth, truth[:-1])
