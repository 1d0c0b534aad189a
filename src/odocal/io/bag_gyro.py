"""What the gyro-only calibration reads from a bag: the IMU's angular velocity, the wheel odometry
(a ``nav_msgs/Odometry`` topic, or JointState wheel angles) and the IMU's mounting from
``/tf_static``. The calibration itself is :func:`odocal.app.fit_gyro.gyro_fit`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .bag_options import BagOptions
from .bags import (
    BASE_FRAMES,
    IMU,
    JOINT_STATE,
    ODOMETRY,
    BagContents,
    TopicInfo,
    TopicSeries,
    check_bag_path,
    imu_series,
    joint_series,
    pick_topic,
    pose_series,
    present,
    read_bag,
    static_rotation,
)

__all__ = ["GyroBag", "read_gyro_bag"]


@dataclass(frozen=True)
class GyroBag:
    """The series of one bag for the gyro calibration.

    Attributes
    ----------
    path : Path
    imu : TopicSeries
        ``values['angular_velocity']`` (rad/s, IMU frame), shape (K, 3).
    odometry : TopicSeries
        JointState wheel angles (``values`` 'right', 'left', rad; ``from_joints``), else the
        Odometry pose (``values`` 'yaw' unwrapped, 'yaw_rate', 'speed').
    from_joints : bool
    base_frames : tuple of str
        The frames the IMU's mounting is looked up to (the odometry's child frame first).
    mounting : ndarray, shape (3, 3), or None
        R_base_imu along ``/tf_static`` (None without a chain, or when not looked up).
    mounting_parent : str or None
        The base frame the mounting reaches.
    """

    path: Path
    imu: TopicSeries
    odometry: TopicSeries
    from_joints: bool
    base_frames: tuple[str, ...]
    mounting: np.ndarray | None = None
    mounting_parent: str | None = None


def _odometry_topic(
    info: list[TopicInfo], options: BagOptions, have_geometry: bool, p: Path
) -> str | None:
    """The wheel odometry's topic: the options' topics win; else the JointState topic (the
    wheels themselves; it needs the nominal geometry), else the only Odometry topic that is not
    a pose in a world frame (a ground truth such as a lidar ICP odometry in 'map')."""
    use_joints = options.joint_topic is not None
    if options.odom_topic is None and options.joint_topic is None:
        has_joints = any(t.msgtype == JOINT_STATE for t in info)
        use_joints = has_joints and have_geometry
        info = [t for t in info if not t.world_pose]
    if use_joints:
        if not have_geometry:
            raise InputError(
                "odometry from wheel joints needs the nominal wheel geometry (--robot)", p
            )
        return pick_topic(
            info, options.joint_topic, (JOINT_STATE,), "wheel joints", p, "--joint-topic"
        )
    return pick_topic(info, options.odom_topic, (ODOMETRY,), "wheel odometry", p, "--odom-topic")


def read_gyro_bag(
    path: str | Path | BagContents,
    options: BagOptions,
    *,
    have_geometry: bool,
    mounting: bool = True,
) -> GyroBag:
    """The IMU and wheel-odometry series of the bag ``path`` (topics from ``options``, else the
    only candidates; JointState only with ``have_geometry``), and with ``mounting`` the IMU's
    mounting from ``/tf_static``."""
    p = check_bag_path(path)

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        it = pick_topic(info, options.imu_topic, (IMU,), "gyro", p, "--imu-topic")
        src = _odometry_topic(info, options, have_geometry, p)
        return {"imu": it, "odometry": src, "tf_static": present(info, "/tf_static")}

    bag = read_bag(path, choose)
    it, src = bag.picked["imu"], bag.picked["odometry"]
    from_joints = bag.msgtype(src) == JOINT_STATE
    imu = imu_series(bag, it)
    base_frames: tuple[str, ...]
    if from_joints:
        odometry = joint_series(bag, src, options.right_joint, options.left_joint)
        base_frames = BASE_FRAMES
    else:
        odometry = pose_series(bag, src)
        child = odometry.child_frame_id
        base_frames = ((child,) if child else ()) + BASE_FRAMES
    rot, parent = None, None
    if mounting and imu.frame_id:
        rot, parent = static_rotation(bag, imu.frame_id, base_frames)
    return GyroBag(p, imu, odometry, from_joints, base_frames, rot, parent)
