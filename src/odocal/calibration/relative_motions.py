"""Relative motions over intervals, the input of the relative-motion calibration
(:func:`odocal.calibration.censi.fit_censi`), whatever measured them: ``.tuple`` files, a SLAM
pose between its updates (:mod:`odocal.calibration.slam`) or scan matching
(:mod:`odocal.calibration.scan_matching`).

Each interval has the wheel rotations over it and the sensor's motion over it; a source that
knows the wheel angles within the interval also gives the increments of every wheel sample (the
fit then integrates the odometry over them instead of assuming one arc). Several sources (bags,
files) are stacked into one fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

__all__ = [
    "RelativeMotions",
    "wheel_increments",
    "stack_increments",
    "stack_motions",
    "overlapping_sources",
]


@dataclass(frozen=True)
class RelativeMotions:
    """The intervals of one source.

    Attributes
    ----------
    phi_right_rad, phi_left_rad : ndarray, shape (n,)
        Wheel rotation over each interval (rad, forward positive).
    sensor_motion : ndarray, shape (n, 3)
        The sensor's motion over each interval in its frame at the interval's start
        (dx_m, dy_m, dtheta_rad).
    increments : (ndarray, ndarray) or None
        Right and left wheel increments within each interval, each shape (n, K), rows zero
        padded (:func:`wheel_increments`); None when the source has only the totals.
    start_s, end_s : ndarray, shape (n,), or None
        Each interval's bounds on the wheels' clock (s), where known (bags): for the time
        blocks of the uncertainty and the held-out check.
    """

    phi_right_rad: np.ndarray
    phi_left_rad: np.ndarray
    sensor_motion: np.ndarray
    increments: tuple[np.ndarray, np.ndarray] | None = None
    start_s: np.ndarray | None = None
    end_s: np.ndarray | None = None


def wheel_increments(
    t: np.ndarray, right: np.ndarray, left: np.ndarray, start_s: np.ndarray, end_s: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The wheel rotations of each interval [start_s, end_s] as sampled: the differences of the
    wheel angles (rad; ``right``, ``left`` at times ``t``, s, increasing) at the interval's ends
    and at every wheel sample between them. Two arrays of shape (n, K), rows zero padded; each
    row sums to the interval's rotation.

    All intervals at once: the samples strictly inside each are found by bisection, and every
    row's instants (start, the samples inside, end, then the end repeated as padding) are
    interpolated in one call; the padding's differences are set to zero."""
    t = np.asarray(t, dtype=float)
    a = np.asarray(start_s, dtype=float).reshape(-1)
    b = np.asarray(end_s, dtype=float).reshape(-1)
    if a.shape != b.shape:
        raise ValueError(f"{a.size} interval starts for {b.size} ends")
    if len(a) == 0:
        return np.zeros((0, 1)), np.zeros((0, 1))
    lo = np.searchsorted(t, a, side="right")  # the first sample after the start
    hi = np.searchsorted(t, b, side="left")  # the first sample at or after the end
    with np.errstate(invalid="ignore"):
        inside = np.where(a < b, np.maximum(hi - lo, 0), 0)  # NaN ends: nothing inside
    k = int(inside.max()) + 1  # increments of the longest row
    col = np.arange(k + 1)
    # column 0 the start, 1..inside the samples, then the end (repeated to the row's width)
    idx = np.minimum(lo[:, None] + col[None, :] - 1, len(t) - 1)
    tt = np.where(col[None, :] <= inside[:, None], t[np.maximum(idx, 0)], b[:, None])
    tt[:, 0] = a
    used = col[None, :-1] <= inside[:, None]
    out_r = np.where(used, np.diff(np.interp(tt, t, right), axis=1), 0.0)
    out_l = np.where(used, np.diff(np.interp(tt, t, left), axis=1), 0.0)
    return out_r, out_l


def stack_increments(
    parts: Sequence[tuple[np.ndarray, np.ndarray]],
) -> tuple[np.ndarray, np.ndarray]:
    """Per-interval wheel increments of several sources, (right, left), rows zero padded to one
    width."""
    k = max(r.shape[1] for r, _ in parts)

    def pad(a: np.ndarray) -> np.ndarray:
        return np.pad(a, ((0, 0), (0, k - a.shape[1])))

    return (
        np.concatenate([pad(r) for r, _ in parts]),
        np.concatenate([pad(lft) for _, lft in parts]),
    )


def stack_motions(parts: Sequence[RelativeMotions]) -> RelativeMotions:
    """The intervals of several sources as one (in order); increments only if every source has
    them."""
    increments = [p.increments for p in parts]
    timed = all(p.start_s is not None and p.end_s is not None for p in parts)
    start = end = None
    if timed:
        # one clock per source: later sources are moved after the earlier ones (a 1 s gap), so
        # that time blocks never mix two bags
        shift, starts, ends = 0.0, [], []
        for p in parts:
            a, b = np.asarray(p.start_s, float), np.asarray(p.end_s, float)
            off = shift - float(a.min()) if len(a) else shift
            starts.append(a + off)
            ends.append(b + off)
            shift = float(ends[-1].max()) + 1.0 if len(b) else shift
        start, end = np.concatenate(starts), np.concatenate(ends)
    return RelativeMotions(
        np.concatenate([p.phi_right_rad for p in parts]),
        np.concatenate([p.phi_left_rad for p in parts]),
        np.concatenate([p.sensor_motion for p in parts]),
        None
        if any(i is None for i in increments)
        else stack_increments([i for i in increments if i is not None]),
        start,
        end,
    )


#: Sensor motions (m, rad) equal to this are one measurement: a copy's, or the same SLAM update
#: read from a log and from its half. Two recordings that merely share a clock (a simulator's
#: time restarting at zero, a robot without a clock that starts at the same date at every boot)
#: never share many motions.
SAME_MOTION = 1e-7


def overlapping_sources(
    motions: Sequence[RelativeMotions], origins_s: Sequence[float] | None = None
) -> tuple[int, int, float, float] | None:
    """The first two sources (indices i < j) that are one recording given twice, with the time
    they share (s, from, to, on the common clock), or None: their intervals overlap in time and
    at least half of the moving intervals of that time in the one with fewer have the same
    sensor motion in the other (to :data:`SAME_MOTION`); counted twice, its intervals would
    make the standard errors too small. Each source's intervals are on its wheel clock from its
    own origin, ``origins_s[k]`` (s since the epoch; default 0: one clock). Sources without
    times are not compared."""
    origin = list(origins_s) if origins_s is not None else [0.0] * len(motions)
    spans = [
        (k, origin[k] + float(np.min(m.start_s)), origin[k] + float(np.max(m.end_s)))
        for k, m in enumerate(motions)
        if m.start_s is not None and m.end_s is not None and len(m.start_s)
    ]
    for a, (i, lo_i, hi_i) in enumerate(spans):
        for j, lo_j, hi_j in spans[a + 1 :]:
            lo, hi = max(lo_i, lo_j), min(hi_i, hi_j)
            if lo < hi:
                mine = _moving_motions(motions[i], origin[i], lo, hi)
                theirs = _moving_motions(motions[j], origin[j], lo, hi)
                fewer = min(len(mine), len(theirs))
                if fewer and len(mine & theirs) >= 0.5 * fewer:
                    return i, j, lo, hi
    return None


def _moving_motions(m: RelativeMotions, origin_s: float, lo: float, hi: float) -> set[tuple]:
    """The sensor motions (in steps of :data:`SAME_MOTION`) of ``m``'s intervals within
    [``lo``, ``hi``] (on the common clock) that move by more than a hundred steps (finite
    ones)."""
    assert m.start_s is not None and m.end_s is not None
    s = np.asarray(m.sensor_motion, dtype=float)
    inside = (origin_s + m.start_s >= lo) & (origin_s + m.end_s <= hi)
    with np.errstate(invalid="ignore"):
        moving = inside & np.isfinite(s).all(axis=1) & (np.abs(s).max(axis=1) > 100 * SAME_MOTION)
    return {tuple(k) for k in np.round(s[moving] / SAME_MOTION).astype(np.int64).tolist()}
