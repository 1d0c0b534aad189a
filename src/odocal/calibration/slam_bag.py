"""A SLAM pose on ``/tf`` as ground truth, from a bag already read: the relative motions between
the SLAM's update instants, on the wheels' clock (docs/slam-truth.md).

The reader (:func:`odocal.io.bag_slam.read_slam_series`) gives what the bag holds: the wheel
rotations, the correction's update stamps and the poses of the chain at them, and a lookup of
the odometry's pose at any wheel time. :func:`slam_bag` does the calibration work: the SLAM's
clock offset against the wheels (given, else estimated from the heading changes between
consecutive updates: :func:`~odocal.calibration.time_offset.resolve_offset`), the relative
motions at that offset (:func:`~odocal.calibration.slam.slam_relative_motions`), the wheel
increments within each interval and a recording whose truth is valid only at the update
instants (for validation).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import asdict, dataclass, field, replace
from typing import Any

import numpy as np

from ..core.recording import Recording, with_truth_at
from ..core.transforms import se2_compose
from .relative_motions import RelativeMotions, wheel_increments
from .slam import SlamLimits, SlamMotions, slam_relative_motions
from .time_offset import TimeOffset, estimate_time_offset, resolve_offset

__all__ = ["SlamSeries", "SlamBag", "slam_bag"]


@dataclass(frozen=True)
class SlamSeries:
    """What one bag holds for the SLAM route, as read.

    Attributes
    ----------
    path : str
    wheel_time_s, wheel_right_rad, wheel_left_rad : ndarray, shape (K,)
        The wheel rotations (s, rad; the bag's clock).
    wheel_topic : str
    wheels : str
        Where the wheel rotations came from, in words.
    wheel_warnings : tuple of str
    stamps_s : ndarray, shape (M,)
        The correction's messages within the wheels' span (its stamps' post-dating removed).
    correction_pose, odometry_pose : ndarray, shape (M, 3), or None
        The correction (parent -> its child) and the odometry below it at the stamps (the
        chain split at the correction edge); None in direct mode.
    truth_pose : ndarray, shape (M, 3), or None
        The truth pose itself at the stamps (direct mode: the chain's only moving edge).
    odometry_at : callable or None
        Wheel times (s) -> the odometry's pose there, shape (n, 3) (clipped to the span its
        edges cover): for an offset, the odometry at the wheels' clock.
    chain : str
    correction : str or None
        The correction edge in words, None in direct mode.
    meta : dict
    """

    path: str
    wheel_time_s: np.ndarray
    wheel_right_rad: np.ndarray
    wheel_left_rad: np.ndarray
    wheel_topic: str
    wheels: str
    wheel_warnings: tuple[str, ...]
    stamps_s: np.ndarray
    correction_pose: np.ndarray | None
    odometry_pose: np.ndarray | None
    truth_pose: np.ndarray | None
    odometry_at: Callable[[np.ndarray], np.ndarray] | None
    chain: str
    correction: str | None
    meta: dict = field(default_factory=dict)


@dataclass(frozen=True)
class SlamBag:
    """What one bag gives: the relative motions between SLAM updates, the wheel increments
    within each interval (right, left; shape (n, K), zero padded: the odometry is integrated
    over them, not assumed to be one arc), and a recording at the wheel rate whose ground truth
    is valid only at the update instants (for validation).

    ``chain`` describes the lookup (e.g. 'map -> odom -> base_link'); ``correction`` the edge
    whose messages are the update instants, or None in direct mode. ``time_offset`` the SLAM's
    clock against the wheels' (applied: the intervals' wheel rotations are taken at the wheel
    clock); ``every_increments`` the wheel increments of every interval between updates,
    dropped ones included (for the held-out check); ``wheels`` where the wheel rotations came
    from."""

    path: str
    motions: SlamMotions
    recording: Recording
    chain: str
    correction: str | None
    increments: tuple[np.ndarray, np.ndarray]
    meta: dict = field(default_factory=dict)
    time_offset: TimeOffset = field(default_factory=lambda: TimeOffset.given("slam", 0.0))
    every_increments: tuple[np.ndarray, np.ndarray] | None = None
    wheels: str = ""
    wheel_warnings: tuple[str, ...] = ()
    wheel_series: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None

    @property
    def relative_motions(self) -> RelativeMotions:
        """The intervals as the relative-motion calibration takes them (the truth frame is the
        base itself)."""
        m, d = self.motions, self.time_offset.applied_s
        return RelativeMotions(
            m.phi_right_rad, m.phi_left_rad, m.sensor_motion, self.increments,
            np.asarray(m.start_s) - d, np.asarray(m.end_s) - d,
        )  # fmt: skip

    @property
    def every_motions(self) -> RelativeMotions:
        """Every interval between the SLAM's updates but its jumps, on the wheels' clock: the
        held-out check's stretches (the intervals dropped as too short or as outliers carry them;
        a jump, a loop closure or a relocalisation, breaks them: the truth is not continuous
        there). Which of them are the fit's: :attr:`every_used`."""
        m, inc, d = self.motions, self.every_increments, self.time_offset.applied_s
        assert inc is not None  # the loader sets them
        keep = self._not_jumps
        return RelativeMotions(
            inc[0][keep].sum(axis=1), inc[1][keep].sum(axis=1),
            np.asarray(m.every_motion)[keep], (inc[0][keep], inc[1][keep]),
            np.asarray(m.every_start_s)[keep] - d, np.asarray(m.every_end_s)[keep] - d,
        )  # fmt: skip

    @property
    def every_used(self) -> np.ndarray:
        """Which intervals of :attr:`every_motions` the fit was given."""
        return np.asarray(self.motions.every_used, dtype=bool)[self._not_jumps]

    @property
    def _not_jumps(self) -> np.ndarray:
        """Every interval between updates that is not a jump."""
        m = self.motions
        jumps = [d.start_s for d in m.dropped if d.reason == "jump"]
        return ~np.isin(np.asarray(m.every_start_s), np.asarray(jumps, dtype=float))

    def as_dict(self) -> dict[str, Any]:
        """What ``odocal fit --truth-frames --json`` reports of this bag (its ``slam`` entry)."""
        m = self.motions
        return {
            "bag": self.path,
            "chain": self.chain,
            "correction_edge": self.correction,
            **asdict(m.counts),
            "dropped": m.counts.dropped,
            "segments": m.segments,
            "summary": m.summary(),
            "warnings": list(m.warnings),
        }


def slam_bag(
    series: SlamSeries,
    time_offset_s: float | None = None,
    limits: SlamLimits | None = None,
) -> SlamBag:
    """The SLAM relative motions of one bag read (module docstring). ``time_offset_s``: how
    late the SLAM's clock runs behind the wheels' (its pose stamped t is the robot's pose at
    wheel time t - offset); None estimates it."""
    lim = limits if limits is not None else SlamLimits()
    t_j, right, left = series.wheel_time_s, series.wheel_right_rad, series.wheel_left_rad
    stamps = series.stamps_s

    def motions_at(offset: float, gate: SlamLimits) -> SlamMotions:
        at = stamps - offset
        wr, wl = np.interp(at, t_j, right), np.interp(at, t_j, left)
        wheel_odo = None
        if offset and series.odometry_pose is not None and series.odometry_at is not None:
            wheel_odo = series.odometry_at(at)
        return slam_relative_motions(
            stamps, wr, wl, correction_pose=series.correction_pose,
            odometry_pose=series.odometry_pose, truth_pose=series.truth_pose, limits=gate,
            wheel_time_odometry_pose=wheel_odo,
        )  # fmt: skip

    def estimate() -> TimeOffset:
        # on the heading changes between every pair of consecutive update instants (dropped
        # intervals included: the estimator's robust loss deals with real jumps, and a clock
        # offset is what makes ordinary turns look like jumps)
        first = motions_at(0.0, replace(lim, min_intervals=1))
        return estimate_time_offset(
            t_j, right, left, first.every_start_s, first.every_end_s,
            first.every_motion[:, 2], source="slam",
        )  # fmt: skip

    offset = resolve_offset("slam", time_offset_s, estimate)
    motions = motions_at(offset.applied_s, lim)
    recording = _recording(
        series.path, series.wheel_topic, t_j, right, left, stamps, motions,
        series.correction_pose, series.odometry_pose, series.truth_pose, series.meta,
        offset.applied_s,
    )  # fmt: skip
    d = offset.applied_s
    increments = wheel_increments(t_j, right, left, motions.start_s - d, motions.end_s - d)
    every = wheel_increments(t_j, right, left, motions.every_start_s - d, motions.every_end_s - d)
    return SlamBag(
        series.path, motions, recording, series.chain, series.correction, increments,
        series.meta, offset, every, series.wheels, series.wheel_warnings, (t_j, right, left),
    )  # fmt: skip


def _recording(
    p: str,
    jt: str,
    t: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    stamps: np.ndarray,
    motions: SlamMotions,
    corr: np.ndarray | None,
    odo: np.ndarray | None,
    truth: np.ndarray | None,
    meta: dict,
    offset: float,
) -> Recording:
    """The wheel-rate run with the SLAM truth at the update instants used (other samples are
    not truth: ``meta['truth_samples']`` lists the valid indices), placed at their wheel-clock
    instants (``stamps - offset``)."""
    if truth is None:
        assert corr is not None and odo is not None  # correction mode: the chain split there
        truth = se2_compose(corr, odo)
    pose = np.asarray(truth, dtype=np.float64)
    # the update instants the motions used (their starts and ends)
    used_t = np.unique(np.r_[motions.start_s, motions.end_s])
    on = np.isin(stamps, used_t)
    t_u, pose_u = stamps[on] - offset, pose[on]
    pose_u[:, 2] = np.unwrap(pose_u[:, 2])  # less than half a turn between updates
    return with_truth_at(f"{p}:{jt}", t, right, left, t_u, pose_u, {**meta, "truth": "slam"})
