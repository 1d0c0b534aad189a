"""Odometry drift per distance driven, KITTI style: the relative error over pieces of the path.

(Not :mod:`odocal.calibration.drift`, which is a fleet's parameter drift over time.)

The truth's path is cut into pieces of a fixed length of TRUTH path (10 m outdoors, 1 m for a
small indoor run), and for each piece the estimate is re-anchored to the truth at the piece's
start (an SE(2) alignment of that one pose, no scale): the piece's error is the distance between
where the estimate and the truth say the robot went over the piece, both seen from their own
start pose,

    e = | R(theta_est_i)^T (p_est_j - p_est_i) - R(theta_true_i)^T (p_true_j - p_true_i) |,

reported as a percentage of the piece's truth path length (median and mean over the pieces, and
how many), with the heading error over the piece, (theta_est_j - theta_est_i) - (theta_true_j -
theta_true_i), as degrees per 10 m. ``e`` is also the norm of the translation of the relative pose
error E = (Q_i^-1 Q_j)^-1 (P_i^-1 P_j) of Geiger et al.'s KITTI benchmark and of evo's RPE
(``translation_part``): the rotation of E does not change the norm.

Path length is the sum of the truth's position steps between consecutive samples (as evo's
``accumulated_distances``); a truth whose positions jitter by sigma between samples lengthens it.

Two ways to choose the pieces (``mode``):

- ``"consecutive"``: pieces that follow each other: the first starts at sample 0, each ends at
  the first sample at which the truth path since its start reaches ``length_m``, and the next
  starts there. This is evo's ``filter_pairs_by_path`` without ``all_pairs`` (evo 1.38; an
  older one started at the first piece's end) applied to the reference: ``evo_rpe ... --delta L
  --delta_unit m --pairs_from_reference``.
- ``"all-pairs"``: a piece starts at every sample i; it ends at the sample j > i whose path
  distance from i is nearest ``length_m`` (the first of equals), kept only when that distance is
  within ``tolerance x length_m`` of ``length_m``: evo's ``--all_pairs`` with its default
  ``--delta_tol 0.1``, again with ``--pairs_from_reference`` (without that flag evo measures
  the path along the ESTIMATE, so a model that under-reports distance gets longer pieces).

evo reports the errors in metres; this module's percentages divide each by its piece's truth
path length, which in consecutive mode exceeds ``length_m`` by at most one sample's step, and in
all-pairs mode may differ from it by up to the tolerance (``error_m`` holds evo's numbers).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError

__all__ = [
    "DriftMode",
    "DRIFT_MODES",
    "PathDrift",
    "path_drift",
    "path_length",
    "piece_length_for",
    "pool_drift",
    "LONG_RUN_M",
]

DriftMode = Literal["consecutive", "all-pairs"]
DRIFT_MODES: tuple[DriftMode, ...] = ("consecutive", "all-pairs")


@dataclass(frozen=True)
class PathDrift:
    """The relative error of an estimate over pieces of the truth's path (module docstring).

    Attributes
    ----------
    length_m : float
        The piece length asked for (m).
    mode : str
        'consecutive' or 'all-pairs'.
    start, end : ndarray of int, shape (n,)
        Sample indices of each piece's start and end.
    piece_length_m : ndarray, shape (n,)
        Each piece's truth path length (m).
    error_m : ndarray, shape (n,)
        End-point position error of each piece, the estimate re-anchored at its start (m).
    heading_error_rad : ndarray, shape (n,)
        Heading error over each piece, estimate minus truth (rad, signed).
    """

    length_m: float
    mode: str
    start: np.ndarray
    end: np.ndarray
    piece_length_m: np.ndarray
    error_m: np.ndarray
    heading_error_rad: np.ndarray

    @property
    def pieces(self) -> int:
        """Number of pieces."""
        return len(self.start)

    @property
    def error_pct(self) -> np.ndarray:
        """Each piece's end-point error as a percentage of its truth path length."""
        return 100.0 * self.error_m / self.piece_length_m

    @property
    def median_pct(self) -> float:
        """Median of :attr:`error_pct` (NaN without pieces)."""
        return float(np.median(self.error_pct)) if self.pieces else math.nan

    @property
    def mean_pct(self) -> float:
        """Mean of :attr:`error_pct` (NaN without pieces)."""
        return float(np.mean(self.error_pct)) if self.pieces else math.nan

    @property
    def heading_deg_per_10m(self) -> np.ndarray:
        """Each piece's |heading error| in degrees per 10 m of its truth path."""
        return np.degrees(np.abs(self.heading_error_rad)) * 10.0 / self.piece_length_m

    @property
    def median_heading_deg_per_10m(self) -> float:
        """Median of :attr:`heading_deg_per_10m` (NaN without pieces)."""
        return float(np.median(self.heading_deg_per_10m)) if self.pieces else math.nan

    def contract(self) -> dict:
        """The JSON contract's ``drift_percent_per_10m`` object: ``median`` and ``mean`` (% of
        the piece length), ``pieces``, the piece length (m) and the heading drift (deg per
        10 m)."""
        return {
            "median": self.median_pct,
            "mean": self.mean_pct,
            "pieces": self.pieces,
            "piece_length_m": self.length_m,
            "heading_deg_per_10m": self.median_heading_deg_per_10m,
        }

    def as_dict(self) -> dict:
        """JSON-ready summary."""
        return {
            "length_m": self.length_m,
            "mode": self.mode,
            "pieces": self.pieces,
            "median_pct": self.median_pct,
            "mean_pct": self.mean_pct,
            "median_heading_deg_per_10m": self.median_heading_deg_per_10m,
        }


#: Runs with at least this much truth path are cut into 10 m pieces, shorter ones into 1 m.
LONG_RUN_M = 20.0


def piece_length_for(path_lengths_m: Sequence[float]) -> float:
    """The piece length (m) for runs of these truth path lengths: 10 m when every run has
    :data:`LONG_RUN_M` or more (a robot outdoors), else 1 m (small indoor runs)."""
    return 10.0 if path_lengths_m and min(path_lengths_m) >= LONG_RUN_M else 1.0


def pool_drift(parts: Sequence[PathDrift]) -> PathDrift | None:
    """One PathDrift of the pieces of several runs (their indices per run); None without any
    piece."""
    parts = [d for d in parts if d.pieces]
    if not parts:
        return None
    first = parts[0]
    return PathDrift(
        first.length_m, first.mode,
        np.concatenate([d.start for d in parts]), np.concatenate([d.end for d in parts]),
        np.concatenate([d.piece_length_m for d in parts]),
        np.concatenate([d.error_m for d in parts]),
        np.concatenate([d.heading_error_rad for d in parts]),
    )  # fmt: skip


def _poses(p: ArrayLike, name: str) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.ndim != 2 or a.shape[1] != 3:
        raise ModelError(f"{name} must have shape (n, 3) (x_m, y_m, theta_rad), got {a.shape}")
    if not np.all(np.isfinite(a)):
        raise ModelError(f"{name} must be finite")
    return a


def path_length(positions: ArrayLike) -> np.ndarray:
    """Cumulative path length (m) along positions of shape (n, 2) or (n, 3), from 0: shape (n,)."""
    p = np.asarray(positions, dtype=float)
    steps = np.linalg.norm(np.diff(p[:, :2], axis=0), axis=1)
    return np.concatenate([[0.0], np.cumsum(steps)])


def _consecutive(dist: np.ndarray, length: float) -> tuple[np.ndarray, np.ndarray]:
    starts, ends = [], []
    i = 0
    n = len(dist)
    while True:
        j = int(np.searchsorted(dist, dist[i] + length, side="left"))
        # the first sample whose distance from i reaches the length (>=, as evo's running sum)
        while j < n and dist[j] - dist[i] < length:
            j += 1
        if j >= n:
            break
        starts.append(i)
        ends.append(j)
        i = j
    return np.array(starts, dtype=int), np.array(ends, dtype=int)


def _all_pairs(dist: np.ndarray, length: float, tol: float) -> tuple[np.ndarray, np.ndarray]:
    n = len(dist)
    i = np.arange(n - 1)
    target = dist[i] + length
    above = np.searchsorted(dist, target, side="left")  # first index with dist >= target
    above = np.clip(np.maximum(above, i + 1), 0, n - 1)
    below = np.maximum(above - 1, i + 1)
    # the first index holding the value below (argmin keeps the first of equal values)
    below = np.maximum(np.searchsorted(dist, dist[below], side="left"), i + 1)
    d_above = np.abs(dist[above] - dist[i] - length)
    d_below = np.abs(dist[below] - dist[i] - length)
    j = np.where(d_below <= d_above, below, above)
    err = np.minimum(d_below, d_above)
    keep = err <= tol * length
    return i[keep], j[keep]


def path_drift(
    truth: ArrayLike,
    estimate: ArrayLike,
    *,
    length_m: float = 10.0,
    mode: DriftMode = "consecutive",
    tolerance: float = 0.1,
    breaks: ArrayLike | None = None,
) -> PathDrift:
    """The drift of ``estimate`` against ``truth`` over pieces of ``length_m`` of truth path
    (module docstring).

    Parameters
    ----------
    truth, estimate : ndarray, shape (n, 3)
        Poses (x_m, y_m, theta_rad) at the same n instants, each in its own frame (only
        relative motions are compared); headings unwrapped.
    length_m : float
        Piece length (m, > 0).
    mode : {'consecutive', 'all-pairs'}
    tolerance : float
        All-pairs mode: the relative tolerance on a piece's length (evo's ``--delta_tol``).
    breaks : array of int, optional
        Sample indices where a new segment starts (after a hole in the data): no piece spans
        one; each segment is cut into pieces on its own, from its first sample.
    """
    q = _poses(truth, "truth")
    p = _poses(estimate, "estimate")
    if q.shape != p.shape:
        raise ModelError(f"truth and estimate differ in shape: {q.shape} and {p.shape}")
    if not (math.isfinite(length_m) and length_m > 0):
        raise ModelError(f"length_m must be > 0 (m), got {length_m!r}")
    if mode not in DRIFT_MODES:
        raise ModelError(f"mode must be one of {', '.join(DRIFT_MODES)}, got {mode!r}")
    if not (math.isfinite(tolerance) and tolerance >= 0):
        raise ModelError(f"tolerance must be >= 0, got {tolerance!r}")
    dist = path_length(q)
    cuts = np.unique(np.asarray(breaks if breaks is not None else [], dtype=int))
    if np.any((cuts <= 0) | (cuts >= len(q))):
        raise ModelError(f"breaks must be sample indices in 1..{len(q) - 1}, got {cuts}")
    bounds = np.concatenate([[0], cuts, [len(q)]]).astype(int)
    starts, ends = [], []
    for lo, hi in zip(bounds[:-1], bounds[1:], strict=True):
        if hi - lo < 2:
            continue
        seg = dist[lo:hi] - dist[lo]
        if mode == "consecutive":
            a, b = _consecutive(seg, float(length_m))
        else:
            a, b = _all_pairs(seg, float(length_m), float(tolerance))
        starts.append(a + lo)
        ends.append(b + lo)
    i = np.concatenate(starts).astype(int) if starts else np.zeros(0, dtype=int)
    j = np.concatenate(ends).astype(int) if ends else np.zeros(0, dtype=int)

    def rel(a: np.ndarray) -> np.ndarray:
        c, s = np.cos(a[i, 2]), np.sin(a[i, 2])
        dx, dy = a[j, 0] - a[i, 0], a[j, 1] - a[i, 1]
        return np.column_stack([c * dx + s * dy, -s * dx + c * dy, a[j, 2] - a[i, 2]])

    rq, rp = rel(q), rel(p)
    err = np.hypot(rp[:, 0] - rq[:, 0], rp[:, 1] - rq[:, 1])
    return PathDrift(float(length_m), mode, i, j, dist[j] - dist[i], err, rp[:, 2] - rq[:, 2])
