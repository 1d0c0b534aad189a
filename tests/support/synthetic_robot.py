"""A simulated robot with wheel encoders, a 2D laser and a gyro in a synthetic room, written
into a ROS 2 bag (a helper for tests; not a test module).

The robot drives a track open loop on its encoders with odocal's simulator
(``odocal.core.simulate.drive``, noise-free or with wheel-travel noise): every increment of at
most ``max_step_m`` of wheel travel takes ``dt_s``. What is recorded:

- ``/joint_states`` (``sensor_msgs/msg/JointState``): the wheel joint angles (rad) the encoders
  read, i.e. the commanded rotations, at every increment;
- ``/scan`` (``sensor_msgs/msg/LaserScan``, frame ``laser``): ray-cast in the room from the
  TRUE laser pose every ``Laser.every`` increments (an instantaneous scan: no motion skew);
- ``/tf_static``: ``base_link`` -> ``laser`` (the mounting) and ``base_link`` -> ``imu_link``
  (identity);
- ``/tf``: ``odom`` -> ``base_link`` from the wheel odometry with the BELIEVED geometry, at every
  increment; optionally ``map`` -> ``odom`` at a lower rate, the correction a SLAM system would
  publish (here exact: the true pose composed with the inverse odometry);
- optionally ``/imu`` (``sensor_msgs/msg/Imu``, frame ``imu_link``, axes as ``base_link``): the
  true yaw rate over each increment, stamped mid-increment, plus a constant bias and white noise.

Frames (docs/conventions.md, REP-105): ``map`` is the room frame; ``odom`` coincides with the
base's start pose in ``map``. Every stamp is an int in nanoseconds; the bag's log time of a
message equals its header stamp. The returned :class:`RobotRun` keeps the truth for assertions.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from odocal.core.model import NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.simulate import drive
from odocal.core.tracks import Track, arc, spot_turn, straight
from odocal.errors import ModelError
from tests.support.room import Room, ray_cast

__all__ = [
    "Laser",
    "Gyro",
    "RobotRun",
    "default_track",
    "simulate_robot",
    "write_ros2_bag",
    "repeat_run",
    "compose",
    "relative",
    "TOPICS",
]

START_TIME_NS = 1_700_000_000 * 10**9  # an arbitrary epoch for the first stamp
TOPICS = {
    "joints": "/joint_states",
    "scan": "/scan",
    "tf": "/tf",
    "tf_static": "/tf_static",
    "imu": "/imu",
}


def compose(a, b) -> np.ndarray:
    """Pose ``b`` (x_m, y_m, theta_rad; shape (..., 3)) given in frame ``a`` -> in a's parent."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    return np.stack(
        [
            a[..., 0] + c * b[..., 0] - s * b[..., 1],
            a[..., 1] + s * b[..., 0] + c * b[..., 1],
            a[..., 2] + b[..., 2],
        ],
        axis=-1,
    )


def relative(a, b) -> np.ndarray:
    """Pose ``b`` expressed in frame ``a`` (both in one parent frame; shape (..., 3))."""
    a, b = np.asarray(a, float), np.asarray(b, float)
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, b[..., 2] - a[..., 2]], axis=-1)


@dataclass(frozen=True)
class Laser:
    """A 2D lidar and its mounting on ``base_link``.

    ``mount`` is (x_m, y_m, yaw_rad) of the laser frame in ``base_link``. Rays are
    ``angle_min_rad + i * 2 pi / n_rays`` (a full turn). One scan every ``every`` increments.
    """

    mount: tuple[float, float, float] = (0.15, 0.05, 0.1)
    n_rays: int = 720
    angle_min_rad: float = -math.pi
    range_min_m: float = 0.05
    range_max_m: float = 12.0
    sigma_m: float = 0.0
    every: int = 5
    frame_id: str = "laser"

    @property
    def angle_increment_rad(self) -> float:
        return 2.0 * math.pi / self.n_rays

    @property
    def angles_rad(self) -> np.ndarray:
        return self.angle_min_rad + self.angle_increment_rad * np.arange(self.n_rays)


@dataclass(frozen=True)
class Gyro:
    """A yaw-rate gyro aligned with ``base_link``: bias (rad/s) and white noise (rad/s per
    sample)."""

    bias_rad_s: float = 0.0
    sigma_rad_s: float = 0.0
    frame_id: str = "imu_link"


@dataclass(frozen=True)
class RobotRun:
    """A simulated run and everything recorded of it.

    Attributes
    ----------
    time_ns : ndarray of int, shape (K,)
        Stamp of every increment's end (the first is the start).
    wheel_angle_right_rad, wheel_angle_left_rad : ndarray, shape (K,)
        Encoder readings (rad), starting at 0.
    true_pose : ndarray, shape (K, 3)
        True base pose (x_m, y_m, theta_rad; theta unwrapped) in the room (``map``) frame.
    odom_pose : ndarray, shape (K, 3)
        Wheel odometry with the believed geometry, in the ``odom`` frame (starts at zero).
    scan_index : ndarray of int, shape (S,)
        Increments at which a scan was taken.
    scan_ranges_m : ndarray, shape (S, n_rays)
        Ranges (m; inf where nothing is hit within range).
    gyro_time_ns : ndarray of int, shape (K - 1,) or None
        Gyro stamps (mid-increment).
    gyro_z_rad_s : ndarray, shape (K - 1,) or None
        Measured yaw rate (rad/s): true rate + bias + noise.
    """

    time_ns: np.ndarray
    wheel_angle_right_rad: np.ndarray
    wheel_angle_left_rad: np.ndarray
    true_pose: np.ndarray
    odom_pose: np.ndarray
    scan_index: np.ndarray
    scan_ranges_m: np.ndarray
    laser: Laser
    room: Room = field(repr=False)
    true: WheelGeometry
    believed: WheelGeometry
    gyro: Gyro | None = None
    gyro_time_ns: np.ndarray | None = None
    gyro_z_rad_s: np.ndarray | None = None

    @property
    def time_s(self) -> np.ndarray:
        """Seconds since the first stamp, shape (K,)."""
        return (self.time_ns - self.time_ns[0]) * 1e-9

    @property
    def scan_time_ns(self) -> np.ndarray:
        return self.time_ns[self.scan_index]

    @property
    def laser_pose(self) -> np.ndarray:
        """True laser pose in the room frame at every scan, shape (S, 3)."""
        return compose(self.true_pose[self.scan_index], np.asarray(self.laser.mount, float))

    def laser_motion(self, start: int, end: int) -> np.ndarray:
        """True laser displacement from scan ``start`` to scan ``end``, in the laser frame at
        ``start`` (what scan matching estimates), shape (3,)."""
        pose = self.laser_pose
        return relative(pose[start], pose[end])

    def map_to_odom(self) -> np.ndarray:
        """The exact ``map`` -> ``odom`` transform at every increment, shape (K, 3)."""
        return compose(self.true_pose, _inverse(self.odom_pose))


def _inverse(pose: np.ndarray) -> np.ndarray:
    """Inverse of rigid transforms (x, y, theta), shape (..., 3)."""
    return relative(pose, np.zeros_like(pose))


def default_track() -> Track:
    """Straights (one backwards), spot turns and arcs turning both ways, about 8.3 m in all, that
    keep at least 0.8 m from the walls and boxes of :meth:`Room.default` when started at
    (3, 2.5, 0) with a geometry a few per cent off."""
    return Track(
        "room tour",
        (
            straight(1.0),
            arc(0.6, math.pi / 2),
            spot_turn(math.pi / 2),
            straight(0.8),
            arc(0.5, -math.pi),
            spot_turn(-math.pi / 2),
            straight(1.2),
            arc(0.7, -math.pi / 2),
            spot_turn(3 * math.pi / 4),
            straight(-0.5),
            arc(0.4, math.pi / 2),
            straight(0.6),
        ),
    )


def simulate_robot(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    *,
    room: Room | None = None,
    start_pose=(3.0, 2.5, 0.0),
    laser: Laser | None = None,
    gyro: Gyro | None = None,
    noise: NonSystematicError | None = None,
    rng: np.random.Generator | None = None,
    dt_s: float = 0.02,
    max_step_m: float = 0.01,
    still_s: float = 1.0,
) -> RobotRun:
    """Drive ``track`` once in ``room`` (default :meth:`Room.default`) from ``start_pose``
    (x_m, y_m, theta_rad in the room frame), standing still ``still_s`` before and after.

    Each segment is cut into increments of at most ``max_step_m`` of BELIEVED wheel travel;
    each increment takes ``dt_s``. ``rng`` is needed for wheel noise, range noise
    (``laser.sigma_m``) and gyro noise.
    """
    room = Room.default() if room is None else room
    laser = Laser() if laser is None else laser
    noise = NonSystematicError() if noise is None else noise
    dt_ns = round(dt_s * 1e9)
    if dt_ns <= 0 or abs(dt_ns - dt_s * 1e9) > 1e-3:
        raise ModelError(f"dt_s must be a positive whole number of nanoseconds, got {dt_s}")

    pose = np.asarray(start_pose, float)
    poses = [pose[None, :]]
    right, left = [np.zeros(1)], [np.zeros(1)]
    b_hat = believed.wheelbase_m
    for seg in track.segments:
        s_r, s_l = seg.wheel_travel(b_hat)
        n = max(1, math.ceil(max(abs(s_r), abs(s_l)) / max_step_m - 1e-9))
        res = drive(
            Track("segment", (seg,)), true, believed, noise, 1, rng,
            steps_per_segment=n, trajectory=True,
        )  # fmt: skip
        poses.append(compose(pose, res.trajectory[0, 1:]))
        pose = poses[-1][-1]
        k = np.arange(1, n + 1) / n
        right.append(right[-1][-1] + 2.0 * s_r / believed.diameter_right_m * k)
        left.append(left[-1][-1] + 2.0 * s_l / believed.diameter_left_m * k)
    n_still = round(still_s / dt_s)
    true_pose = np.concatenate(poses)
    r_ang, l_ang = np.concatenate(right), np.concatenate(left)

    def pad(a):
        return np.concatenate([np.repeat(a[:1], n_still, 0), a, np.repeat(a[-1:], n_still, 0)])

    true_pose, r_ang, l_ang = pad(true_pose), pad(r_ang), pad(l_ang)
    k_total = len(r_ang)
    time_ns = START_TIME_NS + dt_ns * np.arange(k_total, dtype=np.int64)
    odom = dead_reckon(r_ang, l_ang, believed)

    scan_index = np.arange(0, k_total, laser.every)
    laser_pose = compose(true_pose[scan_index], np.asarray(laser.mount, float))
    ranges = ray_cast(room, laser_pose, laser.angles_rad, laser.range_max_m, rng, laser.sigma_m)

    gyro_t = gyro_z = None
    if gyro is not None:
        gyro_t = time_ns[1:] - dt_ns // 2
        gyro_z = np.diff(true_pose[:, 2]) / dt_s + gyro.bias_rad_s
        if gyro.sigma_rad_s > 0:
            if rng is None:
                raise ModelError("a numpy.random.Generator is needed for gyro noise")
            gyro_z = gyro_z + gyro.sigma_rad_s * rng.standard_normal(gyro_z.shape)
    return RobotRun(
        time_ns, r_ang, l_ang, true_pose, odom, scan_index, ranges, laser, room, true, believed,
        gyro, gyro_t, gyro_z,
    )  # fmt: skip


def repeat_run(run: RobotRun, repeats: int) -> RobotRun:
    """``run`` driven ``repeats`` times in a row, for long bags: the wheel angles and the
    odometry continue, the true pose starts over each time (a SLAM would see a jump there),
    the stamps run on without a gap."""
    if repeats < 1:
        raise ModelError(f"repeats must be >= 1, got {repeats}")
    k = len(run.time_ns)
    dt_ns = int(run.time_ns[1] - run.time_ns[0])
    time_ns = run.time_ns[0] + dt_ns * np.arange(k * repeats, dtype=np.int64)
    r_end, l_end = run.wheel_angle_right_rad[-1], run.wheel_angle_left_rad[-1]
    right = np.concatenate([run.wheel_angle_right_rad + i * r_end for i in range(repeats)])
    left = np.concatenate([run.wheel_angle_left_rad + i * l_end for i in range(repeats)])
    odom, start = [], np.zeros(3)
    for _ in range(repeats):
        odom.append(compose(np.broadcast_to(start, run.odom_pose.shape), run.odom_pose))
        start = odom[-1][-1]
    scans = np.concatenate([run.scan_index + i * k for i in range(repeats)])
    gyro_t = gyro_z = None
    if run.gyro_time_ns is not None and run.gyro_z_rad_s is not None:
        gyro_t = np.concatenate([run.gyro_time_ns + i * k * dt_ns for i in range(repeats)])
        gyro_z = np.tile(run.gyro_z_rad_s, repeats)
    return RobotRun(
        time_ns, right, left, np.tile(run.true_pose, (repeats, 1)), np.concatenate(odom), scans,
        np.tile(run.scan_ranges_m, (repeats, 1)), run.laser, run.room, run.true, run.believed,
        run.gyro, gyro_t, gyro_z,
    )  # fmt: skip


class _Ros2Writer:
    """Thin layer over rosbags' ROS 2 writer: typestore, connections, int-ns stamps."""

    def __init__(self, path: Path):
        from tests.support.bag_files import Writer2, typestore

        # one ROS 2 (Humble) type store per process: rosbags compiles each serialiser once
        self.ts = typestore(ros1=False)
        self.w = Writer2(path, version=9)  # the default storage (sqlite3 in rosbags 0.11)
        self.conns: dict[str, object] = {}
        self.counts: dict[str, int] = {}

    def T(self, name):
        return self.ts.types[name]

    def header(self, t_ns: int, frame: str):
        sec, nsec = divmod(int(t_ns), 10**9)
        stamp = self.T("builtin_interfaces/msg/Time")(sec=sec, nanosec=nsec)
        return self.T("std_msgs/msg/Header")(stamp=stamp, frame_id=frame)

    def vec(self, x=0.0, y=0.0, z=0.0):
        return self.T("geometry_msgs/msg/Vector3")(x=float(x), y=float(y), z=float(z))

    def quat_yaw(self, yaw: float):
        return self.T("geometry_msgs/msg/Quaternion")(
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        )

    def transform(self, t_ns, parent, child, pose):
        tr = self.T("geometry_msgs/msg/Transform")(
            translation=self.vec(pose[0], pose[1]), rotation=self.quat_yaw(float(pose[2]))
        )
        return self.T("geometry_msgs/msg/TransformStamped")(
            header=self.header(t_ns, parent), child_frame_id=child, transform=tr
        )

    def tf(self, topic, t_ns, transforms):
        self.write(topic, "tf2_msgs/msg/TFMessage", t_ns, self.T("tf2_msgs/msg/TFMessage")(
            transforms=list(transforms)))  # fmt: skip

    def write(self, topic, msgtype, t_ns, msg):
        if topic not in self.conns:
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts)
            self.counts[topic] = 0
        self.w.write(self.conns[topic], int(t_ns), self.ts.serialize_cdr(msg, msgtype))
        self.counts[topic] += 1


def write_ros2_bag(
    path,
    run: RobotRun,
    *,
    joint_names: tuple[str, str] = ("right_wheel_joint", "left_wheel_joint"),
    map_odom_every: int | None = None,
    imu: bool = True,
    scan_time_s: float = 0.1,
    slam_noise: tuple[float, float] | None = None,
    rng: np.random.Generator | None = None,
    laser_delay_s: float = 0.0,
    slam_delay_s: float = 0.0,
    joints: bool = True,
    scan_mirrored: str | None = None,
    scan_increment_scale: float = 1.0,
) -> dict[str, int]:
    """Write ``run`` into a ROS 2 bag folder ``path`` (must not exist); returns the message
    count per topic.

    ``joint_names`` are (right, left), written in that order. ``map_odom_every``: publish
    ``map`` -> ``odom`` on ``/tf`` every that many increments (None: never). ``imu``: write
    ``/imu`` when the run has a gyro. ``slam_noise`` = (sigma_xy_m, sigma_theta_rad): the SLAM
    pose at each update is the true one plus independent Gaussian noise (drawn from ``rng``).

    Clock offsets (s, whole increments): ``laser_delay_s`` stamps every scan that much late
    (the scan taken at t carries t + delay); ``slam_delay_s`` stamps every ``map -> odom``
    update late in the same way, and computes it as a SLAM on that clock would: the pose at
    the scan, composed with the inverse odometry looked up at the (late) stamp, so that the
    composed ``map -> base_link`` at the stamp is the true pose at the scan.

    Scan headers: ``scan_mirrored`` writes each scan as a laser mounted upside down, its rays in
    the opposite order with a negative ``angle_increment`` ('header': ``angle_min`` and
    ``angle_max`` swapped too, the same points in the upright frame of ``/tf_static``;
    'ranges': not swapped, a header that disagrees with itself); ``scan_increment_scale``
    writes an ``angle_increment`` that many times the true one, ``angle_min`` and ``angle_max``
    true (an inconsistent header).
    """
    w = _Ros2Writer(Path(path))
    w.w.open()
    try:
        t0 = int(run.time_ns[0])
        w.tf(
            TOPICS["tf_static"],
            t0,
            [
                w.transform(t0, "base_link", run.laser.frame_id, run.laser.mount),
                w.transform(
                    t0, "base_link", run.gyro.frame_id if run.gyro else "imu_link", (0, 0, 0)
                ),
            ],
        )
        joint_state = w.T("sensor_msgs/msg/JointState")
        map_odom = run.map_to_odom() if map_odom_every else None
        if map_odom is not None and slam_noise is not None:
            if rng is None:
                raise ModelError("a numpy.random.Generator is needed for SLAM noise")
            sigma = np.array([slam_noise[0], slam_noise[0], slam_noise[1]])
            noisy_truth = run.true_pose + rng.standard_normal(map_odom.shape) * sigma
            map_odom = compose(noisy_truth, _inverse(run.odom_pose))
        # merge the streams in time order: joints + odom tf at every increment, scans, imu
        events: list[tuple[int, int, int]] = []  # (t_ns, kind, index); kind orders ties
        events += [(int(t), 0, k) for k, t in enumerate(run.time_ns)]
        dt_ns = int(run.time_ns[1] - run.time_ns[0])
        laser_shift, slam_shift = (round(d * 1e9 / dt_ns) for d in (laser_delay_s, slam_delay_s))
        if map_odom is not None and slam_shift > 0:
            # published at increment k (stamped k): the update of the scan at k - shift, composed
            # with the odometry at k (the SLAM looks it up at its own, late, stamp)
            truth_at = compose(map_odom, run.odom_pose)  # the (noisy) SLAM pose at each k
            late = compose(truth_at[:-slam_shift], _inverse(run.odom_pose[slam_shift:]))
            map_odom = np.concatenate([np.repeat(late[:1], slam_shift, 0), late])
        events += [
            (int(run.time_ns[min(k + laser_shift, len(run.time_ns) - 1)]), 1, i)
            for i, k in enumerate(run.scan_index)
        ]
        if imu and run.gyro_z_rad_s is not None:
            events += [(int(t), 2, k) for k, t in enumerate(run.gyro_time_ns)]
        events.sort()
        laser = run.laser
        for t_ns, kind, k in events:
            if kind == 0:
                msg = joint_state(
                    header=w.header(t_ns, ""),
                    name=list(joint_names),
                    position=np.array(
                        [run.wheel_angle_right_rad[k], run.wheel_angle_left_rad[k]], float
                    ),
                    velocity=np.array([], float),
                    effort=np.array([], float),
                )
                if joints:
                    w.write(TOPICS["joints"], "sensor_msgs/msg/JointState", t_ns, msg)
                transforms = [w.transform(t_ns, "odom", "base_link", run.odom_pose[k])]
                if map_odom is not None and k % map_odom_every == 0:
                    transforms.append(w.transform(t_ns, "map", "odom", map_odom[k]))
                w.tf(TOPICS["tf"], t_ns, transforms)
            elif kind == 1:
                first, last = laser.angle_min_rad, laser.angles_rad[-1]
                ranges = run.scan_ranges_m[k]
                increment = laser.angle_increment_rad * scan_increment_scale
                if scan_mirrored:
                    ranges, increment = ranges[::-1], -increment
                    if scan_mirrored == "header":
                        first, last = last, first
                msg = w.T("sensor_msgs/msg/LaserScan")(
                    header=w.header(t_ns, laser.frame_id),
                    angle_min=float(first),
                    angle_max=float(last),
                    angle_increment=float(increment),
                    time_increment=0.0,
                    scan_time=float(scan_time_s),
                    range_min=float(laser.range_min_m),
                    range_max=float(laser.range_max_m),
                    ranges=np.ascontiguousarray(ranges, dtype=np.float32),
                    intensities=np.array([], np.float32),
                )
                w.write(TOPICS["scan"], "sensor_msgs/msg/LaserScan", t_ns, msg)
            else:
                z9 = np.zeros(9)
                z9_unknown = z9.copy()
                z9_unknown[0] = -1.0  # REP-145: no orientation estimate
                msg = w.T("sensor_msgs/msg/Imu")(
                    header=w.header(t_ns, run.gyro.frame_id),
                    orientation=w.T("geometry_msgs/msg/Quaternion")(x=0.0, y=0.0, z=0.0, w=1.0),
                    orientation_covariance=z9_unknown,
                    angular_velocity=w.vec(0.0, 0.0, run.gyro_z_rad_s[k]),
                    angular_velocity_covariance=z9,
                    linear_acceleration=w.vec(0.0, 0.0, 9.81),
                    linear_acceleration_covariance=z9,
                )
                w.write(TOPICS["imu"], "sensor_msgs/msg/Imu", t_ns, msg)
    finally:
        w.w.close()
    return dict(w.counts)
