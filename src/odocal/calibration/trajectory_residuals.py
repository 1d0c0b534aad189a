"""The trajectory fit's residual vector: which rows and columns mean what.

The trajectory fit (:func:`odocal.calibration.trajectory.fit_trajectory`), the log check
(:func:`odocal.calibration.identifiability.check_recordings`) and the tests read the residual
through this layout, so it is public and lives here, in one place.

Layout. For the runs j = 1 .. R in the order given, each run contributes a block of rows, and
every row has three columns (:data:`COLUMNS`)::

    (e_x (m), e_y (m), heading_weight_m * e_theta (m))     e = ground truth - odometry

- ``'pose'`` residual: one row per compared sample k of the run (:func:`pose_samples`: at most
  ``samples_per_run`` evenly spaced samples, the start left out), e the pose error at k in the
  start frame;
- ``'segment'`` residual: one row per segment [i0, i1) of ``segment_m`` of travel (travel = the
  mean absolute wheel travel, :func:`cumulative_travel`, so spot turns count), e the error of the
  relative motion over the segment in the segment's start frame (:func:`relative_poses`).

Each run's block is scaled by its weight sqrt(W_j / rows_j) (:func:`block_weight`), W_j the run's
travel in m (``run_weight='travel'``) or 1 (``'equal'``), so that its squared weight sums to W_j
however many rows it has. The vector is the blocks flattened row after row (e_x, e_y, w e_theta
of the first row, then the second ...), the runs' blocks one after the other: its length is
3 sum_j rows_j. :class:`RunResiduals` holds one run's rows (``idx``, or ``i0``/``i1``) and
weight; :func:`run_residual` is the definition of one block, :class:`TrajectoryResiduals` the
whole vector, evaluated for all runs at once and bit for bit equal to the definition.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon, dead_reckon_rows
from .fit_methods import Residual, RunWeight

__all__ = [
    "COLUMNS",
    "cumulative_travel",
    "pose_samples",
    "block_weight",
    "RunResiduals",
    "relative_poses",
    "run_residual",
    "TrajectoryResiduals",
]

#: The three columns of every residual row (the heading error is scaled to metres).
COLUMNS = ("x_m", "y_m", "heading_m")


def cumulative_travel(phi_r: np.ndarray, phi_l: np.ndarray, geometry: WheelGeometry) -> np.ndarray:
    """Cumulative mean absolute wheel travel (m) at every sample, shape (K,): spins count too."""
    step = 0.25 * (
        np.abs(np.diff(phi_r)) * geometry.diameter_right_m
        + np.abs(np.diff(phi_l)) * geometry.diameter_left_m
    )
    return np.concatenate([[0.0], np.cumsum(step)])


def pose_samples(n: int, samples: int) -> np.ndarray:
    """Indices of the (at most ``samples``) evenly spaced samples of a run of ``n`` samples that
    the 'pose' residual compares (the start, 0 = 0, is left out)."""
    return np.unique(np.linspace(1, n - 1, min(samples, n - 1)).round().astype(int))


def block_weight(travel_m: float, count: int, run_weight: RunWeight) -> float:
    """Scale of a run's residual rows: total weight 1 ('equal') or its travel in m ('travel'),
    however many rows it has."""
    total = 1.0 if run_weight == "equal" else max(travel_m, 1e-9)
    return float(np.sqrt(total / count))


def _segment_marks(travel: np.ndarray, segment_m: float, n: int) -> np.ndarray:
    """Sample indices where the segments of ``segment_m`` of travel start (and the last ends)."""
    if travel[-1] > 10 * n * segment_m:  # (not travel / segment_m: it overflows at 5e-324)
        # segments shorter than the samples: every sample that moved starts one (what the
        # grid below gives in that limit, without a grid of billions of points)
        marks = np.r_[0, np.flatnonzero(np.diff(travel) > 0) + 1]
    else:
        marks = np.searchsorted(travel, np.arange(0.0, travel[-1], segment_m))
    marks = np.unique(np.append(marks, n - 1))
    if len(marks) < 2:
        marks = np.array([0, n - 1])
    return marks


class RunResiduals:
    """One run's rows of the residual (module docstring), pre-computed for fast evaluation.

    Attributes: ``name``; ``phi_r``, ``phi_l`` (rad, shape (K,)) and ``gt`` (shape (K, 3)) of
    the run; ``travel_m`` (m, measured with ``start``); 'pose': ``idx`` (the compared samples);
    'segment': ``i0``, ``i1`` (each segment's first and last sample) and ``gt_rel`` (the true
    relative motions, shape (segments, 3)); ``weight`` (the block's scale)."""

    idx: np.ndarray
    i0: np.ndarray
    i1: np.ndarray
    gt_rel: np.ndarray

    def __init__(
        self,
        rec: Any,
        kind: Residual,
        samples: int,
        segment_m: float,
        start: WheelGeometry,
        run_weight: RunWeight = "travel",
    ) -> None:
        self.name = rec.name
        self.phi_r = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        self.phi_l = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        self.gt = np.asarray(rec.ground_truth, dtype=float)
        n = len(self.gt)
        travel = cumulative_travel(self.phi_r, self.phi_l, start)
        self.travel_m = float(travel[-1])
        if kind == "pose":
            self.idx = pose_samples(n, samples)
            count = len(self.idx)
        else:
            marks = _segment_marks(travel, segment_m, n)
            self.i0, self.i1 = marks[:-1], marks[1:]
            self.gt_rel = relative_poses(self.gt, self.i0, self.i1)
            count = len(self.i0)
        self.weight = block_weight(self.travel_m, count, run_weight)


def relative_poses(P: np.ndarray, i0: np.ndarray, i1: np.ndarray) -> np.ndarray:
    """The motion from pose ``P[i0]`` to ``P[i1]`` in the frame of ``P[i0]``, shape (n, 3)
    (dx_m, dy_m, dtheta_rad; dtheta not wrapped)."""
    d = P[i1, :2] - P[i0, :2]
    c, s = np.cos(P[i0, 2]), np.sin(P[i0, 2])
    return np.column_stack(
        [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], P[i1, 2] - P[i0, 2]]
    )


def run_residual(run: RunResiduals, p: Any, kind: Residual, w_head: float) -> np.ndarray:
    """One run's (unweighted) residual at geometry ``p`` = (D_R, D_L, b): the definition that
    :class:`TrajectoryResiduals` evaluates for many runs at once."""
    odo = dead_reckon(run.phi_r, run.phi_l, WheelGeometry.unchecked(*p))
    if kind == "pose":
        e = run.gt[run.idx] - odo[run.idx]
    else:
        e = run.gt_rel - relative_poses(odo, run.i0, run.i1)
    e = e.copy()
    e[:, 2] *= w_head
    return e.ravel()


# Blocks of runs dead-reckoned at once: at most this share of zero padding (extra work) and
# this many increments (temporaries of 128 KiB that stay in the cache; larger blocks are slower)
MAX_PADDING = 0.1
MAX_BLOCK = 2**14


class TrajectoryResiduals:
    """The residual of ``runs`` at a geometry, bit for bit ``np.concatenate([r.weight *
    run_residual(r, p, kind, w_head) for r in runs])`` (``weighted=False``: without r.weight).

    The runs are sorted by length and packed into blocks of similar length, each dead-reckoned
    at once by :func:`~odocal.core.odometry.dead_reckon_rows` (the operations of
    ``dead_reckon`` on every element); the compared samples are gathered per block and put back
    in the runs' order with one precomputed permutation.
    """

    def __init__(
        self, runs: Sequence[RunResiduals], kind: Residual, w_head: float, weighted: bool = True
    ) -> None:
        self.kind, self.w_head = kind, w_head
        if kind == "pose":
            samples = [r.idx for r in runs]
            truth = [r.gt[r.idx] for r in runs]
        else:  # the starts, then the ends of a run's segments
            samples = [np.concatenate([r.i0, r.i1]) for r in runs]
            truth = [r.gt_rel for r in runs]
        self.truth = np.concatenate(truth)
        counts = [len(t) for t in truth]
        self.splits = 3 * np.cumsum(counts)[:-1]  # where each run's part of the residual starts
        self.weight = np.repeat([r.weight if weighted else 1.0 for r in runs], counts)[:, None]
        # where every run's samples go in self.poses
        sizes = [len(t) for t in samples]
        where = np.split(np.arange(sum(sizes)), np.cumsum(sizes)[:-1])
        if kind == "segment":
            self.i0 = np.concatenate([w[:n] for w, n in zip(where, counts, strict=True)])
            self.i1 = np.concatenate([w[n:] for w, n in zip(where, counts, strict=True)])
        self.blocks, gathered = _pack(runs, samples, where)
        gathered_at = np.concatenate(gathered)
        self.order = np.empty_like(gathered_at)
        self.order[gathered_at] = np.arange(len(gathered_at))

    def poses(self, p: Any) -> np.ndarray:
        """Dead-reckoned poses at the compared samples, shape (samples, 3), in the runs' order."""
        g = WheelGeometry.unchecked(*p)
        parts = [dead_reckon_rows(ri, li, g).reshape(3, -1)[:, k] for ri, li, k in self.blocks]
        return np.concatenate(parts, axis=1)[:, self.order].T

    def __call__(self, p: Any) -> np.ndarray:
        """The residual at ``p`` = (D_R, D_L, b) (m), flat, the runs' parts one after the other
        (heading times ``w_head``, each run's part scaled by its weight when ``weighted``)."""
        odo = self.poses(p)
        if self.kind == "pose":
            e = self.truth - odo
        else:
            e = self.truth - relative_poses(odo, self.i0, self.i1)
        e[:, 2] *= self.w_head
        return (self.weight * e).ravel()

    def per_run(self, residual: np.ndarray) -> list[np.ndarray]:
        """A residual of __call__ cut into the runs' parts."""
        return np.split(residual, self.splits)


def _pack(
    runs: Sequence[RunResiduals], samples: list[np.ndarray], where: list[np.ndarray]
) -> tuple[list[tuple[np.ndarray, np.ndarray, np.ndarray]], list[np.ndarray]]:
    """The runs packed into blocks of similar length (longest first): per block the zero-padded
    increments (right, left; shape (runs, width)) and the flat indices of the compared samples
    in its poses; and where each block's samples go in the runs' order."""
    lengths = [len(r.phi_r) - 1 for r in runs]
    by_length = sorted(range(len(runs)), key=lambda j: -lengths[j])
    blocks = []
    gathered: list[np.ndarray] = []
    while by_length:
        width = lengths[by_length[0]]
        n, work = 1, width
        while (
            n < len(by_length)
            and (n + 1) * width <= MAX_BLOCK
            and (n + 1) * width <= (1 + MAX_PADDING) * (work + lengths[by_length[n]])
        ):
            work += lengths[by_length[n]]
            n += 1
        block, by_length = by_length[:n], by_length[n:]
        inc_r = np.zeros((n, width))
        inc_l = np.zeros((n, width))
        for i, j in enumerate(block):
            inc_r[i, : lengths[j]] = np.diff(runs[j].phi_r)
            inc_l[i, : lengths[j]] = np.diff(runs[j].phi_l)
        flat = np.concatenate([i * (width + 1) + samples[j] for i, j in enumerate(block)])
        blocks.append((inc_r, inc_l, flat))
        gathered += [where[j] for j in block]
    return blocks, gathered
