"""Relative motions from a SLAM pose: only between the instants where the SLAM updated it.

A robot without motion capture gets its reference pose from SLAM through the tf tree:
``map -> odom`` is the SLAM correction (changed at each processed scan, 1-5 Hz) and
``odom -> base_link`` is the wheel odometry (high rate). Between two SLAM updates the composed
pose ``map -> base_link`` = correction (+) odometry moves WITH THE ODOMETRY: a fit of the odometry
against it "confirms" whatever the odometry believes. It is a measurement only at the update
instants, where the SLAM has just matched a scan (docs/slam-truth.md).

So this module keeps only the update instants and returns the RELATIVE motion between
consecutive ones (not one absolute trajectory, which a loop closure would bend):

1. **Update instants.** A message whose value equals the previous one (to
   ``unchanged_translation_m`` / ``unchanged_rotation_rad``) brings no new information: SLAM
   packages republish the last correction at a fixed rate (slam_toolbox every 20 ms). The first
   message counts only if the publisher does not repeat its value while the robot moves
   (``first_is_update``): otherwise its value may date from before the recording. Use the
   message's header stamp, which should be the time of the scan the SLAM matched (subtract a
   known post-dating first: slam_toolbox stamps ``scan time + transform_timeout``, AMCL
   ``scan time + transform_tolerance``), never the time the bag received it.
2. **Intervals** between consecutive update instants a, b: the true motion
   ``truth_a^-1 (+) truth_b`` in the base frame at a, and the wheel rotations ``phi(b) - phi(a)``.
3. **Jumps.** The odometry's own motion over the interval, ``odom_a^-1 (+) odom_b``, differs from
   the true one by the discrepancy ``d = odometry_motion^-1 (+) true_motion``: the odometry's error
   over the interval as the SLAM sees it (in correction mode it is the change of the correction,
   seen from the robot). A calibration error makes it a small fraction of the motion; a loop
   closure or relocalisation makes it large at once. An interval is a jump when
   ``|d_xy| > jump_translation_m + jump_fraction * distance`` or
   ``|d_theta| > jump_rotation_rad + jump_fraction * rotation``, with the distance travelled and
   the angle turned by the odometry along the messages between the two instants (the chord and
   the net angle when messages come only at the updates); it is dropped and the run is split
   there (``segment``).
4. **Too short / too long.** Intervals whose odometric motion is below ``min_travel_m`` AND
   ``min_rotation_rad`` are dominated by the SLAM's own noise; intervals longer than
   ``max_interval_s`` mean the SLAM stopped updating (lost, paused, or waiting for motion), and the
   wheel rotations over them no longer describe one simple arc. Both are dropped.

The gates look at the odometry's motion, not at the SLAM's, so that intervals are chosen by what
the wheels did, not by the value being measured. Defaults are in :class:`SlamLimits`.

Two modes: **correction** (``correction_pose`` of each ``map -> odom`` message, plus the
odometry ``odom -> base_link`` or the composed truth ``map -> base_link`` at the message
stamps) and **direct** (``truth_pose``: the SLAM publishes ``map -> base_link`` itself, at its
update rate, or a pose topic such as slam_toolbox's ``/pose`` or AMCL's ``/amcl_pose``; each
changed message is an update instant; ``odometry_pose`` is optional and needed for the jump test).

All poses are planar (x_m, y_m, yaw_rad), see :func:`odocal.core.transforms.planar_pose`; headings
may be wrapped and are unwrapped along the messages (less than half a turn between consecutive
messages). Frames and signs: docs/conventions.md.
"""

from __future__ import annotations

import math
import numbers
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.transforms import se2_compose, se2_inverse, se2_relative
from ..errors import CalibrationError, InputError, ModelError

__all__ = [
    "SlamLimits",
    "IntervalCounts",
    "DroppedInterval",
    "SlamMotions",
    "slam_relative_motions",
    "REASONS",
    "FAST_CHANGES_S",
]

REASONS = ("jump", "too_long", "too_short")
#: A SLAM value that changes more often than this (s, the median interval) is not updated once
#: per matched scan (1-5 Hz) but between scans too (extrapolated from odometry or an IMU).
FAST_CHANGES_S = 0.1


@dataclass(frozen=True)
class SlamLimits:
    """Thresholds of :func:`slam_relative_motions`, with the reasons for their defaults.

    unchanged_translation_m, unchanged_rotation_rad : 1e-6 m, 1e-6 rad
        A message within this of the previous one repeats it (no new information). Far below any
        SLAM resolution, far above the rounding of a value that is republished or recomputed.
    jump_translation_m, jump_rotation_rad : 0.05 m, 3 deg
        Allowance for the SLAM's own noise: scan matching places each pose to about a centimetre
        and a fraction of a degree, and an interval holds two poses; 5 cm and 3 deg are two to
        three standard deviations of that. A loop closure or relocalisation moves the map by
        decimetres or several degrees at once.
    jump_fraction : 0.25
        Allowance for the odometry's real error, per metre travelled and per radian turned. An
        uncalibrated odometry is off by a few per cent (even a 10 % wheelbase error stays well
        inside). It is generous on purpose: this test looks at the very error being calibrated,
        and a tight one would drop the intervals where the odometry is most wrong and pull the
        fit toward what the odometry believes.
    min_travel_m, min_rotation_rad : 0.05 m, 5 deg
        An interval whose odometric motion is below BOTH is dropped: its true motion is
        comparable to the SLAM's noise and tells little about the wheels.
    max_interval_s : 5 s
        Longer intervals mean the SLAM stopped updating; over them the wheel rotations at the
        two ends no longer describe one arc, which relative-motion estimators assume.
    min_intervals : 10
        Fewer usable intervals are refused (three parameters, and outliers to see).
    """

    unchanged_translation_m: float = 1e-6
    unchanged_rotation_rad: float = 1e-6
    jump_translation_m: float = 0.05
    jump_rotation_rad: float = math.radians(3.0)
    jump_fraction: float = 0.25
    min_travel_m: float = 0.05
    min_rotation_rad: float = math.radians(5.0)
    max_interval_s: float = 5.0
    min_intervals: int = 10

    def __post_init__(self) -> None:
        for name in (
            "unchanged_translation_m",
            "unchanged_rotation_rad",
            "jump_translation_m",
            "jump_rotation_rad",
            "jump_fraction",
            "min_travel_m",
            "min_rotation_rad",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0):
                raise ModelError(f"{name} must be a finite number >= 0, got {v!r}")
        v = self.max_interval_s
        if not (isinstance(v, numbers.Real) and math.isfinite(v) and v > 0):
            raise ModelError(f"max_interval_s must be > 0 (s), got {self.max_interval_s!r}")
        if not (isinstance(self.min_intervals, numbers.Integral) and self.min_intervals >= 1):
            raise ModelError(f"min_intervals must be an integer >= 1, got {self.min_intervals!r}")


@dataclass(frozen=True)
class IntervalCounts:
    """How the messages became intervals.

    messages: messages given; unchanged: messages repeating the previous value (no new
    information); first_unknown: 1 when the first message is not taken as an update (its age is
    unknown); superseded: updates replaced by a later one with the same stamp; updates: update
    instants kept; intervals: intervals between them (updates - 1); used: intervals returned;
    jump, too_long, too_short: intervals dropped for that reason (each counted once, in that
    order of precedence).
    """

    messages: int
    unchanged: int
    first_unknown: int
    superseded: int
    updates: int
    intervals: int
    used: int
    jump: int
    too_long: int
    too_short: int

    @property
    def dropped(self) -> int:
        """Intervals dropped for any reason (jump + too_long + too_short)."""
        return self.jump + self.too_long + self.too_short


@dataclass(frozen=True)
class DroppedInterval:
    """One dropped interval: its update instants (s), the reason (one of :data:`REASONS`) and
    the discrepancy (dx_m, dy_m, dtheta_rad; None without odometry)."""

    start_s: float
    end_s: float
    reason: str
    discrepancy: tuple[float, float, float] | None


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


@dataclass(frozen=True, eq=False)
class SlamMotions:
    """Relative-motion pairs between consecutive SLAM update instants (n usable intervals).

    Attributes
    ----------
    mode : str
        'correction' (map -> odom edge) or 'direct' (map -> base_link published by the SLAM).
    start_s, end_s : ndarray, shape (n,)
        Update instants bounding each interval (s, the message stamps given).
    phi_right_rad, phi_left_rad : ndarray, shape (n,)
        Wheel rotation over each interval (rad, forward positive).
    sensor_motion : ndarray, shape (n, 3)
        True base motion over each interval in the base frame at its start:
        (dx_m forward, dy_m left, dtheta_rad CCW +), from the SLAM poses at the two instants.
    odometry_motion : ndarray, shape (n, 3), or None
        The odometry's own belief over the same intervals (None in direct mode without odometry).
    discrepancy : ndarray, shape (n, 3), or None
        ``odometry_motion^-1 (+) sensor_motion``: the odometry's error as the SLAM sees it.
    segment : ndarray of int, shape (n,)
        Map segment of each interval: 0 until the first jump, then 1, ...
    counts : IntervalCounts
    dropped : tuple of DroppedInterval
    limits : SlamLimits
        The thresholds used.
    warnings : tuple of str
    every_start_s, every_end_s : ndarray, shape (N,)
        All N intervals between consecutive update instants, dropped ones included (s).
    every_motion : ndarray, shape (N, 3)
        The SLAM's base motion over each of them (as ``sensor_motion``).
    every_used : ndarray of bool, shape (N,)
        Which of them are the n used intervals.
    """

    mode: str
    start_s: np.ndarray
    end_s: np.ndarray
    phi_right_rad: np.ndarray
    phi_left_rad: np.ndarray
    sensor_motion: np.ndarray
    odometry_motion: np.ndarray | None
    discrepancy: np.ndarray | None
    segment: np.ndarray
    counts: IntervalCounts
    dropped: tuple[DroppedInterval, ...]
    limits: SlamLimits
    warnings: tuple[str, ...]
    every_start_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    every_end_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    every_motion: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    every_used: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=bool))

    def __len__(self) -> int:
        return len(self.start_s)

    @property
    def segments(self) -> int:
        """Number of map segments (jumps + 1)."""
        return self.counts.jump + 1

    def fast_changes_problem(self) -> str | None:
        """Why these intervals cannot calibrate when the SLAM value changes faster than a SLAM
        updates (the median interval below :data:`FAST_CHANGES_S`) and most intervals are
        therefore too short to use; None otherwise."""
        dt = np.asarray(self.every_end_s) - np.asarray(self.every_start_s)
        return _fast_changes(self.counts, dt, self.limits)

    def summary(self) -> str:
        """One line: updates, intervals used and dropped by reason."""
        c = self.counts
        return (
            f"{c.updates} SLAM updates in {c.messages} messages ({c.unchanged} unchanged), "
            f"{c.intervals} intervals: {c.used} used, {c.jump} jumps, {c.too_long} too long, "
            f"{c.too_short} too short; {self.segments} segment(s)"
        )


def _vector(a: ArrayLike, name: str, m: int | None) -> np.ndarray:
    v = np.asarray(a, dtype=float)
    if v.ndim != 1 or (m is not None and len(v) != m):
        want = f"({m},)" if m is not None else "(m,)"
        raise ModelError(f"{name} must have shape {want}, got {v.shape}")
    if not np.all(np.isfinite(v)):
        raise InputError(f"{name}: value {int(np.flatnonzero(~np.isfinite(v))[0])} is not finite")
    return v


def _poses(a: ArrayLike | None, name: str, m: int) -> np.ndarray | None:
    if a is None:
        return None
    p = np.asarray(a, dtype=float)
    if p.shape != (m, 3):
        raise ModelError(f"{name} must have shape ({m}, 3) (x_m, y_m, yaw_rad), got {p.shape}")
    bad = ~np.all(np.isfinite(p), axis=1)
    if np.any(bad):
        raise InputError(f"{name}: pose {int(np.flatnonzero(bad)[0])} is not finite")
    return p


def _unwrapped(p: np.ndarray) -> np.ndarray:
    return np.column_stack([p[:, :2], np.unwrap(p[:, 2])])


def slam_relative_motions(
    stamp_s: ArrayLike,
    wheel_angle_right_rad: ArrayLike,
    wheel_angle_left_rad: ArrayLike,
    *,
    correction_pose: ArrayLike | None = None,
    odometry_pose: ArrayLike | None = None,
    truth_pose: ArrayLike | None = None,
    limits: SlamLimits | None = None,
    first_is_update: bool | None = None,
    wheel_time_odometry_pose: ArrayLike | None = None,
) -> SlamMotions:
    """Relative motions between consecutive SLAM update instants (module docstring).

    Parameters
    ----------
    stamp_s : ndarray, shape (m,)
        Header stamp of every message of the SLAM edge (s; the scan time: see the module
        docstring), repeats included. Sorted here if needed.
    wheel_angle_right_rad, wheel_angle_left_rad : ndarray, shape (m,)
        Cumulative wheel angles (rad) interpolated at ``stamp_s``.
    correction_pose : ndarray, shape (m, 3), optional
        Correction mode: the value (x_m, y_m, yaw_rad) of every ``map -> odom`` message. Give
        with it either ``odometry_pose`` (``odom -> base_link`` at ``stamp_s``) or
        ``truth_pose`` (the composed ``map -> base_link`` at ``stamp_s`` with that message's
        correction), not both.
    truth_pose : ndarray, shape (m, 3), optional
        Direct mode (no ``correction_pose``): the SLAM's ``map -> base_link`` messages.
    odometry_pose : ndarray, shape (m, 3), optional
        The robot's own ``odom -> base_link`` pose at ``stamp_s``; in direct mode optional, but
        without it jumps cannot be detected.
    limits : SlamLimits, optional
        Thresholds (defaults explained there).
    first_is_update : bool, optional
        Whether the first message is an update instant. Default: yes unless the value is repeated
        while the odometry moves (without odometry: repeated at all), which shows a publisher
        that republishes its last value; its first message was sent at an unknown time.
    wheel_time_odometry_pose : ndarray, shape (m, 3), optional
        When the SLAM's clock is offset from the wheels' (:mod:`odocal.calibration.time_offset`):
        the odometry at the wheel-clock instant of each stamp (``stamp - offset``), for the jump
        test and the distance and rotation of each interval; ``wheel_angle_*`` must then be
        taken at those instants too. The truth is still composed at the stamps (a SLAM looks the
        odometry up at its own stamp, so the composed pose there is the pose at its scan).

    Raises
    ------
    ModelError
        Wrong shapes or combination of poses.
    InputError
        Non-finite values.
    CalibrationError
        Fewer than ``limits.min_intervals`` usable intervals (the message gives the counts).
    """
    lim = limits if limits is not None else SlamLimits()
    p = _prepared(
        stamp_s,
        wheel_angle_right_rad,
        wheel_angle_left_rad,
        correction_pose,
        odometry_pose,
        truth_pose,
    )
    u = _update_instants(p, lim, first_is_update)
    wheel_odo = _poses(wheel_time_odometry_pose, "wheel_time_odometry_pose", p.m)
    if wheel_odo is not None:
        wheel_odo = _unwrapped(wheel_odo[np.argsort(np.asarray(stamp_s, float), kind="stable")])
    iv = _intervals(p, u.idx, wheel_odo)
    reason = _gate(iv, lim)
    used = reason == ""
    segment = np.cumsum(reason == "jump")  # for a used interval: the jumps before it
    n_by = {r: int((reason == r).sum()) for r in REASONS}
    counts = IntervalCounts(
        messages=p.m,
        unchanged=u.unchanged,
        first_unknown=int(p.m > 0 and not u.first),
        superseded=u.superseded,
        updates=len(u.idx),
        intervals=len(iv.a),
        used=int(used.sum()),
        **n_by,
    )
    dropped = tuple(
        DroppedInterval(
            float(p.t[iv.a[k]]),
            float(p.t[iv.b[k]]),
            str(reason[k]),
            None
            if iv.disc is None
            else (float(iv.disc[k, 0]), float(iv.disc[k, 1]), float(iv.disc[k, 2])),
        )
        for k in np.flatnonzero(~used)
    )
    warnings = u.warnings + iv.warnings + _interval_warnings(counts, dropped, iv.dt, lim)

    def pick(x: np.ndarray | None) -> np.ndarray | None:
        return None if x is None else _readonly(np.array(x[used], dtype=float))

    return SlamMotions(
        mode=p.mode,
        start_s=_readonly(np.array(p.t[iv.a][used], dtype=float)),
        end_s=_readonly(np.array(p.t[iv.b][used], dtype=float)),
        phi_right_rad=_readonly(np.array((p.phi_r[iv.b] - p.phi_r[iv.a])[used], dtype=float)),
        phi_left_rad=_readonly(np.array((p.phi_l[iv.b] - p.phi_l[iv.a])[used], dtype=float)),
        sensor_motion=_readonly(np.array(iv.true_motion[used], dtype=float)),
        odometry_motion=pick(iv.odo_motion),
        discrepancy=pick(iv.disc),
        segment=_readonly(np.asarray(segment[used], dtype=int)),
        counts=counts,
        dropped=dropped,
        limits=lim,
        warnings=tuple(warnings),
        every_start_s=_readonly(np.array(p.t[iv.a], dtype=float)),
        every_end_s=_readonly(np.array(p.t[iv.b], dtype=float)),
        every_motion=_readonly(np.array(iv.true_motion, dtype=float)),
        every_used=_readonly(np.array(used, dtype=bool)),
    )


@dataclass(frozen=True)
class _Prepared:
    """The checked inputs, sorted by stamp, headings unwrapped: ``truth`` the composed (or
    direct) SLAM pose, ``odo`` the odometry (None in direct mode without it), ``source`` the
    poses whose changes are the update instants."""

    mode: str
    t: np.ndarray
    phi_r: np.ndarray
    phi_l: np.ndarray
    truth: np.ndarray
    odo: np.ndarray | None
    source: np.ndarray
    correction: bool

    @property
    def m(self) -> int:
        return len(self.t)


def _prepared(
    stamp_s: Any,
    wheel_angle_right_rad: Any,
    wheel_angle_left_rad: Any,
    correction_pose: Any,
    odometry_pose: Any,
    truth_pose: Any,
) -> _Prepared:
    """The inputs checked (shapes, finite values, the combination of poses) and sorted."""
    t = _vector(stamp_s, "stamp_s", None)
    m = len(t)
    phi_r = _vector(wheel_angle_right_rad, "wheel_angle_right_rad", m)
    phi_l = _vector(wheel_angle_left_rad, "wheel_angle_left_rad", m)
    corr = _poses(correction_pose, "correction_pose", m)
    odo = _poses(odometry_pose, "odometry_pose", m)
    truth = _poses(truth_pose, "truth_pose", m)
    if corr is not None:
        mode = "correction"
        if (odo is None) == (truth is None):
            raise ModelError(
                "correction mode needs exactly one of odometry_pose (odom -> base_link) and "
                "truth_pose (map -> base_link) at the message stamps"
            )
    else:
        mode = "direct"
        if truth is None:
            raise ModelError("give correction_pose (map -> odom) or truth_pose (map -> base_link)")
    order = np.argsort(t, kind="stable")
    t, phi_r, phi_l = t[order], phi_r[order], phi_l[order]
    corr, odo, truth = (None if x is None else x[order] for x in (corr, odo, truth))
    if corr is not None:
        corr = _unwrapped(corr)
        if odo is None:
            assert truth is not None  # checked above: exactly one of odometry and truth
            odo = se2_compose(se2_inverse(corr), truth)
        odo = _unwrapped(odo)
        truth = se2_compose(corr, odo)  # yaw = unwrapped correction + unwrapped odometry
        source = corr
    else:
        assert truth is not None  # checked above: direct mode needs the truth
        truth = _unwrapped(truth)
        odo = None if odo is None else _unwrapped(odo)
        source = truth
    return _Prepared(mode, t, phi_r, phi_l, truth, odo, source, corr is not None)


@dataclass(frozen=True)
class _Updates:
    """The update instants (indices into the sorted messages) and how they were found."""

    idx: np.ndarray
    unchanged: int
    superseded: int
    first: bool
    warnings: list[str]


def _update_instants(p: _Prepared, lim: SlamLimits, first_is_update: bool | None) -> _Updates:
    """Step 1 of the module docstring: the messages that change the value."""
    t, m, odo = p.t, p.m, p.odo
    if m >= 2:
        step = se2_relative(p.source[:-1], p.source[1:])
        changed = (np.hypot(step[:, 0], step[:, 1]) > lim.unchanged_translation_m) | (
            np.abs(step[:, 2]) > lim.unchanged_rotation_rad
        )
    else:
        changed = np.zeros(0, dtype=bool)
    unchanged = int((~changed).sum())
    # A publisher that repeats its value while the robot moves (a republishing timer) sent the
    # first message at an unknown time after the update that computed it. Repeats while the
    # robot stands still prove nothing: a SLAM that matched the same pose gives the same value.
    repeats = ~changed
    if odo is not None and m >= 2:
        moved = se2_relative(odo[:-1], odo[1:])
        repeats &= (np.hypot(moved[:, 0], moved[:, 1]) > lim.unchanged_translation_m) | (
            np.abs(moved[:, 2]) > lim.unchanged_rotation_rad
        )
    republished = bool(np.any(repeats))
    first = not republished if first_is_update is None else bool(first_is_update)
    idx = np.flatnonzero(np.r_[first, changed]) if m else np.zeros(0, dtype=int)
    # several updates with one stamp: the last value is the SLAM's final word for that scan
    same = np.r_[t[idx][1:] == t[idx][:-1], False] if len(idx) else np.zeros(0, dtype=bool)
    superseded = int(same.sum())
    idx = idx[~same]
    warnings: list[str] = []
    if m and not first:
        why = (
            "the SLAM value is repeated while the robot moves (republished between updates), so "
            if first_is_update is None
            else ""
        )
        warnings.append(
            f"{why}the first message (sent at an unknown time after its update) is not taken as "
            "an update instant"
        )
    if len(idx) < 2:
        raise CalibrationError(
            f"{len(idx)} SLAM update instant(s) in {m} messages of the "
            f"{'correction' if p.correction else 'pose'} ({unchanged} repeat the previous "
            "value): no interval between two updates; was the SLAM running and the robot moving?"
        )
    return _Updates(idx, unchanged, superseded, first, warnings)


@dataclass(frozen=True)
class _Intervals:
    """Step 2 of the module docstring: the intervals between consecutive update instants."""

    a: np.ndarray
    b: np.ndarray
    dt: np.ndarray
    true_motion: np.ndarray
    odo_motion: np.ndarray | None
    disc: np.ndarray | None
    dist: np.ndarray
    rot: np.ndarray
    warnings: list[str]


def _intervals(p: _Prepared, idx: np.ndarray, wheel_odo: np.ndarray | None) -> _Intervals:
    """The true and odometric motion over each interval, their discrepancy, and the distance
    and rotation along the path (the odometry at the wheel-clock instants where given)."""
    a, b = idx[:-1], idx[1:]
    dt = p.t[b] - p.t[a]
    true_motion = se2_relative(p.truth[a], p.truth[b], wrap=False)
    odo_motion: np.ndarray | None
    disc: np.ndarray | None
    warnings = []
    odo = wheel_odo if wheel_odo is not None else p.odo
    if odo is not None:
        odo_motion = se2_relative(odo[a], odo[b], wrap=False)
        disc = se2_relative(odo_motion, true_motion)
    else:
        odo_motion = disc = None
        warnings.append(
            "no odometry poses: jumps of the SLAM pose (loop closures, relocalisations) cannot be "
            "detected and would enter the fit"
        )
    # how far the robot went and how much it turned: along the odometry (else the SLAM pose) at
    # every message, so that a curved or back-and-forth interval counts its whole path
    path = odo if odo is not None else p.truth
    if p.m >= 2:
        steps = se2_relative(path[:-1], path[1:], wrap=False)
        cum_dist = np.r_[0.0, np.cumsum(np.hypot(steps[:, 0], steps[:, 1]))]
        cum_rot = np.r_[0.0, np.cumsum(np.abs(steps[:, 2]))]
    else:
        cum_dist = cum_rot = np.zeros(p.m)
    dist = cum_dist[b] - cum_dist[a]
    rot = cum_rot[b] - cum_rot[a]
    return _Intervals(a, b, dt, true_motion, odo_motion, disc, dist, rot, warnings)


def _gate(iv: _Intervals, lim: SlamLimits) -> np.ndarray:
    """Steps 3 and 4 of the module docstring, in order of precedence: the reason each interval
    is dropped ('' for a used one)."""
    reason = np.full(len(iv.a), "", dtype=object)
    disc = iv.disc
    if disc is not None:
        jump = (
            np.hypot(disc[:, 0], disc[:, 1]) > lim.jump_translation_m + lim.jump_fraction * iv.dist
        ) | (np.abs(disc[:, 2]) > lim.jump_rotation_rad + lim.jump_fraction * iv.rot)
        reason[jump] = "jump"
    reason[(reason == "") & (iv.dt > lim.max_interval_s)] = "too_long"
    short = (iv.dist < lim.min_travel_m) & (iv.rot < lim.min_rotation_rad)
    reason[(reason == "") & short] = "too_short"
    return reason


def _fast_changes(counts: IntervalCounts, dt: np.ndarray, lim: SlamLimits) -> str | None:
    """The real cause of too few usable intervals when the SLAM value changes faster than a SLAM
    updates and most intervals between its changes are too short (see
    :meth:`SlamMotions.fast_changes_problem`); None otherwise."""
    if not len(dt) or float(np.median(dt)) >= FAST_CHANGES_S or 2 * counts.too_short <= len(dt):
        return None
    return (
        f"the SLAM value changes every {float(np.median(dt)) * 1e3:.0f} ms (median), faster "
        "than a SLAM updates its pose (once per matched scan, about 1-5 Hz): "
        f"{counts.too_short} of {counts.intervals} intervals between its changes are too short "
        f"to measure the wheels (< {lim.min_travel_m:g} m and < "
        f"{math.degrees(lim.min_rotation_rad):g} deg), so the intervals are too short for the "
        "SLAM's updates; is the pose extrapolated between scans (predicted from odometry or an "
        "IMU)? Record the SLAM's own updates, stamped at scan time"
    )


def _interval_warnings(
    counts: IntervalCounts,
    dropped: tuple[DroppedInterval, ...],
    dt: np.ndarray,
    lim: SlamLimits,
) -> list[str]:
    """Jumps, a SLAM value that changes too often, and too few usable intervals (an error)."""
    warnings = []
    if counts.jump:
        at = ", ".join(f"{d.start_s:.2f}-{d.end_s:.2f} s" for d in dropped if d.reason == "jump")
        warnings.append(
            f"{counts.jump} jump(s) of the SLAM pose (loop closure or relocalisation) at {at}: "
            f"those intervals are dropped, the run is split into {counts.jump + 1} segments"
        )
    period = float(np.median(dt))
    if period < FAST_CHANGES_S:
        warnings.append(
            f"the SLAM value changes every {period * 1e3:.0f} ms (median): if it is extrapolated "
            "between scans (e.g. a pose predicted from odometry or IMU), it carries the "
            "odometry's belief; prefer a pose stamped at scan time"
        )
    if counts.used < lim.min_intervals:
        raise CalibrationError(
            f"only {counts.used} usable SLAM intervals (need {lim.min_intervals}): "
            f"{counts.updates} updates in {counts.messages} messages, {counts.intervals} "
            f"intervals, {counts.jump} jumps, {counts.too_long} too long "
            f"(> {lim.max_interval_s:g} s), {counts.too_short} too short "
            f"(< {lim.min_travel_m:g} m and < {math.degrees(lim.min_rotation_rad):g} deg); "
            + (_fast_changes(counts, dt, lim) or "record a longer drive")
        )
    if counts.used < 0.5 * counts.intervals:
        warnings.append(
            f"only {counts.used} of {counts.intervals} intervals between SLAM updates are usable"
        )
    return warnings
