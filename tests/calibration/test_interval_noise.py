"""The wheels' random error from one log's intervals (calibration.interval_noise)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration.interval_noise import MAX_INTERVALS, estimate_interval_noise
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon_rows
from odocal.core.transforms import se2_compose, se2_relative
from odocal.errors import CalibrationError

G = WheelGeometry(0.2, 0.2, 0.5)


def log(k_sum, truth_sigma=(0.005, 0.005), n=500, steps=20, seed=0):
    """n intervals of 0.3-3 m of mixed motion; each wheel step's travel gets variance
    k_w |s| (k_w = k_sum / 2); the truth measures the motion with white noise."""
    rng = np.random.default_rng(seed)
    length = rng.uniform(1.5, 15.0, size=(n, 1))  # rad of wheel rotation per interval
    turn = rng.uniform(-0.8, 0.8, size=(n, 1))
    r = np.repeat(length * (1 + turn), steps, axis=1) / steps
    lft = np.repeat(length * (1 - turn), steps, axis=1) / steps
    s_r, s_l = 0.1 * r, 0.1 * lft
    noisy_r = s_r + rng.standard_normal(s_r.shape) * np.sqrt(0.5 * k_sum * np.abs(s_r))
    noisy_l = s_l + rng.standard_normal(s_l.shape) * np.sqrt(0.5 * k_sum * np.abs(s_l))
    true_motion = dead_reckon_rows(noisy_r / 0.1, noisy_l / 0.1, G)[:, :, -1].T
    sig = np.array([truth_sigma[0], truth_sigma[0], truth_sigma[1]])
    measured = true_motion + rng.standard_normal(true_motion.shape) * sig
    return r, lft, measured, np.arange(n, dtype=float)


def test_k_and_the_truth_noise_are_recovered():
    hits = 0
    for seed in range(2):
        r, lft, m, t = log(4e-4, seed=seed)
        est = estimate_interval_noise(r, lft, m, G, t)
        lo, hi = est.k_ci95_m
        hits += lo <= 4e-4 <= hi
        assert est.k_sum_m == pytest.approx(4e-4, rel=0.35)
        assert est.truth_sigma_xy_m == pytest.approx(0.005, rel=0.3)
        # the heading noise of the truth hides under the wheels' (0.05 rad over 1.5 m): weakly
        # identified, within a factor 2
        assert 0.0025 < est.truth_sigma_theta_rad < 0.01
    assert hits >= 1  # coverage over many seeds: benchmarks/bench_uncertainty.py
    assert est.as_dict()["intervals"] == MAX_INTERVALS  # of the 500: chunks spread over the log


def test_too_few_intervals():
    r, lft, m, t = log(4e-4, n=10)
    with pytest.raises(CalibrationError, match="too few intervals"):
        estimate_interval_noise(r, lft, m, G, t)


def test_intervals_of_one_length_are_separated_by_composing_them():
    # every interval the same length (a SLAM updating at a fixed rate): alone they cannot
    # tell the wheels' noise from the truth's; composed into stretches of 2-16 they can
    rng = np.random.default_rng(4)
    n, steps, k_sum = 400, 10, 4e-4
    turn = np.repeat(rng.uniform(-0.6, 0.6, size=(n // 4, 1)), 4, axis=0)
    r = np.repeat(5.0 * (1 + turn), steps, axis=1) / steps
    lft = np.repeat(5.0 * (1 - turn), steps, axis=1) / steps
    s_r, s_l = 0.1 * r, 0.1 * lft
    noisy_r = s_r + rng.standard_normal(s_r.shape) * np.sqrt(0.5 * k_sum * np.abs(s_r))
    noisy_l = s_l + rng.standard_normal(s_l.shape) * np.sqrt(0.5 * k_sum * np.abs(s_l))
    # the truth is a pose track (its noise on each pose, not on each interval's motion)
    true_motion = dead_reckon_rows(noisy_r / 0.1, noisy_l / 0.1, G)[:, :, -1].T
    poses = [np.zeros(3)]
    for mo in true_motion:
        poses.append(se2_compose(poses[-1], mo))
    poses = np.array(poses) + rng.standard_normal((n + 1, 3)) * np.array([0.01, 0.01, 0.005])
    measured = se2_relative(poses[:-1], poses[1:])
    t = np.arange(n, dtype=float)
    est = estimate_interval_noise(r, lft, measured, G, t, end_s=t + 1.0)
    lo, hi = est.k_ci95_m
    assert lo <= est.k_sum_m <= hi
    assert est.k_sum_m == pytest.approx(k_sum, rel=0.4)
