"""ROS 1 ``.bag`` and ROS 2 (``.mcap``, ``.db3`` or a rosbag2 folder) bags via ``rosbags``: opening,
topics, and messages as numeric series.

No ROS installation is needed; ``rosbags`` (the ``bags`` extra) is imported only when a bag is
read. Timestamps are integer nanoseconds inside rosbags; they are turned into seconds here, at the
edge, relative to the bag's start time. A message's time is its ``header.stamp`` (when the
measurement was made); a topic whose stamps are zero falls back to the time it was recorded.

What is read (docs/ros.md):

- wheel angles from ``sensor_msgs/JointState`` (positions in rad, or ticks with
  ``ticks_per_rev``); wrapped positions (a driver reporting angles in (-pi, pi]) are unwrapped;
- ground truth from ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped``,
  ``TransformStamped`` or ``nav_msgs/Odometry``, expressed in the start frame;
- gyro angular velocity from ``sensor_msgs/Imu``, the IMU mounting from ``/tf_static``;
- wheel odometry from ``nav_msgs/Odometry`` (for the gyro calibration).

Runs are assembled from these series in :mod:`odocal.io.bag_recording`. Every problem is an
:class:`~odocal.errors.InputError` naming the bag and the topic.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.gyro import rotation_from_quaternion
from ..errors import InputError, OdocalError
from .bag_decode import RECORD_TYPES, ImuRecord, OdometryRecord, decoder, record, stamp_ns
from .limits import (
    POSITION_MAX_M,
    RATE_MAX_RAD_S,
    SPEED_MAX_M_S,
    TICKS_MAX,
    TICKS_PER_REV,
    WHEEL_ANGLE_MAX_RAD,
)

__all__ = [
    "TopicInfo",
    "BagContents",
    "TopicSeries",
    "is_bag",
    "list_topics",
    "read_bag",
    "TopicChoice",
    "present",
    "check_bag_path",
    "pick_topic",
    "pose_series",
    "imu_series",
    "joint_series",
    "static_rotation",
    "BAG_SUFFIXES",
    "BASE_FRAMES",
    "EdgeMessages",
    "tf_messages",
    "transform_buffer",
    "ScanSeries",
    "scan_series",
    "LASER_SCAN",
    "JOINT_STATE",
    "IMU",
    "ODOMETRY",
    "POSE_TYPES",
]

JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
)
BASE_FRAMES = ("base_link", "base_footprint")
BAG_SUFFIXES = (".bag", ".db3", ".mcap")
_INSTALL_HINT = (
    "reading ROS bags needs the 'rosbags' package: pip install rosbags (or, in the odocal "
    "folder, pip install -e '.[bags]')"
)


# --------------------------------------------------------------------------- opening bags

_RECORDS = (ImuRecord, OdometryRecord)


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: name, message type ('sensor_msgs/msg/Imu') and message count."""

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class BagContents:
    """Deserialised messages of some topics of one bag.

    Attributes
    ----------
    path : Path
    topics : list of TopicInfo
        Every topic of the bag (not only the ones read).
    messages : dict
        topic -> list of (log_time_ns, message), in recording order; ``sensor_msgs/Imu`` and
        ``nav_msgs/Odometry`` messages as :class:`~odocal.io.bag_decode.ImuRecord` and
        :class:`~odocal.io.bag_decode.OdometryRecord` (the fields odocal reads).
    start_ns : int
        The bag's start time (ns since the epoch); times in seconds are relative to it.
    picked : dict
        role -> topic, as chosen by the function given to :func:`read_bag` (else empty).
    """

    path: Path
    topics: list[TopicInfo]
    messages: dict
    start_ns: int
    picked: dict = field(default_factory=dict)

    def msgtype(self, topic: str) -> str | None:
        """The message type of ``topic`` (None when the bag has no such topic)."""
        return next((t.msgtype for t in self.topics if t.name == topic), None)


def is_bag(path) -> bool:
    """True for a ``.bag``, ``.mcap`` or ``.db3`` file or a folder holding ``metadata.yaml``."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in BAG_SUFFIXES


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:  # pragma: no cover - depends on the installation
        raise InputError(_INSTALL_HINT) from None
    return AnyReader, Stores, get_typestore


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def check_bag_path(path) -> Path:
    """``path`` as a Path when it is a bag (a .bag, .mcap or .db3 file or a rosbag2 folder);
    InputError otherwise."""
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or folder", p)
    if p.is_dir():
        if not (p / "metadata.yaml").is_file():
            raise InputError("not a ROS 2 bag folder (no metadata.yaml)", p)
    elif p.suffix.lower() not in BAG_SUFFIXES:
        raise InputError(
            "not a ROS bag: expected a .bag, .mcap or .db3 file or a rosbag2 folder", p
        )
    elif p.suffix.lower() == ".bag":
        _check_ros1_version(p)
    return p


def _check_ros1_version(p: Path) -> None:
    """A ROS 1 bag of another format version than 2.0 (rosbags reads 2.0 only) is refused as
    such, not as a corrupt file."""
    try:
        with p.open("rb") as f:
            head = f.read(32)
    except OSError:
        return  # the reader says what is wrong
    for magic in (b"#ROSBAG V", b"#ROSRECORD V"):
        if head.startswith(magic):
            version = head[len(magic) :].split(b"\n", 1)[0].decode("ascii", "replace").strip()
            if version != "2.0":
                raise InputError(
                    f"unsupported ROS 1 bag format version {version} (odocal reads 2.0, the "
                    "format of every ROS 1 release since 2010): rewrite it with ROS 1's rosbag, "
                    "e.g. rosbag filter IN.bag OUT.bag 'True'",
                    p,
                )
            return


class _Bag:
    """An open AnyReader whose every failure becomes an InputError naming the bag."""

    def __init__(self, path) -> None:
        self.path = check_bag_path(path)
        any_reader, stores, get_typestore = _rosbags()
        ros1 = self.path.suffix.lower() == ".bag"
        default = get_typestore(stores.ROS1_NOETIC if ros1 else stores.ROS2_HUMBLE)
        try:
            self.reader = any_reader([self.path], default_typestore=default)
            self.reader.open()
        except OdocalError:
            raise
        except Exception as exc:  # corrupt or truncated data can raise anything
            raise InputError(
                f"cannot read the bag; is it truncated or corrupt? ({_why(exc)})", self.path
            ) from None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            self.reader.close()
        except Exception:  # noqa: BLE001 - closing a broken bag must not mask the real error
            pass

    def topics(self) -> list[TopicInfo]:
        counts: dict[str, list] = {}
        for c in self.reader.connections:
            entry = counts.setdefault(c.topic, [c.msgtype, 0])
            entry[1] += int(c.msgcount)
        return [TopicInfo(name, t, n) for name, (t, n) in sorted(counts.items())]

    def read(self, topics: Iterable[str], fast: bool = True) -> dict:
        """topic -> [(log_time_ns, message)]; Imu and Odometry as records
        (:mod:`odocal.io.bag_decode`), decoded there unless ``fast`` is False or the message is
        not of the standard form (then by rosbags, as every other type)."""
        wanted = set(topics)
        out: dict[str, list] = {t: [] for t in wanted}
        conns = [c for c in self.reader.connections if c.topic in wanted]
        deserialize = self.reader.deserialize
        ros1 = not self.reader.is2
        decoders = {
            c.id: decoder(c.msgtype, self.reader.typestore, ros1) if fast else None for c in conns
        }
        topic, count = None, 0
        try:
            for conn, t_ns, raw in self.reader.messages(connections=conns):
                topic = conn.topic
                fast_decode = decoders[conn.id]
                msg = fast_decode(raw) if fast_decode else None
                if msg is None:
                    msg = deserialize(raw, conn.msgtype)
                    if conn.msgtype in RECORD_TYPES:
                        msg = self._record(conn.msgtype, msg, topic)
                out[topic].append((int(t_ns), msg))
                count += 1
        except OdocalError:
            raise
        except Exception as exc:
            last = f", the last on '{topic}'" if topic else ""
            raise InputError(
                f"cannot read the bag after {count} good messages{last} ({_why(exc)}); is it "
                "truncated or corrupt?",
                self.path,
            ) from None
        return out

    def _record(self, msgtype: str, msg, topic: str):
        try:
            return record(msgtype, msg)
        except AttributeError as exc:
            raise InputError(
                f"{_short(msgtype)} of a non-standard definition: it has no field '{exc.name}'",
                self.path,
                None,
                topic,
            ) from None


def list_topics(path) -> list[TopicInfo]:
    """The topics of a bag, sorted by name."""
    with _Bag(path) as bag:
        return bag.topics()


TopicChoice = Callable[[list[TopicInfo]], Mapping[str, str | None]]


def read_bag(path, topics: Iterable[str] | TopicChoice = (), *, fast: bool = True) -> BagContents:
    """Read the messages of some topics of a bag, opening it once.

    ``topics``: topic names (each must exist), or a function of the bag's topic list returning
    role -> topic name (None: that role has no topic; nothing is read for it), which picks the
    topics on the open bag (with :func:`pick_topic`, whose errors it raises); the roles are kept
    in :attr:`BagContents.picked`. ``fast``: decode ``sensor_msgs/Imu`` and ``nav_msgs/Odometry``
    of the standard definition with :mod:`odocal.io.bag_decode` (the same numbers as rosbags);
    False: every message through rosbags (the reference the tests and benchmarks compare with).
    """
    with _Bag(path) as bag:
        info = bag.topics()
        picked: dict[str, str] = {}
        if callable(topics):
            picked = {role: t for role, t in topics(info).items() if t is not None}
            wanted = list(dict.fromkeys(picked.values()))
        else:
            wanted = list(topics)
        names = {t.name for t in info}
        for t in wanted:
            if t not in names:
                raise InputError(f"no topic '{t}' in the bag; {_available(info)}", bag.path)
        messages = bag.read(wanted, fast)
        start = int(bag.reader.start_time) if info else 0
    return BagContents(bag.path, info, messages, start, picked)


def present(topics: Sequence[TopicInfo], name: str) -> str | None:
    """``name`` if the bag has that topic (an optional topic such as ``/tf_static``), else None."""
    return name if any(t.name == name for t in topics) else None


def _available(topics: Sequence[TopicInfo]) -> str:
    if not topics:
        return "the bag holds no topics"
    return "topics: " + ", ".join(f"{t.name} ({_short(t.msgtype)})" for t in topics)


def _short(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


# --------------------------------------------------------------------------- topic choice


def pick_topic(
    topics: Sequence[TopicInfo],
    requested: str | None,
    types: Sequence[str],
    role: str,
    path: Path,
    flag: str,
    required: bool = True,
) -> str | None:
    """The topic for ``role``: the requested one (checked) or the only one of ``types``."""
    by_name = {t.name: t for t in topics}
    wanted = " or ".join(_short(t) for t in types)
    if requested:
        if requested not in by_name:
            raise InputError(f"no topic '{requested}' in the bag; {_available(topics)}", path)
        got = by_name[requested].msgtype
        if got not in types:
            raise InputError(
                f"topic '{requested}' has type {_short(got)}, expected {wanted} for the {role}",
                path,
            )
        return requested
    found = [t.name for t in topics if t.msgtype in types]
    if len(found) == 1:
        return found[0]
    if not found:
        if not required:
            return None
        raise InputError(f"no {wanted} topic for the {role}; {_available(topics)}", path)
    raise InputError(
        f"several {wanted} topics could be the {role}: {', '.join(found)}; choose one with {flag}",
        path,
    )


# --------------------------------------------------------------------------- series


@dataclass(frozen=True)
class TopicSeries:
    """Numeric arrays of one topic. ``time_s`` shape (K,), relative to the bag start (s)."""

    topic: str
    time_s: np.ndarray
    values: dict
    frame_id: str = ""
    child_frame_id: str = ""
    meta: dict = field(default_factory=dict)


def _stamp_ns(msg) -> int:
    """The header stamp (ns) of a message, or of a record (Imu, Odometry; io.bag_decode)."""
    return msg.stamp_ns if isinstance(msg, _RECORDS) else stamp_ns(msg.header)


def _frame_id(msg) -> str:
    return msg.frame_id if isinstance(msg, _RECORDS) else msg.header.frame_id


def _times(msgs: list, path: Path, topic: str, start_ns: int) -> np.ndarray:
    """Header stamps (or log times when the stamps are zero) in s relative to ``start_ns``;
    InputError unless strictly increasing."""
    stamps = [_stamp_ns(m) for _, m in msgs]
    if any(s == 0 for s in stamps):
        stamps = [t for t, _ in msgs]
    t = (np.array(stamps, dtype=np.int64) - np.int64(start_ns)).astype(float) * 1e-9
    d = np.diff(t)
    bad = np.nonzero(d <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        what = "repeats" if d[bad[0]] == 0 else "goes backwards"
        raise InputError(
            f"time {what} at message {i} ({t[i]:.6f} s after {t[i - 1]:.6f} s); the header "
            "stamps must be strictly increasing",
            path,
            None,
            topic,
        )
    return t


def _finite(arr: np.ndarray, path: Path, topic: str, what: str, limit: float | None = None) -> None:
    """InputError naming the first message whose ``what`` is not finite, or larger than
    ``limit`` in magnitude (an absurd value; odocal.io.limits)."""
    flat = arr.reshape(len(arr), -1)
    ok = np.all(np.isfinite(flat), axis=1)
    if not np.all(ok):
        i = int(np.nonzero(~ok)[0][0])
        raise InputError(f"message {i}: {what} is not finite (NaN or inf)", path, None, topic)
    if limit is not None and len(flat):
        big = np.nonzero(np.any(np.abs(flat) > limit, axis=1))[0]
        if len(big):
            i = int(big[0])
            v = flat[i][np.argmax(np.abs(flat[i]))]
            raise InputError(
                f"message {i}: {what} is implausibly large ({v:.6g}; at most {limit:g})",
                path,
                None,
                topic,
            )


def _need(msgs: list, path: Path, topic: str, n: int = 2) -> None:
    if len(msgs) < n:
        raise InputError(f"needs at least {n} messages, got {len(msgs)}", path, None, topic)


def _yaw(x: float, y: float, z: float, w: float) -> float:
    return math.atan2(2.0 * (w * z + x * y), 1.0 - 2.0 * (y * y + z * z))


def _pose_of(msg, msgtype: str):
    """Position (x, y, z) and orientation (x, y, z, w) of a pose message or an odometry record."""
    if msgtype == ODOMETRY:
        return msg.position, msg.orientation
    if msgtype.endswith("PoseWithCovarianceStamped"):
        p, q = msg.pose.pose.position, msg.pose.pose.orientation
    elif msgtype.endswith("TransformStamped"):
        p, q = msg.transform.translation, msg.transform.rotation
    else:
        p, q = msg.pose.position, msg.pose.orientation
    return (p.x, p.y, p.z), (q.x, q.y, q.z, q.w)


def pose_series(bag: BagContents, topic: str) -> TopicSeries:
    """x_m, y_m, yaw_rad (unwrapped) of a pose or odometry topic."""
    msgs, mt = bag.messages[topic], bag.msgtype(topic) or ""
    _need(msgs, bag.path, topic)
    rows = []
    for _, m in msgs:
        p, q = _pose_of(m, mt)
        rows.append((p[0], p[1], _yaw(*q)))
    xy = np.array(rows, dtype=float)
    _finite(xy[:, :2], bag.path, topic, "the position (m)", POSITION_MAX_M)
    _finite(xy[:, 2:], bag.path, topic, "the orientation")
    t = _times(msgs, bag.path, topic, bag.start_ns)
    values = {"x": xy[:, 0], "y": xy[:, 1], "yaw": np.unwrap(xy[:, 2])}
    if mt == ODOMETRY:
        tw = np.array([(m.linear[0], m.angular[2]) for _, m in msgs], dtype=float)
        _finite(tw[:, :1], bag.path, topic, "the twist's linear speed (m/s)", SPEED_MAX_M_S)
        _finite(tw[:, 1:], bag.path, topic, "the twist's yaw rate (rad/s)", RATE_MAX_RAD_S)
        values["speed"], values["yaw_rate"] = tw[:, 0], tw[:, 1]
    last = msgs[0][1]
    return TopicSeries(
        topic,
        t,
        values,
        _frame_id(last).lstrip("/"),
        getattr(last, "child_frame_id", "").lstrip("/"),
    )


def imu_series(bag: BagContents, topic: str) -> TopicSeries:
    """Angular velocity (rad/s, IMU frame), ``values['angular_velocity']`` shape (K, 3)."""
    msgs = bag.messages[topic]
    _need(msgs, bag.path, topic)
    w = np.array([m.angular_velocity for _, m in msgs], dtype=float)
    _finite(w, bag.path, topic, "angular_velocity (rad/s)", RATE_MAX_RAD_S)
    t = _times(msgs, bag.path, topic, bag.start_ns)
    return TopicSeries(topic, t, {"angular_velocity": w}, msgs[0][1].frame_id.lstrip("/"))


def _side_joint(names: set[str], side: str, path: Path, topic: str) -> str:
    cands = sorted(n for n in names if side in n.lower())
    if len(cands) > 1:
        wheels = [n for n in cands if "wheel" in n.lower()]
        cands = wheels or cands
    if len(cands) == 1:
        return cands[0]
    what = "no" if not cands else "several"
    raise InputError(
        f"{what} {side}-wheel joint among {', '.join(sorted(names)) or 'no joints'}"
        f"{': ' + ', '.join(cands) if cands else ''}; name it with the {side}_joint option "
        f"(--{side}-joint)",
        path,
        None,
        topic,
    )


def _unwrap_wheel(phi: np.ndarray, period: float, path: Path, topic: str, joint: str):
    """Unwrap a wheel angle reported modulo ``period``; reject other jumps.

    A position whose samples all lie in one window of width ``period`` and that jumps by more
    than half a period is a wrapped angle: it is unwrapped (the wheel must turn less than half a
    revolution between samples, else the direction is ambiguous). A jump of more than half a
    period in a position that is NOT confined to one window is a glitch or a reset: rejected.
    Returns (angle, number of wraps removed).
    """
    d = np.diff(phi)
    jumps = np.abs(d) > 0.5 * period
    if not np.any(jumps):
        return phi, 0
    span = float(phi.max() - phi.min())
    if span <= period * (1 + 1e-6):
        return np.unwrap(phi, period=period), int(jumps.sum())
    i = int(np.nonzero(jumps)[0][0]) + 1
    raise InputError(
        f"joint '{joint}' jumps by {d[i - 1]:+.3f} rad at message {i}, more than half a "
        "revolution between samples: an encoder reset or glitch, or a too-low sampling rate",
        path,
        None,
        topic,
    )


def joint_series(
    bag: BagContents,
    topic: str,
    right_joint: str | None = None,
    left_joint: str | None = None,
    ticks_per_rev: float | None = None,
) -> TopicSeries:
    """Right and left wheel angles (rad) from a JointState topic.

    Messages that do not carry both joints are skipped (several publishers may share
    ``/joint_states``). ``values``: 'right', 'left' (rad, cumulative, unwrapped).
    """
    msgs = bag.messages[topic]
    path = bag.path
    names: set[str] = set()
    for _, m in msgs:
        names.update(m.name)
    right = right_joint or _side_joint(names, "right", path, topic)
    left = left_joint or _side_joint(names, "left", path, topic)
    for j in (right, left):
        if j not in names:
            raise InputError(
                f"no joint '{j}'; joints: {', '.join(sorted(names)) or 'none'}", path, None, topic
            )
    if right == left:
        raise InputError(f"the right and left joints are both '{right}'", path, None, topic)
    kept: list[tuple[int, Any]] = []
    rows: list[tuple[float, float]] = []
    for item in msgs:
        m = item[1]
        nm = list(m.name)
        if right in nm and left in nm:
            pos = m.position
            ir, il = nm.index(right), nm.index(left)
            if len(pos) <= max(ir, il):
                raise InputError(
                    f"message {len(kept)}: {len(pos)} positions for {len(nm)} joint names",
                    path,
                    None,
                    topic,
                )
            kept.append(item)
            rows.append((pos[ir], pos[il]))
    _need(kept, path, topic)
    phi = np.array(rows, dtype=float)
    if ticks_per_rev is not None:
        lo, hi = TICKS_PER_REV
        if not (math.isfinite(ticks_per_rev) and lo <= ticks_per_rev <= hi):
            raise InputError(
                f"ticks per revolution must be {lo:g} .. {hi:g}, got {ticks_per_rev!r}",
                field="ticks_per_rev",
            )
        _finite(phi, path, topic, "a wheel position (ticks)", TICKS_MAX)
        phi = phi * (2.0 * math.pi / ticks_per_rev)
    _finite(phi, path, topic, "a wheel position (rad)", WHEEL_ANGLE_MAX_RAD)
    t = _times(kept, path, topic, bag.start_ns)
    r, wr = _unwrap_wheel(phi[:, 0], 2.0 * math.pi, path, topic, right)
    lft, wl = _unwrap_wheel(phi[:, 1], 2.0 * math.pi, path, topic, left)
    return TopicSeries(
        topic,
        t,
        {"right": r, "left": lft},
        kept[0][1].header.frame_id,
        meta={"right_joint": right, "left_joint": left, "wraps_unwrapped": wr + wl},
    )


def static_rotation(bag: BagContents, child: str, parents: Sequence[str]):
    """R_parent_child, shape (3, 3), composed along ``/tf_static`` from ``child`` up to the first
    frame in ``parents``; (None, None) when there is no such chain."""
    edges: dict[str, tuple[str, np.ndarray]] = {}
    for _, m in bag.messages.get("/tf_static", []):
        for tr in m.transforms:
            q = tr.transform.rotation
            edges[tr.child_frame_id.lstrip("/")] = (
                tr.header.frame_id.lstrip("/"),
                rotation_from_quaternion((q.x, q.y, q.z, q.w)),
            )
    frame, rot, seen = child.lstrip("/"), np.eye(3), set()
    while frame not in parents:
        if frame not in edges or frame in seen:
            return None, None
        seen.add(frame)
        parent, r = edges[frame]
        rot = r @ rot
        frame = parent
    return rot, frame


# --------------------------------------------------------------------------- transforms


@dataclass(frozen=True)
class EdgeMessages:
    """Every transform of one edge published on ``/tf``, in publishing order, repeats kept.

    ``time_s`` (K,) header stamps relative to the bag start (s); ``translation_m`` (K, 3);
    ``quaternion_xyzw`` (K, 4)."""

    parent: str
    child: str
    time_s: np.ndarray
    translation_m: np.ndarray
    quaternion_xyzw: np.ndarray


def tf_messages(bag: BagContents, topic: str = "/tf") -> dict[tuple[str, str], EdgeMessages]:
    """The transforms of ``/tf`` per (parent, child) edge, repeats kept (SLAM packages republish
    their last correction; which messages bring news is decided later)."""
    rows: dict[tuple[str, str], list] = {}
    for i, (t_log, m) in enumerate(bag.messages.get(topic, [])):
        for tr in m.transforms:
            key = (tr.header.frame_id.lstrip("/"), tr.child_frame_id.lstrip("/"))
            stamp = stamp_ns(tr.header) or t_log
            p, q = tr.transform.translation, tr.transform.rotation
            rows.setdefault(key, []).append((stamp, p.x, p.y, p.z, q.x, q.y, q.z, q.w, i))
    out = {}
    for (parent, child), r in rows.items():
        a = np.array([row[1:8] for row in r], dtype=float)
        if not np.all(np.isfinite(a)):
            k = int(np.nonzero(~np.all(np.isfinite(a), axis=1))[0][0])
            raise InputError(
                f"message {r[k][8]}: transform '{parent} -> {child}' is not finite (NaN or inf)",
                bag.path,
                None,
                topic,
            )
        t = (np.array([row[0] for row in r], dtype=np.int64) - np.int64(bag.start_ns)) * 1e-9
        out[(parent, child)] = EdgeMessages(parent, child, t, a[:, :3], a[:, 3:])
    return out


def transform_buffer(bag: BagContents):
    """A :class:`~odocal.core.transforms.TransformBuffer` of the bag's ``/tf`` and
    ``/tf_static``."""
    from ..core.transforms import TransformBuffer

    buf = TransformBuffer()
    for (parent, child), e in tf_messages(bag).items():
        buf.add(parent, child, e.time_s, e.translation_m, e.quaternion_xyzw)
    for _, m in bag.messages.get("/tf_static", []):
        for tr in m.transforms:
            p, q = tr.transform.translation, tr.transform.rotation
            buf.add_static(
                tr.header.frame_id.lstrip("/"),
                tr.child_frame_id.lstrip("/"),
                (p.x, p.y, p.z),
                (q.x, q.y, q.z, q.w),
            )
    return buf


# --------------------------------------------------------------------------- laser scans

LASER_SCAN = "sensor_msgs/msg/LaserScan"


@dataclass(frozen=True)
class ScanSeries:
    """The scans of one ``sensor_msgs/LaserScan`` topic as points in the sensor frame.

    ``time_s`` (N,) header stamps relative to the bag start (s); ``points_m`` N arrays of shape
    (n_i, 2) (invalid ranges dropped, REP-117); ``frame_id`` the sensor frame."""

    topic: str
    time_s: np.ndarray
    points_m: tuple[np.ndarray, ...]
    frame_id: str


def scan_series(bag: BagContents, topic: str) -> ScanSeries:
    """Every scan of ``topic`` (InputError for absurd scan parameters or no valid range)."""
    from ..calibration.scan_matching import scan_points

    msgs = bag.messages[topic]
    _need(msgs, bag.path, topic)
    points = []
    for i, (_, m) in enumerate(msgs):
        params = (m.angle_min, m.angle_increment, m.range_min, m.range_max)
        if not all(math.isfinite(v) for v in params) or not 0 <= m.range_min < m.range_max:
            raise InputError(
                f"message {i}: scan parameters are not usable (angle_min {m.angle_min}, "
                f"angle_increment {m.angle_increment}, range_min {m.range_min}, range_max "
                f"{m.range_max})",
                bag.path,
                None,
                topic,
            )
        points.append(scan_points(np.asarray(m.ranges, dtype=float), *params))
    if not any(len(p) for p in points):
        raise InputError(
            f"no scan has a valid range (all NaN, inf or outside [range_min, range_max]) in "
            f"{len(points)} scans",
            bag.path,
            None,
            topic,
        )
    t = _times(msgs, bag.path, topic, bag.start_ns)
    return ScanSeries(topic, t, tuple(points), msgs[0][1].header.frame_id.lstrip("/"))
