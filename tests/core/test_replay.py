"""The replay of recorded wheel rotations (core.replay): without noise it is dead reckoning, with
noise its scatter is the model's."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.core.model import NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.replay import chunk_rotations, replay_final_errors

TRUE = WheelGeometry(0.0837, 0.0838, 0.2020)


def _angles():
    """A run of arcs, spins and lines at 20 Hz (cumulative wheel angles, rad)."""
    t = np.arange(0, 60, 0.05)
    v_r = 0.1 + 0.08 * np.sin(0.3 * t) + 0.15 * (np.sin(0.11 * t) > 0.9)
    v_l = 0.1 - 0.05 * np.sin(0.23 * t) - 0.15 * (np.sin(0.11 * t) > 0.9)
    return np.r_[0, np.cumsum(v_r * 0.05)] / 0.0419, np.r_[0, np.cumsum(v_l * 0.05)] / 0.0419


def test_replay_without_noise_is_dead_reckoning():
    right, left = _angles()
    chunks = chunk_rotations(right, left, 0.05 / 0.042)
    assert len(chunks) < len(right) / 2  # merged
    np.testing.assert_allclose(chunks[[0, -1]], [[0, 0], [right[-1], left[-1]]])
    cals = WheelGeometry.unchecked(
        np.array([[0.0840, 0.0836], [0.0837, 0.0839]]),
        np.array([[0.0840, 0.0837], [0.0838, 0.0838]]),
        np.array([[0.2000, 0.2030], [0.2020, 0.2010]]),
    )
    err = replay_final_errors(chunks, TRUE, NonSystematicError(), cals, None)
    truth = dead_reckon(right, left, TRUE)[-1, :2]
    for i in range(2):
        for j in range(2):
            g = WheelGeometry(
                cals.diameter_right_m[i, j], cals.diameter_left_m[i, j], cals.wheelbase_m[i, j]
            )
            want = np.hypot(*(truth - dead_reckon(right, left, g)[-1, :2]))
            # exact arcs over 5 cm chunks against the midpoint rule over 20 Hz samples: the
            # same end point to 0.1 % of the error (0.5 mm of these 0.1-0.7 m errors)
            assert err[i, j] == pytest.approx(want, rel=1e-3, abs=2e-4)


def test_replay_noise_matches_its_variance():
    """Noise only (calibrated = true): the final heading-free position scatter grows as the
    model's; checked through the mean squared error against the first-order covariance."""
    from odocal.core.covariance import propagate_increments

    right, left = _angles()
    chunks = chunk_rotations(right, left, 0.05 / 0.042)
    k = NonSystematicError(2e-6, 2e-6)
    n = 4000
    cal = WheelGeometry.unchecked(
        np.full(n, TRUE.diameter_right_m), np.full(n, TRUE.diameter_left_m),
        np.full(n, TRUE.wheelbase_m),
    )  # fmt: skip
    err = replay_final_errors(chunks, TRUE, k, cal, np.random.default_rng(2))[0]
    dr = np.diff(right) * TRUE.diameter_right_m / 2
    dl = np.diff(left) * TRUE.diameter_left_m / 2
    _, cov = propagate_increments(dr, dl, TRUE.wheelbase_m, k)
    want = cov[0, 0] + cov[1, 1]
    # mean of n squared errors: relative standard error about sqrt(2 / n) ~ 2 %, plus first
    # order: 10 %
    assert np.mean(err**2) == pytest.approx(want, rel=0.1)
