"""Skid-steer models identified from wheel increments against truth increments, with honest errors.

The data are a log of cumulative wheel angles (the wheels' clock) and a truth track at its own
rate and on its own clock (lidar ICP poses, motion capture, ...): a :class:`SkidLog`.

**Intervals.** The truth is cut into consecutive intervals of about ``interval_s`` (1 s) between
its own samples (:func:`skid_intervals`); an interval is left out when the truth has a hole in it
(a gap between samples longer than ``max_gap_s``) or the wheels barely turned in it (it says
nothing about the parameters). Each interval's measured motion is the truth's relative pose
(dx, dy, dtheta in the frame of its start). The wheels are read over the same interval moved onto
their clock by the truth's clock offset (the truth stamped t saw the robot at wheel time
t - offset; :func:`truth_clock_offset`, the temporal registration of
:mod:`odocal.calibration.time_offset`), cut into ``substep_s`` sub-steps, and dead-reckoned with
the model (:mod:`odocal.core.skid_steer`) to predict the motion.

**Models** (:data:`SKID_MODELS`; ``wheel_scales`` 'common' fits one factor on both nominal
radii, 'left-right' one per side, as diff_drive_controller's two radius multipliers):

- ``effective-track``: the wheel scale(s) and the track multiplier m (effective track = m b_n,
  ros2 diff_drive_controller's ``wheel_separation_multiplier``);
- ``turn-rate``: the wheel scale(s) and the track multiplier at knots of the wheel yaw rate
  (:class:`~odocal.core.skid_steer.TurnRateTable`; knots the data support, :func:`turn_rate_knots`);
- ``extended``: the wheel scale(s) and the centres of rotation y_ICR_l, y_ICR_r of the two sides
  and x_ICR of the body (Martinez et al. 2005, Mandow et al. 2007; lateral slip v_y = -x_ICR
  omega).

**Fit.** Residuals are the measured minus the predicted motion, each component divided by its
robust spread (1.4826 MAD at a first least-squares fit, so that metres and radians weigh by their
noise); the fit minimises the soft-L1 loss of those (quadratic within one spread, linear
beyond), then drops intervals with a component beyond ``reject_z`` spreads (ICP jumps,
relocalisations: counted in the result) and fits again.

**Standard errors** are cluster-robust over contiguous time blocks of ``block_s`` seconds of each
log: by default the delete-one-block jackknife of the M-estimate
(:func:`odocal.calibration.robust_covariance.cluster_jackknife_covariance`; ``covariance=
"sandwich"`` for :func:`~odocal.calibration.robust_covariance.cluster_covariance`). 1 s
intervals share truth samples, the ground and the truth's own errors change slowly, so
neighbouring intervals are not independent and the formal errors would be several times too
small. Their degrees of freedom are the blocks minus one. On simulated logs with slip correlated
over 2 s the 95 % intervals (Student t) covered 94.5-95.5 % (200 logs; the tests run 40).
:func:`block_bootstrap` refits on resampled blocks as a check. The clock offset's own
uncertainty is added by :func:`fit_skid_logs` (two refits per log at offset +- its standard
error). A truth whose latency wanders over the log (the Norlab ICP: by 0.1-0.4 s) can be given
one offset per window (:func:`windowed_truth_offset`, :class:`WindowedOffset`).

**Choosing a model** is by held-out drift (:func:`cross_validate`): fitted on some logs (days),
each other log is dead-reckoned whole with it and scored by the KITTI-style drift of
:mod:`odocal.core.path_drift`; not by the in-sample fit, which always favours more parameters.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.path_drift import DriftMode, PathDrift, path_drift
from ..core.recording import Recording, with_truth_at
from ..core.skid_steer import (
    SkidSteerModel,
    TurnRateTable,
    body_motion_end,
    dead_reckon_skid,
    skid_body_increments,
)
from ..core.transforms import se2_relative
from ..errors import CalibrationError, ModelError
from .robust_covariance import cluster_covariance, cluster_jackknife_covariance
from .time_offset import TimeOffset, estimate_time_offset

__all__ = [
    "SkidModelKind",
    "SKID_MODELS",
    "WheelScales",
    "SkidLog",
    "SkidIntervals",
    "SkidSteerFit",
    "TurnRateRow",
    "SkidHeldOut",
    "Candidate",
    "CANDIDATES",
    "candidate_label",
    "DEFAULT_RATE_LADDER",
    "truth_clock_offset",
    "WindowedOffset",
    "windowed_truth_offset",
    "Offset",
    "offset_at",
    "skid_recording",
    "skid_intervals",
    "turn_rate_knots",
    "fit_skid_steer",
    "fit_skid_logs",
    "predict_motion",
    "block_bootstrap",
    "z_score",
    "log_drift",
    "cross_validate",
]

SkidModelKind = Literal["effective-track", "turn-rate", "extended"]
SKID_MODELS: tuple[SkidModelKind, ...] = ("effective-track", "turn-rate", "extended")
WheelScales = Literal["common", "left-right"]

#: Candidate knots of the turn-rate table (|wheel yaw rate|, rad/s); :func:`turn_rate_knots`
#: keeps those the data support.
DEFAULT_RATE_LADDER: tuple[float, ...] = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2)
#: Rotation (rad) the sub-steps around a knot must add up to for it to be kept: one full turn.
MIN_KNOT_ROTATION_RAD = 2 * math.pi
#: Intervals whose wheels turned less than this (rad, both wheels' |rotation| summed) are
#: left out.
MIN_WHEEL_ROTATION_RAD = 0.05
#: A drift piece never spans a hole in the truth longer than this (s): the log is cut there.
MAX_TRUTH_GAP_S = 2.0
# Fewest intervals and blocks for a fit with a cluster-robust covariance.
_MIN_INTERVALS = 20
_MIN_BLOCKS = 3


# --------------------------------------------------------------------------------------- data


@dataclass(frozen=True)
class SkidLog:
    """Wheel angles and a truth track, each on its own clock.

    Attributes
    ----------
    name : str
    time_s : ndarray, shape (K,)
        Wheel sample times (s), increasing.
    angle_right_rad, angle_left_rad : ndarray, shape (K,)
        Cumulative wheel angles (rad, forward +).
    truth_time_s : ndarray, shape (M,)
        Truth sample stamps (s, the truth's clock: the same clock as the wheels up to an
        offset), increasing.
    truth_pose : ndarray, shape (M, 3)
        Truth poses (x_m, y_m, yaw_rad; any fixed frame), yaw unwrapped.
    group : str
        What the log belongs to for held-out checks (a day, a terrain, a robot).
    wheels : str
        Where the wheel angles came from: 'joint_states', or the controller's odometry inverted
        through the geometry it ran with ('odometry', 'tf').
    """

    name: str
    time_s: np.ndarray
    angle_right_rad: np.ndarray
    angle_left_rad: np.ndarray
    truth_time_s: np.ndarray
    truth_pose: np.ndarray
    group: str = ""
    wheels: str = "joint_states"

    def __post_init__(self) -> None:
        t = np.asarray(self.time_s, dtype=float)
        if t.ndim != 1 or len(t) < 2 or not np.all(np.diff(t) > 0):
            raise ModelError(f"{self.name}: wheel times must be increasing, shape (K,), K >= 2")
        for nm in ("angle_right_rad", "angle_left_rad"):
            a = np.asarray(getattr(self, nm), dtype=float)
            if a.shape != t.shape or not np.all(np.isfinite(a)):
                raise ModelError(f"{self.name}: {nm} must be finite, shape {t.shape}")
        tt = np.asarray(self.truth_time_s, dtype=float)
        if tt.ndim != 1 or not np.all(np.diff(tt) > 0):
            raise ModelError(f"{self.name}: truth times must be increasing, shape (M,)")
        p = np.asarray(self.truth_pose, dtype=float)
        if p.shape != (len(tt), 3) or not np.all(np.isfinite(p)):
            raise ModelError(f"{self.name}: truth poses must be finite, shape ({len(tt)}, 3)")

    def window(self, start_s: float, end_s: float, *, group: str | None = None) -> SkidLog:
        """The part of the log between ``start_s`` and ``end_s`` (both clocks cut at the same
        times), named '<name>[start-end s]', in ``group`` (default this log's)."""
        t = np.asarray(self.time_s)
        tt = np.asarray(self.truth_time_s)
        w = (t >= start_s) & (t <= end_s)
        v = (tt >= start_s) & (tt <= end_s)
        return SkidLog(
            f"{self.name}[{start_s:g}-{end_s:g} s]", t[w],
            np.asarray(self.angle_right_rad)[w], np.asarray(self.angle_left_rad)[w], tt[v],
            np.asarray(self.truth_pose)[v], self.group if group is None else group, self.wheels,
        )  # fmt: skip


@dataclass(frozen=True)
class SkidIntervals:
    """Truth intervals and the wheel sub-steps over each (module docstring).

    Attributes
    ----------
    start_s, end_s : ndarray, shape (n,)
        Each interval's truth stamps (s, the truth's clock).
    motion : ndarray, shape (n, 3)
        The truth's relative motion over each (dx_m, dy_m, dtheta_rad; frame of its start).
    dphi_right, dphi_left : ndarray, shape (n, S)
        Wheel rotation over each of S equal sub-steps (rad).
    dt : ndarray, shape (n,)
        Sub-step duration of each interval (s).
    block : ndarray of int, shape (n,)
        Cluster label (a time block of one log; unique across logs).
    log : ndarray of int, shape (n,)
        Index of the log into ``names``.
    names : tuple of str
        The logs.
    """

    start_s: np.ndarray
    end_s: np.ndarray
    motion: np.ndarray
    dphi_right: np.ndarray
    dphi_left: np.ndarray
    dt: np.ndarray
    block: np.ndarray
    log: np.ndarray
    names: tuple[str, ...]

    def __len__(self) -> int:
        return len(self.start_s)

    def subset(self, keep: ArrayLike) -> SkidIntervals:
        """The intervals where ``keep`` (bool mask or indices)."""
        k = np.asarray(keep)
        return replace(
            self,
            start_s=self.start_s[k],
            end_s=self.end_s[k],
            motion=self.motion[k],
            dphi_right=self.dphi_right[k],
            dphi_left=self.dphi_left[k],
            dt=self.dt[k],
            block=self.block[k],
            log=self.log[k],
        )

    @property
    def duration_s(self) -> np.ndarray:
        """Each interval's duration (s)."""
        return self.end_s - self.start_s

    @classmethod
    def concatenate(cls, parts: Sequence[SkidIntervals]) -> SkidIntervals:
        """One set of intervals from several (logs renumbered, blocks kept apart, sub-steps
        zero-padded to the longest)."""
        if not parts:
            raise ModelError("no intervals to concatenate")
        width = max(p.dphi_right.shape[1] for p in parts)

        def pad(a: np.ndarray) -> np.ndarray:
            return np.pad(a, ((0, 0), (0, width - a.shape[1])))

        names: list[str] = []
        logs, blocks = [], []
        block_base = 0
        for p in parts:
            logs.append(p.log + len(names))
            names.extend(p.names)
            blocks.append(p.block - (p.block.min() if len(p) else 0) + block_base)
            block_base = int(blocks[-1].max()) + 1 if len(p) else block_base
        return cls(
            np.concatenate([p.start_s for p in parts]),
            np.concatenate([p.end_s for p in parts]),
            np.concatenate([p.motion for p in parts]),
            np.concatenate([pad(p.dphi_right) for p in parts]),
            np.concatenate([pad(p.dphi_left) for p in parts]),
            np.concatenate([p.dt for p in parts]),
            np.concatenate(blocks),
            np.concatenate(logs),
            tuple(names),
        )

    def wheel_yaw_rate(self, nominal: WheelGeometry) -> np.ndarray:
        """The nominal wheel yaw rate of every sub-step, (v_R - v_L) / b_n (rad/s), (n, S)."""
        d = (0.5 * float(nominal.diameter_right_m)) * self.dphi_right - (
            0.5 * float(nominal.diameter_left_m)
        ) * self.dphi_left
        return d / (float(nominal.wheelbase_m) * self.dt[:, None])


def truth_clock_offset(
    log: SkidLog,
    *,
    max_offset_s: float = 0.5,
    max_gap_s: float = 0.5,
    rng: np.random.Generator | None = None,
) -> TimeOffset:
    """The truth's clock offset against the wheels (s, > 0: the truth is stamped late), from the
    heading changes between consecutive truth samples no further apart than ``max_gap_s``
    (:func:`odocal.calibration.time_offset.estimate_time_offset`, block-bootstrap error)."""
    tt = np.asarray(log.truth_time_s, dtype=float)
    yaw = np.asarray(log.truth_pose, dtype=float)[:, 2]
    a, b = tt[:-1], tt[1:]
    ok = (b - a) <= max_gap_s
    found = estimate_time_offset(
        log.time_s, log.angle_right_rad, log.angle_left_rad, a[ok], b[ok], np.diff(yaw)[ok],
        source="truth", max_offset_s=max_offset_s, rng=rng,
    )  # fmt: skip
    return replace(found, part=log.name)


@dataclass(frozen=True)
class WindowedOffset:
    """A truth clock offset that changes over the log: one estimate per window.

    Attributes
    ----------
    centre_s : ndarray, shape (W,)
        Each window's centre (s, the truth's clock).
    offset_s, stderr_s : ndarray, shape (W,)
        Each window's offset and its block-bootstrap standard error (s).
    overall : TimeOffset
        The whole log's single offset (used where no window could be estimated).
    """

    centre_s: np.ndarray
    offset_s: np.ndarray
    stderr_s: np.ndarray
    overall: TimeOffset

    def at(self, time_s: ArrayLike) -> np.ndarray:
        """The offset (s) at each truth stamp: linear between window centres, held beyond."""
        t = np.asarray(time_s, dtype=float)
        if len(self.centre_s) == 0:
            return np.full(t.shape, self.overall.offset_s)
        return np.interp(t, self.centre_s, self.offset_s)

    @property
    def spread_s(self) -> float:
        """Largest minus smallest window offset (s): how far the latency wandered."""
        return float(np.ptp(self.offset_s)) if len(self.offset_s) else 0.0

    @property
    def typical_stderr_s(self) -> float:
        """Median of the windows' standard errors (s), or the overall one."""
        if len(self.stderr_s):
            return float(np.median(self.stderr_s))
        return float(self.overall.stderr_s or 0.0)


def windowed_truth_offset(
    log: SkidLog,
    *,
    window_s: float = 60.0,
    step_s: float = 30.0,
    max_offset_s: float = 0.6,
    rng: np.random.Generator | None = None,
) -> WindowedOffset:
    """The truth's clock offset in windows of ``window_s`` every ``step_s`` (each by
    :func:`truth_clock_offset` on that part of the log; a window with too little turning is
    skipped). For a truth whose latency wanders (a lidar mapper that falls behind while the
    robot moves fast): one offset for the whole log then leaves a timing error that changes
    over the log and biases the fit."""
    overall = truth_clock_offset(log, max_offset_s=max_offset_s, rng=rng)
    t0, t1 = float(log.time_s[0]), float(log.time_s[-1])
    centres: list[float] = []
    values: list[float] = []
    errors: list[float] = []
    start = t0
    while True:
        end = min(start + window_s, t1)
        part = log.window(start, end)
        if len(part.time_s) >= 2 and len(part.truth_time_s) >= 2:
            try:
                o = truth_clock_offset(part, max_offset_s=max_offset_s, rng=rng)
            except CalibrationError:
                o = None
            if o is not None and o.stderr_s is not None and math.isfinite(o.stderr_s):
                centres.append(0.5 * (start + end))
                values.append(o.offset_s)
                errors.append(o.stderr_s)
        start += step_s
        if start + 0.5 * window_s >= t1:
            break
    return WindowedOffset(np.array(centres), np.array(values), np.array(errors), overall)


Offset = TimeOffset | WindowedOffset


def offset_at(offset: Offset | float, log: SkidLog) -> float | np.ndarray:
    """The offset (s) of each of ``log``'s truth stamps: a number, or one per stamp."""
    if isinstance(offset, WindowedOffset):
        return offset.at(log.truth_time_s)
    if isinstance(offset, TimeOffset):
        return offset.offset_s
    return float(offset)


def skid_recording(log: SkidLog, offset: TimeOffset) -> Recording:
    """``log`` as a wheel-rate :class:`~odocal.core.recording.Recording` whose truth is valid
    at its stamps only, placed on the wheels' clock by ``offset`` (its ``offset_s``: what the
    skid-steer fit uses), so that every differential-drive evaluation (validate's errors, its
    drift, plots, TUM files) applies to the effective geometry."""
    shifted = np.asarray(log.truth_time_s, dtype=float) - offset.offset_s
    inside = (shifted >= log.time_s[0]) & (shifted <= log.time_s[-1])
    if inside.sum() < 2:
        raise CalibrationError(
            f"{log.name}: fewer than 2 truth samples within the wheels' time once the truth's "
            f"clock offset ({offset.offset_s:+.3f} s) is applied"
        )
    return with_truth_at(
        log.name, log.time_s, log.angle_right_rad, log.angle_left_rad, shifted[inside],
        np.asarray(log.truth_pose, dtype=float)[inside],
        {
            "truth": "pose", "truth_offset_s": offset.offset_s, "truth_max_gap_s": MAX_TRUTH_GAP_S,
            "dataset": log.group or log.name,
        },
    )  # fmt: skip


def _offset_stderr(offset: Offset) -> float | None:
    if isinstance(offset, WindowedOffset):
        return offset.typical_stderr_s
    return offset.stderr_s


def skid_intervals(
    log: SkidLog,
    *,
    offset_s: float | np.ndarray = 0.0,
    interval_s: float = 1.0,
    max_gap_s: float = 1.5,
    substep_s: float = 0.05,
    block_s: float = 15.0,
    min_wheel_rotation_rad: float = MIN_WHEEL_ROTATION_RAD,
) -> SkidIntervals:
    """The log's truth intervals of about ``interval_s`` and the wheel sub-steps over each
    (module docstring). Consecutive intervals share their truth sample; ``block_s`` sets the
    clusters of the standard errors (contiguous blocks of the log's time). ``offset_s``: the
    truth's clock offset (s), one for the log or one per truth stamp (:func:`offset_at`)."""
    if not (interval_s > 0 and substep_s > 0 and block_s > 0 and max_gap_s > 0):
        raise ModelError("interval_s, substep_s, block_s and max_gap_s must be > 0 (s)")
    tt = np.asarray(log.truth_time_s, dtype=float)
    pose = np.asarray(log.truth_pose, dtype=float)
    tw = np.asarray(log.time_s, dtype=float)
    big = np.concatenate([[0], np.cumsum(np.diff(tt) > max_gap_s)])
    starts, ends = [], []
    k, m = 0, len(tt)
    while k < m - 1:
        e = int(np.searchsorted(tt, tt[k] + interval_s, side="left"))
        if e >= m:
            break
        if big[e] != big[k]:  # a hole in the truth: start again after it
            k = int(np.searchsorted(big, big[e], side="left"))
            continue
        starts.append(k)
        ends.append(e)
        k = e
    i0, i1 = np.array(starts, dtype=int), np.array(ends, dtype=int)
    off = np.broadcast_to(np.asarray(offset_s, dtype=float), tt.shape)
    a, b = tt[i0] - off[i0], tt[i1] - off[i1]
    inside = (a >= tw[0]) & (b <= tw[-1])
    i0, i1, a, b = i0[inside], i1[inside], a[inside], b[inside]
    dur = b - a
    steps = max(1, int(math.ceil(float(dur.max(initial=0.0)) / substep_s))) if len(dur) else 1
    grid = a[:, None] + dur[:, None] * np.linspace(0.0, 1.0, steps + 1)[None, :]
    ang_r = np.interp(grid, tw, np.asarray(log.angle_right_rad, dtype=float))
    ang_l = np.interp(grid, tw, np.asarray(log.angle_left_rad, dtype=float))
    dr, dl = np.diff(ang_r, axis=1), np.diff(ang_l, axis=1)
    moved = (np.abs(dr).sum(axis=1) + np.abs(dl).sum(axis=1)) > min_wheel_rotation_rad
    motion = se2_relative(pose[i0], pose[i1], wrap=False)
    block = np.floor((tt[i0] - tt[0]) / block_s).astype(int)
    out = SkidIntervals(
        tt[i0], tt[i1], motion, dr, dl, dur / steps, block, np.zeros(len(i0), dtype=int),
        (log.name,),
    )  # fmt: skip
    return out.subset(moved)


def turn_rate_knots(
    intervals: SkidIntervals,
    nominal: WheelGeometry,
    *,
    ladder: Sequence[float] = DEFAULT_RATE_LADDER,
    min_rotation_rad: float = MIN_KNOT_ROTATION_RAD,
) -> tuple[float, ...]:
    """The knots of ``ladder`` (|wheel yaw rate|, rad/s) that the intervals support: the
    sub-steps whose nominal wheel yaw rate lies within a factor sqrt(2) of the knot turn by
    ``min_rotation_rad`` or more in all (a knot only the data beyond its neighbour inform would
    be extrapolated, and come out anywhere). CalibrationError when fewer than two are."""
    rate = np.abs(intervals.wheel_yaw_rate(nominal))
    rot = rate * intervals.dt[:, None]
    lad = np.asarray(sorted(ladder), dtype=float)
    kept = []
    for k in lad:
        near = (rate >= k / math.sqrt(2.0)) & (rate < k * math.sqrt(2.0))
        if float(rot[near].sum()) >= min_rotation_rad:
            kept.append(float(k))
    if len(kept) < 2:
        raise CalibrationError(
            f"a turn-rate model needs turning at two rates or more: only {len(kept)} of the "
            f"knots {', '.join(f'{x:g}' for x in lad)} rad/s have {min_rotation_rad:.3g} rad of "
            "turning near them; drive arcs and spins at several speeds, or fit the "
            "effective-track model"
        )
    return tuple(kept)


# ---------------------------------------------------------------------------------- the models


def _param_names(kind: SkidModelKind, scales: WheelScales, knots: Sequence[float]) -> list[str]:
    head = ["scale"] if scales == "common" else ["scale_right", "scale_left"]
    if kind == "effective-track":
        return head + ["track_multiplier"]
    if kind == "turn-rate":
        return head + [f"multiplier@{k:g}rad/s" for k in knots]
    if kind == "extended":
        return head + ["y_icr_left_m", "y_icr_right_m", "x_icr_m"]
    raise ModelError(f"unknown skid-steer model {kind!r}; one of {', '.join(SKID_MODELS)}")


def _model(
    kind: SkidModelKind,
    scales: WheelScales,
    knots: Sequence[float],
    nominal: WheelGeometry,
    q: np.ndarray,
) -> SkidSteerModel:
    r_r, r_l = 0.5 * float(nominal.diameter_right_m), 0.5 * float(nominal.diameter_left_m)
    half = 0.5 * float(nominal.wheelbase_m)
    if scales == "common":
        s_r = s_l = float(q[0])
        rest = q[1:]
    else:
        s_r, s_l = float(q[0]), float(q[1])
        rest = q[2:]
    if kind == "effective-track":
        m = float(rest[0])
        return SkidSteerModel(s_r * r_r, s_l * r_l, m * half, -m * half)
    if kind == "turn-rate":
        table = TurnRateTable(tuple(float(k) for k in knots), tuple(float(v) for v in rest))
        return SkidSteerModel(s_r * r_r, s_l * r_l, half, -half, 0.0, table)
    return SkidSteerModel(s_r * r_r, s_l * r_l, float(rest[0]), float(rest[1]), float(rest[2]))


def _start_and_bounds(
    kind: SkidModelKind, scales: WheelScales, knots: Sequence[float], nominal: WheelGeometry
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    b = float(nominal.wheelbase_m)
    ns = 1 if scales == "common" else 2
    x0 = [1.0] * ns
    lo, hi = [0.2] * ns, [5.0] * ns
    if kind == "effective-track":
        x0 += [1.0]
        lo += [0.1]
        hi += [20.0]
    elif kind == "turn-rate":
        x0 += [1.0] * len(knots)
        lo += [0.1] * len(knots)
        hi += [20.0] * len(knots)
    else:
        x0 += [0.5 * b, -0.5 * b, 0.0]
        lo += [0.02 * b, -10.0 * b, -5.0 * b]
        hi += [10.0 * b, -0.02 * b, 5.0 * b]
    return np.array(x0), np.array(lo), np.array(hi)


def predict_motion(model: SkidSteerModel, intervals: SkidIntervals) -> np.ndarray:
    """``model``'s motion over each interval (dx_m, dy_m, dtheta_rad in the frame of its
    start), dead-reckoned over its sub-steps: shape (n, 3). The truth's minus this is a fit's
    raw residual; on intervals a model was not fitted to, its held-out error."""
    inc = skid_body_increments(
        model, intervals.dphi_right, intervals.dphi_left, intervals.dt[:, None]
    )
    return body_motion_end(*inc)


# ------------------------------------------------------------------------------------- result


@dataclass(frozen=True)
class TurnRateRow:
    """One knot of a fitted turn-rate table."""

    wheel_rate_rad_s: float
    true_rate_rad_s: float
    multiplier: float
    stderr: float


@dataclass(frozen=True)
class SkidSteerFit:
    """A skid-steer model fitted to truth intervals.

    Attributes
    ----------
    kind : str
        'effective-track', 'turn-rate' or 'extended'.
    wheel_scales : str
        'common' or 'left-right'.
    names : tuple of str
        Parameter names.
    values : ndarray, shape (p,)
    covariance : ndarray, shape (p, p)
        Cluster-robust over time blocks (plus the clock offsets' share when
        :func:`fit_skid_logs` added it).
    formal : ndarray, shape (p, p)
        The formal covariance on the same residuals (for comparison).
    clusters : int
        Time blocks behind the covariance; ``dof`` = clusters - 1.
    model : SkidSteerModel
    nominal : WheelGeometry
    intervals : int
        Intervals fitted (after rejection).
    rejected : int
        Intervals dropped as outliers.
    residual_scale : ndarray, shape (3,)
        Robust spread of the residuals (m, m, rad) the fit divided them by.
    knots_rad_s : tuple of float
        The turn-rate model's knots (empty otherwise).
    offset_variance_added : bool
        Whether the clock offsets' uncertainty is in ``covariance``.
    """

    kind: str
    wheel_scales: str
    names: tuple[str, ...]
    values: np.ndarray
    covariance: np.ndarray
    formal: np.ndarray
    clusters: int
    model: SkidSteerModel
    nominal: WheelGeometry
    intervals: int
    rejected: int
    residual_scale: np.ndarray
    knots_rad_s: tuple[float, ...] = ()
    offset_variance_added: bool = False

    @property
    def dof(self) -> int:
        """Degrees of freedom of the standard errors (time blocks - 1)."""
        return self.clusters - 1

    @property
    def stderr(self) -> np.ndarray:
        """Standard errors, shape (p,)."""
        return np.sqrt(np.clip(np.diag(self.covariance), 0.0, None))

    def value(self, name: str) -> float:
        """The parameter ``name``."""
        return float(self.values[self.names.index(name)])

    def se(self, name: str) -> float:
        """The standard error of ``name``."""
        return float(self.stderr[self.names.index(name)])

    def track_multiplier(self) -> tuple[float, float]:
        """The effective track over the nominal wheelbase and its standard error (the
        effective-track and extended models; for the extended one (y_l - y_r) / b_n by the delta
        method). ModelError for the turn-rate model (see :meth:`turn_rate_rows`)."""
        b = float(self.nominal.wheelbase_m)
        if self.kind == "effective-track":
            return self.value("track_multiplier"), self.se("track_multiplier")
        if self.kind == "extended":
            g = np.zeros(len(self.values))
            g[self.names.index("y_icr_left_m")] = 1.0 / b
            g[self.names.index("y_icr_right_m")] = -1.0 / b
            return self.model.track_m / b, float(math.sqrt(max(g @ self.covariance @ g, 0.0)))
        raise ModelError("a turn-rate model has one multiplier per knot: turn_rate_rows()")

    def turn_rate_rows(self) -> tuple[TurnRateRow, ...]:
        """The turn-rate table with standard errors (empty for the other models)."""
        table = self.model.turn_rate
        if table is None:
            return ()
        true = table.true_rate_rad_s()
        first = len(self.names) - len(table.multiplier)
        se = self.stderr[first:]
        return tuple(
            TurnRateRow(float(k), float(t), float(m), float(s))
            for k, t, m, s in zip(table.rate_rad_s, true, table.multiplier, se, strict=True)
        )

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {
            "kind": self.kind,
            "wheel_scales": self.wheel_scales,
            "parameters": {
                n: {"value": float(v), "stderr": float(s)}
                for n, v, s in zip(self.names, self.values, self.stderr, strict=True)
            },
            "clusters": self.clusters,
            "intervals": self.intervals,
            "rejected": self.rejected,
            "model": self.model.as_dict(),
        }


# ----------------------------------------------------------------------------------- fitting


def _psi(f: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """The soft-L1 loss's influence psi(f) = f / sqrt(1 + f^2) and its derivative
    (1 + f^2)^-3/2 (scipy's least_squares 'soft_l1' at f_scale 1)."""
    q = 1.0 + f * f
    return f / np.sqrt(q), q**-1.5


def _jacobian(fun: Callable[[np.ndarray], np.ndarray], x: np.ndarray, lo: np.ndarray,
              hi: np.ndarray) -> np.ndarray:  # fmt: skip
    """Central differences (one-sided at a bound), relative step 1e-6."""
    f0 = fun(x)
    jac = np.empty((len(f0), len(x)))
    for k in range(len(x)):
        h = 1e-6 * max(abs(x[k]), 1e-2)
        up, dn = x.copy(), x.copy()
        up[k] = min(x[k] + h, hi[k])
        dn[k] = max(x[k] - h, lo[k])
        jac[:, k] = (fun(up) - fun(dn)) / (up[k] - dn[k])
    return jac


@dataclass
class _Problem:
    data: SkidIntervals
    kind: SkidModelKind
    scales: WheelScales
    knots: tuple[float, ...]
    nominal: WheelGeometry
    scale: np.ndarray = field(default_factory=lambda: np.ones(3))

    def model(self, q: np.ndarray) -> SkidSteerModel:
        return _model(self.kind, self.scales, self.knots, self.nominal, q)

    def raw(self, q: np.ndarray) -> np.ndarray:
        return self.data.motion - predict_motion(self.model(q), self.data)

    def residual(self, q: np.ndarray) -> np.ndarray:
        return (self.raw(q) / self.scale).ravel()


def _loss(f: np.ndarray, robust: bool) -> float:
    """Half the sum of soft-L1 losses 2 (sqrt(1 + f^2) - 1), or of squares."""
    if robust:
        return float(np.sum(np.sqrt(1.0 + f * f) - 1.0))
    return 0.5 * float(f @ f)


def _solve(
    problem: _Problem, x0: np.ndarray, lo: np.ndarray, hi: np.ndarray, robust: bool
) -> np.ndarray:
    """Minimise the (soft-L1 or squared) loss of ``problem``'s residuals within the bounds:
    Levenberg-Marquardt on iteratively reweighted least squares (the soft-L1 weights
    1 / sqrt(1 + f^2)), steps projected onto the bounds, a forward-difference Jacobian. A few
    milliseconds for these small problems, where scipy's least_squares took 15 and its import
    a second."""
    x = np.clip(np.asarray(x0, dtype=float), lo, hi)
    f = problem.residual(x)
    cost = _loss(f, robust)
    lam = 1e-3
    for _ in range(100):
        jac = np.empty((len(f), len(x)))
        for k in range(len(x)):
            h = 1e-7 * max(abs(x[k]), 1e-2)
            up = x.copy()
            up[k] = x[k] + h if x[k] + h <= hi[k] else x[k] - h
            jac[:, k] = (problem.residual(up) - f) / (up[k] - x[k])
        w = 1.0 / np.sqrt(1.0 + f * f) if robust else np.ones_like(f)
        a = jac.T @ (jac * w[:, None])
        g = jac.T @ (w * f)
        improved = False
        while lam < 1e12:
            step = np.linalg.solve(a + lam * np.diag(np.diag(a) + 1e-12), -g)
            x_new = np.clip(x + step, lo, hi)
            f_new = problem.residual(x_new)
            cost_new = _loss(f_new, robust)
            if cost_new <= cost:
                improved = True
                break
            lam *= 10.0
        if not improved:
            break
        done = np.all(np.abs(x_new - x) <= 1e-10 * (1.0 + np.abs(x))) or (
            cost - cost_new <= 1e-12 * max(cost, 1e-300)
        )
        x, f, cost = x_new, f_new, cost_new
        lam = max(lam / 10.0, 1e-9)
        if done:
            break
    return x


def _robust_scale(raw: np.ndarray) -> np.ndarray:
    s = 1.4826 * np.median(np.abs(raw - np.median(raw, axis=0)), axis=0)
    return np.maximum(s, np.array([1e-4, 1e-4, 1e-5]))


def fit_skid_steer(
    intervals: SkidIntervals,
    nominal: WheelGeometry,
    kind: SkidModelKind = "effective-track",
    *,
    wheel_scales: WheelScales = "common",
    knots_rad_s: Sequence[float] | None = None,
    reject_z: float = 6.0,
    start: np.ndarray | None = None,
    residual_scale: np.ndarray | None = None,
    covariance: Literal["jackknife", "sandwich"] = "jackknife",
) -> SkidSteerFit:
    """Fit a skid-steer model to truth intervals (module docstring).

    Parameters
    ----------
    intervals : SkidIntervals
        From :func:`skid_intervals` (several logs: :meth:`SkidIntervals.concatenate`).
    nominal : WheelGeometry
        Nominal wheel diameters and wheelbase (the scales and multipliers are relative to it).
    kind : {'effective-track', 'turn-rate', 'extended'}
    wheel_scales : {'common', 'left-right'}
    knots_rad_s : sequence of float, optional
        The turn-rate model's knots (default :func:`turn_rate_knots` of the intervals).
    reject_z : float
        Intervals with a residual component beyond this many robust spreads are dropped.
    start, residual_scale : ndarray, optional
        A starting point and fixed residual spreads (a refit of the same data, e.g. a bootstrap
        replicate: skips the first stages).

    Raises
    ------
    CalibrationError
        Too few intervals or time blocks, or (turn-rate) too few supported knots.
    """
    if kind not in SKID_MODELS:
        raise ModelError(f"unknown skid-steer model {kind!r}; one of {', '.join(SKID_MODELS)}")
    if wheel_scales not in ("common", "left-right"):
        raise ModelError(f"wheel_scales must be 'common' or 'left-right', got {wheel_scales!r}")
    n = len(intervals)
    if n < _MIN_INTERVALS:
        raise CalibrationError(
            f"a skid-steer fit needs {_MIN_INTERVALS} intervals with motion or more, got {n}"
        )
    knots: tuple[float, ...] = ()
    if kind == "turn-rate":
        knots = (
            tuple(float(k) for k in knots_rad_s)
            if knots_rad_s is not None
            else turn_rate_knots(intervals, nominal)
        )
    names = _param_names(kind, wheel_scales, knots)
    x0, lo, hi = _start_and_bounds(kind, wheel_scales, knots, nominal)
    prob = _Problem(intervals, kind, wheel_scales, knots, nominal)
    if start is None or residual_scale is None:
        # 1: least squares on unscaled residuals (metres and radians) from the nominal
        # 2: each component divided by its robust spread there; soft-L1
        x = _solve(prob, x0, lo, hi, False)
        prob.scale = _robust_scale(prob.raw(x))
        x = _solve(prob, x, lo, hi, True)
    else:
        prob.scale = np.asarray(residual_scale, dtype=float)
        x = np.asarray(start, dtype=float)
    # 3: drop gross outliers, refit
    z = np.abs(prob.raw(x) / prob.scale)
    keep = ~np.any(z > reject_z, axis=1)
    rejected = int(n - keep.sum())
    if rejected or start is not None:
        prob.data = intervals.subset(keep)
        x = _solve(prob, x, lo, hi, True)
    blocks = np.unique(prob.data.block)
    if len(blocks) < _MIN_BLOCKS:
        raise CalibrationError(
            f"standard errors need {_MIN_BLOCKS} time blocks or more; these intervals fall in "
            f"{len(blocks)} (a longer log, or shorter blocks)"
        )
    f = prob.residual(x)
    jac = _jacobian(prob.residual, x, lo, hi)
    psi, dpsi = _psi(f)
    rows_block = np.repeat(prob.data.block, 3)
    cc = (cluster_jackknife_covariance if covariance == "jackknife" else cluster_covariance)(
        jac, psi, rows_block, curvature=dpsi
    )
    return SkidSteerFit(
        kind, wheel_scales, tuple(names), x, cc.covariance, cc.formal, cc.clusters,
        prob.model(x), nominal, len(prob.data), rejected, prob.scale.copy(), knots,
    )  # fmt: skip


def fit_skid_logs(
    logs: Sequence[SkidLog],
    nominal: WheelGeometry,
    kind: SkidModelKind = "effective-track",
    *,
    offsets: Sequence[Offset] | None = None,
    wheel_scales: WheelScales = "common",
    knots_rad_s: Sequence[float] | None = None,
    interval_s: float = 1.0,
    block_s: float = 15.0,
    offset_variance: bool = True,
) -> tuple[SkidSteerFit, tuple[Offset, ...]]:
    """Fit ``kind`` to the intervals of ``logs`` pooled, each moved onto the wheels' clock by
    its own truth clock offset (given, else estimated: :func:`truth_clock_offset`, applied
    whatever its significance; a :class:`WindowedOffset` gives one per truth stamp). With
    ``offset_variance`` each offset's uncertainty is added to the covariance, J J^T se^2 with J
    from two refits at offset +- se (the other logs held; a windowed offset moved as a whole by
    its windows' median error). Returns the fit and the offsets used."""
    if offsets is None:
        offsets = tuple(truth_clock_offset(log) for log in logs)
    if len(offsets) != len(logs):
        raise ModelError(f"{len(offsets)} offsets for {len(logs)} logs")

    def parts(shift: dict[int, float]) -> SkidIntervals:
        return SkidIntervals.concatenate(
            [
                skid_intervals(
                    log,
                    offset_s=offset_at(o, log) + shift.get(i, 0.0),
                    interval_s=interval_s,
                    block_s=block_s,
                )  # fmt: skip
                for i, (log, o) in enumerate(zip(logs, offsets, strict=True))
            ]
        )

    fit = fit_skid_steer(
        parts({}), nominal, kind, wheel_scales=wheel_scales, knots_rad_s=knots_rad_s
    )
    if not offset_variance:
        return fit, tuple(offsets)
    extra = np.zeros_like(fit.covariance)
    for i, o in enumerate(offsets):
        se = _offset_stderr(o)
        if se is None or not math.isfinite(se) or se <= 0:
            continue
        ends = []
        for sign in (1.0, -1.0):
            again = fit_skid_steer(
                parts({i: sign * se}), nominal, kind, wheel_scales=wheel_scales,
                knots_rad_s=fit.knots_rad_s or None, start=fit.values,
                residual_scale=fit.residual_scale,
            )  # fmt: skip
            ends.append(again.values)
        jac = (ends[0] - ends[1]) / 2.0  # per standard error of the offset
        extra += np.outer(jac, jac)
    return replace(fit, covariance=fit.covariance + extra, offset_variance_added=True), tuple(
        offsets
    )


def block_bootstrap(
    intervals: SkidIntervals,
    fit: SkidSteerFit,
    *,
    replicates: int = 200,
    rng: np.random.Generator | None = None,
) -> np.ndarray:
    """Standard errors of ``fit``'s parameters by resampling its time blocks with replacement
    and refitting each replicate (from the fit, with its residual spreads): shape (p,). A check
    of the cluster-robust errors, at ``replicates`` refits' cost."""
    gen = rng if rng is not None else np.random.default_rng(0)
    blocks, inverse = np.unique(intervals.block, return_inverse=True)
    members = [np.flatnonzero(inverse == g) for g in range(len(blocks))]
    reps = []
    for _ in range(int(replicates)):
        draw = gen.integers(0, len(blocks), size=len(blocks))
        idx = np.concatenate([members[g] for g in draw])
        sample = intervals.subset(idx)
        # each drawn copy of a block is its own cluster (a label per draw)
        sample = replace(
            sample, block=np.repeat(np.arange(len(draw)), [len(members[g]) for g in draw])
        )
        try:
            again = fit_skid_steer(
                sample, fit.nominal, fit.kind,  # type: ignore[arg-type]
                wheel_scales=fit.wheel_scales,  # type: ignore[arg-type]
                knots_rad_s=fit.knots_rad_s or None, start=fit.values,
                residual_scale=fit.residual_scale,
            )  # fmt: skip
        except CalibrationError:
            continue
        reps.append(again.values)
    if len(reps) < 2:
        raise CalibrationError("the block bootstrap found too few usable replicates")
    return np.std(np.array(reps), axis=0, ddof=1)


def z_score(a: float, se_a: float, b: float, se_b: float) -> float:
    """(a - b) / sqrt(se_a^2 + se_b^2): how many combined standard errors two independent
    estimates of one quantity differ by."""
    return float((a - b) / math.hypot(se_a, se_b))


# --------------------------------------------------------------------------------- evaluation


def _segments(truth_time_s: np.ndarray, max_gap_s: float) -> np.ndarray:
    """Sample indices where a new segment of the truth starts (after a hole)."""
    return np.flatnonzero(np.diff(truth_time_s) > max_gap_s) + 1


def log_drift(
    log: SkidLog,
    model: SkidSteerModel,
    *,
    offset_s: float | np.ndarray = 0.0,
    length_m: float = 10.0,
    mode: DriftMode = "consecutive",
    max_gap_s: float = MAX_TRUTH_GAP_S,
) -> PathDrift:
    """The KITTI-style drift (:func:`odocal.core.path_drift.path_drift`) of ``model``'s dead
    reckoning over the whole log against its truth: the wheels dead-reckoned from the start and
    taken at each truth stamp minus ``offset_s`` (one, or one per stamp: :func:`offset_at`;
    linear between wheel samples); pieces never
    span a hole in the truth longer than ``max_gap_s`` (the log is cut there)."""
    est = dead_reckon_skid(model, log.angle_right_rad, log.angle_left_rad, log.time_s)
    tt = np.asarray(log.truth_time_s, dtype=float)
    tw = np.asarray(log.time_s, dtype=float)
    q = tt - np.broadcast_to(np.asarray(offset_s, dtype=float), tt.shape)
    inside = (q >= tw[0]) & (q <= tw[-1])
    at = np.column_stack([np.interp(q[inside], tw, est[:, k]) for k in range(3)])
    truth = np.asarray(log.truth_pose, dtype=float)[inside]
    breaks = _segments(tt[inside], max_gap_s)
    return path_drift(truth, at, length_m=length_m, mode=mode, breaks=breaks)


Candidate = tuple[SkidModelKind, WheelScales]
#: The models :func:`cross_validate` compares by default.
CANDIDATES: tuple[Candidate, ...] = (
    ("effective-track", "common"),
    ("effective-track", "left-right"),
    ("turn-rate", "left-right"),
    ("extended", "left-right"),
)


def candidate_label(candidate: Candidate) -> str:
    """'effective-track (common)' and the like."""
    return f"{candidate[0]} ({candidate[1]})"


@dataclass(frozen=True)
class SkidHeldOut:
    """Models scored on logs they were not fitted to.

    Attributes
    ----------
    held_out : tuple of str
        The groups (or logs) held out, in order.
    labels : tuple of str
        The models compared (:func:`candidate_label`), 'nominal' first (the nominal geometry as
        a differential drive).
    drift : dict of str -> tuple of PathDrift
        Per model, the drift on each held-out unit (in ``held_out`` order; a unit's logs
        pooled).
    fits : dict of str -> tuple of SkidSteerFit or None
        Per model (not 'nominal'), the fit used for each held-out unit; None where the model
        could not be fitted on that fold (then its drift is the effective-track model's with the
        same wheel scales, and ``fallbacks`` counts it).
    fallbacks : dict of str -> int
    """

    held_out: tuple[str, ...]
    labels: tuple[str, ...]
    drift: dict[str, tuple[PathDrift, ...]]
    fits: dict[str, tuple[SkidSteerFit | None, ...]]
    fallbacks: dict[str, int]

    def median_pct(self, label: str) -> np.ndarray:
        """Median drift (% of piece length) per held-out unit, shape (units,)."""
        return np.array([d.median_pct for d in self.drift[label]])

    def pieces_pct(self, label: str) -> np.ndarray:
        """Every held-out piece's drift (%), the units in order."""
        return np.concatenate([d.error_pct for d in self.drift[label]])

    def pooled_median_pct(self, label: str) -> float:
        """Median drift over every held-out piece of every unit."""
        pieces = self.pieces_pct(label)
        return float(np.median(pieces)) if len(pieces) else math.nan

    def best(self) -> str:
        """The model with the lowest pooled held-out median drift."""
        return min(self.labels, key=self.pooled_median_pct)

    def pooled(self, label: str) -> PathDrift:
        """Every held-out piece of a model, the units pooled."""
        return _pool(self.drift[label])


def cross_validate(
    logs: Sequence[SkidLog],
    nominal: WheelGeometry,
    candidates: Sequence[Candidate] = CANDIDATES,
    *,
    offsets: Sequence[Offset] | None = None,
    length_m: float = 10.0,
    interval_s: float = 1.0,
    train_filter: Callable[[SkidIntervals], SkidIntervals] | None = None,
) -> SkidHeldOut:
    """Leave-one-group-out held-out drift: for each group (``SkidLog.group``, or each log when
    no log has a group), every candidate (kind, wheel scales) is fitted on the logs of the other
    groups and each log of the group is dead-reckoned whole with it (:func:`log_drift`,
    consecutive pieces of ``length_m``, the log's own clock offset); the pieces of a group's
    logs are pooled. The nominal geometry is scored too. ``train_filter`` may thin each fold's
    training intervals (e.g. to a few minutes of driving). A candidate that cannot be fitted on
    a fold (CalibrationError, e.g. turn rates the training logs do not cover) is scored with the
    effective-track model of the same wheel scales (``SkidHeldOut.fallbacks``)."""
    if offsets is None:
        offsets = tuple(truth_clock_offset(log) for log in logs)
    groups = [log.group or log.name for log in logs]
    units = list(dict.fromkeys(groups))
    if len(units) < 2:
        raise CalibrationError("a held-out check needs logs of two groups or more")
    parts = [
        skid_intervals(log, offset_s=offset_at(o, log), interval_s=interval_s)
        for log, o in zip(logs, offsets, strict=True)
    ]
    labels = ("nominal", *(candidate_label(c) for c in candidates))
    drift: dict[str, list[PathDrift]] = {k: [] for k in labels}
    fits: dict[str, list[SkidSteerFit | None]] = {k: [] for k in labels[1:]}
    fallbacks = dict.fromkeys(labels[1:], 0)
    nominal_model = SkidSteerModel.from_geometry(nominal)
    for unit in units:
        train = SkidIntervals.concatenate(
            [p for p, g in zip(parts, groups, strict=True) if g != unit]
        )
        if train_filter is not None:
            train = train_filter(train)
        test = [(log, o) for log, o, g in zip(logs, offsets, groups, strict=True) if g == unit]
        models: dict[str, SkidSteerModel] = {"nominal": nominal_model}
        for cand, label in zip(candidates, labels[1:], strict=True):
            kind, scales = cand
            try:
                fit: SkidSteerFit | None = fit_skid_steer(train, nominal, kind, wheel_scales=scales)
            except CalibrationError:
                if kind == "effective-track":
                    raise
                fit = None
                fallbacks[label] += 1
            fits[label].append(fit)
            models[label] = (
                fit.model
                if fit is not None
                else fit_skid_steer(train, nominal, "effective-track", wheel_scales=scales).model
            )
        for label in labels:
            scored = [
                log_drift(log, models[label], offset_s=offset_at(o, log), length_m=length_m)
                for log, o in test
            ]
            drift[label].append(_pool(scored))
    return SkidHeldOut(
        tuple(units), labels, {k: tuple(v) for k, v in drift.items()},
        {k: tuple(v) for k, v in fits.items()}, fallbacks,
    )  # fmt: skip


def _pool(parts: Sequence[PathDrift]) -> PathDrift:
    """One PathDrift of several logs' pieces (indices are per log)."""
    if len(parts) == 1:
        return parts[0]
    first = parts[0]
    return PathDrift(
        first.length_m, first.mode,
        np.concatenate([p.start for p in parts]), np.concatenate([p.end for p in parts]),
        np.concatenate([p.piece_length_m for p in parts]),
        np.concatenate([p.error_m for p in parts]),
        np.concatenate([p.heading_error_rad for p in parts]),
    )  # fmt: skip
