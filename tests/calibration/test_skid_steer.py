"""Skid-steer identification (calibration/skid_steer): simulated robots with known parameters
are recovered within their stated errors, the 95 % intervals cover about 95 % of the time over
many simulated logs, the truth's clock offset and jumps are handled; and on a real Warthog log
the numbers are those docs/skid-steer.md reports."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.special import stdtrit

from odocal.calibration.skid_steer import (
    SkidIntervals,
    block_bootstrap,
    cross_validate,
    fit_skid_logs,
    fit_skid_steer,
    log_drift,
    offset_at,
    skid_intervals,
    truth_clock_offset,
    turn_rate_knots,
    windowed_truth_offset,
    z_score,
)
from odocal.core.model import WheelGeometry
from odocal.core.skid_steer import SkidSteerModel, TurnRateTable
from odocal.errors import CalibrationError
from tests.support.skid_robot import simulate_skid_log

NOMINAL = WheelGeometry.symmetric(0.6, 1.08)  # a Warthog
TRUE = SkidSteerModel(0.3 * 0.96, 0.3 * 0.95, 1.08 * 1.65 / 2, -1.08 * 1.65 / 2)
TRUE_VALUES = np.array([0.96, 0.95, 1.65])  # scale_right, scale_left, track_multiplier


def _log(seed, true=TRUE, **kw):
    kw.setdefault("duration_s", 150.0)
    kw.setdefault("sim_hz", 50.0)
    return simulate_skid_log(true, np.random.default_rng(seed), **kw)


def _within(fit, truth, z=3.5):
    err = (fit.values - np.asarray(truth)) / fit.stderr
    assert np.all(np.abs(err) < z), (fit.names, fit.values, fit.stderr)


def test_the_effective_track_and_the_wheel_scales_are_recovered_within_their_errors():
    log = _log(1, slip=0.02, duration_s=300.0)
    fit = fit_skid_steer(skid_intervals(log), NOMINAL, wheel_scales="left-right")
    assert fit.names == ("scale_right", "scale_left", "track_multiplier")
    _within(fit, TRUE_VALUES)
    assert fit.stderr[2] < 0.02 and fit.clusters >= 15 and fit.dof == fit.clusters - 1
    assert fit.track_multiplier() == (fit.values[2], fit.stderr[2])
    ros = fit.model.ros2_multipliers(NOMINAL)
    assert ros["wheel_separation_multiplier"] == pytest.approx(fit.values[2])
    assert ros["right_wheel_radius_multiplier"] == pytest.approx(fit.values[0])


def test_95_percent_intervals_cover_about_95_percent_of_simulated_logs():
    # slip correlated over 2 s (the reason for time-block clusters), truth noise; 40 logs of
    # 150 s: coverage of each of 3 parameters, and all 120 together
    hits = []
    for seed in range(40):
        fit = fit_skid_steer(
            skid_intervals(_log(100 + seed, slip=0.02)), NOMINAL, wheel_scales="left-right"
        )
        t = stdtrit(fit.dof, 0.975)  # Student's t quantile
        hits.append(np.abs(fit.values - TRUE_VALUES) <= t * fit.stderr)
    hits = np.array(hits)
    assert np.all(hits.mean(axis=0) >= 0.85)
    assert 0.89 <= hits.mean() <= 0.99  # 200 logs gave 0.945, 0.955, 0.95


def test_a_turn_rate_table_is_recovered():
    table = TurnRateTable((0.2, 0.4, 0.8, 1.6), (2.0, 1.8, 1.7, 1.6))
    true = SkidSteerModel(0.3 * 0.96, 0.3 * 0.96, 0.54, -0.54, turn_rate=table)
    log = _log(2, true=true, slip=0.01, duration_s=300.0)
    iv = skid_intervals(log)
    fit = fit_skid_steer(iv, NOMINAL, "turn-rate", knots_rad_s=table.rate_rad_s)
    _within(fit, [0.96, *table.multiplier])
    rows = fit.turn_rate_rows()
    assert [r.wheel_rate_rad_s for r in rows] == [0.2, 0.4, 0.8, 1.6]
    assert rows[0].true_rate_rad_s == pytest.approx(0.2 / rows[0].multiplier)
    # the constant-track model misses it: its multiplier is a compromise between the table's
    # ends, far from each of them in its own errors
    plain = fit_skid_steer(iv, NOMINAL)
    m, se = plain.value("track_multiplier"), plain.se("track_multiplier")
    lo, hi = min(table.multiplier), max(table.multiplier)
    assert lo + 3 * se < m < hi - 3 * se
    # the default knots are those of the ladder the data support
    assert set(turn_rate_knots(iv, NOMINAL)) >= {0.2, 0.4, 0.8}


def test_the_extended_model_recovers_asymmetric_centres_and_lateral_slip():
    true = SkidSteerModel(0.3 * 0.97, 0.3 * 0.97, 0.80, -0.95, x_icr_m=-0.12)
    fit = fit_skid_steer(skid_intervals(_log(3, true=true, slip=0.01)), NOMINAL, "extended")
    assert fit.names == ("scale", "y_icr_left_m", "y_icr_right_m", "x_icr_m")
    _within(fit, [0.97, 0.80, -0.95, -0.12])
    m, se = fit.track_multiplier()
    assert m == pytest.approx(1.75 / 1.08, abs=4 * se)


def test_the_truth_clock_offset_is_found_and_used():
    log = _log(4, slip=0.01, offset_s=0.2)
    off = truth_clock_offset(log)
    assert off.offset_s == pytest.approx(0.2, abs=max(4 * off.stderr_s, 0.005))
    right = fit_skid_steer(
        skid_intervals(log, offset_s=off.offset_s), NOMINAL, wheel_scales="left-right"
    )
    _within(right, TRUE_VALUES)
    fit, offsets = fit_skid_logs([log], NOMINAL, wheel_scales="left-right", offsets=[off])
    assert fit.offset_variance_added and offsets == (off,)
    assert np.all(fit.stderr >= right.stderr - 1e-12)


def test_truth_jumps_are_rejected_and_do_not_move_the_answer():
    log = _log(5, slip=0.01)
    pose = log.truth_pose.copy()
    rng = np.random.default_rng(0)
    # relocalisations: from 8 instants on, the truth is 1.5 m off (and stays so)
    for k in rng.choice(np.arange(50, len(pose) - 50), size=8, replace=False):
        pose[k:, :2] += 1.5
    from dataclasses import replace

    jumpy = replace(log, truth_pose=pose)
    fit = fit_skid_steer(skid_intervals(jumpy), NOMINAL, wheel_scales="left-right")
    assert fit.rejected >= 8
    _within(fit, TRUE_VALUES)


def test_block_bootstrap_agrees_with_the_jackknife_errors():
    log = _log(6, slip=0.02)
    iv = skid_intervals(log)
    fit = fit_skid_steer(iv, NOMINAL)
    boot = block_bootstrap(iv, fit, replicates=30, rng=np.random.default_rng(1))
    assert np.all((boot / fit.stderr > 0.5) & (boot / fit.stderr < 2.0))


def test_held_out_drift_ranks_the_fitted_model_above_the_nominal():
    logs = [_log(7 + k, slip=0.003, group=f"day {k}", name=f"log {k}") for k in range(2)]
    held = cross_validate(
        logs,
        NOMINAL,
        [("effective-track", "left-right")],
        offsets=[truth_clock_offset(g) for g in logs],
    )
    assert held.held_out == ("day 0", "day 1")
    assert held.labels == ("nominal", "effective-track (left-right)")
    # the fitted model drifts about as much as the true one (by the slip), far less than nominal
    true = np.median([log_drift(g, TRUE).median_pct for g in logs])
    fitted = held.pooled_median_pct("effective-track (left-right)")
    assert held.pooled_median_pct("nominal") > 10.0
    assert fitted < 1.5 * true + 0.5, (fitted, true)
    assert held.best() == "effective-track (left-right)"


def test_concatenation_keeps_the_logs_and_their_blocks_apart():
    a, b = skid_intervals(_log(9)), skid_intervals(_log(10, duration_s=60.0))
    both = SkidIntervals.concatenate([a, b])
    assert len(both) == len(a) + len(b) and both.names == ("sim", "sim")
    assert set(np.unique(both.block[: len(a)])).isdisjoint(np.unique(both.block[len(a) :]))
    assert np.array_equal(both.log, np.r_[np.zeros(len(a)), np.ones(len(b))])


def test_straight_driving_cannot_identify_a_turn_rate_table():
    log = _log(11, max_rate_rad_s=0.0)  # standing still: nothing turns
    iv = skid_intervals(log)
    assert len(iv) == 0
    with pytest.raises(CalibrationError, match="intervals"):
        fit_skid_steer(iv, NOMINAL)
    log = simulate_skid_log(TRUE, np.random.default_rng(12), duration_s=120.0, sim_hz=50.0)
    straight = skid_intervals(log)
    only = straight.subset(np.abs(straight.motion[:, 2]) < 0.02)
    with pytest.raises(CalibrationError, match="two rates"):
        turn_rate_knots(only, NOMINAL)


def test_z_score():
    assert z_score(1.64, 0.03, 1.60, 0.04) == pytest.approx(0.8)


# ------------------------------------------------------------------------------ real data


WARTHOG_LOG = "warthog_wheels_grass_2024_8_8_15h56s39"


@pytest.fixture(scope="module")
def warthog(realdata):
    from odocal.io.norlab_csv import read_norlab_csv

    folder = realdata / "norlab_skid" / WARTHOG_LOG
    if not folder.is_dir():  # the realdata folder is there (the fixture says so): it is broken
        pytest.fail(f"{folder} is missing from the real-data folder")
    return read_norlab_csv(folder / f"{folder.name}.csv").skid_log()


def test_a_real_warthog_log_needs_a_wide_track_and_two_wheel_scales(warthog, realdata):
    # docs/skid-steer.md: ICP turns at about 0.6 of the nominal yaw rate; the right side rolls
    # about 1.6 % further than the left; the ICP poses are stamped about 0.12 s late
    off = truth_clock_offset(warthog)
    assert 0.05 < off.offset_s < 0.2 and off.applied
    iv = skid_intervals(warthog, offset_s=off.offset_s)
    fit = fit_skid_steer(iv, NOMINAL, wheel_scales="left-right")
    # the turning gains (each side's radius over the effective track) are those of a plain
    # regression of the ICP heading on the wheels (tests/support/skid_plain.py) within 2 %
    from tests.support.skid_plain import plain_turning_gains

    plain = plain_turning_gains([realdata / "norlab_skid" / WARTHOG_LOG / f"{WARTHOG_LOG}.csv"])
    model = fit.model
    gains = (model.radius_right_m / model.track_m, model.radius_left_m / model.track_m)
    assert gains == pytest.approx(plain, rel=0.02)
    m, se = fit.track_multiplier()
    assert 0 < se < 0.03 * m
    assert z_score(fit.value("scale_right"), fit.se("scale_right"),
                   fit.value("scale_left"), fit.se("scale_left")) > 3  # fmt: skip
    nominal = log_drift(warthog, SkidSteerModel.from_geometry(NOMINAL), offset_s=off.offset_s)
    fitted = log_drift(warthog, fit.model, offset_s=off.offset_s)
    assert nominal.median_pct > 20.0 and fitted.median_pct < 3.0 and fitted.pieces >= 10


def test_a_wandering_truth_latency_is_followed_window_by_window():
    # the truth's latency is 0.1 s for the first minute and 0.4 s after (a mapper that fell
    # behind): windows of 40 s see it; one offset for the log sees one of the two
    def late(t):
        return np.where(t < 60.0, 0.1, 0.4)

    log = _log(13, slip=0.005, duration_s=120.0, offset_s=late)
    w = windowed_truth_offset(log, window_s=40.0, step_s=40.0)
    assert np.array_equal(w.centre_s, [20.0, 60.0, 100.0])
    assert w.at([0.0, 20.0])[1] == pytest.approx(0.1, abs=0.03)
    assert w.at([100.0, 200.0]) == pytest.approx([0.4, 0.4], abs=0.03)
    assert w.spread_s > 0.25 and w.typical_stderr_s < 0.03
    assert offset_at(w, log).shape == log.truth_time_s.shape
    assert offset_at(w.overall, log) == w.overall.offset_s
    fit, _ = fit_skid_logs([log], NOMINAL, wheel_scales="left-right", offsets=[w])
    _within(fit, TRUE_VALUES)
