"""Which topics and joints of a ROS bag to read: one frozen value from the command line (or a
library call) down to the bag readers. Importing it imports nothing heavy (the command line
builds it while parsing)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BagOptions", "NO_BAG_OPTIONS"]


@dataclass(frozen=True)
class BagOptions:
    """Topics, joints and IMU axis of a bag; None lets the reader pick the only candidate.

    Attributes
    ----------
    joint_topic : str or None
        ``sensor_msgs/JointState`` wheel positions.
    truth_topic : str or None
        Ground-truth pose (PoseStamped, PoseWithCovarianceStamped, TransformStamped, Odometry).
    imu_topic : str or None
        ``sensor_msgs/Imu`` gyro.
    odom_topic : str or None
        ``nav_msgs/Odometry`` wheel odometry (the gyro calibration).
    scan_topic : str or None
        ``sensor_msgs/LaserScan`` (the scan-matching fit).
    right_joint, left_joint : str or None
        Wheel joint names in the JointState messages.
    imu_axis : str or None
        The IMU axis carrying the yaw rate ('z', '-y', ...); None: from ``/tf_static``, else
        detected.
    invert_right, invert_left : bool
        Negate a wheel joint whose axis is mirrored.
    """

    joint_topic: str | None = None
    truth_topic: str | None = None
    imu_topic: str | None = None
    odom_topic: str | None = None
    scan_topic: str | None = None
    right_joint: str | None = None
    left_joint: str | None = None
    imu_axis: str | None = None
    invert_right: bool = False
    invert_left: bool = False


#: The defaults: every topic and joint picked by the readers.
NO_BAG_OPTIONS = BagOptions()
