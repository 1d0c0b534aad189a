"""A SLAM pose on ``/tf`` as ground truth, read: what the SLAM route needs of a bag.

Reads the wheel joints, ``/tf`` and ``/tf_static`` of a bag, finds the chain between the truth
frames (e.g. ``map`` -> ``base_link``, composed through ``map`` -> ``odom`` -> ``base_link``),
takes the SLAM correction edge (the dynamic edge of the chain published least often, normally
``map`` -> ``odom``) and gives its stamps, the chain's poses there, the wheel angles and a
lookup of the odometry (:class:`~odocal.calibration.slam_bag.SlamSeries`). The relative motions
between the update instants, and the SLAM's clock offset, are computed from it by
:func:`odocal.calibration.slam_bag.slam_bag` (docs/slam-truth.md: why only the update instants,
and relative motions, can be trusted).
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.slam_bag import SlamSeries
from ..core.model import WheelGeometry
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

__all__ = ["parse_truth_frames", "read_slam_series"]


def parse_truth_frames(text: str) -> tuple[str, str]:
    """'PARENT:CHILD' (e.g. 'map:base_link') as (parent, child)."""
    parent, sep, child = text.partition(":")
    parent, child = parent.strip().lstrip("/"), child.strip().lstrip("/")
    if not sep or not parent or not child or ":" in child:
        raise InputError(f"expected PARENT:CHILD frames (e.g. map:base_link), got {text!r}")
    if parent == child:
        raise InputError(f"the truth frames must differ, got {text!r}")
    return parent, child


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


def read_slam_series(
    path,
    truth_frames: tuple[str, str] = ("map", "base_link"),
    options: BagOptions | None = None,
    *,
    ticks_per_rev: float | None = None,
    stamp_offset_s: float = 0.0,
    ran_with: WheelGeometry | None = None,
) -> SlamSeries:
    """What one bag holds for the SLAM route (module docstring), read: the wheels, the
    correction's update stamps within them and the chain's poses there
    (:class:`~odocal.calibration.slam_bag.SlamSeries`); the motions are computed from it by
    :func:`~odocal.calibration.slam_bag.slam_bag`.

    ``stamp_offset_s`` (s) is subtracted from the correction's stamps: slam_toolbox post-dates
    ``map -> odom`` by its ``transform_timeout`` (0.2 s by default), AMCL by its
    ``transform_tolerance``. The wheels are the joint states, else the controller's odometry
    inverted through ``ran_with`` (:mod:`odocal.io.bag_wheels`)."""
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
    odometry_at = None
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
        spans = [edges[_edge_key(s)].time_s for s in below if not s.static]

        def odometry_at(at: np.ndarray) -> np.ndarray:
            """The odometry's pose at wheel times ``at`` (clipped to the span its edges and
            the wheels cover)."""
            inside = at[(at >= t_j[0]) & (at <= t_j[-1])]
            lo = max(float(inside[0]), *(float(t[0]) for t in spans))
            hi = min(float(inside[-1]), *(float(t[-1]) for t in spans))
            return planar_pose(buf.lookup(ce.child, child, np.clip(at, lo, hi)).transform)

    return SlamSeries(
        str(p), t_j, wheels.right, wheels.left, wheels.topic, wheels.describe(),
        wheels.warnings + mounting, stamps, correction_pose, odometry_pose, truth_pose,
        odometry_at, chain_text, meta["correction_edge"], meta | wheels.meta,
    )  # fmt: skip
