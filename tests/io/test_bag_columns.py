"""The columnar reading of JointState, TFMessage and LaserScan topics (odocal.io.bag_columns)
against rosbags.

Exactness is checked bit for bit: the columns built from the raw bytes (templates and the
parser) and from rosbags' decoding of every message (``fast=False``) are identical, for ROS 1
and CDR of both byte orders, for damaged bytes (parsed only when rosbags would read the same,
else rosbags decides: the same numbers or the same error), for topics whose messages change
layout (other joints, other frames, other lengths), and for the series made from them on the bags
the tests write and on the MIT bag.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.errors import InputError
from odocal.io import bag_columns, bags
from odocal.io.bag_columns import JOINT_STATE, LASER_SCAN, TF, ColumnBuilder
from odocal.io.bag_decode import stamp_ns
from tests.support.bag_files import KINDS, bag_path, make_run, typestore, write_bag
from tests.support.synthetic_robot import Laser, default_track, simulate_robot, write_ros2_bag

STORES = {}


def store(ros1: bool):
    if ros1 not in STORES:
        STORES[ros1] = typestore(ros1)
    return STORES[ros1]


def _header(T, ros1, t, frame):
    sec = int(np.floor(t))
    stamp = T["builtin_interfaces/msg/Time"](sec=sec, nanosec=int(round((t - sec) * 1e9)))
    head = {"seq": 7} if ros1 else {}
    return T["std_msgs/msg/Header"](**head, stamp=stamp, frame_id=frame)


def joint_state(ros1, t, names, pos, frame="", vel=(), eff=()):
    T = store(ros1).types
    return T[JOINT_STATE](
        header=_header(T, ros1, t, frame),
        name=list(names),
        position=np.array(pos, dtype=float),
        velocity=np.array(vel, dtype=float),
        effort=np.array(eff, dtype=float),
    )


def tf_message(ros1, t, edges, values):
    T = store(ros1).types
    out = []
    for (parent, child), v in zip(edges, values, strict=True):
        tr = T["geometry_msgs/msg/Transform"](
            translation=T["geometry_msgs/msg/Vector3"](x=v[0], y=v[1], z=v[2]),
            rotation=T["geometry_msgs/msg/Quaternion"](x=v[3], y=v[4], z=v[5], w=v[6]),
        )
        out.append(
            T["geometry_msgs/msg/TransformStamped"](
                header=_header(T, ros1, t, parent), child_frame_id=child, transform=tr
            )
        )
    return T[TF](transforms=out)


def laser_scan(ros1, t, ranges, frame="laser", intensities=()):
    T = store(ros1).types
    return T[LASER_SCAN](
        header=_header(T, ros1, t, frame),
        angle_min=-1.5,
        angle_max=1.5,
        angle_increment=0.1 / 3,
        time_increment=1e-5,
        scan_time=0.1,
        range_min=0.05,
        range_max=12.0,
        ranges=np.array(ranges, dtype=np.float32),
        intensities=np.array(intensities, dtype=np.float32),
    )


def messages(msgtype, ros1, rng, n=60):
    """``n`` messages of ``msgtype`` of several layouts (frames and names of awkward lengths, so
    that the CDR padding is not zero), interleaved."""
    out = []
    for k in range(n):
        t = 1e9 + 0.01 * k + rng.uniform(0, 1e-3)
        v = rng.normal(size=12)
        if msgtype == JOINT_STATE:
            kind = k % 4
            if kind == 0:
                out.append(joint_state(ros1, t, ("l_wheel", "r_wheel_joint"), v[:2]))
            elif kind == 1:
                out.append(joint_state(ros1, t, ("arm",), v[:1], "b", vel=v[2:3], eff=v[3:4]))
            elif kind == 2:
                out.append(joint_state(ros1, t, ("l_wheel", "r_wheel_joint", "c"), v[:2]))
            else:
                out.append(joint_state(ros1, t, ("l_wheel", "r_wheel_joint"), [-0.0, np.nan]))
        elif msgtype == TF:
            kind = k % 3
            edges = [("odom", "base_link"), ("/map", "odom"), ("base_link", "wheel_l")][: kind + 1]
            vals = [v[:7], v[5:12], [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0]][: kind + 1]
            out.append(tf_message(ros1, t, edges, vals) if k % 7 else tf_message(ros1, t, [], []))
        else:
            m = (0, 5, 7)[k % 3]
            r = rng.uniform(0, 13, m).astype(np.float32)
            r[: m // 3] = [np.inf, np.nan, 0.01][: m // 3]
            out.append(laser_scan(ros1, t, r, ("laser", "l2")[k % 2], r[:2] if k % 5 else ()))
    return out


def serialize(msgtype, msg, ros1, little=True) -> bytes:
    ts = store(ros1)
    if ros1:
        return bytes(ts.serialize_ros1(msg, msgtype))
    return bytes(ts.serialize_cdr(msg, msgtype, little_endian=little))


def build(msgtype, raws, ros1, fast, chunk=None):
    """The columns of ``raws`` (all fast or all through rosbags), and the failures."""
    ts = store(ros1)

    def deser(raw):
        return ts.deserialize_ros1(raw, msgtype) if ros1 else ts.deserialize_cdr(raw, msgtype)

    b = ColumnBuilder("/t", msgtype, ros1, deser, 2**32 - 1)
    for i, raw in enumerate(raws):
        if not fast:
            b.slow.append(len(b.raws))
        b.raws.append(raw)
        b.logs.append(1000 + i)
        b.index.append(i)
        if chunk and len(b.raws) >= chunk:
            b.flush()
    b.flush()
    return b.finish(), [(f.index, str(f.exc)) for f in b.failures]


def same_columns(a, b) -> None:
    """Every field of two column objects identical, bit for bit."""
    assert type(a) is type(b)
    for name in a.__dataclass_fields__:
        x, y = getattr(a, name), getattr(b, name)
        if isinstance(x, np.ndarray):
            assert x.dtype == y.dtype and x.shape == y.shape, name
            assert x.tobytes() == y.tobytes(), name
        elif name == "ranges":
            assert [r.tobytes() for r in x] == [r.tobytes() for r in y]
            assert all(r.dtype == np.float32 for r in x + y)
        else:
            assert x == y, name


ENCODINGS = [(True, True), (False, True), (False, False)]  # ROS 1; CDR little, big endian


def _id(enc):
    return "ros1" if enc[0] else "cdr-le" if enc[1] else "cdr-be"


@pytest.mark.parametrize("msgtype", bag_columns.COLUMN_TYPES)
@pytest.mark.parametrize("enc", ENCODINGS, ids=_id)
def test_columns_from_bytes_equal_rosbags(msgtype, enc):
    ros1, little = enc
    rng = np.random.default_rng(3)
    raws = [serialize(msgtype, m, ros1, little) for m in messages(msgtype, ros1, rng)]
    fast, f1 = build(msgtype, raws, ros1, True, chunk=17)
    ref, f2 = build(msgtype, raws, ros1, False)
    assert f1 == f2 == []
    same_columns(fast, ref)
    assert len(fast) == len(raws)
    if msgtype == JOINT_STATE:
        assert len(fast.layouts) == 3 and fast.position.shape == (len(raws), 2)
        assert np.isnan(fast.position[1, 1])  # one position: the second column is padding
    if msgtype == TF:
        assert fast.messages == len(raws) and len(fast.edges) == 3


@pytest.mark.parametrize("msgtype", bag_columns.COLUMN_TYPES)
@pytest.mark.parametrize("enc", ENCODINGS, ids=_id)
def test_damaged_bytes_decode_as_rosbags(msgtype, enc):
    """Whatever the bytes, a message gives rosbags' numbers or rosbags' error; among good ones
    (the template) and alone."""
    ros1, little = enc
    rng = np.random.default_rng(11)
    good = serialize(msgtype, messages(msgtype, ros1, rng, 3)[2], ros1, little)
    bad = [good[:n] for n in range(0, len(good), 3)]
    bad += [good + b"\x00" * k for k in (1, 3, 4, 8)]
    for pos in range(0, min(len(good) - 4, 80), 4):
        for v in (0, 1, 3, 9, 2**31):
            bad.append(good[:pos] + struct.pack("<I", v) + good[pos + 4 :])
    for _ in range(60):
        b = bytearray(good)
        for i in rng.integers(0, len(good), rng.integers(1, 3)):
            b[i] = int(rng.integers(0, 256))
        bad.append(bytes(b))
    refused = taken = 0
    for raw in bad:
        for batch in ([raw], [good, raw, good]):
            fast, f1 = build(msgtype, batch, ros1, True)
            ref, f2 = build(msgtype, batch, ros1, False)
            assert f1 == f2, raw.hex()
            same_columns(fast, ref)
        refused += bool(f1)
        taken += not f1
    assert refused > 10 and taken > 10


def test_big_and_little_endian_give_the_same_columns():
    rng = np.random.default_rng(5)
    for msgtype in bag_columns.COLUMN_TYPES:
        msgs = messages(msgtype, False, rng, 12)
        le = build(msgtype, [serialize(msgtype, m, False, True) for m in msgs], False, True)[0]
        be = build(msgtype, [serialize(msgtype, m, False, False) for m in msgs], False, True)[0]
        same_columns(le, be)


def test_many_layouts_in_one_chunk_fall_back_to_one_message_at_a_time():
    """More frames than templates tried: the rest are parsed one by one (same columns)."""
    raws = [
        serialize(JOINT_STATE, joint_state(False, 5.0 + k, ("a", "b"), [k, -k], f"f{k}"), False)
        for k in range(3 * bag_columns.MAX_TEMPLATES)
    ]
    fast, _ = build(JOINT_STATE, raws, False, True)
    ref, _ = build(JOINT_STATE, raws, False, False)
    same_columns(fast, ref)
    assert len(fast.layouts) == len(raws)


# --------------------------------------------------------------------------- whole bags


def series_of(bag: bags.BagContents) -> dict:
    out = {}
    for t in bag.topics:
        if t.name not in bag.messages:
            continue
        if t.msgtype == JOINT_STATE:
            s = bags.joint_series(bag, t.name)
            out[t.name] = (s.time_s, s.values["right"], s.values["left"], s.frame_id, s.meta)
        elif t.name == "/tf":
            out[t.name] = {
                k: (e.time_s, e.translation_m, e.quaternion_xyzw)
                for k, e in bags.tf_messages(bag).items()
            }
        elif t.msgtype == LASER_SCAN:
            s = bags.scan_series(bag, t.name)
            out[t.name] = (s.time_s, s.frame_id, [s.points_m[i] for i in range(len(s.points_m))])
    out["static"] = bags.static_rotation(bag, "imu_link", ("base_link",))
    return out


def assert_same(a, b) -> None:
    if isinstance(a, np.ndarray):
        assert a.dtype == b.dtype and a.shape == b.shape and a.tobytes() == b.tobytes()
    elif isinstance(a, dict):
        assert list(a) == list(b)
        for k in a:
            assert_same(a[k], b[k])
    elif isinstance(a, (list, tuple)):
        assert len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            assert_same(x, y)
    else:
        assert a == b


@pytest.fixture(scope="module")
def robot_bag(tmp_path_factory):
    """The synthetic robot's tour with a 90-beam laser and 2 Hz map -> odom (ROS 2, sqlite3)."""
    g = WheelGeometry.symmetric(0.066, 0.16)
    run = simulate_robot(default_track(), g, g, laser=Laser(n_rays=90, every=10))
    path = tmp_path_factory.mktemp("robot") / "robot"
    write_ros2_bag(path, run, map_odom_every=25)
    return path


@pytest.mark.parametrize("kind", KINDS)
def test_series_from_columns_equal_rosbags_on_written_bags(kind, tmp_path):
    path = write_bag(bag_path(tmp_path, kind), kind, make_run_small(), imu=False, truth=False)
    topics = [t.name for t in bags.list_topics(path)]
    assert_same(
        series_of(bags.read_bag(path, topics)), series_of(bags.read_bag(path, topics, fast=False))
    )


def make_run_small():
    # a straight and a spot turn between the 3 s still periods: 381 joint states of every value
    # the tour has (still, both wheels forward, opposite), not the 741 of the square and circle
    from odocal.core.tracks import Track, spot_turn, straight

    return make_run(Track("short", (straight(0.5), spot_turn(math.pi / 2))))


def test_series_from_columns_equal_rosbags_on_the_robot_bag(robot_bag):
    topics = ["/joint_states", "/tf", "/tf_static", "/scan"]
    fast = bags.read_bag(robot_bag, topics)
    ref = bags.read_bag(robot_bag, topics, fast=False)
    assert_same(series_of(fast), series_of(ref))
    assert isinstance(fast.messages["/tf"], bag_columns.Transforms)
    assert len(fast.messages["/scan"]) > 100


def test_series_from_columns_equal_rosbags_on_the_mit_bag(realdata):
    path = realdata / "mit_csail" / "csail_half1"
    topics = ["/joint_states", "/tf", "/tf_static", "/scan"]
    assert_same(
        series_of(bags.read_bag(path, topics)), series_of(bags.read_bag(path, topics, fast=False))
    )


def test_a_broken_joint_state_in_a_bag_is_refused_as_before(tmp_path):
    """A JointState cut short among good ones: the same one-line error with and without the
    columnar reading, naming the message before which all were good."""
    path = tmp_path / "cut.bag"
    from rosbags.rosbag1 import Writer

    ts = store(True)
    raws = [serialize(JOINT_STATE, joint_state(True, 10.0 + k, ("l", "r"), [k, k]), True) for k in
            range(9)]  # fmt: skip
    raws[6] = raws[6][:-5]
    with Writer(path) as w:
        conn = w.add_connection("/joint_states", JOINT_STATE, typestore=ts)
        for k, raw in enumerate(raws):
            w.write(conn, (10 + k) * 10**9, raw)
    errors = []
    for fast in (True, False):
        with pytest.raises(InputError) as exc:
            bags.read_bag(path, ["/joint_states"], fast=fast)
        errors.append(str(exc.value))
    assert errors[0] == errors[1]
    assert "after 6 good messages, the last on '/joint_states'" in errors[0]


def test_columns_iterate_as_messages_with_rosbags_fields():
    """Code that reads a column topic one message at a time (``for t, m in bag.messages[...]``)
    sees the fields rosbags' messages have, with the same values."""
    rng = np.random.default_rng(8)
    for msgtype in bag_columns.COLUMN_TYPES:
        msgs = messages(msgtype, False, rng, 14)
        raws = [serialize(msgtype, m, False) for m in msgs]
        cols, _ = build(msgtype, raws, False, True, chunk=5)
        got = list(cols)
        assert len(got) == len(msgs) and [t for t, _ in got] == [1000 + i for i in range(14)]
        assert cols[-1][0] == got[-1][0]
        for (_, view), raw in zip(got, raws, strict=True):
            m = store(False).deserialize_cdr(raw, msgtype)  # as rosbags reads it
            if msgtype == TF:
                assert len(view.transforms) == len(m.transforms)
                pairs = list(zip(view.transforms, m.transforms, strict=True))
            else:
                pairs = [(view, m)]
            for v, w in pairs:
                assert stamp_ns(v.header) == stamp_ns(w.header)
                assert v.header.frame_id == w.header.frame_id
                if msgtype == JOINT_STATE:
                    assert v.name == tuple(w.name)
                    assert v.position.tobytes() == np.asarray(w.position).tobytes()
                elif msgtype == TF:
                    assert v.child_frame_id == w.child_frame_id
                    for a in ("translation", "rotation"):
                        x, y = getattr(v.transform, a), getattr(w.transform, a)
                        assert all(getattr(x, f) == getattr(y, f) for f in x._fields)
                else:
                    assert (v.angle_min, v.angle_increment, v.range_min, v.range_max) == (
                        w.angle_min, w.angle_increment, w.range_min, w.range_max
                    )  # fmt: skip
                    assert v.ranges.tobytes() == w.ranges.tobytes()
