"""Steps 2-3 of the paper from recordings (calibration.noise): k from repeated recorded runs, the
tracker's noise, and the covariances for the robot stack (the measured robot through ``noise``,
``design --robot-from`` and ``fit --robot-out`` is tested in tests/cli)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.noise import estimate_k_from_recordings, tracker_noise
from odocal.core.covariance import odometry_covariance, straight_line_covariance
from odocal.core.model import MeasurementNoise
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.errors import CalibrationError
from tests.support.noise_runs import TRUE, K, noisy_run


@pytest.fixture(scope="module")
def repeats():
    rng = np.random.default_rng(11)
    return [
        noisy_run(f"{d}-{direction}-{i}", d, direction, rng)
        for d in ("set-a", "set-b")
        for direction in ("cw", "ccw")
        for i in range(20)
    ]


@pytest.fixture(scope="module")
def clean(repeats):
    """k estimated from the noise-free-tracker repeats (computed once, only inspected)."""
    return estimate_k_from_recordings(repeats, TRUE)


def test_k_from_repeated_squares_recovers_the_truth(clean):
    est = clean
    assert est.runs == 80 and est.dof == 76 and len(est.groups) == 4
    # the pooled heading variance has a relative standard error sqrt(2 / 76) = 16 %: 3 of them
    assert est.k_sum_m == pytest.approx(2 * K, rel=0.49)
    lo, hi = est.k_sum_ci95_m
    assert lo < est.k_sum_m < hi
    assert lo < 2 * K < hi  # the 95 % interval covers the truth (seeded, so deterministic)
    # squares turn on the spot with both wheels alike: k_r and k_l cannot be told apart
    assert est.k_r_m is None and "not identifiable" in est.split_note
    # each group's own interval contains the pooled value (one track, one k)
    assert not any("disagree" in w for w in est.warnings)


def test_the_systematic_part_is_removed(repeats, clean):
    """A different systematic error per data set (a different wheelbase) shifts the means, not
    the spread: k is unchanged."""
    shifted = []
    for r in repeats:
        if r.meta["dataset"] == "set-b":
            gt = r.ground_truth.copy()
            # the same runs seen by a robot turning 1 % more: a big systematic heading offset
            odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, TRUE)
            gt[:, 2] += 0.01 * odo[:, 2]
            r = Recording(r.name, r.time_s, r.wheel_angle_right_rad, r.wheel_angle_left_rad,
                          ground_truth=gt, label=r.label, meta=r.meta)  # fmt: skip
        shifted.append(r)
    b = estimate_k_from_recordings(shifted, TRUE)
    assert b.k_sum_m == pytest.approx(clean.k_sum_m, rel=1e-6)


def test_tracker_noise_is_subtracted_and_measured(repeats, clean):
    rng = np.random.default_rng(3)
    sigma = math.radians(0.6)
    jittered = []
    for r in repeats:
        gt = r.ground_truth.copy()
        gt[:, 2] += rng.normal(0, sigma, len(gt))
        gt[:, :2] += rng.normal(0, 0.001, (len(gt), 2))
        gt -= gt[0]  # the start frame is the (measured) start pose
        jittered.append(Recording(r.name, r.time_s, r.wheel_angle_right_rad,
                                  r.wheel_angle_left_rad, ground_truth=gt, label=r.label,
                                  meta=r.meta))  # fmt: skip
    tr = tracker_noise(jittered)
    # white noise on a path that turns smoothly: the second differences see it (10 %)
    assert tr.sigma_theta_rad == pytest.approx(sigma, rel=0.1)
    assert tr.sigma_xy_m == pytest.approx(0.001, rel=0.1)
    naive = estimate_k_from_recordings(jittered, TRUE)
    fixed = estimate_k_from_recordings(jittered, TRUE, MeasurementNoise(0.001, sigma))
    # the jitter adds 2 sigma^2 (start and end), a third of the wheel noise's heading variance
    assert naive.k_sum_m > 1.15 * clean.k_sum_m
    # subtracting it brings the estimate back; what is left is the jitter's own sampling error
    # and its cross term with the wheel noise, relative standard error about 0.14: 3 of them
    assert abs(fixed.k_sum_m - clean.k_sum_m) < abs(naive.k_sum_m - clean.k_sum_m)
    assert fixed.k_sum_m == pytest.approx(clean.k_sum_m, rel=0.42)


def test_single_runs_and_non_repeats_are_refused():
    rng = np.random.default_rng(0)
    runs = [noisy_run("a", "s1", "cw", rng), noisy_run("b", "s2", "ccw", rng)]
    with pytest.raises(CalibrationError, match="no group of repeated runs") as exc:
        estimate_k_from_recordings(runs, TRUE)
    assert "a single run" in str(exc.value)


def test_ros2_covariance_formulas():
    c = odometry_covariance(1e-6, 3e-6, 0.2, speed_m_s=0.5, distance_m=2.0, window_s=0.1)
    p = straight_line_covariance(2.0, 0.2, 1e-6, 3e-6)
    assert c.pose_diagonal[0] == pytest.approx(p[0, 0]) and c.pose_diagonal[5] == p[2, 2]
    assert c.pose_diagonal[1] == pytest.approx(4e-6 * 8 / (3 * 0.04))
    # velocity from the wheel travel over 0.1 s at 0.5 m/s: var = (k_r + k_l) v / (4 T)
    assert c.twist_diagonal[0] == pytest.approx(4e-6 * 0.5 / 0.4)
    assert c.twist_diagonal[5] == pytest.approx(4e-6 * 0.5 / (0.04 * 0.1))
    assert c.process_noise_per_s["yaw"] == pytest.approx(4e-6 * 0.5 / 0.04)
    with pytest.raises(Exception, match="speed_m_s"):
        odometry_covariance(1e-6, 1e-6, 0.2, speed_m_s=0.0)
