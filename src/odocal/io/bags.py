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

import gc
import math
from collections.abc import Callable, Iterable, Iterator, Mapping, Sequence, Sized
from contextlib import contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.gyro import rotation_from_quaternion
from ..errors import BagDataError, InputError, OdocalError
from .bag_columns import (
    CHUNK,
    COLUMN_TYPES,
    ColumnBuilder,
    JointStates,
    LaserScans,
    NonStandard,
    Transforms,
    is_standard,
)
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
    "read_bag_once",
    "ROUTE_TYPES",
    "RUN_TYPES",
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
    "ScanPoints",
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
    """One topic of a bag: name, message type ('sensor_msgs/msg/Imu') and message count;
    ``frames``: the (frame_id, child_frame_id) of its first message, when the bag was read
    (:func:`read_bag_once`), else None."""

    name: str
    msgtype: str
    count: int
    frames: tuple[str, str] | None = None

    @property
    def world_pose(self) -> bool:
        """An Odometry in a world frame ('map', 'world', ...: no 'odom' in its frame name): a
        localisation or ground truth (lidar ICP, SLAM, motion capture), not the wheel
        odometry, whose frame is the odometry frame ('odom')."""
        if self.msgtype != ODOMETRY or self.frames is None or not self.frames[0]:
            return False
        return "odom" not in self.frames[0].lstrip("/").lower()

    @property
    def wheel_odometry_frame(self) -> bool:
        """An Odometry whose frame is the odometry frame ('odom'): the wheels' own odometry (or
        a filter of it), never a reference for the wheels."""
        if self.msgtype != ODOMETRY or self.frames is None:
            return False
        return "odom" in self.frames[0].lstrip("/").lower()


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
        :class:`~odocal.io.bag_decode.OdometryRecord` (the fields odocal reads). A
        ``sensor_msgs/JointState``, ``tf2_msgs/TFMessage`` or ``sensor_msgs/LaserScan`` topic as
        columns instead (:class:`~odocal.io.bag_columns.JointStates`, ``Transforms``,
        ``LaserScans``): read them with :func:`joint_series`, :func:`tf_messages`,
        :func:`transform_buffer`, :func:`static_rotation` and :func:`scan_series`; iterating
        one still gives (log_time_ns, message) pairs with rosbags' field names, slowly.
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
    InputError otherwise. A bag already read (:class:`BagContents`) gives its path."""
    if isinstance(path, BagContents):
        return path.path
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
            raise BagDataError(
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
        not of the standard form (then by rosbags, as every other type); JointState, TFMessage
        and LaserScan topics as columns (:mod:`odocal.io.bag_columns`, parsed there on the same
        terms).

        The garbage collector is paused during the read: it would otherwise walk the messages
        read so far again and again (half the time of a long read), and they hold no cycles."""
        wanted = set(topics)
        out: dict[str, Any] = {t: [] for t in wanted}
        conns = [c for c in self.reader.connections if c.topic in wanted]
        if not conns:  # (rosbags reads every connection when given none)
            return out
        deserialize = self.reader.deserialize
        ros1 = not self.reader.is2
        typestore = self.reader.typestore
        decoders = {c.id: decoder(c.msgtype, typestore, ros1) if fast else None for c in conns}
        builders = self._builders(conns, fast)
        parse = {c.id: fast and is_standard(c.msgtype, typestore, ros1) for c in conns}
        targets = {c.id: builders[c.topic] for c in conns if c.topic in builders}
        topic, count = None, 0
        paused = gc.isenabled()
        gc.disable()
        try:
            for conn, t_ns, raw in self.reader.messages(connections=conns):
                topic = conn.topic
                builder = targets.get(conn.id)
                if builder is not None:  # a column topic: decoded a chunk at a time
                    if not parse[conn.id]:
                        builder.slow.append(len(builder.raws))
                    builder.raws.append(raw)
                    builder.logs.append(t_ns)
                    builder.index.append(count)
                    count += 1
                    if len(builder.raws) >= CHUNK:
                        builder.flush()
                        if builder.failures:
                            self._first_failure(builders)
                    continue
                fast_decode = decoders[conn.id]
                msg = fast_decode(raw) if fast_decode else None
                if msg is None:
                    msg = deserialize(raw, conn.msgtype)
                    if conn.msgtype in RECORD_TYPES:
                        msg = self._record(conn.msgtype, msg, topic)
                out[topic].append((int(t_ns), msg))
                count += 1
            for builder in builders.values():
                builder.flush()
            self._first_failure(builders)
        except OdocalError:
            self._first_failure(builders)
            raise
        except Exception as exc:
            self._first_failure(builders)
            last = f", the last on '{topic}'" if topic else ""
            raise BagDataError(
                f"cannot read the bag after {count} good messages{last} ({_why(exc)}); is it "
                "truncated or corrupt?",
                self.path,
            ) from None
        finally:
            if paused:
                gc.enable()
        for name, builder in builders.items():
            out[name] = builder.finish()
        return out

    def _builders(self, conns, fast: bool) -> dict[str, ColumnBuilder]:
        """topic -> the builder of its columns, for the topics of a column type (all their
        connections of that one type)."""
        types: dict[str, set[str]] = {}
        for c in conns:
            types.setdefault(c.topic, set()).add(c.msgtype)
        ros1 = not self.reader.is2
        deserialize = self.reader.deserialize
        max_sequence = int(getattr(self.reader.typestore, "max_sequence_length", 2**32 - 1))
        builders = {}
        for topic, kinds in types.items():
            (msgtype,) = kinds if len(kinds) == 1 else (None,)
            if msgtype in COLUMN_TYPES:
                builders[topic] = ColumnBuilder(
                    topic,
                    msgtype,
                    ros1,
                    lambda raw, mt=msgtype: deserialize(raw, mt),
                    max_sequence,
                )
            elif any(k in COLUMN_TYPES for k in kinds):
                raise InputError(
                    f"topic '{topic}' carries several message types ({', '.join(sorted(kinds))})",
                    self.path,
                )
        return builders

    def _first_failure(self, builders: Mapping[str, ColumnBuilder]) -> None:
        """Raise the first message (in reading order) the column builders could not decode,
        as the read would have at that message; nothing when none failed."""
        if not any(b.failures for b in builders.values()):
            return
        for b in builders.values():
            b.flush()  # a message read earlier, still waiting in a chunk, may have failed too
        first = min((f for b in builders.values() for f in b.failures), key=lambda f: f.index)
        exc = first.exc
        if isinstance(exc, NonStandard):
            raise InputError(
                f"{_short(exc.msgtype)} of a non-standard definition: it has no field '{exc.name}'",
                self.path,
                None,
                first.topic,
            ) from None
        if isinstance(exc, OdocalError):
            raise exc
        raise BagDataError(
            f"cannot read the bag after {first.index} good messages, the last on "
            f"'{first.topic}' ({_why(exc)}); is it truncated or corrupt?",
            self.path,
        ) from None

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


@dataclass(frozen=True)
class BagOverview:
    """What ``odocal bag-info`` shows of a bag: its topics, its time span (log times, ns since
    the epoch; 0 and 0 for a bag without messages) and the frame tree of ``/tf`` and
    ``/tf_static``: each (parent, child, static) edge once, frames without a leading '/', in the
    order they first appear (``/tf_static`` first)."""

    topics: list[TopicInfo]
    start_ns: int
    end_ns: int
    frames: tuple[tuple[str, str, bool], ...]

    @property
    def duration_s(self) -> float:
        """Time between the first and the last message (s)."""
        return (self.end_ns - self.start_ns) / 1e9


def bag_overview(path) -> BagOverview:
    """The topics, time span and ``/tf`` + ``/tf_static`` frame tree of a bag, opening it once
    (only the two transform topics are read)."""
    with _Bag(path) as bag:
        info = bag.topics()
        names = {t.name for t in info}
        tf_topics = [t for t in ("/tf_static", "/tf") if t in names]
        messages = bag.read(tf_topics) if tf_topics else {}
        has_messages = any(t.count for t in info)
        start = int(bag.reader.start_time) if has_messages else 0
        end = int(bag.reader.end_time) if has_messages else 0
    edges: dict[tuple[str, str, bool], None] = {}
    for topic in tf_topics:
        tf = messages.get(topic)
        if isinstance(tf, Transforms):
            for e in dict.fromkeys(tf.edge.tolist()):
                parent, child = tf.edges[e]
                edges[(parent.lstrip("/"), child.lstrip("/"), topic == "/tf_static")] = None
    return BagOverview(info, start, end, tuple(edges))


TopicChoice = Callable[[list[TopicInfo]], Mapping[str, str | None]]


def read_bag(
    path,
    topics: Iterable[str] | TopicChoice = (),
    *,
    fast: bool = True,
    then: Callable[[BagContents], Mapping[str, str | None]] | None = None,
) -> BagContents:
    """Read the messages of some topics of a bag, opening it once.

    ``topics``: topic names (each must exist), or a function of the bag's topic list returning
    role -> topic name (None: that role has no topic; nothing is read for it), which picks the
    topics on the open bag (with :func:`pick_topic`, whose errors it raises); the roles are kept
    in :attr:`BagContents.picked`. ``fast``: decode ``sensor_msgs/Imu`` and ``nav_msgs/Odometry``
    of the standard definition with :mod:`odocal.io.bag_decode` and JointState, TFMessage and
    LaserScan into columns with :mod:`odocal.io.bag_columns` (the same numbers as rosbags);
    False: every message through rosbags (the reference the tests and benchmarks compare with).
    ``then``: a function of what was read returning more roles -> topics (None: not needed),
    read in a second pass over the open bag (a topic only some bags need: ``/tf`` when
    ``/tf_static`` lacks a transform).
    """
    if isinstance(path, BagContents):
        return _from_contents(path, topics, fast, then)
    with _Bag(path) as bag:
        info = bag.topics()
        picked: dict[str, str] = {}
        if callable(topics):
            picked = {role: t for role, t in topics(info).items() if t is not None}
            wanted = list(dict.fromkeys(picked.values()))
        else:
            wanted = list(topics)
        _check_present(wanted, info, bag.path)
        messages = bag.read(wanted, fast)
        start = int(bag.reader.start_time) if info else 0
        contents = BagContents(bag.path, info, messages, start, picked)
        if then is not None:
            more = {role: t for role, t in then(contents).items() if t is not None}
            extra = [t for t in dict.fromkeys(more.values()) if t not in messages]
            _check_present(extra, info, bag.path)
            if extra:
                messages.update(bag.read(extra, fast))
            picked.update(more)
    return contents


def _from_contents(
    bag: BagContents,
    topics: Iterable[str] | TopicChoice,
    fast: bool,
    then: Callable[[BagContents], Mapping[str, str | None]] | None,
) -> BagContents:
    """:func:`read_bag` of a bag already read (every topic a command needs, in one pass): the
    topics picked from what was read, without opening the bag again (a topic that was not read
    is read from the file)."""
    picked: dict[str, str] = {}
    if callable(topics):
        picked = {role: t for role, t in topics(bag.topics).items() if t is not None}
        wanted = list(dict.fromkeys(picked.values()))
    else:
        wanted = list(topics)
    _check_present(wanted, bag.topics, bag.path)
    messages = {t: bag.messages[t] for t in wanted if t in bag.messages}
    missing = [t for t in wanted if t not in messages]
    if missing:
        messages.update(read_bag(bag.path, missing, fast=fast).messages)
    contents = BagContents(bag.path, bag.topics, messages, bag.start_ns, picked)
    if then is not None:
        more = {role: t for role, t in then(contents).items() if t is not None}
        extra = [t for t in dict.fromkeys(more.values()) if t not in messages]
        _check_present(extra, bag.topics, bag.path)
        messages.update({t: bag.messages[t] for t in extra if t in bag.messages})
        rest = [t for t in extra if t not in messages]
        if rest:
            messages.update(read_bag(bag.path, rest, fast=fast).messages)
        picked.update(more)
    return contents


#: The message types a bag route may read: what :func:`read_bag_once` reads.
ROUTE_TYPES = (JOINT_STATE, IMU, ODOMETRY, "sensor_msgs/msg/LaserScan", *POSE_TYPES)
#: What a run of a bag is made of (wheels, truth, gyro): :func:`read_bag_once` without scans.
RUN_TYPES = (JOINT_STATE, IMU, ODOMETRY, *POSE_TYPES)


def read_bag_once(
    path, named: Iterable[str | None] = (), types: Sequence[str] = ROUTE_TYPES
) -> BagContents:
    """Every topic of ``path`` any bag route may read (the ``types``, default
    :data:`ROUTE_TYPES`; ``/tf``, ``/tf_static`` and the topics ``named`` by the user), in one
    pass: the routes then pick their topics from it (:func:`read_bag` of a :class:`BagContents`)
    without opening the bag again. Each topic's frames are known then
    (:attr:`TopicInfo.frames`: an Odometry in a world frame is a truth, not the wheels)."""

    def choose(info: list[TopicInfo]) -> dict[str, str | None]:
        names = {t.name for t in info}
        # /tf (often most of a bag's messages) when a route may need it: a SLAM pose, a laser's
        # mounting, or wheels that are only odom -> base_link; /tf_static (an IMU's or a laser's
        # mounting) when something it mounts is read
        wheels = any(t.msgtype in (JOINT_STATE, ODOMETRY) for t in info)
        frames = ["/tf"] if (ROUTE_TYPES == tuple(types) or not wheels) else []
        if any(t.msgtype in types and t.msgtype in (IMU, "sensor_msgs/msg/LaserScan")
               for t in info):  # fmt: skip
            frames.append("/tf_static")
        keep = [t.name for t in info if t.msgtype in types or t.name in frames]
        keep += [t for t in named if t and t in names]
        return {t: t for t in dict.fromkeys(keep)}

    bag = read_bag(path, choose)
    info = [replace(t, frames=_first_frames(bag.messages.get(t.name))) for t in bag.topics]
    return BagContents(bag.path, info, bag.messages, bag.start_ns)


def _first_frames(messages: Any) -> tuple[str, str] | None:
    """(frame_id, child_frame_id) of the first Odometry or pose message of a topic read, else
    None."""
    if not isinstance(messages, list) or not messages:
        return None
    first = messages[0][1]
    if not isinstance(first, OdometryRecord) and not hasattr(first, "header"):
        return None
    return _frame_id(first).lstrip("/"), str(getattr(first, "child_frame_id", "")).lstrip("/")


def _check_present(wanted: Iterable[str], info: Sequence[TopicInfo], path: Path) -> None:
    names = {t.name for t in info}
    for t in wanted:
        if t not in names:
            raise InputError(f"no topic '{t}' in the bag; {_available(info)}", path)


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
    stamps = np.array([_stamp_ns(m) for _, m in msgs], dtype=np.int64)
    return _seconds(stamps, np.array([t for t, _ in msgs], dtype=np.int64), path, topic, start_ns)


def _seconds(
    stamps: np.ndarray, log_ns: np.ndarray, path: Path, topic: str, start_ns: int
) -> np.ndarray:
    """:func:`_times` of header stamps and log times (int64 ns)."""
    if np.any(stamps == 0):
        stamps = log_ns
    t = (np.asarray(stamps, dtype=np.int64) - np.int64(start_ns)).astype(float) * 1e-9
    d = np.diff(t)
    bad = np.nonzero(d <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        if np.count_nonzero(d == 0) >= 0.4 * len(d):
            what = (
                f"every message appears twice ({np.count_nonzero(d == 0)} of {len(t)} stamps "
                "repeat the one before: recorded twice, or two publishers of one topic?)"
            )
        elif d[bad[0]] == 0:
            what = f"time repeats at message {i} ({t[i]:.6f} s after {t[i - 1]:.6f} s)"
        elif d[bad[0]] < -1.0:
            what = (
                f"time jumps back {-d[bad[0]]:.3g} s at message {i} ({t[i]:.6f} s after "
                f"{t[i - 1]:.6f} s): a clock reset?"
            )
        else:
            what = f"time goes backwards at message {i} ({t[i]:.6f} s after {t[i - 1]:.6f} s)"
        raise BagDataError(
            f"{what}; the header stamps must be strictly increasing", path, None, topic
        )
    return t


def _finite(arr: np.ndarray, path: Path, topic: str, what: str, limit: float | None = None) -> None:
    """InputError naming the first message whose ``what`` is not finite, or larger than
    ``limit`` in magnitude (an absurd value; odocal.io.limits)."""
    flat = arr.reshape(len(arr), -1)
    ok = np.all(np.isfinite(flat), axis=1)
    if not np.all(ok):
        i = int(np.nonzero(~ok)[0][0])
        raise BagDataError(f"message {i}: {what} is not finite (NaN or inf)", path, None, topic)
    if limit is not None and len(flat):
        big = np.nonzero(np.any(np.abs(flat) > limit, axis=1))[0]
        if len(big):
            i = int(big[0])
            v = flat[i][np.argmax(np.abs(flat[i]))]
            raise BagDataError(
                f"message {i}: {what} is implausibly large ({v:.6g}; at most {limit:g})",
                path,
                None,
                topic,
            )


def _need(msgs: Sized, path: Path, topic: str, n: int = 2) -> None:
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
    raise BagDataError(
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
    js: JointStates = bag.messages[topic]
    path = bag.path
    names: set[str] = set()
    for _, nm in js.layouts:
        twice = sorted({n for n in nm if nm.count(n) > 1})
        if twice:
            raise BagDataError(
                f"two joints named the same in one message: '{twice[0]}' ({', '.join(nm)}): "
                "which is the wheel?",
                path,
                None,
                topic,
            )
        names.update(nm)
    right = right_joint or _side_joint(names, "right", path, topic)
    left = left_joint or _side_joint(names, "left", path, topic)
    for j in (right, left):
        if j not in names:
            raise InputError(
                f"no joint '{j}'; joints: {', '.join(sorted(names)) or 'none'}", path, None, topic
            )
    if right == left:
        raise InputError(f"the right and left joints are both '{right}'", path, None, topic)
    # per layout (names): whether it carries both joints, and where (the first of each name)
    carries = np.array([right in nm and left in nm for _, nm in js.layouts] + [False])
    ir = np.array([nm.index(right) if right in nm else 0 for _, nm in js.layouts] + [0])
    il = np.array([nm.index(left) if left in nm else 0 for _, nm in js.layouts] + [0])
    both = carries[js.layout]
    short = both & (js.count <= np.maximum(ir, il)[js.layout])
    if np.any(short):
        i = int(np.flatnonzero(short)[0])
        raise InputError(
            f"message {int(np.count_nonzero(both[:i]))}: {int(js.count[i])} positions for "
            f"{len(js.layouts[js.layout[i]][1])} joint names",
            path,
            None,
            topic,
        )
    kept = np.flatnonzero(both)
    lay = js.layout[kept]
    rows = np.column_stack([js.position[kept, ir[lay]], js.position[kept, il[lay]]])
    _need(kept, path, topic)
    phi = np.array(rows, dtype=float).reshape(len(kept), 2)
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
    t = _seconds(js.stamp_ns[kept], js.log_ns[kept], path, topic, bag.start_ns)
    r, wr = _unwrap_wheel(phi[:, 0], 2.0 * math.pi, path, topic, right)
    lft, wl = _unwrap_wheel(phi[:, 1], 2.0 * math.pi, path, topic, left)
    return TopicSeries(
        topic,
        t,
        {"right": r, "left": lft},
        js.layouts[js.layout[kept[0]]][0],
        meta={"right_joint": right, "left_joint": left, "wraps_unwrapped": wr + wl},
    )


def static_rotation(bag: BagContents, child: str, parents: Sequence[str]):
    """R_parent_child, shape (3, 3), composed along ``/tf_static`` from ``child`` up to the first
    frame in ``parents``; (None, None) when there is no such chain."""
    edges: dict[str, tuple[str, np.ndarray]] = {}
    for parent, child, v in _static_transforms(bag):
        edges[child] = (parent, rotation_from_quaternion(tuple(v[3:])))
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
    tf = bag.messages.get(topic)
    if not isinstance(tf, Transforms) or not len(tf.edge):
        return {}
    keys: dict[tuple[str, str], int] = {}
    key_of_edge = np.array(
        [keys.setdefault((p.lstrip("/"), c.lstrip("/")), len(keys)) for p, c in tf.edges]
    )
    row_key = key_of_edge[tf.edge]
    stamps = np.where(tf.stamp_ns != 0, tf.stamp_ns, tf.log_ns)
    names = list(keys)
    order = np.argsort(row_key, kind="stable")  # each edge's rows, in publishing order
    ids, first = np.unique(row_key, return_index=True)
    starts = np.searchsorted(row_key[order], ids)
    ends = np.r_[starts[1:], len(order)]
    out = {}
    for k in np.argsort(first, kind="stable"):  # the edges in the order they first appear
        rows = order[starts[k] : ends[k]]
        parent, child = names[int(ids[k])]
        a = tf.values[rows]
        if not np.all(np.isfinite(a)):
            bad = int(np.nonzero(~np.all(np.isfinite(a), axis=1))[0][0])
            raise InputError(
                f"message {int(tf.message[rows[bad]])}: transform '{parent} -> {child}' is not "
                "finite (NaN or inf)",
                bag.path,
                None,
                topic,
            )
        t = (stamps[rows] - np.int64(bag.start_ns)) * 1e-9
        back = np.nonzero(np.diff(t) < 0)[0]
        if len(back):
            i = int(back[0]) + 1
            raise InputError(
                f"message {int(tf.message[rows[i]])}: the stamps of transform '{parent} -> "
                f"{child}' go backwards ({t[i]:.6f} s after {t[i - 1]:.6f} s); each edge's header "
                "stamps must not decrease (two recordings merged, or two publishers of one edge?)",
                bag.path,
                None,
                topic,
            )
        out[(parent, child)] = EdgeMessages(parent, child, t, a[:, :3], a[:, 3:])
    return out


def _static_transforms(bag: BagContents) -> list[tuple[str, str, list[float]]]:
    """The transforms of ``/tf_static`` in publishing order: (parent, child, [x, y, z, qx, qy,
    qz, qw]), frames without a leading '/'."""
    tf = bag.messages.get("/tf_static")
    if not isinstance(tf, Transforms):
        return []
    return [
        (tf.edges[e][0].lstrip("/"), tf.edges[e][1].lstrip("/"), v)
        for e, v in zip(tf.edge.tolist(), tf.values.tolist(), strict=True)
    ]


@contextmanager
def _in_bag(path: Path, topic: str) -> Iterator[None]:
    """Errors of the transform buffer (which knows no file) named with the bag and topic."""
    try:
        yield
    except InputError as exc:
        if exc.path is not None:
            raise
        raise InputError(str(exc), path, None, topic) from None


def transform_buffer(bag: BagContents):
    """A :class:`~odocal.core.transforms.TransformBuffer` of the bag's ``/tf`` and
    ``/tf_static``; its errors (filling, :meth:`chain`, :meth:`lookup`) name the bag and the
    transform topics."""
    from ..core.transforms import TransformBuffer

    topic = "/tf" if isinstance(bag.messages.get("/tf"), Transforms) else "/tf_static"

    class BagTransformBuffer(TransformBuffer):
        def chain(self, parent, child):
            with _in_bag(bag.path, topic):
                return super().chain(parent, child)

        def lookup(self, parent, child, time_s, **kwargs):
            with _in_bag(bag.path, topic):
                return super().lookup(parent, child, time_s, **kwargs)

    buf = BagTransformBuffer()
    with _in_bag(bag.path, topic):
        for (parent, child), e in tf_messages(bag).items():
            buf.add(parent, child, e.time_s, e.translation_m, e.quaternion_xyzw)
        for parent, child, v in _static_transforms(bag):
            buf.add_static(parent, child, tuple(v[:3]), tuple(v[3:]))
    return buf


# --------------------------------------------------------------------------- laser scans

LASER_SCAN = "sensor_msgs/msg/LaserScan"


@dataclass(frozen=True)
class ScanSeries:
    """The scans of one ``sensor_msgs/LaserScan`` topic as points in the sensor frame.

    ``time_s`` (N,) header stamps relative to the bag start (s); ``points_m`` N arrays of shape
    (n_i, 2) (invalid ranges dropped, REP-117), made when asked for (:class:`ScanPoints`);
    ``frame_id`` the sensor frame."""

    topic: str
    time_s: np.ndarray
    points_m: Sequence[np.ndarray]
    frame_id: str


class ScanPoints(Sequence):
    """The points of every scan of a topic, each made from its ranges when asked for
    (:func:`~odocal.calibration.scan_matching.scan_points`; read-only arrays). An hour of scans
    as points takes four times the memory of their ranges, and a fit matches a fifth of them;
    the last few asked for are kept (an interval's end scan is the next one's start)."""

    def __init__(self, ranges: Sequence[np.ndarray], params: np.ndarray, keep: int = 4) -> None:
        self._ranges, self._params, self._keep = ranges, params, keep
        self._recent: dict[int, np.ndarray] = {}

    def __len__(self) -> int:
        return len(self._ranges)

    def __getitem__(self, index):
        if isinstance(index, slice):
            return [self[i] for i in range(*index.indices(len(self)))]
        i = range(len(self))[index]  # IndexError out of range; negative from the end
        got = self._recent.get(i)
        if got is None:
            from ..calibration.scan_matching import scan_points

            got = scan_points(np.asarray(self._ranges[i], dtype=float), *self._params[i].tolist())
            got.setflags(write=False)
            if len(self._recent) >= self._keep:
                del self._recent[next(iter(self._recent))]
            self._recent[i] = got
        return got


def _has_valid_range(ranges: np.ndarray, range_min: float, range_max: float) -> bool:
    """Whether :func:`~odocal.calibration.scan_matching.scan_points` keeps a point of a scan."""
    r = np.asarray(ranges, dtype=float)
    with np.errstate(invalid="ignore"):
        return bool(np.any(np.isfinite(r) & (r >= range_min) & (r <= range_max)))


#: Largest disagreement of a scan header (angle_max against angle_min + (count - 1)
#: angle_increment), in beams (angle_increment). The rays' angles come from angle_min and
#: angle_increment; a header that disagrees with itself by more says that one of them is wrong
#: (a 1 % wrong increment moves the wheelbase by 15 standard errors; an upside-down laser's
#: reversed rays with angle_min, angle_max unchanged make it 18 % too large).
SCAN_HEADER_TOLERANCE_BEAMS = 0.5


def _check_scan_headers(sc: LaserScans, path: Path, topic: str) -> None:
    """InputError naming the first scan whose header disagrees with itself (angle_min,
    angle_increment, angle_max and the number of ranges; a negative increment, rays clockwise,
    is consistent when angle_max < angle_min)."""
    if len(sc.angle_max) != len(sc):
        return
    count = np.array([len(r) for r in sc.ranges], dtype=float)
    a_min, a_inc = sc.params[:, 0], sc.params[:, 1]
    last = a_min + np.maximum(count - 1, 0) * a_inc
    with np.errstate(divide="ignore", invalid="ignore"):
        off = np.abs(last - sc.angle_max) / np.abs(a_inc)
    bad = np.nonzero((count > 1) & ~(off <= SCAN_HEADER_TOLERANCE_BEAMS))[0]
    if len(bad):
        i = int(bad[0])
        raise InputError(
            f"message {i}: the scan header disagrees with itself: angle_min "
            f"{a_min[i]:.6g} + ({int(count[i])} - 1) x angle_increment {a_inc[i]:.6g} = "
            f"{last[i]:.6g} rad, but angle_max is {sc.angle_max[i]:.6g} rad ({off[i]:.3g} beams "
            "apart); the rays' angles would be wrong (a mirrored laser with angle_min and "
            "angle_max not swapped, or a wrong angle_increment)",
            path,
            None,
            topic,
        )


def scan_series(bag: BagContents, topic: str) -> ScanSeries:
    """Every scan of ``topic`` (InputError for absurd scan parameters or no valid range)."""
    sc: LaserScans = bag.messages[topic]
    _need(sc, bag.path, topic)
    params = sc.params  # angle_min, angle_increment, range_min, range_max
    with np.errstate(invalid="ignore"):
        usable = np.all(np.isfinite(params), axis=1) & (params[:, 2] >= 0)
        usable &= params[:, 2] < params[:, 3]
    if not np.all(usable):
        i = int(np.flatnonzero(~usable)[0])
        a_min, a_inc, r_min, r_max = params[i].tolist()
        raise InputError(
            f"message {i}: scan parameters are not usable (angle_min {a_min}, "
            f"angle_increment {a_inc}, range_min {r_min}, range_max {r_max})",
            bag.path,
            None,
            topic,
        )
    _check_scan_headers(sc, bag.path, topic)
    if not any(
        _has_valid_range(r, *p) for r, p in zip(sc.ranges, params[:, 2:].tolist(), strict=True)
    ):
        raise InputError(
            f"no scan has a valid range (all NaN, inf or outside [range_min, range_max]) in "
            f"{len(sc)} scans",
            bag.path,
            None,
            topic,
        )
    t = _seconds(sc.stamp_ns, sc.log_ns, bag.path, topic, bag.start_ns)
    points = ScanPoints(sc.ranges, params)
    return ScanSeries(topic, t, points, sc.frames[sc.layout[0]].lstrip("/"))
