"""A SLAM pose on ``/tf`` as ground truth: relative motions between the SLAM's update instants.

Reads the wheel joints, ``/tf`` and ``/tf_static`` of a bag, finds the chain between the truth
frames (e.g. ``map`` -> ``base_link``, composed through ``map`` -> ``odom`` -> ``base_link``),
takes the SLAM correction edge (the dynamic edge of the chain published least often, normally
``map`` -> ``odom``) and hands its messages, the odometry at their stamps and the wheel angles at
their stamps to :func:`odocal.calibration.slam.slam_relative_motions` (docs/slam-truth.md: why
only the update instants, and relative motions, can be trusted).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.relative_motions import RelativeMotions, wheel_increments
from ..calibration.slam import SlamLimits, SlamMotions, slam_relative_motions
from ..calibration.time_offset import TimeOffset, estimate_time_offset, resolve_offset
from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..core.transforms import RigidTransforms, planar_pose
from ..errors import InputError
from .bag_options import BagOptions
from .bag_wheels import ODOM_FRAMES, choose_wheels, wheel_series
from .bags import (
    EdgeMessages,
    check_bag_path,
    present,
    read_bag,
    tf_messages,
    transform_buffer,
)

__all__ = ["SlamBag", "parse_truth_frames", "load_slam_bag", "load_slam_bags", "wheel_increments"]


def parse_truth_frames(text: str) -> tuple[str, str]:
    """'PARENT:CHILD' (e.g. 'map:base_link') as (parent, child)."""
    parent, sep, child = text.partition(":")
    parent, child = parent.strip().lstrip("/"), child.strip().lstrip("/")
    if not sep or not parent or not child or ":" in child:
        raise InputError(f"expected PARENT:CHILD frames (e.g. map:base_link), got {text!r}")
    if parent == child:
        raise InputError(f"the truth frames must differ, got {text!r}")
    return parent, child


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


def _span(t: np.ndarray, lo: float, hi: float) -> np.ndarray:
    return (t >= lo) & (t <= hi)


def _truth_chain(buf: Any, parent: str, child: str, p: Path) -> tuple[list[Any], str]:
    """The moving steps of the chain from ``parent`` to ``child`` on /tf and /tf_static, and
    the chain in words; InputError when a frame is missing or the chain does not move."""
    for frame in (parent, child):
        if frame not in buf.frames:
            raise InputError(
                f"frame '{frame}' never appears on /tf or /tf_static (frames: "
                f"{', '.join(buf.frames) or 'none'})",
                p,
                None,
                "--truth-frames",
            )
    chain = buf.chain(parent, child)  # InputError when the trees do not connect
    dynamic = [s for s in chain if not s.static]
    chain_text = " -> ".join([chain[0].frm] + [s.to for s in chain]) if chain else parent
    if not dynamic:
        raise InputError(
            f"the chain {chain_text} is static: it holds no SLAM pose", p, None, "--truth-frames"
        )
    odom = ODOM_FRAMES[0]
    if all(_edge_key(s)[0] == odom for s in dynamic):
        moving = ", ".join(" -> ".join(_edge_key(s)) for s in dynamic)
        raise InputError(
            f"{parent}:{child} moves only by {moving}, the wheel odometry itself ('{odom}' is the "
            "odometry frame, REP 105): the odometry cannot be its own reference; give the "
            f"frames of the SLAM's pose, its map above '{odom}' (e.g. map:{child})",
            p,
            None,
            "--truth-frames",
        )
    return dynamic, chain_text


def _base_below(buf: Any, parent: str, child: str) -> tuple[str, tuple[str, ...]]:
    """The frame whose motion the truth is: ``child``, or when ``child`` hangs below the moving
    part of the chain by ``/tf_static`` alone (a sensor's frame, e.g. ``map:laser``), the
    frame it is mounted on (the base: the wheels move it, the mounting is fixed), with a note
    saying so. Taking the sensor's motion for the base's would be off by its mounting."""
    chain = buf.chain(parent, child)
    k = len(chain)
    while k > 0 and chain[k - 1].static:
        k -= 1
    if k == len(chain):
        return child, ()
    base = chain[k].frm
    x, y, yaw = buf.lookup(base, child, 0.0).planar()[0].tolist()
    return base, (
        f"the truth frame '{child}' is mounted on '{base}' by /tf_static (x {x:.4g} m, y "
        f"{y:.4g} m, yaw {yaw:.4g} rad): the motion of '{base}' is used",
    )


def _edge_key(step: Any) -> tuple[str, str]:
    """The (parent, child) of the /tf edge a chain step follows (either way)."""
    return (step.to, step.frm) if step.inverted else (step.frm, step.to)


def _correction_edge(
    edges: dict[tuple[str, str], EdgeMessages],
    dynamic: list[Any],
    parent: str,
    child: str,
    p: Path,
) -> EdgeMessages:
    """The SLAM correction: the moving edge of the chain published least often; InputError
    when it points from the child towards the parent."""
    key, step = min(((_edge_key(s), s) for s in dynamic), key=lambda ks: len(edges[ks[0]].time_s))
    if step.inverted:
        raise InputError(
            f"the SLAM edge {key[0]} -> {key[1]} points from {child} towards {parent}; "
            f"give the truth frames as {child}:{parent}'s parent first",
            p,
            None,
            "--truth-frames",
        )
    return edges[key]


def load_slam_bag(
    path,
    truth_frames: tuple[str, str] = ("map", "base_link"),
    options: BagOptions | None = None,
    *,
    ticks_per_rev: float | None = None,
    stamp_offset_s: float = 0.0,
    ran_with: WheelGeometry | None = None,
    time_offset_s: float | None = None,
    limits: SlamLimits | None = None,
) -> SlamBag:
    """The SLAM relative motions of one bag (module docstring).

    ``stamp_offset_s`` (s) is subtracted from the correction's stamps: slam_toolbox post-dates
    ``map -> odom`` by its ``transform_timeout`` (0.2 s by default), AMCL by its
    ``transform_tolerance``. ``time_offset_s``: how late the SLAM's clock runs behind the
    wheels' (its pose stamped t is the robot's pose at wheel time t - offset); None estimates
    it (:mod:`odocal.calibration.time_offset`). The wheels are the joint states, else the
    controller's odometry inverted through ``ran_with`` (:mod:`odocal.io.bag_wheels`)."""
    opts = options if options is not None else BagOptions()
    parent, child = truth_frames
    p = check_bag_path(path)

    def choose(info):
        if present(info, "/tf") is None:
            raise InputError(
                f"no /tf topic: the truth frames {parent}:{child} need the SLAM pose on /tf", p
            )
        return {**choose_wheels(info, opts, p), "tf": "/tf",
                "tf_static": present(info, "/tf_static")}  # fmt: skip

    bag = read_bag(path, choose)
    wheels = wheel_series(bag, opts, ticks_per_rev, ran_with)
    buf = transform_buffer(bag)
    dynamic, chain_text = _truth_chain(buf, parent, child, p)
    child, mounting = _base_below(buf, parent, child)
    edges = tf_messages(bag)
    ce = _correction_edge(edges, dynamic, parent, child, p)
    stamps = ce.time_s - float(stamp_offset_s)
    t_j = wheels.time_s
    keep = _span(stamps, t_j[0], t_j[-1])
    direct = len(dynamic) == 1
    below: list[Any] = [] if direct else list(buf.chain(ce.child, child))
    for s in below:
        if not s.static:
            e = edges[_edge_key(s)]
            keep &= _span(stamps, e.time_s[0], e.time_s[-1])
    meta: dict = {"bag": str(p), "joint_topic": wheels.topic, "chain": chain_text,
                  "wheels": wheels.describe(), "start_ns": int(bag.start_ns)}  # fmt: skip
    meta.update(
        correction_edge=None if direct else f"{ce.parent} -> {ce.child}",
        slam_messages=int(len(ce.time_s)),
        slam_messages_outside_joints=int((~keep).sum()),
        stamp_offset_s=float(stamp_offset_s),
    )
    if int(keep.sum()) < 2:
        raise InputError(
            f"only {int(keep.sum())} SLAM message(s) on '{ce.parent} -> {ce.child}' fall within "
            f"the wheel data's time span ({t_j[0]:.3f} to {t_j[-1]:.3f} s): the sources do not "
            "overlap in time",
            p,
        )
    stamps = stamps[keep]
    if direct:
        # the chain's only moving edge is the SLAM pose itself (e.g. map -> base_link)
        truth_pose = planar_pose(
            buf.lookup(parent, child, stamps, max_extrapolation_s=1e-9).transform
        )
        correction_pose = odometry_pose = None
    else:
        # the chain splits at the correction edge: parent -> ce.child (the correction, with any
        # static part above it) and ce.child -> child (the odometry, at the correction stamps)
        above = buf.chain(parent, ce.parent) if ce.parent != parent else ()
        corr = RigidTransforms(ce.translation_m[keep], ce.quaternion_xyzw[keep])
        if above:
            corr = buf.lookup(parent, ce.parent, stamps).transform @ corr
        correction_pose = planar_pose(corr)
        odometry_pose = planar_pose(buf.lookup(ce.child, child, stamps).transform)
        truth_pose = None
    right, left = wheels.right, wheels.left
    lim = limits if limits is not None else SlamLimits()

    def motions_at(offset: float, gate: SlamLimits) -> SlamMotions:
        at = stamps - offset
        wr, wl = np.interp(at, t_j, right), np.interp(at, t_j, left)
        wheel_odo = None
        if offset and odometry_pose is not None:
            span = (at >= t_j[0]) & (at <= t_j[-1])
            lo = max(float(at[span][0]), *(float(edges[_edge_key(s)].time_s[0]) for s in below
                                            if not s.static))  # fmt: skip
            hi = min(float(at[span][-1]), *(float(edges[_edge_key(s)].time_s[-1]) for s in below
                                             if not s.static))  # fmt: skip
            wheel_odo = planar_pose(buf.lookup(ce.child, child, np.clip(at, lo, hi)).transform)
        return slam_relative_motions(
            stamps, wr, wl, correction_pose=correction_pose, odometry_pose=odometry_pose,
            truth_pose=truth_pose, limits=gate, wheel_time_odometry_pose=wheel_odo,
        )  # fmt: skip

    offset = _slam_offset(p, motions_at, lim, t_j, right, left, time_offset_s)
    motions = motions_at(offset.applied_s, lim)
    recording = _recording(
        p,
        wheels.topic,
        t_j,
        right,
        left,
        stamps,
        motions,
        correction_pose,
        odometry_pose,
        truth_pose,
        meta | wheels.meta,
        offset.applied_s,
    )
    d = offset.applied_s
    increments = wheel_increments(t_j, right, left, motions.start_s - d, motions.end_s - d)
    every = wheel_increments(t_j, right, left, motions.every_start_s - d, motions.every_end_s - d)
    return SlamBag(
        str(p), motions, recording, chain_text, meta["correction_edge"], increments, meta,
        offset, every, wheels.describe(), wheels.warnings + mounting, (t_j, right, left),
    )  # fmt: skip


def _slam_offset(
    p: Path,
    motions_at: Any,
    lim: SlamLimits,
    t_j: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    given: float | None,
) -> TimeOffset:
    """The SLAM's clock offset: given, else registered on the heading changes between every
    pair of consecutive update instants (dropped intervals included: the estimator's robust
    loss deals with real jumps, and a clock offset is what makes ordinary turns look like
    jumps)."""

    def estimate() -> TimeOffset:
        first = motions_at(0.0, replace(lim, min_intervals=1))
        return estimate_time_offset(
            t_j, right, left, first.every_start_s, first.every_end_s,
            first.every_motion[:, 2], source="slam",
        )  # fmt: skip

    return resolve_offset("slam", given, estimate)


def _recording(
    p: Path, jt, t, right, left, stamps, motions, corr, odo, truth, meta, offset: float
) -> Recording:
    """The wheel-rate run with the SLAM truth at the update instants used (other samples are
    not truth: ``meta['truth_samples']`` lists the valid indices), placed at their wheel-clock
    instants (``stamps - offset``)."""
    from ..core.transforms import se2_compose

    pose = np.array(truth if truth is not None else se2_compose(corr, odo), dtype=float)
    # the update instants the motions used (their starts and ends), as wheel-sample indices
    used_t = np.unique(np.r_[motions.start_s, motions.end_s])
    on = np.isin(stamps, used_t)
    t_u, pose_u = stamps[on] - offset, pose[on]
    pose_u[:, 2] = np.unwrap(pose_u[:, 2])  # less than half a turn between updates
    # insert the instants into the wheel-rate time base (angles interpolated there)
    tt = np.union1d(t[(t >= t_u[0]) & (t <= t_u[-1])], t_u)
    rr, ll = np.interp(tt, t, right), np.interp(tt, t, left)
    idx = np.searchsorted(tt, t_u)
    gt = np.full((len(tt), 3), np.nan)
    gt[idx] = pose_u
    # start frame at the first valid instant
    c, s = np.cos(pose_u[0, 2]), np.sin(pose_u[0, 2])
    dx, dy = gt[:, 0] - pose_u[0, 0], gt[:, 1] - pose_u[0, 1]
    gt = np.column_stack([c * dx + s * dy, -s * dx + c * dy, gt[:, 2] - pose_u[0, 2]])
    return Recording(
        name=f"{p}:{jt}",
        time_s=tt - tt[0],
        wheel_angle_right_rad=rr - rr[0],
        wheel_angle_left_rad=ll - ll[0],
        ground_truth=gt,
        meta={**meta, "truth": "slam", "truth_samples": [int(i) for i in idx]},
    )


def load_slam_bags(
    paths: Sequence[str | Path],
    truth_frames: tuple[str, str],
    bag: BagOptions,
    *,
    ticks_per_rev: float | None = None,
    stamp_offset_s: float = 0.0,
    ran_with: WheelGeometry | None = None,
    time_offset_s: float | None = None,
) -> list[SlamBag]:
    """:func:`load_slam_bag` of every bag of ``paths`` with the topics of ``bag``; InputError
    when a path is given twice (its runs would count twice)."""
    from .recordings import refuse_repeated

    return [
        load_slam_bag(
            p,
            truth_frames,
            bag,
            ticks_per_rev=ticks_per_rev,
            stamp_offset_s=stamp_offset_s,
            ran_with=ran_with,
            time_offset_s=time_offset_s,
        )
        for p in refuse_repeated(paths)
    ]
