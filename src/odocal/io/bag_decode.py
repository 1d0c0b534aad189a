"""Fast decoding of the high-rate bag messages odocal reads: ``sensor_msgs/Imu`` and
``nav_msgs/Odometry``, into one flat record per message.

rosbags builds a full message object per message (nested objects, covariance arrays), about
15-40 us each, and a bag's IMU and odometry topics hold most of its messages. Here the fields
the series functions of :mod:`odocal.io.bags` read are unpacked with :mod:`struct` straight into
an :class:`ImuRecord` or :class:`OdometryRecord` (one object per message: cheap to build and
light on the garbage collector, which nested objects are not). Messages decoded by rosbags are
turned into the same records by :func:`record`, so the series functions see one form.

The numbers are exactly rosbags' (the same bytes through the same ``struct`` types), because a
message is decoded here only when rosbags would decode it the same way:

- the type's definition in the open reader's typestore (the bag's own definitions, or the
  default store when the bag has none) is field for field the standard one (ROS 1 Noetic for
  ``.bag``, ROS 2 Humble for ROS 2 bags); a custom type of the same name is left to rosbags;
- ROS 1: the message has exactly the bytes the layout needs;
- ROS 2: CDR with a plain encapsulation header (``00 00`` big-endian or ``00 01``
  little-endian), alignment counted from the end of that 4-byte header, strings NUL-terminated,
  at most 3 bytes of trailing padding (rosbags' tolerance);
- strings are valid UTF-8.

Anything else (:func:`decoder` returns None, or a decoder returns None for one message) goes
through rosbags, which decodes it or raises exactly as it always did.
"""

from __future__ import annotations

import struct
from collections.abc import Callable
from functools import cache
from typing import NamedTuple

__all__ = ["ImuRecord", "OdometryRecord", "RECORD_TYPES", "decoder", "record", "stamp_ns"]

IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"

Xyz = tuple[float, float, float]


class ImuRecord(NamedTuple):
    """What odocal reads of a ``sensor_msgs/Imu``: header stamp (ns) and frame, angular
    velocity (x, y, z) in rad/s."""

    stamp_ns: int
    frame_id: str
    angular_velocity: Xyz


class OdometryRecord(NamedTuple):
    """What odocal reads of a ``nav_msgs/Odometry``: header stamp (ns) and frame, child frame,
    ``pose.pose`` position (x, y, z) m and orientation (x, y, z, w), ``twist.twist`` linear
    (x, y, z) m/s and angular (x, y, z) rad/s velocity."""

    stamp_ns: int
    frame_id: str
    child_frame_id: str
    position: Xyz
    orientation: tuple[float, float, float, float]
    linear: Xyz
    angular: Xyz


RECORD_TYPES = (IMU, ODOMETRY)


def stamp_ns(header) -> int:
    """A ROS header's stamp in integer nanoseconds."""
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def record(msgtype: str, msg) -> ImuRecord | OdometryRecord:
    """The record of a message rosbags decoded (AttributeError when a custom definition of the
    type lacks a field read here)."""
    h = msg.header
    if msgtype == IMU:
        w = msg.angular_velocity
        return ImuRecord(stamp_ns(h), h.frame_id, (w.x, w.y, w.z))
    p, q = msg.pose.pose.position, msg.pose.pose.orientation
    v, w = msg.twist.twist.linear, msg.twist.twist.angular
    return OdometryRecord(
        stamp_ns(h),
        h.frame_id,
        msg.child_frame_id,
        (p.x, p.y, p.z),
        (q.x, q.y, q.z, q.w),
        (v.x, v.y, v.z),
        (w.x, w.y, w.z),
    )


# --------------------------------------------------------------------------- layouts

# Built with tuple.__new__ (what a NamedTuple's own __new__ does, minus a Python-level call).
_new = tuple.__new__


def _imu(stamp_ns: int, frame: str, child: str, v: tuple) -> ImuRecord:
    return _new(ImuRecord, (stamp_ns, frame, v))


def _odometry(stamp_ns: int, frame: str, child: str, v: tuple) -> OdometryRecord:
    return _new(OdometryRecord, (stamp_ns, frame, child, v[0:3], v[3:7], v[7:10], v[10:13]))


class _Layout(NamedTuple):
    """What follows the header: a child_frame_id string or not, then a block of float64s (a
    struct format without byte order: the fields read, ``x`` pad bytes for the rest)."""

    child: bool
    body: str
    build: Callable


# after the header, Imu: orientation (4 float64), covariance[9], angular_velocity (3),
# covariance[9], linear_acceleration (3), covariance[9]; Odometry: child_frame_id, then
# pose.pose position (3) orientation (4), covariance[36], twist.twist linear (3) angular (3),
# covariance[36]
_LAYOUTS = {
    IMU: _Layout(False, "32x72x3d72x24x72x", _imu),
    ODOMETRY: _Layout(True, "7d288x6d288x", _odometry),
}


def decoder(msgtype: str, typestore, ros1: bool) -> Callable[[bytes], object | None] | None:
    """A function raw bytes -> record (None when rosbags must decode that message), or None
    when ``msgtype`` as defined in ``typestore`` (the open reader's) is not decoded here."""
    layout = _LAYOUTS.get(msgtype)
    if layout is None or _definition(typestore, msgtype) != _standard(msgtype, ros1):
        return None
    if ros1:
        body = struct.Struct("<" + layout.body)
        return lambda raw: _decode_ros1(raw, layout, body)
    bodies = (struct.Struct(">" + layout.body), struct.Struct("<" + layout.body))
    return lambda raw: _decode_cdr(raw, layout, bodies)


# --------------------------------------------------------------------------- definitions


def _names(desc) -> list[str]:
    """The message types a field description refers to (nested in arrays and sequences)."""
    from rosbags.interfaces import Nodetype

    if desc[0] == Nodetype.NAME:
        return [desc[1]]
    if desc[0] in (Nodetype.ARRAY, Nodetype.SEQUENCE):
        return _names(desc[1][0])
    return []


def _definition(typestore, msgtype: str) -> dict | None:
    """``msgtype`` and every type it contains: name -> field list (constants left out: they
    are not serialised)."""
    out: dict = {}
    todo = [msgtype]
    while todo:
        name = todo.pop()
        if name in out:
            continue
        entry = typestore.fielddefs.get(name)
        if entry is None:
            return None
        out[name] = entry[1]
        for _, desc in entry[1]:
            todo += _names(desc)
    return out


@cache
def _standard(msgtype: str, ros1: bool) -> dict | None:
    from rosbags.typesys import Stores, get_typestore

    return _definition(get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE), msgtype)


# --------------------------------------------------------------------------- decoding

_ROS1_HEADER = struct.Struct("<IiII")  # seq, stamp.sec (int32, as rosbags), nanosec, frame length
_U32 = (struct.Struct(">I"), struct.Struct("<I"))
_CDR_TIME = (struct.Struct(">iI"), struct.Struct("<iI"))  # stamp.sec, stamp.nanosec


def _decode_ros1(raw: bytes, layout: _Layout, body: struct.Struct) -> object | None:
    try:
        _, sec, nanosec, n = _ROS1_HEADER.unpack_from(raw, 0)
        pos = 16 + n
        frame = bytes(raw[16:pos]).decode()
        child = ""
        if layout.child:
            (m,) = _U32[1].unpack_from(raw, pos)
            child = bytes(raw[pos + 4 : pos + 4 + m]).decode()
            pos += 4 + m
        if pos + body.size != len(raw):  # also catches a string running past the end
            return None
        values = body.unpack_from(raw, pos)
    except (struct.error, UnicodeDecodeError):
        return None
    return layout.build(sec * 1_000_000_000 + nanosec, frame, child, values)


def _cdr_string(raw: bytes, pos: int, u32: struct.Struct) -> tuple[str, int]:
    """A CDR string at ``pos`` (uint32 length counting the NUL, bytes, NUL) and the position
    after it; ValueError if malformed (as rosbags' check_string)."""
    (n,) = u32.unpack_from(raw, pos)
    end = pos + 4 + n
    if n < 1 or end > len(raw) or raw[end - 1] != 0:
        raise ValueError("not a CDR string")
    return bytes(raw[pos + 4 : end - 1]).decode(), end


def _decode_cdr(raw: bytes, layout: _Layout, bodies: tuple) -> object | None:
    # encapsulation header 00 00 (big-endian) or 00 01 (little-endian); CDR alignment counts
    # from its end, hence the (pos - 4) below
    if len(raw) < 4 or raw[0] != 0 or raw[1] > 1:
        return None
    little = raw[1]
    try:
        sec, nanosec = _CDR_TIME[little].unpack_from(raw, 4)
        frame, pos = _cdr_string(raw, 12, _U32[little])
        child = ""
        if layout.child:
            pos += -(pos - 4) % 4
            child, pos = _cdr_string(raw, pos, _U32[little])
        pos += -(pos - 4) % 8
        body = bodies[little]
        end = pos + body.size
        if end > len(raw) or end + 3 < len(raw):
            return None
        values = body.unpack_from(raw, pos)
    except (struct.error, UnicodeDecodeError, ValueError):
        return None
    return layout.build(sec * 1_000_000_000 + nanosec, frame, child, values)
