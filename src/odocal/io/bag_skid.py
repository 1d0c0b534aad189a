"""What the skid-steer route reads from a bag: the wheels (joint states, else the controller's
odometry inverted through the geometry it ran with: :mod:`odocal.io.bag_wheels`) and a truth
pose track on its own clock (an Odometry in a world frame such as a lidar-ICP ``/icp_odom``, a
PoseStamped, ...; else a SLAM pose on ``/tf`` at its update stamps), as a
:class:`~odocal.calibration.skid_steer.SkidLog`. The identification is
:mod:`odocal.calibration.skid_steer`'s."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.skid_steer import SkidLog
from ..core.model import WheelGeometry
from ..core.transforms import se2_compose
from ..errors import InputError
from .bag_options import BagOptions
from .bag_slam import read_slam_series
from .bag_survey import slam_frames
from .bag_wheels import choose_wheels, wheel_series
from .bags import (
    BASE_FRAMES,
    IMU,
    POSE_TYPES,
    BagContents,
    TopicInfo,
    check_bag_path,
    imu_series,
    list_topics,
    pick_topic,
    pose_series,
    present,
    read_bag,
    static_rotation,
)

__all__ = ["read_skid_log", "truth_topic", "has_truth", "SkidGyroLog", "read_skid_gyro_log"]


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


def has_truth(path: BagContents, options: BagOptions) -> bool:
    """Whether the bag has a truth pose track the skid-steer fit can use (a named or the only
    pose topic, a world-frame Odometry, a SLAM pose on /tf)."""
    try:
        truth_topic(path.topics, options, path.path)
        return True
    except InputError:
        if options.truth_topic:
            raise
    return any(t.name == "/tf" for t in path.topics) and slam_frames(path) is not None


@dataclass(frozen=True)
class SkidGyroLog:
    """The wheels and the IMU of one bag, each on its own clock, for the skid-steer gyro route.

    ``time_s``, ``angle_right_rad``, ``angle_left_rad``: the wheels (cumulative rad);
    ``imu_time_s`` and ``angular_velocity`` (rad/s, IMU frame, shape (K, 3)); ``mounting`` the
    IMU's R_base_imu from /tf_static (None without a chain) and ``mounting_source`` saying so;
    ``wheels`` where the wheels came from; ``imu_topic``."""

    name: str
    time_s: np.ndarray
    angle_right_rad: np.ndarray
    angle_left_rad: np.ndarray
    imu_time_s: np.ndarray
    angular_velocity: np.ndarray
    mounting: np.ndarray | None
    mounting_source: str | None
    wheels: str
    imu_topic: str


def read_skid_gyro_log(
    path: BagContents,
    options: BagOptions,
    ran_with: WheelGeometry | None,
    *,
    ticks_per_rev: float | None = None,
) -> SkidGyroLog:
    """The wheels (as :func:`read_skid_log` reads them) and the IMU's angular velocity and
    mounting of one bag."""
    p = check_bag_path(path)

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        imu = pick_topic(info, options.imu_topic, (IMU,), "IMU", p, "--imu-topic")
        return {**choose_wheels(info, options, p), "imu": imu,
                "tf_static": present(info, "/tf_static")}  # fmt: skip

    bag = read_bag(path, choose)
    wheels = wheel_series(bag, options, ticks_per_rev, ran_with)
    imu = imu_series(bag, str(bag.picked["imu"]))
    rot, parent, source = None, None, None
    if imu.frame_id:
        rot, parent = static_rotation(bag, imu.frame_id, BASE_FRAMES)
        if rot is not None:
            source = f"tf_static ({parent} -> {imu.frame_id})"
    return SkidGyroLog(
        str(p), wheels.time_s, wheels.right, wheels.left, imu.time_s,
        np.asarray(imu.values["angular_velocity"], dtype=float), rot, source, wheels.source,
        imu.topic,
    )  # fmt: skip


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
    info = path.topics if isinstance(path, BagContents) else list_topics(p)
    try:
        truth_topic(info, options, p)
    except InputError:
        if options.truth_topic or not isinstance(path, BagContents):
            raise
        edge = slam_frames(path) if any(t.name == "/tf" for t in info) else None
        if edge is None:
            raise
        return _slam_log(path, edge, options, ran_with, ticks_per_rev, group)

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
        str(p), wheels.time_s, wheels.right, wheels.left, truth.time_s, pose, group or str(p),
        wheels.source,
    )  # fmt: skip


def _slam_log(
    bag: BagContents,
    edge: tuple[str, str],
    options: BagOptions,
    ran_with: WheelGeometry | None,
    ticks_per_rev: float | None,
    group: str,
) -> SkidLog:
    """A bag whose truth is a SLAM pose on /tf: its pose at the SLAM's update stamps (a
    measurement only there: docs/slam-truth.md), on the SLAM's clock, as the truth track."""
    series = read_slam_series(bag, edge, options, ticks_per_rev=ticks_per_rev, ran_with=ran_with)
    if series.truth_pose is not None:
        pose = series.truth_pose
    else:
        assert series.correction_pose is not None and series.odometry_pose is not None
        pose = se2_compose(series.correction_pose, series.odometry_pose)
    pose = np.array(pose, dtype=float)
    pose[:, 2] = np.unwrap(pose[:, 2])
    source = "odometry" if "inverted" in series.wheels else "joint_states"
    return SkidLog(
        series.path, series.wheel_time_s, series.wheel_right_rad, series.wheel_left_rad,
        series.stamps_s, pose, group or series.path, source,
    )  # fmt: skip
