"""What the scan-matching fit reads from a bag: the wheel joints, the laser scans and the laser's
mounting on the base from ``/tf_static`` (a guess for the matcher's start; the fit estimates it).
The matching itself is :func:`odocal.calibration.scan_matching.scan_interval_motions`.

``/tf`` (in a long bag most of the messages besides the scans and joints) is read only when
``/tf_static`` does not place the laser under ``base_link`` (a laser whose mounting is published
on ``/tf``, or a robot whose base frame is another one)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..errors import InputError
from .bag_columns import LaserScans
from .bag_options import BagOptions
from .bag_wheels import choose_wheels, wheel_series
from .bags import (
    BASE_FRAMES,
    LASER_SCAN,
    BagContents,
    ScanSeries,
    TopicInfo,
    TopicSeries,
    check_bag_path,
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
    start_ns : int
        The bag's start (ns since the epoch); the times are relative to it.
    """

    path: Path
    joints: TopicSeries
    scans: ScanSeries
    mount: np.ndarray
    mount_source: str
    warnings: tuple[str, ...] = ()
    start_ns: int = 0


def read_scan_bag(
    path: str | Path | BagContents,
    options: BagOptions,
    ticks_per_rev: float | None,
    ran_with: WheelGeometry | None = None,
) -> ScanBag:
    """The wheels, laser scans and laser mounting of the bag ``path`` (topics from ``options``,
    else the only candidates; joint positions in ticks with ``ticks_per_rev``). Without joint
    states the wheels are the controller's odometry inverted through ``ran_with``
    (:mod:`odocal.io.bag_wheels`)."""
    p = check_bag_path(path)

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        wheels = choose_wheels(info, options, p)
        return {
            **wheels,
            "scan": pick_topic(
                info, options.scan_topic, (LASER_SCAN,), "laser scans", p, "--scan-topic"
            ),
            "tf_static": present(info, "/tf_static"),
        }

    def tf_if_needed(bag: BagContents) -> dict[str, str | None]:
        if bag.picked.get("tf"):  # the wheels are odom -> base_link on /tf
            return {}
        return {"tf": None if _static_mount(bag) else present(bag.topics, "/tf")}

    bag = read_bag(path, choose, then=tf_if_needed)
    st = bag.picked["scan"]
    w = wheel_series(bag, options, ticks_per_rev, ran_with)
    joints = TopicSeries(w.topic, w.time_s, {"right": w.right, "left": w.left},
                         meta={**w.meta, "wheels": w.describe()})  # fmt: skip
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
    return ScanBag(
        p, joints, scans, mount, mount_source, tuple(warnings) + w.warnings, int(bag.start_ns)
    )


def _static_mount(bag: BagContents) -> bool:
    """Whether ``/tf_static`` alone links ``base_link`` (the base frame the lookup prefers: /tf
    cannot make it pick another) to the laser's frame, so that ``/tf`` need not be read."""
    scans = bag.messages.get(bag.picked.get("scan", ""))
    if not isinstance(scans, LaserScans) or not len(scans) or "tf_static" not in bag.picked:
        return False
    frame = scans.frames[scans.layout[0]].lstrip("/")
    try:
        buf = transform_buffer(bag)
        base = BASE_FRAMES[0]
        return base in buf.frames and all(s.static for s in buf.chain(base, frame))
    except InputError:
        return False
