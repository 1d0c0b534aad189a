"""What to add to a log (calibration.topup) and the named degenerate motions
(calibration.identifiability.DEGENERATE_MOTIONS): each degenerate motion recorded alone is
flagged by name, the log information is additive over runs, the top-up uses the robot's own
speeds, and the recommended top-up, simulated with noise, added to the simulated log and fitted
by the trajectory fit, shows the spread the check predicts."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from odocal.calibration.identifiability import (
    DEGENERATE_MOTIONS,
    NoiseModel,
    check_recordings,
    degenerate_motions,
    judge,
    log_information,
)
from odocal.calibration.topup import find_top_up, observed_rates
from odocal.calibration.trajectory import fit_trajectory_trials
from odocal.core import tracks as T
from odocal.core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.core.simulate import commanded_wheel_angles, drive
from odocal.core.topup_motion import Maneuver, maneuver_recording, maneuver_track
from odocal.errors import CalibrationError, ModelError

NOMINAL = WheelGeometry(0.084, 0.084, 0.200)
TRUE = WheelGeometry(0.0838, 0.0839, 0.2015)
WHEEL = NonSystematicError(1e-6, 1e-6)
TRACKER = MeasurementNoise(1e-3, math.radians(0.2))
NOISE = NoiseModel(WHEEL, TRACKER)


def recorded(track: T.Track, dt: float = 0.02, name: str = "run") -> tuple[Recording, int]:
    """The noise-free recording of driving ``track`` (commanded wheel angles in 1 cm steps, one
    sample every ``dt`` s) and its increments per segment (for ``drive``)."""
    n, ang = commanded_wheel_angles(track, NOMINAL, 0.01)
    rec = Recording(
        name=name,
        time_s=dt * np.arange(len(ang)),
        wheel_angle_right_rad=ang[:, 0],
        wheel_angle_left_rad=ang[:, 1],
        ground_truth=dead_reckon(ang[:, 0], ang[:, 1], NOMINAL),
        ran_with=NOMINAL,
    )
    return rec, n


def still(samples: int = 50) -> Recording:
    zero = np.zeros(samples)
    return Recording("still", 0.02 * np.arange(samples), zero, zero, np.zeros((samples, 3)))


def spins(*angles: float) -> T.Track:
    return T.Track("spins", tuple(T.spot_turn(a) for a in angles))


# --------------------------------------------------------------------------------------------
# The five degenerate motions, each recorded alone


ALONE = {
    "no-motion": lambda: [still()],
    "pure-translation": lambda: [recorded(T.straight_line(3.0), name=f"s{i}")[0] for i in range(3)],
    "pure-rotation": lambda: [recorded(spins(2 * math.pi, -2 * math.pi))[0]],
    "constant-velocity": lambda: [recorded(T.circle(0.5, "ccw", turns=2.0))[0]],
    "one-axis-rotation": lambda: [
        recorded(T.polygon(4, 1.0, "ccw"), name=f"sq{i}")[0] for i in range(2)
    ],
}


@pytest.mark.parametrize("code", list(ALONE))
def test_each_degenerate_motion_recorded_alone_is_flagged_by_name(code):
    chk = check_recordings(ALONE[code](), NOMINAL, noise=NOISE)
    named = {m["code"]: m for m in degenerate_motions(chk)}
    assert code in named
    name, flag, _ = DEGENERATE_MOTIONS[code]
    assert named[code]["name"] == name and chk.flagged(flag)
    assert code in {m["code"] for m in chk.as_dict()["degenerate_motions"]}
    # the motions that make the information singular are the blind ones; one sense of
    # rotation only is a weak finding (the model still sees everything)
    severity = {d.code: d.severity for d in chk.degeneracies}[flag]
    assert severity == ("weak" if code == "one-axis-rotation" else "blind")


def test_a_rich_log_shows_none_of_the_degenerate_motions():
    rich = [
        recorded(T.polygon(4, 1.0, "cw"))[0],
        recorded(T.polygon(4, 1.0, "ccw"))[0],
        recorded(T.circle(0.5, "ccw"))[0],
        recorded(T.circle(0.5, "cw"))[0],
    ]
    chk = check_recordings(rich, NOMINAL, noise=NOISE)
    assert chk.ok and degenerate_motions(chk) == []


# --------------------------------------------------------------------------------------------
# Information is additive over runs


def test_the_information_of_a_log_is_the_sum_over_its_runs_and_judges_as_the_check():
    a = [recorded(T.straight_line(3.0))[0]]
    b = [recorded(spins(math.pi, -math.pi))[0], recorded(T.circle(0.5, "cw"))[0]]
    whole = log_information(a + b, NOMINAL, noise=NOISE)
    parts = log_information(a, NOMINAL, noise=NOISE) + log_information(b, NOMINAL, noise=NOISE)
    for x, y in ((whole.fisher, parts.fisher), (whole.hessian, parts.hessian)):
        np.testing.assert_allclose(x, y, rtol=1e-10)
    np.testing.assert_allclose(whole.meat, parts.meat, rtol=1e-10)
    twice = log_information(b + b, NOMINAL, noise=NOISE)
    np.testing.assert_allclose(
        twice.fisher, log_information(b, NOMINAL, noise=NOISE).times(2).fisher, rtol=1e-10
    )
    with pytest.raises(CalibrationError, match="different parameters or settings"):
        _ = whole + log_information(a, NOMINAL, noise=NOISE, residual="segment")
    direct = check_recordings(a + b, NOMINAL, noise=NOISE)
    judged = judge(parts, a + b)
    for k in direct.stderr:
        assert judged.stderr[k] == pytest.approx(direct.stderr[k], rel=1e-9)
    assert judged.condition_number == pytest.approx(direct.condition_number, rel=1e-9)


# --------------------------------------------------------------------------------------------
# The top-up


def test_the_top_up_uses_the_speeds_the_robot_drove():
    # straight at 0.1 m/s (1 cm steps every 0.1 s), spins at 0.2 rad/s
    line, _ = recorded(T.straight_line(2.0), dt=0.1)
    w = 0.01 / (0.5 * NOMINAL.wheelbase_m)  # rad per 1 cm wheel step
    turn, _ = recorded(spins(math.pi), dt=w / 0.2)
    rates = observed_rates([line, turn], NOMINAL)
    assert rates.speed_m_s == pytest.approx(0.1, rel=0.02)
    assert rates.rate_rad_s == pytest.approx(0.2, rel=0.02)
    # a straight log that never turned: spins with the wheels at the speed they drove
    only = observed_rates([line], NOMINAL)
    assert only.rate_rad_s == pytest.approx(2 * 0.1 / NOMINAL.wheelbase_m, rel=0.02)
    assert "no spot turns seen" in only.source
    # a log of arcs only: spins at the turn rate the arcs showed (0.3 rad/s)
    circle, n = recorded(T.circle(0.5, "ccw"), dt=1.0)
    circle = replace(circle, time_s=circle.time_s * (2 * math.pi / n) / 0.3)
    arcs = observed_rates([line, circle], NOMINAL)
    assert arcs.rate_rad_s == pytest.approx(0.3, rel=0.02) and "seen on arcs" in arcs.source
    info = log_information([line, line], NOMINAL, noise=NOISE)
    top = find_top_up(info, judge(info, [line, line]), [line, line])
    for m in top.maneuvers:
        assert abs(m.rate_rad_s) <= only.rate_rad_s * (1 + 1e-9)
        assert abs(m.speed_m_s) <= only.speed_m_s * (1 + 1e-9)


def test_the_top_up_is_the_shortest_candidate_that_makes_the_log_enough():
    log = [recorded(T.straight_line(3.0), name=f"s{i}")[0] for i in range(3)]
    info = log_information(log, NOMINAL, noise=NOISE)
    chk = judge(info, log)
    top = find_top_up(info, chk, log)
    assert not chk.ok and top.goal == "enough" and top.reached and top.ok_after
    assert top.flags_after == ()
    assert math.isinf(top.before["wheelbase_m"])
    assert top.after["wheelbase_m"] / NOMINAL.wheelbase_m <= 5e-3
    # every candidate of a shorter total leaves something flagged
    shorter = find_top_up(
        info, chk, log, run_durations_s=[t for t in (5, 10, 15) if t < top.duration_s], repeats=(1,)
    )
    assert not shorter.reached and shorter.flags_after
    d = top.as_dict()
    assert d["duration_s"] == top.duration_s and d["maneuvers"]
    assert set(d["predicted_std_error"]) == {"before", "after"}
    assert "makes the log enough" in top.sentence()


def test_a_log_that_is_enough_gets_the_top_up_that_halves_its_weakest_parameter():
    rich = [
        recorded(T.polygon(4, 1.0, "cw"))[0],
        recorded(T.polygon(4, 1.0, "ccw"))[0],
    ]
    info = log_information(rich, NOMINAL, noise=NOISE)
    chk = judge(info, rich)
    top = find_top_up(info, chk, rich)
    assert top.goal == "halve" and top.weakest == "wheelbase_m"
    assert top.reached
    assert top.after["wheelbase_m"] <= 0.5 * top.before["wheelbase_m"]
    assert "halves the wheelbase b's standard error" in top.sentence()


def test_a_log_that_is_enough_but_flagged_is_not_told_the_top_up_makes_it_enough():
    """check printed "enough" and then "adding ... makes the log enough" for a log with a weak
    finding only (turning one way): the sentence says what the addition does to such a log."""
    one_way = [recorded(T.polygon(4, 1.0, "ccw"))[0]]
    info = log_information(one_way, NOMINAL, noise=NOISE)
    chk = judge(info, one_way)
    assert chk.ok and chk.degeneracies  # enough, with something flagged
    top = find_top_up(info, chk, one_way)
    assert top.goal == "enough" and top.log_ok
    assert "makes the log enough" not in top.sentence()
    assert "enough already" in top.sentence()


def _measured(gt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """True poses (runs, K, 3) seen by the tracker (white noise) and re-expressed in each run's
    measured start frame."""
    sd = [TRACKER.sigma_xy_m, TRACKER.sigma_xy_m, TRACKER.sigma_theta_rad]
    gt = gt + rng.standard_normal(gt.shape) * sd
    c, s = np.cos(gt[:, :1, 2]), np.sin(gt[:, :1, 2])
    d = gt[:, :, :2] - gt[:, :1, :2]
    return np.stack(
        [c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], gt[..., 2] - gt[:, :1, 2]],
        axis=-1,
    )


LOGS = {
    "straight lines": (T.straight_line(3.0), 3),
    "spins one way": (spins(4 * math.pi), 2),
}


@pytest.mark.parametrize("which", list(LOGS))
def test_the_recommended_top_up_simulated_and_added_shows_the_predicted_spread(which):
    """300 seeded replicates of the whole log plus the recommended top-up, driven open loop
    with wheel noise by odocal's simulator, seen by a noisy tracker, fitted together by the
    trajectory fit (its vectorised form, fit_trajectory_trials): the standard deviation of the
    fits is the predicted standard error after the top-up within 20 % (the sample standard
    deviation of 300 values is itself uncertain by about 4 %)."""
    track, runs = LOGS[which]
    rec, n = recorded(track)
    log = [rec] * runs
    info = log_information(log, NOMINAL, noise=NOISE)
    chk = judge(info, log)
    top = find_top_up(info, chk, log)
    assert not chk.ok and top.reached and top.ok_after
    top_track = maneuver_track(top.maneuvers)
    top_rec, top_n = maneuver_recording(top.maneuvers, NOMINAL)
    m = 300
    rng = np.random.default_rng(20261129)
    g_log = drive(track, TRUE, NOMINAL, WHEEL, m * runs, rng, steps_per_segment=n, trajectory=True)
    g_top = drive(
        top_track, TRUE, NOMINAL, WHEEL, m * top.runs, rng, steps_per_segment=top_n,
        trajectory=True,
    )  # fmt: skip
    assert g_log.trajectory is not None and g_top.trajectory is not None
    truth = [
        _measured(g_log.trajectory, rng).reshape(m, runs, -1, 3),
        _measured(g_top.trajectory, rng).reshape(m, top.runs, -1, 3),
    ]
    angles = [
        np.column_stack([rec.wheel_angle_right_rad, rec.wheel_angle_left_rad]),
        np.column_stack([top_rec.wheel_angle_right_rad, top_rec.wheel_angle_left_rad]),
    ]
    fits = fit_trajectory_trials(angles, truth, NOMINAL)
    assert np.all(np.isfinite(fits))
    realised = fits.std(axis=0, ddof=1)
    predicted = np.array([top.after[k] for k in top.after])
    np.testing.assert_allclose(realised / predicted, 1.0, atol=0.2)
    # and the fits are centred on the truth (within 4 of their standard errors of the mean)
    true = [TRUE.diameter_right_m, TRUE.diameter_left_m, TRUE.wheelbase_m]
    assert np.all(np.abs(fits.mean(axis=0) - true) < 4 * realised / math.sqrt(m) + 1e-7)


def test_maneuvers_refuse_what_cannot_be_driven():
    with pytest.raises(ModelError):
        Maneuver("hop", 1.0, speed_m_s=0.1)
    with pytest.raises(ModelError):
        Maneuver("spin", 0.0, rate_rad_s=0.5)
    with pytest.raises(ModelError):
        Maneuver("spin", 10.0)
    with pytest.raises(ModelError):
        Maneuver("arc", 10.0, speed_m_s=-0.1, rate_rad_s=0.2)
    arc = Maneuver("arc", 10.0, speed_m_s=0.2, rate_rad_s=-0.4)
    assert arc.radius_m == pytest.approx(0.5) and arc.as_dict()["direction"] == "cw"
    rec, _ = maneuver_recording([arc], NOMINAL)
    assert rec.time_s[-1] == pytest.approx(10.0)
    assert rec.ground_truth is not None
    assert rec.ground_truth[-1, 2] == pytest.approx(-4.0, rel=1e-9)
