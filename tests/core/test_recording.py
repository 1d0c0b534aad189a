"""One recording given twice, told from two recordings that merely share a clock."""

from dataclasses import replace

import numpy as np
import pytest

from odocal.core.recording import Recording, same_recording


def _run(seed, start_s=1.7e9, n=500, still=False):
    rng = np.random.default_rng(seed)
    steps = np.zeros((n - 1, 2)) if still else rng.uniform(0.0, 0.02, size=(n - 1, 2))
    angles = np.vstack([[0.0, 0.0], np.cumsum(steps, axis=0)])
    return Recording(
        f"run{seed}.bag",
        0.02 * np.arange(n),
        angles[:, 0],
        angles[:, 1],
        meta={"bag": f"run{seed}.bag", "start_s": start_s},
    )


def _part(r, lo, hi):
    """Samples lo..hi of ``r`` as a loader gives them: times and angles from zero."""
    t, right, left = r.time_s[lo:hi], r.wheel_angle_right_rad[lo:hi], r.wheel_angle_left_rad[lo:hi]
    return replace(
        r,
        name="part.bag",
        time_s=t - t[0],
        wheel_angle_right_rad=right - right[0],
        wheel_angle_left_rad=left - left[0],
        meta={**r.meta, "bag": "part.bag", "start_s": r.meta["start_s"] + t[0]},
    )


def test_a_copy_and_a_part_are_the_same_recording():
    a = _run(1)
    assert same_recording(a, replace(a, name="copy.bag")) == pytest.approx(
        (1.7e9, 1.7e9 + 0.02 * 499), abs=1e-6
    )
    lo, hi = same_recording(a, _part(a, 250, 500))
    assert (lo - 1.7e9, hi - lo) == pytest.approx((5.0, 0.02 * 249), abs=1e-6)
    assert same_recording(_part(a, 100, 400), a) is not None


def test_runs_on_the_same_stamps_with_other_samples_are_two_recordings():
    # a simulator whose clock restarts at zero; a robot whose clock starts at one date
    assert same_recording(_run(1), _run(2)) is None
    # standing still on the same stamps is no shared measurement
    assert same_recording(_run(1, still=True), _run(2, still=True)) is None
    # consecutive logs, and runs without instants, are never compared
    assert same_recording(_run(1), _run(1, start_s=1.7e9 + 10.0)) is None
    no_clock = replace(_run(1), meta={})
    assert same_recording(no_clock, no_clock) is None


def test_the_same_wheels_with_another_gyro_or_truth_are_two_runs():
    # a noise-free simulator repeats the wheels bit for bit; the gyro's noise (or the truth)
    # still tells two runs apart, and a copy shares every channel
    a = _run(1)
    gyro = np.cumsum(np.random.default_rng(5).normal(0.01, 0.001, len(a.time_s)))
    truth = np.column_stack([np.linspace(0, 2, len(a.time_s)), np.zeros(len(a.time_s)), gyro])
    a = replace(a, gyro_yaw_rad=gyro, ground_truth=truth)
    assert same_recording(a, replace(a, name="copy.bag")) is not None
    assert same_recording(a, replace(a, gyro_yaw_rad=gyro[::-1].copy())) is None
    other_truth = truth.copy()
    other_truth[:, 0] *= 1.01
    assert same_recording(a, replace(a, ground_truth=other_truth)) is None


def test_runs_sharing_a_minority_of_their_measurements_are_two_runs():
    # on one clock, b repeats a's wheel increments on 40 % of the steps and stands still on
    # the rest: fewer than half of the moving increments are shared, so two runs
    a = _run(1)
    keep = np.random.default_rng(7).random(len(a.time_s) - 1) < 0.4
    right = np.concatenate([[0.0], np.cumsum(np.where(keep, np.diff(a.wheel_angle_right_rad), 0))])
    left = np.concatenate([[0.0], np.cumsum(np.where(keep, np.diff(a.wheel_angle_left_rad), 0))])
    b = replace(a, name="b.bag", wheel_angle_right_rad=right, wheel_angle_left_rad=left)
    assert same_recording(a, b) is None and same_recording(b, a) is None


def test_another_true_heading_on_the_same_path_is_another_run():
    a = _run(1)
    n = len(a.time_s)
    truth = np.column_stack([np.linspace(0, 2, n), np.zeros(n), np.linspace(0, 1, n)])
    a = replace(a, ground_truth=truth)
    turned = truth.copy()
    turned[:, 2] *= 1.01
    assert same_recording(a, replace(a, name="copy.bag")) is not None
    assert same_recording(a, replace(a, name="b.bag", ground_truth=turned)) is None


def test_runs_with_a_quarter_of_their_stamps_in_common_are_not_one_recording():
    # the same values, but three stamps in four of b 1 ms off a's: fewer than half of the
    # shared time's samples fall on the other's stamps (the rule in the docstring)
    a = _run(1)
    shifted = a.time_s + np.where(np.arange(len(a.time_s)) % 4 == 0, 0.0, 0.001)
    shifted[0] = 0.0
    assert same_recording(a, replace(a, name="b.bag", time_s=shifted)) is None
    assert same_recording(a, replace(a, name="b.bag", time_s=a.time_s.copy())) is not None
