"""What the skid-steer route reads from a bag: the wheels (joint states, else the controller's
odometry inverted through the geometry it ran with: :mod:`odocal.io.bag_wheels`) and a truth
pose track on its own clock (an Odometry in a world frame such as a lidar-ICP ``/icp_odom``, a
PoseStamped, ...), as a :class:`~odocal.calibration.skid_steer.SkidLog`. The identification is
:mod:`odocal.calibration.skid_steer`'s."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..calibration.skid_steer import SkidLog
from ..core.model import WheelGeometry
from ..errors import InputError
from .bag_options import BagOptions
from .bag_wheels import choose_wheels, wheel_series
from .bags import (
    POSE_TYPES,
    BagContents,
    TopicInfo,
    check_bag_path,
    pick_topic,
    pose_series,
    read_bag,
)

__all__ = ["read_skid_log", "truth_topic"]


def truth_topic(info: list[TopicInfo], options: BagOptions, path: Path) -> str:
    """The truth pose topic: the one named, else the only pose topic, else the only Odometry in a
    world frame (not the wheels); InputError naming what the bag has otherwise."""
    if options.truth_topic:
        return str(pick_topic(info, options.truth_topic, (*POSE_TYPES, "nav_msgs/msg/Odometry"),
                              "ground truth", path, "--truth-topic"))  # fmt: skip
    pose = pick_topic(info, None, POSE_TYPES, "ground truth", path, "--truth-topic", False)
    if pose is not None:
        return pose
    world = [t.name for t in info if t.world_pose]
    if len(world) == 1:
        return world[0]
    raise InputError(
        "the skid-steer fit needs a truth pose track (a PoseStamped, or an Odometry in a world "
        "frame such as a lidar-ICP odometry in 'map'); name it with --truth-topic"
        + (f" (several: {', '.join(world)})" if world else ""),
        path,
    )


def read_skid_log(
    path: str | Path | BagContents,
    options: BagOptions,
    ran_with: WheelGeometry | None,
    *,
    ticks_per_rev: float | None = None,
    group: str = "",
) -> SkidLog:
    """The wheels and the truth of one bag, each on its own clock (the truth's offset is the
    route's to estimate)."""
    p = check_bag_path(path)

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        return {**choose_wheels(info, options, p), "truth": truth_topic(info, options, p)}

    bag = read_bag(path, choose)
    topic = bag.picked["truth"]
    wheels = wheel_series(bag, options, ticks_per_rev, ran_with)
    truth = pose_series(bag, topic)
    if bag.msgtype(topic) == "nav_msgs/msg/Odometry" and "odom" in truth.frame_id.lower():
        raise InputError(
            f"the truth {topic} is the wheel odometry (frame '{truth.frame_id}'): the odometry "
            "cannot be its own reference",
            p,
            None,
            topic,
        )
    lo, hi = float(wheels.time_s[0]), float(wheels.time_s[-1])
    if float(truth.time_s[-1]) < lo or float(truth.time_s[0]) > hi:
        raise InputError(
            f"the truth ({truth.time_s[0]:.3f} to {truth.time_s[-1]:.3f} s) never overlaps the "
            f"wheels ({lo:.3f} to {hi:.3f} s)",
            p,
            None,
            topic,
        )
    pose = np.column_stack([truth.values["x"], truth.values["y"], truth.values["yaw"]])
    return SkidLog(
        str(p), wheels.time_s, wheels.right, wheels.left, truth.time_s, pose, group or str(p)
    )
