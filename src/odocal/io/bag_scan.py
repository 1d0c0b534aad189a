"""What the scan-matching fit reads from a bag: the wheel joints, the laser scans and the laser's
mounting on the base from ``/tf`` (a guess for the matcher's start; the fit estimates it). The
matching itself is :func:`odocal.calibration.scan_matching.scan_interval_motions`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from .bag_options import BagOptions
from .bags import (
    BASE_FRAMES,
    JOINT_STATE,
    LASER_SCAN,
    ScanSeries,
    TopicInfo,
    TopicSeries,
    check_bag_path,
    joint_series,
    pick_topic,
    present,
    read_bag,
    scan_series,
    transform_buffer,
)

__all__ = ["ScanBag", "read_scan_bag"]


@dataclass(frozen=True)
class ScanBag:
    """The series of one bag for the scan-matching fit.

    Attributes
    ----------
    path : Path
    joints : TopicSeries
        Wheel angles (``values`` 'right', 'left', rad).
    scans : ScanSeries
        The laser scans as points (m) in the laser frame.
    mount : ndarray, shape (3,)
        The laser's pose on the base (x_m, y_m, yaw_rad) from ``/tf`` (zero when unknown).
    mount_source : str
        Where ``mount`` came from.
    warnings : tuple of str
    """

    path: Path
    joints: TopicSeries
    scans: ScanSeries
    mount: np.ndarray
    mount_source: str
    warnings: tuple[str, ...] = ()


def read_scan_bag(path: str | Path, options: BagOptions, ticks_per_rev: float | None) -> ScanBag:
    """The wheel joints, laser scans and laser mounting of the bag ``path`` (topics from
    ``options``, else the only candidates; joint positions in ticks with ``ticks_per_rev``)."""
    p = check_bag_path(path)

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        return {
            "joints": pick_topic(
                info, options.joint_topic, (JOINT_STATE,), "wheel joints", p, "--joint-topic"
            ),
            "scan": pick_topic(
                info, options.scan_topic, (LASER_SCAN,), "laser scans", p, "--scan-topic"
            ),
            "tf": present(info, "/tf"),
            "tf_static": present(info, "/tf_static"),
        }

    bag = read_bag(p, choose)
    jt, st = bag.picked["joints"], bag.picked["scan"]
    joints = joint_series(bag, jt, options.right_joint, options.left_joint, ticks_per_rev)
    scans = scan_series(bag, st)
    warnings = []
    mount = np.zeros(3)
    mount_source = "none (assumed at the base origin)"
    buf = transform_buffer(bag)
    base = next((f for f in BASE_FRAMES if f in buf.frames), None)
    if base is not None and scans.frame_id in buf.frames:
        mount = buf.lookup(base, scans.frame_id, scans.time_s[:1], max_extrapolation_s=1e9)
        mount = mount.planar()[0]
        mount_source = f"tf ({base} -> {scans.frame_id})"
    else:
        warnings.append(
            f"no transform from the base to the laser frame '{scans.frame_id}': the matcher "
            "starts as if the laser sat at the base origin"
        )
    return ScanBag(p, joints, scans, mount, mount_source, tuple(warnings))
