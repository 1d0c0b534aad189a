"""ROS bags written with rosbags for the bag tests: a known simulated run (wheel angles as
JointState, true poses as PoseStamped, a gyro mounted as on the Husky with bias and noise, the
wheel odometry, the IMU mounting on /tf_static) in ROS 1, ROS 2 mcap and ROS 2 sqlite3 bags; and
a once-per-process read of the real Husky bags."""

from __future__ import annotations

import math
import sqlite3
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin, WriterError
from rosbags.rosbag2 import Writer as _RosbagsWriter2
from rosbags.rosbag2.enums import CompressionMode
from rosbags.rosbag2.storage_sqlite3 import Sqlite3Writer
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from odocal.calibration.gyro import rotation_from_rpy
from odocal.core.model import NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.simulate import drive
from odocal.core.tracks import Track, arc, polygon, spot_turn, straight

NOMINAL = WheelGeometry.symmetric(0.2, 0.5)  # believed: D = 0.2 m, b = 0.5 m
E_B = 1.05  # true wheelbase 5 % larger: every turn really turns 1/1.05 of the belief
TRUE = WheelGeometry(0.2, 0.2, 0.5 * E_B)
STEPS = 40  # increments per segment
DT = 0.02  # s per increment (50 Hz joint states)
STILL_S = 3.0  # s standing still at the start and at the end
GYRO_BIAS = 0.01  # rad/s on the yaw axis
GYRO_NOISE = 0.002  # rad/s per sample
START = (1.0, 2.0, 0.5)  # the robot's first pose in the world (mocap) frame
# The Husky's real mount: static_transform_publisher 0 -0.3 0.52 -pi/2 0 pi/2 base_link imu_link
# (x y z yaw pitch roll), so R_base_imu = Rz(-pi/2) Rx(pi/2): base z is the IMU's +y axis.
R_BASE_IMU = rotation_from_rpy(math.pi / 2, 0.0, -math.pi / 2)


@dataclass
class Run:
    time_s: np.ndarray  # (K,)
    right: np.ndarray  # wheel angles (rad), (K,)
    left: np.ndarray
    true_pose: np.ndarray  # (K, 3), start frame
    odo_pose: np.ndarray  # (K, 3), dead-reckoned with NOMINAL


def make_run(track: Track) -> Run:
    """Noise-free run of ``track`` with STILL_S of standing still before and after."""
    res = drive(
        track,
        TRUE,
        NOMINAL,
        NonSystematicError(),
        1,
        None,
        steps_per_segment=STEPS,
        trajectory=True,
    )
    pose = res.trajectory[0]
    right, left = [0.0], [0.0]
    for seg in track.segments:
        s_r, s_l = seg.wheel_travel(NOMINAL.wheelbase_m)
        for _ in range(STEPS):
            right.append(right[-1] + 2 * s_r / STEPS / NOMINAL.diameter_right_m)
            left.append(left[-1] + 2 * s_l / STEPS / NOMINAL.diameter_left_m)
    right, left = np.array(right), np.array(left)
    n_still = int(round(STILL_S / DT))

    def pad(a):
        return np.concatenate([np.repeat(a[:1], n_still, 0), a, np.repeat(a[-1:], n_still, 0)])

    right, left, pose = pad(right), pad(left), pad(pose)
    t = 5.0 + DT * np.arange(len(right))
    return Run(t, right, left, pose, dead_reckon(right, left, NOMINAL))


TRACK = Track(
    "square and circle",
    polygon(4, 1.0, "ccw").segments + (arc(0.6, 2 * math.pi), straight(0.5), spot_turn(math.pi)),
)


def world(pose):
    """Start-frame poses -> world (mocap) frame starting at START."""
    x0, y0, t0 = START
    c, s = math.cos(t0), math.sin(t0)
    return np.column_stack(
        [
            x0 + c * pose[:, 0] - s * pose[:, 1],
            y0 + s * pose[:, 0] + c * pose[:, 1],
            t0 + pose[:, 2],
        ]
    )


def quat_z(yaw):
    return (0.0, 0.0, math.sin(yaw / 2), math.cos(yaw / 2))


def quat_of(r):
    """Quaternion (x, y, z, w) of a rotation matrix (w > 0 branch is enough here)."""
    w = math.sqrt(max(1e-12, 1 + r[0, 0] + r[1, 1] + r[2, 2])) / 2
    return (
        (r[2, 1] - r[1, 2]) / (4 * w),
        (r[0, 2] - r[2, 0]) / (4 * w),
        (r[1, 0] - r[0, 1]) / (4 * w),
        w,
    )


class _Sqlite3WriterNoSync(Sqlite3Writer):
    """rosbags' sqlite3 storage writer, told not to wait for the disk (``PRAGMA synchronous =
    OFF``): the same file (tests/support/test_synthetic_robot.py compares the bytes), without
    an fsync for every statement of its schema (0.13 s per bag here, most of the time a short
    bag took). A test's bag lives in its tmp_path: nothing to keep across a crash."""

    def __init__(self, path: Path, compression: CompressionMode) -> None:
        # rosbags 0.11's Sqlite3Writer.__init__, with the pragma before the schema
        if compression == CompressionMode.STORAGE:
            raise WriterError("SQLITE3 writer does not support storage-side compression.")
        self.path = path / f"{path.name}.db3"
        self.conn = sqlite3.connect(f"file:{self.path}", uri=True)
        self.conn.execute("PRAGMA synchronous = OFF")
        self.conn.executescript(self.SQLITE_SCHEMA)
        self.cursor = self.conn.cursor()


class Writer2(_RosbagsWriter2):
    """rosbags' ROS 2 bag writer (mcap or sqlite3) with the sqlite3 storage of
    :class:`_Sqlite3WriterNoSync`: every test's ROS 2 bag is written through it."""

    STORAGE_PLUGINS = {
        **_RosbagsWriter2.STORAGE_PLUGINS, StoragePlugin.SQLITE3: _Sqlite3WriterNoSync
    }  # fmt: skip


_STORES: dict = {}


def typestore(ros1: bool):
    """rosbags' ROS 1 (Noetic) or ROS 2 (Humble) type store, with tf2_msgs/TFMessage: one per
    kind for every writer, so that rosbags compiles each serialiser once rather than per bag
    (the bytes written are the same)."""
    if ros1 not in _STORES:
        ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
        if "tf2_msgs/msg/TFMessage" not in ts.types:  # not in rosbags' ROS 1 store
            ts.register(
                get_types_from_msg(
                    "geometry_msgs/TransformStamped[] transforms", "tf2_msgs/msg/TFMessage"
                )
            )
        _STORES[ros1] = ts
    return _STORES[ros1]


class BagWriter:
    """Write messages into a ROS 1 bag or a ROS 2 bag (mcap or sqlite3) with rosbags."""

    def __init__(self, path, kind):
        self.ros1 = kind == "ros1"
        self.ts = typestore(self.ros1)
        if self.ros1:
            self.w = Writer1(path)
        else:
            plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
            self.w = Writer2(path, version=9, storage_plugin=plugin)
        self.conns = {}

    def __enter__(self):
        self.w.open()
        return self

    def __exit__(self, *exc):
        self.w.close()

    def T(self, name):
        return self.ts.types[name]

    def header(self, t, frame=""):
        sec = int(math.floor(t))
        stamp = self.T("builtin_interfaces/msg/Time")(sec=sec, nanosec=int(round((t - sec) * 1e9)))
        H = self.T("std_msgs/msg/Header")
        return (
            H(seq=0, stamp=stamp, frame_id=frame) if self.ros1 else H(stamp=stamp, frame_id=frame)
        )

    def vec(self, x, y, z):
        return self.T("geometry_msgs/msg/Vector3")(x=float(x), y=float(y), z=float(z))

    def quat(self, q):
        x, y, z, w = q
        return self.T("geometry_msgs/msg/Quaternion")(x=x, y=y, z=z, w=w)

    def pose(self, x, y, yaw):
        point = self.T("geometry_msgs/msg/Point")(x=float(x), y=float(y), z=0.0)
        return self.T("geometry_msgs/msg/Pose")(position=point, orientation=self.quat(quat_z(yaw)))

    def write(self, topic, msgtype, t, msg, log_t=None):
        if topic not in self.conns:
            kw = {"latching": 1} if self.ros1 and topic == "/tf_static" else {}
            self.conns[topic] = self.w.add_connection(topic, msgtype, typestore=self.ts, **kw)
        ser = self.ts.serialize_ros1 if self.ros1 else self.ts.serialize_cdr
        stamp = t if log_t is None else log_t
        self.w.write(self.conns[topic], int(round(stamp * 1e9)), ser(msg, msgtype))

    def joints(self, topic, t, names, positions, log_t=None):
        msg = self.T("sensor_msgs/msg/JointState")(
            header=self.header(t),
            name=list(names),
            position=np.array(positions, dtype=float),
            velocity=np.array([], dtype=float),
            effort=np.array([], dtype=float),
        )
        self.write(topic, "sensor_msgs/msg/JointState", t, msg, log_t)

    def pose_stamped(self, topic, t, x, y, yaw):
        msg = self.T("geometry_msgs/msg/PoseStamped")(
            header=self.header(t, "map"), pose=self.pose(x, y, yaw)
        )
        self.write(topic, "geometry_msgs/msg/PoseStamped", t, msg)

    def imu(self, topic, t, w, frame="imu_link"):
        z9 = np.zeros(9)
        msg = self.T("sensor_msgs/msg/Imu")(
            header=self.header(t, frame),
            orientation=self.quat((0.0, 0.0, 0.0, 1.0)),
            orientation_covariance=z9,
            angular_velocity=self.vec(*w),
            angular_velocity_covariance=z9,
            linear_acceleration=self.vec(0, 0, 9.81),
            linear_acceleration_covariance=z9,
        )
        self.write(topic, "sensor_msgs/msg/Imu", t, msg)

    def odometry(self, topic, t, x, y, yaw, v, wz):
        z36 = np.zeros(36)
        pwc = self.T("geometry_msgs/msg/PoseWithCovariance")(
            pose=self.pose(x, y, yaw), covariance=z36
        )
        twist = self.T("geometry_msgs/msg/Twist")(
            linear=self.vec(v, 0, 0), angular=self.vec(0, 0, wz)
        )
        twc = self.T("geometry_msgs/msg/TwistWithCovariance")(twist=twist, covariance=z36)
        msg = self.T("nav_msgs/msg/Odometry")(
            header=self.header(t, "odom"), child_frame_id="base_link", pose=pwc, twist=twc
        )
        self.write(topic, "nav_msgs/msg/Odometry", t, msg)

    def tf_static(self, t, parent, child, rot):
        tr = self.T("geometry_msgs/msg/Transform")(
            translation=self.vec(0, -0.3, 0.52), rotation=self.quat(quat_of(rot))
        )
        ts = self.T("geometry_msgs/msg/TransformStamped")(
            header=self.header(t, parent), child_frame_id=child, transform=tr
        )
        msg = self.T("tf2_msgs/msg/TFMessage")(transforms=[ts])
        self.write("/tf_static", "tf2_msgs/msg/TFMessage", t, msg)


def gyro_samples(run: Run, rng, rate_hz=100.0):
    """IMU times and angular velocity in the IMU frame: the true yaw rate, plus bias and noise."""
    # samples between the joint stamps, so that each one sees one constant true rate
    t = np.arange(run.time_s[0] + 0.25 / rate_hz, run.time_s[-1], 1.0 / rate_hz)
    # the true heading is piecewise linear between the joint samples: its rate is constant there
    rate_steps = np.diff(run.true_pose[:, 2]) / np.diff(run.time_s)
    idx = np.clip(np.searchsorted(run.time_s, t, side="right") - 1, 0, len(rate_steps) - 1)
    yaw_rate = rate_steps[idx] + GYRO_BIAS + GYRO_NOISE * rng.standard_normal(len(t))
    w_base = np.column_stack([np.zeros_like(t), np.zeros_like(t), yaw_rate])
    return t, w_base @ R_BASE_IMU  # rows: R^T w_base


def write_bag(
    path,
    kind,
    run: Run,
    *,
    joints=True,
    truth=True,
    imu=True,
    odom=False,
    tf=True,
    positions=None,
    times=None,
    names=("left_wheel_joint", "right_wheel_joint"),
    extra=None,
):
    """Write ``run`` into a bag; ``positions`` (K, 2) (right, left) and ``times`` override."""
    rng = np.random.default_rng(7)
    pos = np.column_stack([run.right, run.left]) if positions is None else positions
    t_j = run.time_s if times is None else times
    with BagWriter(path, kind) as w:
        if tf:
            w.tf_static(run.time_s[0], "base_link", "imu_link", R_BASE_IMU)
        if joints:
            for t, log_t, (r, lft) in zip(t_j, run.time_s, pos, strict=True):
                w.joints("/joint_states", t, names, [lft, r], log_t)  # names: (left, right)
        if truth:
            for t, p in zip(run.time_s, world(run.true_pose), strict=True):
                w.pose_stamped("/mocap/pose", t, *p)
        if odom:
            v = np.gradient(0.5 * (run.right + run.left) * 0.1, run.time_s)
            wz = np.gradient(run.odo_pose[:, 2], run.time_s)
            for k in range(0, len(run.time_s), 5):  # 10 Hz
                w.odometry("/odom", run.time_s[k], *run.odo_pose[k], v[k], wz[k])
        if imu:
            for t, wv in zip(*gyro_samples(run, rng), strict=True):
                w.imu("/imu", t, wv)
        if extra:
            extra(w)
    return path


KINDS = ["ros1", "mcap", "sqlite3"]


def lazy_bags(tmp_path_factory, run: Run, **options):
    """kind -> a bag of ``run`` of that kind (``write_bag``'s ``options``), written on first use
    into a folder of its own and only read by the tests that ask (a module fixture's value)."""
    paths = {}

    def get(kind):
        if kind not in paths:
            folder = tmp_path_factory.mktemp(kind)
            paths[kind] = write_bag(bag_path(folder, kind), kind, run, **options)
        return paths[kind]

    return get


def bag_path(tmp_path, kind, name="run"):
    return tmp_path / (f"{name}.bag" if kind == "ros1" else name)


# --------------------------------------------------------------------------- the Husky bags

_HUSKY_READS: dict = {}


def read_husky_once(monkeypatch):
    """From now on (``monkeypatch``) odocal's gyro fit reads each Husky bag once per test
    process: a later fit that picks topics already read gets the messages of the first read,
    which it does not change. What the Husky fits vary (axis, bias, mounting, exports) acts after
    the read; the first fit of each bag reads it for real, and test_bag_decode checks the read
    itself message by message."""
    import odocal.io.bag_gyro as gyro_reader

    real = gyro_reader.read_bag

    def read_once(path, topics, *, fast=True):
        key = (str(path), fast)
        bag = _HUSKY_READS.get(key)
        if bag is None:
            bag = _HUSKY_READS[key] = real(path, topics, fast=fast)
            return bag
        picked = {role: t for role, t in topics(bag.topics).items() if t is not None}
        wanted = list(dict.fromkeys(picked.values()))
        if not set(wanted) <= set(bag.messages):
            return real(path, topics, fast=fast)
        return replace(bag, messages={t: bag.messages[t] for t in wanted}, picked=picked)

    monkeypatch.setattr(gyro_reader, "read_bag", read_once)
