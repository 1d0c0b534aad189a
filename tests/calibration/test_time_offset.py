"""Clock offsets by temporal registration of headings (calibration.time_offset)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.time_offset import (
    TimeOffset,
    _argmin_refined,
    estimate_time_offset,
    offset_covariance,
    pooled_offset_s,
    time_blocks,
    truth_on_wheel_clock,
    wheel_rotations,
)
from odocal.core.recording import Recording
from odocal.errors import CalibrationError

D_R, D_L, B = 0.101, 0.099, 0.42  # the true geometry the source sees


def drive(duration_s=240.0, rate_hz=50.0, seed=0):
    """Wheel angles of a robot that alternates straight legs and turns of varied rates."""
    rng = np.random.default_rng(seed)
    t = np.arange(0.0, duration_s, 1.0 / rate_hz)
    # piecewise-constant commands, 1-4 s each, smoothed over 0.3 s
    edges = np.cumsum(rng.uniform(1.0, 4.0, size=200))
    seg = np.searchsorted(edges, t)
    v = rng.uniform(0.0, 0.6, size=201)[seg]
    w = rng.choice([-1.0, -0.4, 0.0, 0.0, 0.5, 1.2], size=201)[seg]
    k = np.ones(int(0.3 * rate_hz)) / int(0.3 * rate_hz)
    v, w = np.convolve(v, k, "same"), np.convolve(w, k, "same")
    wr = (v + 0.5 * B * w) / (0.5 * D_R)  # rad/s
    wl = (v - 0.5 * B * w) / (0.5 * D_L)
    dt = 1.0 / rate_hz
    right = np.concatenate([[0.0], np.cumsum(0.5 * (wr[1:] + wr[:-1]) * dt)])
    left = np.concatenate([[0.0], np.cumsum(0.5 * (wl[1:] + wl[:-1]) * dt)])
    return t, right, left


def source_intervals(t, right, left, offset_s, rate_hz, noise_rad, seed=1):
    """A source at ``rate_hz`` whose stamps are ``offset_s`` late: its heading changes between
    consecutive samples, with white noise on each heading."""
    rng = np.random.default_rng(seed)
    stamps = np.arange(t[0] + 1.0, t[-1] - 1.0, 1.0 / rate_hz)
    seen = stamps - offset_s  # the wheel time each sample saw
    heading = (0.5 * D_R * np.interp(seen, t, right) - 0.5 * D_L * np.interp(seen, t, left)) / B
    heading = heading + noise_rad * rng.standard_normal(len(stamps))
    return stamps[:-1], stamps[1:], np.diff(heading)


@pytest.mark.parametrize("offset_s, rate_hz", [(0.1, 5.0), (-0.07, 10.0), (0.0, 4.7), (0.25, 20.0)])
def test_a_known_offset_is_recovered_within_its_error_and_10_ms(offset_s, rate_hz):
    t, right, left = drive()
    a, b, dth = source_intervals(t, right, left, offset_s, rate_hz, math.radians(0.3))
    est = estimate_time_offset(t, right, left, a, b, dth, source="laser")
    assert est.how.startswith("estimated") and est.source == "laser"
    # applied when it stands out of its noise (the 0 s log keeps its stamps)
    assert est.applied == (offset_s != 0.0) and est.applied_s == (
        est.offset_s if est.applied else 0
    )
    assert abs(est.offset_s - offset_s) < 0.010
    # the bootstrap error is honest: the truth within 4 of them, and it is not absurdly wide
    assert abs(est.offset_s - offset_s) < 4 * est.stderr_s + 1e-4
    assert est.stderr_s < 0.01
    assert est.warnings == ()


def test_the_offset_ignores_outlying_intervals():
    # a tenth of the intervals replaced by loop-closure-like jumps of 20 deg
    t, right, left = drive(seed=3)
    a, b, dth = source_intervals(t, right, left, 0.1, 5.0, math.radians(0.2))
    bad = np.random.default_rng(5).choice(len(dth), size=len(dth) // 10, replace=False)
    dth = dth.copy()
    dth[bad] += math.radians(20.0)
    est = estimate_time_offset(t, right, left, a, b, dth, source="slam")
    assert abs(est.offset_s - 0.1) < 0.010
    # and they do not widen it: a fit that weighs them fully (no Cauchy weights) lands 2 ms
    # off with an 8 ms standard error; the robust one 0.6 ms off with 0.8 ms
    assert abs(est.offset_s - 0.1) < 0.002 and est.stderr_s < 0.002


def test_no_turning_no_offset_and_the_edge_is_reported():
    t = np.arange(0.0, 60.0, 0.02)
    straight = 5.0 * t
    a, b = t[50:-100:10], t[60:-90:10]
    with pytest.raises(CalibrationError, match="turn by more than 0.5 deg"):
        estimate_time_offset(t, straight, straight, a, b, np.zeros(len(a)), source="imu")
    tt, right, left = drive()
    a, b, dth = source_intervals(tt, right, left, 0.45, 10.0, 0.0)
    est = estimate_time_offset(tt, right, left, a, b, dth, source="mocap", max_offset_s=0.3)
    assert any("edge of the searched range" in w for w in est.warnings)


def test_helpers():
    t = np.array([0.0, 1.0, 2.0])
    r, lft = wheel_rotations(t, np.array([0.0, 1.0, 3.0]), np.zeros(3), [0.5], [1.5])
    assert r[0] == pytest.approx(1.5) and lft[0] == 0.0
    blocks = time_blocks(np.linspace(0.0, 100.0, 1001), blocks=10)
    assert blocks.max() == 9 and np.all(np.diff(blocks) >= 0)
    assert time_blocks(np.linspace(0.0, 5.0, 51), blocks=10, min_block_s=2.0).max() == 1
    g = TimeOffset.given("slam", -0.2)
    assert g.as_dict()["offset_s"] == -0.2 and g.stderr_s is None and g.how == "given"


def test_a_heading_can_stand_in_for_the_wheels():
    # the gyro route has the odometry's heading, not two wheels: (heading, zeros) is a model
    # with one coefficient (it was singular, and every candidate fitted nothing)
    # 120 s, not 240: the offset's standard error is ~1 ms (0.5 ms over 240 s), so 5 ms is
    # 5 standard errors (a false failure < 1e-6); a singular model fits nothing at any length
    t, right, left = drive(duration_s=120.0, seed=7)
    heading = (0.5 * D_R * right - 0.5 * D_L * left) / B
    a, b, dth = source_intervals(t, right, left, 0.09, 30.0, math.radians(0.1))
    est = estimate_time_offset(t, heading, np.zeros_like(heading), a, b, dth, source="imu")
    assert abs(est.offset_s - 0.09) < 0.005 and est.stderr_s < 0.005


def test_several_estimates_are_pooled():
    a = TimeOffset("truth (a)", 0.10, 0.01, "estimated")
    b = TimeOffset("truth (b)", 0.04, 0.02, "estimated")
    assert pooled_offset_s([a, b]) == pytest.approx((0.10 / 1e-4 + 0.04 / 4e-4) / (1e4 + 2.5e3))
    c = TimeOffset("truth (c)", 0.0, None, "not estimated")
    assert pooled_offset_s([a, b, c]) == pytest.approx(0.04)  # the median


def test_each_data_set_s_truth_moves_onto_the_wheels_clock():
    t, right, left = drive(duration_s=60.0)
    gt = np.column_stack([np.zeros_like(t), np.zeros_like(t), (t / t[-1]) ** 2])
    runs = [
        Recording("a1", t, right, left, ground_truth=gt, meta={"dataset": "a"}),
        Recording("b1", t, right, left, ground_truth=gt, meta={"dataset": "b"}),
        Recording("b2", t, right, left, meta={"dataset": "b"}),  # no truth: as it was
    ]
    moved, offsets = truth_on_wheel_clock(runs, 0.2)
    assert [o.label for o in offsets] == ["truth (a)", "truth (b)"]
    assert [(o.source, o.part) for o in offsets] == [("truth", "a"), ("truth", "b")]
    assert all(o.how == "given" and o.applied_s == 0.2 for o in offsets)
    assert moved[2] is runs[2]
    assert moved[0].ground_truth[0, 2] == pytest.approx(0.0)
    # the truth taken 0.2 s later (relative to its first pose)
    expected = ((t[10] + 0.2) / t[-1]) ** 2 - ((t[0] + 0.2) / t[-1]) ** 2
    assert moved[0].ground_truth[10, 2] == pytest.approx(expected, rel=1e-6)
    # a truth that cannot be aligned keeps its stamps, with a warning
    still = [Recording("c1", t[:3], right[:3], left[:3], ground_truth=gt[:3],
                       meta={"dataset": "c"})]  # fmt: skip
    kept, (offset,) = truth_on_wheel_clock(still, None)
    assert offset.how == "not estimated" and offset.applied_s == 0.0
    assert offset.warnings[0].endswith("; taken as 0") and kept[0] is still[0]


def test_the_timing_check_passes_a_constant_offset():
    # the turning of the wheels against the source's does not depend on the interval length
    # when the clocks differ by a constant (removed) and nothing else
    from odocal.calibration.time_offset import timing_consistency

    t, right, left = drive(seed=9)
    a, b, dth = source_intervals(t, right, left, 0.0, 10.0, math.radians(0.1))
    pr, pl = wheel_rotations(t, right, left, a, b)
    check = timing_consistency(pr, pl, dth, a, b, source="laser")
    assert check is not None and check.consistent and check.warning is None
    assert check.turn_ratio[0] == 1.0 and len(check.lengths_s) >= 3
    assert max(abs(r - 1) for r in check.turn_ratio) < 0.005


def test_the_timing_check_flags_odometry_that_stalls_and_catches_up():
    # 15 % of the wheel intervals report nothing and the next one reports both: short
    # intervals see it, 8 composed ones hardly (the turning ratio moves by about 2 %)
    from odocal.calibration.time_offset import timing_consistency

    t, right, left = drive(seed=9)
    a, b, dth = source_intervals(t, right, left, 0.0, 10.0, math.radians(0.1))
    pr, pl = wheel_rotations(t, right, left, a, b)
    for k in np.flatnonzero(np.random.default_rng(2).random(len(pr) - 1) < 0.15):
        pr[k + 1], pl[k + 1] = pr[k + 1] + pr[k], pl[k + 1] + pl[k]
        pr[k] = pl[k] = 0.0
    check = timing_consistency(pr, pl, dth, a, b, source="laser")
    assert check is not None and not check.consistent
    # the 8-composed intervals' ratio to the single ones moves (1.022 here) beyond 3 of its
    # errors from the same drive's without the stalls (0.9997, consistent: test above)
    clean = timing_consistency(*wheel_rotations(t, right, left, a, b), dth, a, b, source="laser")
    assert clean is not None and clean.consistent
    assert check.turn_ratio[-1] - clean.turn_ratio[-1] > 3 * check.stderr[-1]
    assert "depends on the interval length" in check.warning


def test_only_intervals_whose_shifted_window_stays_in_the_wheel_data_count():
    # the source covers the whole wheel log: intervals within max_offset_s of its ends would
    # be compared with wheels held at their first or last angle, and are left out
    t, right, left = drive(duration_s=60.0)
    stamps = np.arange(t[0], t[-1], 0.1)
    seen = stamps - 0.05
    heading = (0.5 * D_R * np.interp(seen, t, right) - 0.5 * D_L * np.interp(seen, t, left)) / B
    a, b = stamps[:-1], stamps[1:]
    est = estimate_time_offset(t, right, left, a, b, np.diff(heading), source="mocap")
    assert est.intervals == np.count_nonzero((a - 0.5 >= t[0]) & (b + 0.5 <= t[-1]))
    assert abs(est.offset_s - 0.05) < 0.002


def test_a_sampled_parabola_s_minimum_and_the_offset_s_covariance():
    grid = np.linspace(-0.1, 0.1, 21)
    assert _argmin_refined(grid, (grid - 0.033) ** 2 + 1.0) == pytest.approx(0.033, abs=1e-12)
    assert _argmin_refined(grid, (grid + 0.2) ** 2) == -0.1  # at the edge: the edge
    # two refits at d -+ se: J = dp/dd by central differences, J J^T se^2
    est = TimeOffset("slam", 0.03, 0.004, "estimated", applied=True)
    cov = offset_covariance(lambda d: np.array([2.0 * d, -d + 1.0, 5.0]), est)
    np.testing.assert_allclose(cov, np.outer([2.0, -1.0, 0.0], [2.0, -1.0, 0.0]) * 0.004**2)
    assert offset_covariance(lambda d: np.zeros(3), TimeOffset.given("slam", 0.03)) is None


def test_a_late_ground_truth_s_offset_is_estimated_from_its_heading():
    # two runs of one data set whose truth is stamped 80 ms late; the runs are strung on one
    # clock, each window within a run, the truth's heading change over each compared
    from odocal.calibration.time_offset import truth_offset

    runs = []
    for seed in (0, 1):
        t, right, left = drive(duration_s=40.0, seed=seed)
        heading = (0.5 * D_R * right - 0.5 * D_L * left) / B
        seen = np.interp(t - 0.08, t, heading)
        gt = np.column_stack([np.zeros_like(t), np.zeros_like(t), seen - seen[0]])
        runs.append(Recording(f"r{seed}", t, right, left, ground_truth=gt, meta={"dataset": "a"}))
    est = truth_offset(runs)
    assert abs(est.offset_s - 0.08) < 0.003 and est.applied
    moved, (offset,) = truth_on_wheel_clock(runs, None)
    assert offset.label == "truth (a)" and offset.offset_s == est.offset_s
    # the moved truth's heading is the wheels' (to the estimate's 3 ms of turning, inside)
    t, right, left = runs[1].time_s, runs[1].wheel_angle_right_rad, runs[1].wheel_angle_left_rad
    heading = (0.5 * D_R * right - 0.5 * D_L * left) / B
    inner = slice(50, -50)
    np.testing.assert_allclose(
        moved[1].ground_truth[inner, 2], (heading - heading[0])[inner], atol=0.01
    )


def test_one_closed_set_of_clock_sources():
    # the flag's sources are the closed type's (the wheels are the reference clock, not a flag)
    from odocal.calibration.time_offset import TIME_SOURCES, resolve_offset
    from odocal.io.bag_options import TIME_OFFSET_SOURCES

    assert TIME_SOURCES[0] == "wheels" and TIME_OFFSET_SOURCES == TIME_SOURCES[1:]
    # the one rule: given wins, else the estimate, else 0 with the reason
    assert resolve_offset("imu", 0.02, lambda: 1 / 0).how == "given"

    def fails():
        raise CalibrationError("too little turning")

    o = resolve_offset("laser", None, fails)
    assert o.offset_s == 0.0 and o.how == "not estimated" and "too little turning" in o.warnings[0]
