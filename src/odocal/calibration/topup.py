"""What to add to a log: the shortest top-up that makes it enough (docs/check.md, "What to add").

The information of a log is additive over its runs (their residuals are independent under the
stated noise: every run has its own start frame), so the information of the log plus a top-up
run is the sum of the log's and the top-up's (:class:`~.identifiability.LogInformation`). A
top-up candidate is a synthetic run of simple maneuvers (:mod:`odocal.core.topup_motion`) at the
speeds and turn rates the robot itself drove in the log; its information is computed by the
check's own machinery (same residuals, noise model and fit settings), added to the log's, and
the sum judged exactly as ``check`` judges a log (:func:`~.identifiability.judge`). The
recommendation is the shortest candidate that makes the log enough (no blind direction, no
imprecise parameter), or, for a log that is already enough, the shortest that halves the
weakest parameter's predicted standard error (relative to its value).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.jsonable import jsonable
from ..core.model import WheelGeometry
from ..core.odometry import body_increments, wheel_travel
from ..core.recording import Recording
from ..core.topup_motion import Maneuver, maneuver_recording
from ..errors import CalibrationError
from .identifiability import (
    GEOMETRY_PARAMETERS,
    CheckThresholds,
    LogCheck,
    LogInformation,
    judge,
    log_information,
)

__all__ = [
    "RobotRates",
    "TopUp",
    "observed_rates",
    "candidate_kinds",
    "find_top_up",
    "RUN_DURATIONS_S",
    "REPEATS",
    "MAX_TOTAL_S",
]

#: Durations of one top-up run tried (s).
RUN_DURATIONS_S = (5, 10, 15, 20, 30, 40, 60, 90, 120, 180, 300, 600)

#: Numbers of repeats (separate runs) of one top-up run tried.
REPEATS = (1, 2, 3, 4, 6, 8, 10, 15, 20, 30)

#: The longest top-up tried, all runs together (s).
MAX_TOTAL_S = 1800.0

#: A spin rate never seen in the log is at most this (rad/s): a gentle spin.
UNSEEN_SPIN_CAP_RAD_S = 1.0

#: Arc radius of a figure-eight, in wheelbases (inside the check's 2.5-10 b advice).
ARC_RADIUS_B = 5.0

_WORDS = {
    "wheel_diameter_right_m": "D_R",
    "wheel_diameter_left_m": "D_L",
    "wheelbase_m": "the wheelbase b",
}


@dataclass(frozen=True)
class RobotRates:
    """The speeds the top-up uses, from what the robot drove in the log: ``speed_m_s`` (axle
    centre on straights), ``rate_rad_s`` (spins), ``wheel_speed_m_s`` (the wheels' speed) and
    where they came from (``source``, words)."""

    speed_m_s: float
    rate_rad_s: float
    wheel_speed_m_s: float
    source: str

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {k: jsonable(v) for k, v in self.__dict__.items()}


def observed_rates(
    recordings: Sequence[Recording], geometry: WheelGeometry, window_s: float = 0.5
) -> RobotRates:
    """The 90th percentiles of the speeds the log shows over windows of ``window_s``: the
    wheels' speed, the axle centre's on straight windows (turning radius >= 12.5 b) and the turn
    rate on turning windows (radius <= b). What is not seen is derived from what is: a straight
    at the wheels' speed; a spin at the turn rate seen on arcs (at most the wheels' speed), else
    with the wheels at their speed but at most :data:`UNSEEN_SPIN_CAP_RAD_S`."""
    b = float(geometry.wheelbase_m)
    wheel, straight, turn, arcs = [], [], [], []
    for rec in recordings:
        t = np.asarray(rec.time_s, dtype=float)
        if len(t) < 2 or not t[-1] > t[0]:
            continue
        grid = np.arange(t[0], t[-1] + 1e-12, window_s)
        if len(grid) < 2:
            grid = np.array([t[0], t[-1]])
        ar = np.interp(grid, t, rec.wheel_angle_right_rad)
        al = np.interp(grid, t, rec.wheel_angle_left_rad)
        dr, dl = wheel_travel(np.diff(ar), np.diff(al), geometry)
        ds, dth = body_increments(dr, dl, b)
        dt = np.diff(grid)
        moving = np.maximum(np.abs(dr), np.abs(dl)) > 1e-4 * dt  # faster than 0.1 mm/s
        wheel.append((np.maximum(np.abs(dr), np.abs(dl)) / dt)[moving])
        is_straight = moving & (np.abs(ds) >= 12.5 * b * np.abs(dth))
        is_turn = moving & (np.abs(ds) <= b * np.abs(dth))
        straight.append((np.abs(ds) / dt)[is_straight])
        turn.append((np.abs(dth) / dt)[is_turn])
        arcs.append((np.abs(dth) / dt)[moving & ~is_straight & ~is_turn])
    w, s, r, a = (np.concatenate(x) if x else np.zeros(0) for x in (wheel, straight, turn, arcs))
    if w.size == 0:
        raise CalibrationError("check: no motion in the log to take speeds from")
    v_wheel = float(np.percentile(w, 90))
    notes = []
    if s.size >= 3:
        v = float(np.percentile(s, 90))
        notes.append(f"straight speed {v:.2g} m/s seen")
    else:
        v = v_wheel
        notes.append(f"no straight driving seen: straights at the wheels' {v:.2g} m/s")
    if r.size >= 3:
        omega = float(np.percentile(r, 90))
        notes.append(f"turn rate {omega:.2g} rad/s seen")
    elif a.size >= 3:
        omega = min(2.0 * v_wheel / b, float(np.percentile(a, 90)))
        notes.append(f"no spot turns seen: spins at the turn rate seen on arcs ({omega:.2g} rad/s)")
    else:
        omega = min(2.0 * v_wheel / b, UNSEEN_SPIN_CAP_RAD_S)
        notes.append(
            f"no spot turns seen: spins with the wheels at {v_wheel:.2g} m/s, at most "
            f"{UNSEEN_SPIN_CAP_RAD_S:g} rad/s ({omega:.2g} rad/s)"
        )
    return RobotRates(v, omega, v_wheel, "; ".join(notes) + " (90th percentiles over 0.5 s)")


# A kind of top-up: name and maneuvers of a given total duration at the robot's rates.
_Kind = tuple[str, Callable[[float], list[Maneuver]]]


def candidate_kinds(rates: RobotRates, geometry: WheelGeometry) -> list[_Kind]:
    """The kinds of top-up tried, each a function of the total duration (s): a spin each way,
    a straight out and back, a figure-eight of two circles of radius 5 b (CCW, then CW), and a
    straight out and back followed by a spin each way (half the time each)."""
    v, w = rates.speed_m_s, rates.rate_rad_s
    b = float(geometry.wheelbase_m)
    radius = ARC_RADIUS_B * b
    # the arc's outer wheel at most at the wheels' speed, the turn rate at most the spin's
    v_arc = min(v, rates.wheel_speed_m_s / (1.0 + 0.5 * b / radius), w * radius)

    def spin(t: float) -> list[Maneuver]:
        return [Maneuver("spin", t / 2, rate_rad_s=w), Maneuver("spin", t / 2, rate_rad_s=-w)]

    def straight(t: float) -> list[Maneuver]:
        return [Maneuver("straight", t / 2, speed_m_s=v), Maneuver("straight", t / 2, speed_m_s=-v)]

    def eight(t: float) -> list[Maneuver]:
        return [
            Maneuver("arc", t / 2, speed_m_s=v_arc, rate_rad_s=v_arc / radius),
            Maneuver("arc", t / 2, speed_m_s=v_arc, rate_rad_s=-v_arc / radius),
        ]

    def both(t: float) -> list[Maneuver]:
        return straight(t / 2) + spin(t / 2)

    return [
        ("spin", spin),
        ("straight", straight),
        ("figure-eight", eight),
        ("straight+spin", both),
    ]


def describe(kind: str, maneuvers: Sequence[Maneuver]) -> str:
    """The top-up in words (durations, speeds, rates, distances)."""
    t = sum(m.duration_s for m in maneuvers)

    def spin_words(ms: Sequence[Maneuver]) -> str:
        half = ms[0].duration_s
        deg = math.degrees(abs(ms[0].angle_rad))
        return (
            f"a {2 * half:.3g} s spin at {abs(ms[0].rate_rad_s):.2g} rad/s each way "
            f"({half:.3g} s CCW then {half:.3g} s CW, {deg:.0f} deg each)"
        )

    def straight_words(ms: Sequence[Maneuver]) -> str:
        half = ms[0].duration_s
        return (
            f"a {2 * half:.3g} s straight at {abs(ms[0].speed_m_s):.2g} m/s out and back "
            f"({ms[0].distance_m:.2g} m forward, then backward)"
        )

    if kind == "spin":
        return spin_words(maneuvers)
    if kind == "straight":
        return straight_words(maneuvers)
    if kind == "figure-eight":
        m = maneuvers[0]
        turns = abs(m.angle_rad) / (2 * math.pi)
        return (
            f"a {t:.3g} s figure-eight at {m.speed_m_s:.2g} m/s on circles of "
            f"{m.radius_m:.2g} m radius ({turns:.2g} turns CCW, then CW)"
        )
    return f"{straight_words(maneuvers[:2])}, then {spin_words(maneuvers[2:])}"


@dataclass(frozen=True)
class TopUp:
    """The recommended addition to a log.

    goal : 'enough' (the log is not enough, or a parameter is imprecise) or 'halve' (it is
    enough: halve the weakest parameter's standard error). reached : whether a candidate of at
    most the longest duration tried reaches the goal (else the best one tried is shown).
    kind, maneuvers : one top-up run (the maneuvers in order); runs : how many times to drive it
    (separate runs); duration_s : all runs together. before, after :
    predicted standard errors (m) without and with it. ok_after : the check of log + top-up is
    enough. flags_after : its degeneracy codes. weakest : the parameter the goal is about
    (halve). rates : the speeds used. tried : candidates evaluated.
    """

    goal: str
    reached: bool
    kind: str
    maneuvers: tuple[Maneuver, ...]
    runs: int
    duration_s: float
    before: dict
    after: dict
    ok_after: bool
    flags_after: tuple[str, ...]
    weakest: str | None
    rates: RobotRates
    tried: int
    log_ok: bool = False  # the log alone is enough (no blind direction): 'enough' then clears
    # the check's other findings (weak motion, an imprecise parameter)

    @property
    def description(self) -> str:
        """The maneuvers in words (and how many runs of them)."""
        one = describe(self.kind, self.maneuvers)
        if self.runs == 1:
            return one
        return f"{self.runs} runs (each from a still, tracked start) of {one}"

    def sentence(self) -> str:
        """One sentence: what to drive and what it does to the standard errors."""

        def fmt(k: str, d: dict) -> str:
            v = d[k]
            return "not identifiable" if not math.isfinite(v) else f"{v:.2g} m"

        if self.goal == "halve" and self.weakest is not None:
            k = self.weakest
            change = f"{fmt(k, self.before)} -> {fmt(k, self.after)}"
            if self.reached:
                return f"{self.description} halves {_WORDS[k]}'s standard error: {change}"
            return (
                f"no top-up of up to {MAX_TOTAL_S:g} s tried halves {_WORDS[k]}'s standard "
                f"error; the best tried, {self.description}, brings it {change}"
            )
        does = "clears the check's other findings" if self.log_ok else "makes the log enough"
        head = (
            f"adding {self.description} {does}"
            if self.reached
            else f"no top-up of up to {MAX_TOTAL_S:g} s tried {does}; the best "
            f"tried is {self.description}"
        )
        if self.log_ok:
            head += " (the log is enough already)"
        parts = ", ".join(
            f"{_WORDS[k]} {fmt(k, self.before)} -> {fmt(k, self.after)}"
            for k in GEOMETRY_PARAMETERS
        )
        return f"{head}: predicted standard error {parts}"

    def as_dict(self) -> dict:
        """The JSON ``top_up`` of ``odocal check --json``."""
        return {
            "goal": self.goal,
            "reached": self.reached,
            "kind": self.kind,
            "description": self.description,
            "sentence": self.sentence(),
            "maneuvers": [m.as_dict() for m in self.maneuvers],
            "runs": self.runs,
            "duration_s": float(self.duration_s),
            "predicted_std_error": {
                "before": {k: jsonable(v) for k, v in self.before.items()},
                "after": {k: jsonable(v) for k, v in self.after.items()},
            },
            "weakest_parameter": self.weakest,
            "ok_after": self.ok_after,
            "degeneracies_after": list(self.flags_after),
            "rates": self.rates.as_dict(),
            "candidates_tried": self.tried,
        }


def _relative_se(stderr: dict, values: np.ndarray) -> dict:
    return {k: stderr[k] / float(v) for k, v in zip(GEOMETRY_PARAMETERS, values[:3], strict=True)}


def _enough(check: LogCheck) -> bool:
    """Nothing flagged: no blind direction, no imprecise parameter, no weak motion."""
    return not check.degeneracies


@dataclass(frozen=True)
class _Candidate:
    total_s: float
    runs: int
    kind: str
    maneuvers: list[Maneuver]
    recording: Recording
    extra: LogInformation


def find_top_up(
    info: LogInformation,
    check: LogCheck,
    recordings: Sequence[Recording],
    thresholds: CheckThresholds | None = None,
    *,
    run_durations_s: Sequence[float] = RUN_DURATIONS_S,
    repeats: Sequence[int] = REPEATS,
    max_total_s: float = MAX_TOTAL_S,
    rates: RobotRates | None = None,
    max_step_m: float = 0.01,
) -> TopUp:
    """The shortest top-up (module docstring) for the log ``recordings`` whose information is
    ``info`` and whose check is ``check`` (computed from ``info``; the stated noise).

    Candidates are ``runs`` repeats (separate runs, each from its own tracked start) of one run
    of a kind (:func:`candidate_kinds`) lasting one of ``run_durations_s``, at most
    ``max_total_s`` in all; they are tried shortest total first (then fewer runs), and the first
    that reaches the goal is the answer."""
    geometry = info.geometry
    rates = rates or observed_rates(recordings, geometry)
    goal = "halve" if _enough(check) else "enough"
    rel0 = _relative_se(check.stderr, check.values)
    weakest = max(rel0, key=lambda k: rel0[k]) if goal == "halve" else None
    th = thresholds or CheckThresholds()
    settings = info.settings
    cache: dict[tuple[str, float], tuple[list[Maneuver], Recording, LogInformation]] = {}

    def run_of(
        kind: str, make: Callable[[float], list[Maneuver]], t: float
    ) -> tuple[list[Maneuver], Recording, LogInformation]:
        if (kind, t) not in cache:
            maneuvers = make(t)
            rec, _ = maneuver_recording(maneuvers, geometry, max_step_m=max_step_m, name=kind)
            extra = log_information(
                [rec],
                geometry,
                noise=info.noise,
                residual=settings.residual,
                segment_m=settings.segment_m,
                heading_weight_m=settings.heading_weight_m,
                samples_per_run=settings.samples_per_run,
                run_weight=settings.run_weight,
                mounting=settings.mounting,
            )
            cache[(kind, t)] = (maneuvers, rec, extra)
        return cache[(kind, t)]

    plan = sorted(
        (float(t) * r, r, i, float(t))
        for i in range(len(candidate_kinds(rates, geometry)))
        for t in run_durations_s
        for r in repeats
        if float(t) * r <= max_total_s + 1e-9
    )
    kinds = candidate_kinds(rates, geometry)
    best: tuple[float, _Candidate, dict] | None = None
    chosen: tuple[_Candidate, LogCheck] | None = None
    tried = 0
    for total, r, i, t in plan:
        kind, make = kinds[i]
        maneuvers, rec, extra = run_of(kind, make, t)
        summed = info + extra.times(r)
        se = summed.stderr()
        rel = _relative_se(se, info.values)
        score = rel[weakest] if weakest is not None else max(rel.values())
        score = score if math.isfinite(score) else math.inf
        tried += 1
        cand = _Candidate(total, r, kind, maneuvers, rec, extra)
        if best is None or score < best[0]:
            best = (score, cand, se)
        reaches = (
            score <= 0.5 * rel0[weakest] if weakest is not None else score <= th.max_relative_stderr
        )
        if not reaches:
            continue
        after = judge(summed, [*recordings, *[rec] * r], thresholds)
        if _enough(after) or (goal == "halve" and after.ok):
            chosen = (cand, after)
            break
    if chosen is None:
        assert best is not None
        cand = best[1]
        after = judge(
            info + cand.extra.times(cand.runs),
            [*recordings, *[cand.recording] * cand.runs],
            thresholds,
        )
    else:
        cand, after = chosen
    return TopUp(
        goal=goal,
        reached=chosen is not None,
        kind=cand.kind,
        maneuvers=tuple(cand.maneuvers),
        runs=cand.runs,
        duration_s=cand.total_s,
        before={k: check.stderr[k] for k in GEOMETRY_PARAMETERS},
        after={k: after.stderr[k] for k in GEOMETRY_PARAMETERS},
        ok_after=after.ok,
        flags_after=tuple(d.code for d in after.degeneracies),
        weakest=weakest,
        rates=rates,
        tried=tried,
        log_ok=check.ok,
    )
