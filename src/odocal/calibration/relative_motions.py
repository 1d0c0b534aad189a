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

__all__ = ["RelativeMotions", "wheel_increments", "stack_increments", "stack_motions"]


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
    wheel angles (rad; ``right``, ``left`` at times ``t``, s) at the interval's ends and at every
    wheel sample between them. Two arrays of shape (n, K), rows zero padded; each row sums to the
    interval's rotation."""
    rows_r, rows_l = [], []
    for a, b in zip(start_s, end_s, strict=True):
        inside = t[(t > a) & (t < b)]
        tt = np.r_[a, inside, b]
        rows_r.append(np.diff(np.interp(tt, t, right)))
        rows_l.append(np.diff(np.interp(tt, t, left)))
    k = max((len(x) for x in rows_r), default=1)
    out_r, out_l = np.zeros((len(rows_r), k)), np.zeros((len(rows_r), k))
    for i, (x, y) in enumerate(zip(rows_r, rows_l, strict=True)):
        out_r[i, : len(x)], out_l[i, : len(y)] = x, y
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
