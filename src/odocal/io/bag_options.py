"""Which topics and joints of a ROS bag to read: one frozen value from the command line (or a
library call) down to the bag readers. Importing it imports nothing heavy (the command line
builds it while parsing)."""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["BagOptions", "NO_BAG_OPTIONS", "TIME_OFFSET_SOURCES", "MAX_TIME_OFFSET_S"]

#: The sources whose clock offset against the wheels a route may estimate or take as given:
#: a truth track (motion capture, a pose topic or CSV), a SLAM pose on /tf, a laser, an IMU.
TIME_OFFSET_SOURCES = ("truth", "slam", "laser", "imu")
#: The largest plausible clock offset (s): beyond it the logs are not of the same drive.
MAX_TIME_OFFSET_S = 2.0


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
    time_offsets : tuple of (str, float)
        Clock offsets fixed by the user (``--time-offset SOURCE=SECONDS``): how late each
        source's stamps run behind the wheels' (s); a source not named is estimated.
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
    time_offsets: tuple[tuple[str, float], ...] = ()

    def time_offset(self, source: str) -> float | None:
        """The offset fixed for ``source`` (s), or None (estimate it)."""
        return dict(self.time_offsets).get(source)


#: The defaults: every topic and joint picked by the readers.
NO_BAG_OPTIONS = BagOptions()
