"""Columnar decoding of the bag messages that come by the hundred thousand:
``sensor_msgs/JointState``, ``tf2_msgs/TFMessage`` and ``sensor_msgs/LaserScan``.

An hour of a robot's bag holds about 180 000 joint states, 180 000 ``/tf`` messages and 36 000
scans. Decoding each into rosbags' message objects (nested objects, numpy arrays) takes 10-40 us
a message, and millions of live objects make the garbage collector pause again and again. Here
a topic's messages go into numpy columns instead (stamps, frames, values), without one object
per message:

- The raw messages of a topic are collected in chunks. In a chunk, the messages of one length
  are stacked into a byte matrix; the first one is parsed (:class:`_Cursor`), which gives its
  layout: the bytes that shape it (sequence counts, string lengths, the strings: frames, joint
  names) and where its numbers are. Every message whose shaping bytes equal that template's
  has the same layout, and its numbers are read from the matrix, column by column. The rest are
  matched against the next template, and so on.
- A message is read here only when rosbags would read it the same way (the rules of
  :mod:`odocal.io.bag_decode`: the standard definition of the type in the reader's typestore,
  ROS 1 bytes of exactly the layout's size, CDR with a plain encapsulation header, alignment
  counted from its end, NUL-terminated valid UTF-8 strings, at most 3 bytes of padding at the
  end). A message the parser refuses, or of a connection whose definition is not the standard
  one, is decoded by rosbags and its fields put in the same columns (:meth:`ColumnBuilder.add`
  with ``fast`` False does that for every message: the reference the tests compare with).

The numbers are rosbags' own: the same bytes read as the same types (int32 seconds, uint32
nanoseconds, float64 or float32 values). Stamps are kept as integer nanoseconds.
"""

from __future__ import annotations

import struct
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field
from functools import cache
from typing import Any, NamedTuple

import numpy as np

from .bag_decode import _definition

__all__ = [
    "JOINT_STATE",
    "TF",
    "LASER_SCAN",
    "COLUMN_TYPES",
    "JointStates",
    "Transforms",
    "LaserScans",
    "ColumnBuilder",
    "Failure",
    "NonStandard",
    "is_standard",
]

JOINT_STATE = "sensor_msgs/msg/JointState"
TF = "tf2_msgs/msg/TFMessage"
LASER_SCAN = "sensor_msgs/msg/LaserScan"
COLUMN_TYPES = (JOINT_STATE, TF, LASER_SCAN)

#: Messages collected per topic before they are decoded (bounds the raw bytes kept).
CHUNK = 8192
#: Templates tried on one chunk's messages of one length; the rest are parsed one by one.
MAX_TEMPLATES = 16

_SIZE = {"i4": 4, "u4": 4, "f4": 4, "f8": 8}
_NATIVE = {"i4": np.int64, "u4": np.int64, "f4": np.float32, "f8": np.float64}


# --------------------------------------------------------------------------- columns


class _Stamp(NamedTuple):
    sec: int
    nanosec: int


class _Header(NamedTuple):
    stamp: _Stamp
    frame_id: str


def _header(stamp_ns: int, frame_id: str) -> _Header:
    sec, nanosec = divmod(int(stamp_ns), 1_000_000_000)
    return _Header(_Stamp(sec, nanosec), frame_id)


class _Vector(NamedTuple):
    x: float
    y: float
    z: float


class _Quaternion(NamedTuple):
    x: float
    y: float
    z: float
    w: float


class _Transform(NamedTuple):
    translation: _Vector
    rotation: _Quaternion


class _TransformStamped(NamedTuple):
    header: _Header
    child_frame_id: str
    transform: _Transform


class JointStateView(NamedTuple):
    """One message of :class:`JointStates` with the attributes of rosbags' message that odocal
    reads (``header.stamp``, ``header.frame_id``, ``name``, ``position``)."""

    header: _Header
    name: tuple[str, ...]
    position: np.ndarray


class TFMessageView(NamedTuple):
    """One message of :class:`Transforms`: ``transforms``, each with ``header``,
    ``child_frame_id``, ``transform.translation`` and ``transform.rotation``."""

    transforms: list


class LaserScanView(NamedTuple):
    """One message of :class:`LaserScans`: ``header``, ``angle_min``, ``angle_increment``,
    ``range_min``, ``range_max`` and ``ranges``."""

    header: _Header
    angle_min: float
    angle_increment: float
    range_min: float
    range_max: float
    ranges: np.ndarray


class _Messages:
    """Iterating a column object gives (log_time_ns, message view) pairs, in recording order, as
    the lists of :class:`~odocal.io.bags.BagContents` do for the other types (slow: for code
    that wants one message at a time; the series functions read the columns)."""

    def __iter__(self) -> Iterator[tuple[int, Any]]:
        return (self[i] for i in range(len(self)))  # type: ignore[arg-type]

    def __getitem__(self, i: int) -> tuple[int, Any]:
        raise NotImplementedError


@dataclass(frozen=True, eq=False)
class JointStates(_Messages):
    """The messages of a ``sensor_msgs/JointState`` topic, in recording order.

    ``log_ns``, ``stamp_ns`` (n,) int64: log time and header stamp (ns); ``layout`` (n,) index
    into ``layouts``, each (frame_id, joint names); ``count`` (n,) positions per message;
    ``position`` (n, W) float64, row i valid in ``[:count[i]]`` (NaN beyond)."""

    log_ns: np.ndarray
    stamp_ns: np.ndarray
    layout: np.ndarray
    layouts: tuple[tuple[str, tuple[str, ...]], ...]
    count: np.ndarray
    position: np.ndarray

    def __len__(self) -> int:
        return len(self.log_ns)

    def __getitem__(self, i: int) -> tuple[int, JointStateView]:
        i = range(len(self))[i]
        frame, names = self.layouts[self.layout[i]]
        pos = self.position[i, : self.count[i]]
        return int(self.log_ns[i]), JointStateView(_header(self.stamp_ns[i], frame), names, pos)


@dataclass(frozen=True, eq=False)
class Transforms(_Messages):
    """The transforms of a ``tf2_msgs/TFMessage`` topic, one row each, in publishing order.

    ``messages``: how many messages (some may hold no transform); ``message`` (r,) the index
    of the message holding each; ``log_ns``, ``stamp_ns`` (r,) int64 its log time and the
    transform's header stamp (ns); ``edge`` (r,) index into ``edges``, each (frame_id,
    child_frame_id) as published; ``values`` (r, 7) float64: translation x, y, z and rotation
    x, y, z, w; ``message_log_ns`` (messages,) every message's log time."""

    messages: int
    message: np.ndarray
    log_ns: np.ndarray
    stamp_ns: np.ndarray
    edge: np.ndarray
    edges: tuple[tuple[str, str], ...]
    values: np.ndarray
    message_log_ns: np.ndarray

    def __len__(self) -> int:
        return self.messages

    def __getitem__(self, i: int) -> tuple[int, TFMessageView]:
        i = range(len(self))[i]
        lo, hi = np.searchsorted(self.message, [i, i + 1])
        out = []
        for r in range(int(lo), int(hi)):
            parent, child = self.edges[self.edge[r]]
            v = self.values[r].tolist()
            tr = _Transform(_Vector(*v[:3]), _Quaternion(*v[3:]))
            out.append(_TransformStamped(_header(self.stamp_ns[r], parent), child, tr))
        return int(self.message_log_ns[i]), TFMessageView(out)


@dataclass(frozen=True, eq=False)
class LaserScans(_Messages):
    """The messages of a ``sensor_msgs/LaserScan`` topic, in recording order.

    ``log_ns``, ``stamp_ns`` (n,) int64; ``layout`` (n,) index into ``frames`` (frame_id);
    ``params`` (n, 4) float64: angle_min, angle_increment, range_min, range_max (the float32
    fields, exactly); ``ranges`` n float32 arrays; ``angle_max`` (n,) float64 (to check the
    header: the last ray is at angle_min + (count - 1) angle_increment)."""

    log_ns: np.ndarray
    stamp_ns: np.ndarray
    layout: np.ndarray
    frames: tuple[str, ...]
    params: np.ndarray
    ranges: tuple[np.ndarray, ...]
    angle_max: np.ndarray = field(default_factory=lambda: np.zeros(0))

    def __len__(self) -> int:
        return len(self.log_ns)

    def __getitem__(self, i: int) -> tuple[int, LaserScanView]:
        i = range(len(self))[i]
        a_min, a_inc, r_min, r_max = self.params[i].tolist()
        head = _header(self.stamp_ns[i], self.frames[self.layout[i]])
        return int(self.log_ns[i]), LaserScanView(head, a_min, a_inc, r_min, r_max, self.ranges[i])


# --------------------------------------------------------------------------- parsing


class _Refused(Exception):
    """The parser does not take this message (rosbags decodes it, or says why not)."""


class _Cursor:
    """Walks one raw message, recording the bytes that shape it (``key``: (start, stop)) and
    where its numbers are (``fields``: (offset, code, count))."""

    __slots__ = ("raw", "n", "ros1", "pos", "order", "key", "fields", "max_seq")

    def __init__(self, raw, ros1: bool, max_seq: int) -> None:
        self.raw, self.n, self.ros1, self.max_seq = raw, len(raw), ros1, max_seq
        self.key: list[tuple[int, int]] = []
        self.fields: list[tuple[int, str, int]] = []
        if ros1:
            self.pos, self.order = 0, "<"
        else:
            # encapsulation 00 00 (big-endian) or 00 01 (little-endian); alignment counts from
            # the end of the 4-byte header
            if self.n < 4 or raw[0] != 0 or raw[1] > 1:
                raise _Refused
            self.key.append((0, 2))
            self.pos, self.order = 4, "<" if raw[1] else ">"

    def _align(self, size: int) -> None:
        if not self.ros1:
            self.pos += -(self.pos - 4) % size

    def numbers(self, code: str, count: int, keep: bool = True) -> None:
        """``count`` numbers of type ``code`` (aligned first when there are any, as rosbags
        does); recorded as a field unless ``keep`` is False."""
        size = _SIZE[code]
        if count:
            self._align(size)
        end = self.pos + size * count
        if end > self.n:
            raise _Refused
        if keep:
            self.fields.append((self.pos, code, count))
        self.pos = end

    def count(self) -> int:
        """A uint32 that shapes the message: a sequence's length or a string's."""
        self._align(4)
        p = self.pos
        if p + 4 > self.n:
            raise _Refused
        (value,) = struct.unpack_from(self.order + "I", self.raw, p)
        self.key.append((p, p + 4))
        self.pos = p + 4
        return int(value)

    def sequence(self) -> int:
        value = self.count()
        if value > self.max_seq:
            raise _Refused
        return value

    def string(self) -> str:
        size = self.count()
        p, end = self.pos, self.pos + size
        if end > self.n:
            raise _Refused
        if self.ros1:
            data = bytes(self.raw[p:end])
        else:
            if size < 1 or self.raw[end - 1] != 0:
                raise _Refused
            data = bytes(self.raw[p : end - 1])
        try:
            text = data.decode()
        except UnicodeDecodeError:
            raise _Refused from None
        self.key.append((p, end))
        self.pos = end
        return text

    def header(self) -> str:
        """std_msgs/Header: (ROS 1: seq,) stamp sec (int32) and nanosec (uint32), frame_id."""
        if self.ros1:
            self.numbers("u4", 1, keep=False)
        self.numbers("i4", 1)
        self.numbers("u4", 1)
        return self.string()

    def done(self) -> None:
        """The message ends here (ROS 1: exactly; CDR: up to 3 bytes of padding after)."""
        if self.ros1 and self.pos != self.n:
            raise _Refused
        if not self.ros1 and not self.pos <= self.n <= self.pos + 3:
            raise _Refused


def _parse_joint_state(c: _Cursor) -> tuple:
    frame = c.header()
    names = tuple(c.string() for _ in range(c.sequence()))
    count = c.sequence()
    c.numbers("f8", count)
    for _ in range(2):  # velocity, effort: not read, but they shape the message
        c.numbers("f8", c.sequence(), keep=False)
    c.done()
    return (frame, names, count)


def _parse_tf(c: _Cursor) -> tuple:
    edges = []
    for _ in range(c.sequence()):
        frame = c.header()
        child = c.string()
        c.numbers("f8", 3)
        c.numbers("f8", 4)
        edges.append((frame, child))
    c.done()
    return tuple(edges)


def _parse_scan(c: _Cursor) -> tuple:
    frame = c.header()
    # angle_min, angle_max, angle_increment, time_increment, scan_time, range_min, range_max
    c.numbers("f4", 7)
    n = c.sequence()
    c.numbers("f4", n)
    c.numbers("f4", c.sequence(), keep=False)  # intensities
    c.done()
    return (frame, n)


# rosbags messages -> (layout, field values) in the parser's order


def _stamp(h) -> list:
    return [(int(h.stamp.sec),), (int(h.stamp.nanosec),)]


def _joint_state_of(msg) -> tuple[tuple, list]:
    pos = np.asarray(msg.position, dtype=np.float64).reshape(-1)
    layout = (str(msg.header.frame_id), tuple(str(n) for n in msg.name), len(pos))
    return layout, [*_stamp(msg.header), pos]


def _tf_of(msg) -> tuple[tuple, list]:
    edges, values = [], []
    for tr in msg.transforms:
        p, q = tr.transform.translation, tr.transform.rotation
        edges.append((str(tr.header.frame_id), str(tr.child_frame_id)))
        values += [
            *_stamp(tr.header),
            (float(p.x), float(p.y), float(p.z)),
            (float(q.x), float(q.y), float(q.z), float(q.w)),
        ]
    return tuple(edges), values


def _scan_of(msg) -> tuple[tuple, list]:
    ranges = np.asarray(msg.ranges, dtype=np.float32).reshape(-1)
    head = (
        msg.angle_min,
        msg.angle_max,
        msg.angle_increment,
        msg.time_increment,
        msg.scan_time,
        msg.range_min,
        msg.range_max,
    )
    layout = (str(msg.header.frame_id), len(ranges))
    return layout, [*_stamp(msg.header), tuple(float(v) for v in head), ranges]


def _single_types(msgtype: str, layout: tuple) -> list[type]:
    """The numpy types the fields of messages decoded one at a time are gathered in: int64
    stamps, float64 values, the scan's float32 ranges as they are (its float32 parameters as
    rosbags gives them: as float64)."""
    if msgtype == JOINT_STATE:
        return [np.int64, np.int64, np.float64]
    if msgtype == TF:
        return [np.int64, np.int64, np.float64, np.float64] * len(layout)
    return [np.int64, np.int64, np.float64, np.float32]


_PARSERS: dict[str, Callable[[_Cursor], tuple]] = {
    JOINT_STATE: _parse_joint_state,
    TF: _parse_tf,
    LASER_SCAN: _parse_scan,
}
_FROM_MESSAGE: dict[str, Callable[[Any], tuple[tuple, list]]] = {
    JOINT_STATE: _joint_state_of,
    TF: _tf_of,
    LASER_SCAN: _scan_of,
}


@cache
def _standard(msgtype: str, ros1: bool) -> dict | None:
    """The standard definition of ``msgtype`` (rosbags' ROS 1 store lacks tf2_msgs/TFMessage:
    its definition, the one every ROS 1 bag carries, is added)."""
    from rosbags.typesys import Stores, get_typestore

    ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    if msgtype == TF and msgtype not in ts.fielddefs:
        from rosbags.typesys import get_types_from_msg

        ts.register(get_types_from_msg("geometry_msgs/TransformStamped[] transforms", TF))
    return _definition(ts, msgtype)


def is_standard(msgtype: str, typestore, ros1: bool) -> bool:
    """Whether ``msgtype`` as defined in ``typestore`` (the open reader's) is the standard one
    (then its messages may be parsed here)."""
    return msgtype in _PARSERS and _definition(typestore, msgtype) == _standard(msgtype, ros1)


# --------------------------------------------------------------------------- building


def _field(rows: np.ndarray, offset: int, code: str, count: int, order: str) -> np.ndarray:
    """One field of every row of a byte matrix, shape (n, count), native type."""
    n = rows.shape[0]
    if count == 0:
        return np.zeros((n, 0), dtype=_NATIVE[code])
    block = np.ascontiguousarray(rows[:, offset : offset + _SIZE[code] * count])
    return block.view(np.dtype(order + code)).reshape(n, count).astype(_NATIVE[code])


class NonStandard(Exception):
    """A message rosbags decoded lacks a field read here (a custom definition of the type)."""

    def __init__(self, msgtype: str, name: str) -> None:
        super().__init__(msgtype, name)
        self.msgtype, self.name = msgtype, name


class Failure(Exception):
    """A message rosbags could not decode (``index``: its place among all messages read)."""

    def __init__(self, index: int, topic: str, exc: BaseException) -> None:
        super().__init__(index, topic, exc)
        self.index, self.topic, self.exc = index, topic, exc


@dataclass(frozen=True)
class _Chunk:
    """The messages of one flush: raw bytes, places among all messages read, log times (ns)
    and the topic sequence number of the first."""

    raws: list
    index: list[int]
    logs: np.ndarray
    base: int


class ColumnBuilder:
    """Collects the messages of one topic of a column type and builds its columns.

    The reader appends each message to :attr:`raws`, its log time (ns) to :attr:`logs` and its
    place among all messages read to :attr:`index` (for error messages), and the position in
    :attr:`raws` of those rosbags must decode (not parsed here) to :attr:`slow`; at
    :data:`CHUNK` messages it calls :meth:`flush`. ``deserialize(raw)`` is rosbags' decoding of
    one message; ``max_sequence`` the typestore's longest sequence. Messages rosbags cannot
    decode are listed in :attr:`failures`."""

    def __init__(
        self, topic: str, msgtype: str, ros1: bool, deserialize: Callable, max_sequence: int
    ) -> None:
        self.topic, self.msgtype, self.ros1 = topic, msgtype, ros1
        self.deserialize, self.max_sequence = deserialize, max_sequence
        self.parse = _PARSERS[msgtype]
        self.raws: list[Any] = []
        self.logs: list[int] = []
        self.index: list[int] = []
        self.slow: list[int] = []
        self.seq = 0  # messages flushed so far
        # decoded blocks: (seq (n,), log_ns (n,), layout, [field arrays (n, count)])
        self.blocks: list[tuple[np.ndarray, np.ndarray, tuple, list[np.ndarray]]] = []
        # one message at a time: layout -> (seqs, logs, per field a list of value tuples)
        self.singles: dict[tuple, tuple[list, list, list[list]]] = {}
        self.failures: list[Failure] = []

    def _single(self, seq: int, log_ns: int, layout: tuple, values: list) -> None:
        entry = self.singles.get(layout)
        if entry is None:
            entry = self.singles[layout] = ([], [], [[] for _ in values])
        entry[0].append(seq)
        entry[1].append(log_ns)
        for column, v in zip(entry[2], values, strict=True):
            column.append(v)

    def _through_rosbags(self, seq: int, log_ns: int, index: int, raw) -> None:
        try:
            msg = self.deserialize(raw)
        except Exception as exc:  # noqa: BLE001 - reported with the message's place
            self.failures.append(Failure(index, self.topic, exc))
            return
        try:
            layout, values = _FROM_MESSAGE[self.msgtype](msg)
        except AttributeError as exc:
            problem = NonStandard(self.msgtype, str(exc.name))
            self.failures.append(Failure(index, self.topic, problem))
            return
        self._single(seq, log_ns, layout, values)

    def _parse(self, raw) -> tuple[_Cursor, tuple] | None:
        """The parse of one message and its layout; None when rosbags must decode it."""
        try:
            c = _Cursor(raw, self.ros1, self.max_sequence)
            return c, self.parse(c)
        except (_Refused, struct.error):
            return None

    def flush(self) -> None:
        """Decode the collected messages."""
        raws, logs, index, slow = self.raws, self.logs, self.index, self.slow
        n = len(raws)
        if not n:
            return
        self.raws, self.logs, self.index, self.slow = [], [], [], []
        base = self.seq
        self.seq += n
        for i in slow:
            self._through_rosbags(base + i, int(logs[i]), index[i], raws[i])
        lengths = np.fromiter(map(len, raws), dtype=np.intp, count=n)
        chunk = _Chunk(raws, index, np.array(logs, dtype=np.int64), base)
        if not slow and np.all(lengths == lengths[0]):
            self._templates(chunk, np.arange(n), int(lengths[0]))
            return
        fast = np.ones(n, dtype=bool)
        fast[slow] = False
        members = np.flatnonzero(fast)
        order = members[np.argsort(lengths[members], kind="stable")]
        cuts = np.flatnonzero(np.diff(lengths[order])) + 1
        for group in np.split(order, cuts):
            if len(group):
                self._templates(chunk, group, int(lengths[group[0]]))

    def _templates(self, chunk: _Chunk, members: np.ndarray, length: int) -> None:
        """Decode the messages ``members`` (positions in ``chunk``), all ``length`` bytes."""
        raws = chunk.raws
        joined = (
            b"".join(raws) if len(members) == len(raws) else b"".join([raws[i] for i in members])
        )
        rows = np.frombuffer(joined, dtype=np.uint8).reshape(len(members), length)
        left = np.arange(len(members))
        tried = 0
        while len(left) and tried < MAX_TEMPLATES:
            tried += 1
            first = int(left[0])
            at = int(members[first])
            parsed = self._parse(raws[at])
            if parsed is None:  # rosbags decodes it (or says why not)
                self._through_rosbags(
                    chunk.base + at, int(chunk.logs[at]), chunk.index[at], raws[at]
                )
                left = left[1:]
                continue
            c, layout = parsed
            key = np.concatenate([np.arange(a, b) for a, b in c.key] or [np.zeros(0, int)])
            same = np.all(rows[left[:, None], key[None, :]] == rows[first, key], axis=1)
            take = left[same]
            block = rows[take]
            values = [_field(block, off, code, n, c.order) for off, code, n in c.fields]
            where = members[take]
            self.blocks.append((chunk.base + where, chunk.logs[where], layout, values))
            left = left[~same]
        for i in left.tolist():  # too many layouts in this chunk: one message at a time
            at = int(members[i])
            raw, seq, log_ns = raws[at], chunk.base + at, int(chunk.logs[at])
            parsed = self._parse(raw)
            if parsed is None:
                self._through_rosbags(seq, log_ns, chunk.index[at], raw)
                continue
            c, layout = parsed
            values = [
                np.frombuffer(raw, np.dtype(c.order + code), n, off).astype(_NATIVE[code])
                for off, code, n in c.fields
            ]
            self._single(seq, log_ns, layout, values)

    def finish(self) -> JointStates | Transforms | LaserScans:
        """The columns of every message taken (after :meth:`flush`)."""
        blocks = list(self.blocks)
        for layout, (seqs, logs, columns) in self.singles.items():
            types = _single_types(self.msgtype, layout)
            values: list[np.ndarray] = [
                np.array(col, dtype=kind).reshape(len(seqs), -1)
                for col, kind in zip(columns, types, strict=True)
            ]
            blocks.append(
                (np.array(seqs, dtype=np.int64), np.array(logs, dtype=np.int64), layout, values)
            )
        if self.msgtype == JOINT_STATE:
            return _joint_states(blocks)
        if self.msgtype == TF:
            return _transforms(blocks, self.seq)
        return _laser_scans(blocks)


def _stamps(values: list[np.ndarray], at: int = 0) -> np.ndarray:
    return values[at][:, 0] * np.int64(1_000_000_000) + values[at + 1][:, 0]


def _first_seen(ids: np.ndarray, names: tuple) -> tuple[np.ndarray, tuple]:
    """``ids`` (into ``names``) renumbered in the order they first appear, and the names in that
    order (so that the columns do not depend on how the messages were chunked); names no row
    uses are dropped."""
    if not len(ids):
        return ids.astype(np.intp), ()
    used, first = np.unique(ids, return_index=True)
    order = used[np.argsort(first)]
    new = np.zeros(max(len(names), 1), dtype=np.intp)
    new[order] = np.arange(len(order))
    return new[ids], tuple(names[i] for i in order.tolist())


def _empty_int() -> np.ndarray:
    return np.zeros(0, dtype=np.int64)


def _joint_states(blocks: list) -> JointStates:
    layouts: dict[tuple, int] = {}
    for _, _, layout, _ in blocks:
        layouts.setdefault(layout[:2], len(layouts))
    width = max((layout[2] for _, _, layout, _ in blocks), default=0)
    n = sum(len(b[0]) for b in blocks)
    seq, log_ns, stamp = _empty_int(), _empty_int(), _empty_int()
    lay, count = np.zeros(n, dtype=np.intp), np.zeros(n, dtype=np.intp)
    position = np.full((n, width), np.nan)
    if blocks:
        seq = np.concatenate([b[0] for b in blocks])
        log_ns = np.concatenate([b[1] for b in blocks])
        stamp = np.concatenate([_stamps(b[3]) for b in blocks])
        at = 0
        for s, _, layout, values in blocks:
            k = len(s)
            lay[at : at + k] = layouts[layout[:2]]
            count[at : at + k] = layout[2]
            position[at : at + k, : layout[2]] = values[2]
            at += k
    order = np.argsort(seq, kind="stable")
    lay, names = _first_seen(lay[order], tuple(layouts))
    return JointStates(log_ns[order], stamp[order], lay, names, count[order], position[order])


def _transforms(blocks: list, messages: int) -> Transforms:
    message_log = np.zeros(messages, dtype=np.int64)
    for seq, logs, _, _ in blocks:
        message_log[seq] = logs
    edges: dict[tuple[str, str], int] = {}
    parts: list[tuple] = []  # (message seq, place in the message, log, stamp, edge, values)
    for seq, logs, layout, values in blocks:
        for j, edge in enumerate(layout):
            e = edges.setdefault(edge, len(edges))
            vals = np.hstack([values[4 * j + 2], values[4 * j + 3]])
            parts.append((seq, np.full(len(seq), j), logs, _stamps(values, 4 * j), e, vals))
    if not parts:
        z = _empty_int()
        return Transforms(messages, z, z, z, z.astype(np.intp), (), np.zeros((0, 7)), message_log)
    seq = np.concatenate([p[0] for p in parts])
    place = np.concatenate([p[1] for p in parts])
    order = np.lexsort((place, seq))
    edge = np.concatenate([np.full(len(p[0]), p[4], dtype=np.intp) for p in parts])
    edge, names = _first_seen(edge[order], tuple(edges))
    return Transforms(
        messages,
        seq[order],
        np.concatenate([p[2] for p in parts])[order],
        np.concatenate([p[3] for p in parts])[order],
        edge,
        names,
        np.concatenate([p[5] for p in parts])[order],
        message_log,
    )


def _laser_scans(blocks: list) -> LaserScans:
    frames: dict[str, int] = {}
    seqs, logs, stamps, lays, params, maxima = [], [], [], [], [], []
    ranges: list[np.ndarray] = []
    for seq, log_ns, layout, values in blocks:
        seqs.append(seq)
        logs.append(log_ns)
        stamps.append(_stamps(values))
        lays.append(np.full(len(seq), frames.setdefault(layout[0], len(frames)), dtype=np.intp))
        params.append(values[2][:, [0, 2, 5, 6]].astype(np.float64))
        maxima.append(values[2][:, 1].astype(np.float64))
        ranges += list(values[3])
    if not blocks:
        z = _empty_int()
        return LaserScans(z, z, z.astype(np.intp), (), np.zeros((0, 4)), ())
    seq = np.concatenate(seqs)
    order = np.argsort(seq, kind="stable")
    lay, names = _first_seen(np.concatenate(lays)[order], tuple(frames))
    return LaserScans(
        np.concatenate(logs)[order],
        np.concatenate(stamps)[order],
        lay,
        names,
        np.concatenate(params)[order],
        tuple(ranges[i] for i in order.tolist()),
        np.concatenate(maxima)[order],
    )
