"""The fast Imu / Odometry decoder (odocal.io.bag_decode) against rosbags, and one open per read.

Exactness is checked bit for bit: the records of every Imu and Odometry message of every bag
kind the tests write (ROS 1, ROS 2 sqlite3 and mcap) and of both Husky recordings, decoded fast
and through rosbags, are identical, and so are the series made from them. Messages the decoder
must not take (a custom type of the standard name, bytes rosbags would refuse) go through
rosbags: same numbers, or the same error as before.
"""

from __future__ import annotations

import math
import struct

import numpy as np
import pytest
from rosbags.highlevel import AnyReader
from rosbags.rosbag1 import Writer as Writer1
from rosbags.rosbag2 import StoragePlugin
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from odocal.app.fit import fit_gyro_bag
from odocal.app.slam_bags import load_slam_bag
from odocal.core.model import WheelGeometry
from odocal.core.tracks import Track, spot_turn, straight
from odocal.errors import InputError
from odocal.io import bag_decode, bags
from odocal.io.bag_recording import load_bag_recording
from tests.support.bag_files import (
    KINDS,
    BagWriter,
    Writer2,
    bag_path,
    lazy_bags,
    make_run,
)
from tests.support.synthetic_robot import Gyro, Laser, simulate_robot, write_ros2_bag

IMU, ODOMETRY = bag_decode.IMU, bag_decode.ODOMETRY


def bits(value):
    """``value`` with every float replaced by its 8 bytes (so -0.0 != 0.0 and NaN == NaN)."""
    if isinstance(value, float):
        return struct.pack("<d", value)
    if isinstance(value, tuple):
        return tuple(bits(v) for v in value)
    return value


def series_bits(s) -> tuple:
    if isinstance(s, bags.TopicSeries):
        values = tuple((k, v.dtype.str, v.shape, v.tobytes()) for k, v in s.values.items())
        return (s.topic, s.time_s.tobytes(), values, s.frame_id, s.child_frame_id, s.meta)
    return s


def refuse_records(monkeypatch) -> None:
    """From now on rosbags fails the test when asked to decode an Imu or an Odometry: a read
    that passes took the fast path for every such message."""
    real = AnyReader.deserialize

    def guarded(self, rawdata, typ):
        if typ in bag_decode.RECORD_TYPES:
            pytest.fail(f"rosbags asked to decode a {typ}")  # not an Exception: not caught
        return real(self, rawdata, typ)

    monkeypatch.setattr(AnyReader, "deserialize", guarded)


def assert_fast_equals_rosbags(path, monkeypatch, expect_fast=True) -> bags.BagContents:
    """Read every Imu and Odometry topic of ``path`` fast and through rosbags: the records and
    the series are identical. Returns the fast read (a BagContents)."""
    topics = [t.name for t in bags.list_topics(path) if t.msgtype in bag_decode.RECORD_TYPES]
    assert topics
    ref = bags.read_bag(path, topics, fast=False)
    with monkeypatch.context() as m:
        if expect_fast:
            refuse_records(m)
        fast = bags.read_bag(path, topics)
    for topic in topics:
        a, b = fast.messages[topic], ref.messages[topic]
        assert [bits(x) for x in a] == [bits(x) for x in b], topic
        series = bags.imu_series if fast.msgtype(topic) == IMU else bags.pose_series
        assert series_bits(series(fast, topic)) == series_bits(series(ref, topic)), topic
    return fast


# --------------------------------------------------------------------------- every bag kind


@pytest.fixture(scope="module")
def run():
    # a straight and a half turn between 3 s of standing still: 381 joint states, 760 Imu and
    # 77 Odometry messages (a decoder reads each message alone: the tour adds only more of them)
    return make_run(Track("short", (straight(0.5), spot_turn(math.pi))))


@pytest.fixture(scope="module")
def written(tmp_path_factory, run):
    """kind -> the bag of ``run`` of that kind, with the odometry (written on first use)."""
    return lazy_bags(tmp_path_factory, run, odom=True)


@pytest.mark.parametrize("kind", KINDS)
def test_fast_path_equals_rosbags_on_written_bags(kind, written, monkeypatch):
    messages = assert_fast_equals_rosbags(written(kind), monkeypatch).messages
    assert len(messages["/imu"]) > 700 and len(messages["/odom"]) > 70


@pytest.fixture(scope="module")
def robot_bag(tmp_path_factory):
    """A short synthetic robot run and its ROS 2 (sqlite3) bag, written once and only read."""
    short = Track("short", (straight(0.5), spot_turn(math.pi / 2)))
    geometry = WheelGeometry.symmetric(0.2, 0.5)
    # no test here reads the scans: 8 rays, not 720 (noise-free ranges draw nothing from rng)
    robot = simulate_robot(
        short, geometry, geometry, gyro=Gyro(0.01, 0.002), rng=np.random.default_rng(5),
        laser=Laser(n_rays=8),
    )  # fmt: skip
    path = tmp_path_factory.mktemp("robot") / "robot"
    write_ros2_bag(path, robot)
    return robot, path


@pytest.mark.parametrize("storage", ["sqlite3", "mcap"])
def test_fast_path_equals_rosbags_on_the_synthetic_robot_bag(
    storage, robot_bag, tmp_path, monkeypatch
):
    robot, path = robot_bag
    if storage == "mcap":  # the same messages into an mcap bag
        src = path
        path = tmp_path / "robot_mcap"
        with (
            AnyReader([src]) as r,
            Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP) as w,
        ):
            conns = {
                c.id: w.add_connection(c.topic, c.msgtype, typestore=r.typestore)
                for c in r.connections
            }
            for c, t, raw in r.messages():
                w.write(conns[c.id], t, raw)
    messages = assert_fast_equals_rosbags(path, monkeypatch).messages
    assert len(messages["/imu"]) == len(robot.gyro_time_ns)


def test_fast_path_equals_rosbags_on_the_husky_bag(realdata, monkeypatch):
    """The bag a real ``rosbag record`` wrote. (Its ROS 2 copy was converted by rosbags, like the
    written bags above; test_fit_bags checks that both give the same fit.) Every message is read
    fast; rosbags decodes those of three 20 s windows (the start, the middle, the end of the
    395 s: about 1800 Imu and 600 Odometry messages, every layout the bag has, values from
    standing still and driving), which must be the same records and give the same series."""
    from dataclasses import replace

    path = realdata / "husky" / "husky_test1.bag"
    topics = [t.name for t in bags.list_topics(path) if t.msgtype in bag_decode.RECORD_TYPES]
    with monkeypatch.context() as m:
        refuse_records(m)
        fast = bags.read_bag(path, topics)
    counts = {topic: len(m) for topic, m in fast.messages.items()}
    assert counts == {"/imu/data": 11865, "/husky_velocity_controller/odom": 3952}
    window_ns = 20 * 10**9
    with AnyReader([path]) as r:
        conns = [c for c in r.connections if c.topic in topics]
        middle = (r.start_time + r.end_time) // 2
        for start in (r.start_time, middle, r.end_time - window_ns):
            ref: dict[str, list] = {t: [] for t in topics}
            for c, t_ns, raw in r.messages(connections=conns, start=start, stop=start + window_ns):
                msg = bag_decode.record(c.msgtype, r.deserialize(raw, c.msgtype))
                ref[c.topic].append((int(t_ns), msg))
            for topic in topics:
                first = sum(1 for t_ns, _ in fast.messages[topic] if t_ns < start)
                a, b = fast.messages[topic][first : first + len(ref[topic])], ref[topic]
                assert len(b) > 150 and [bits(x) for x in a] == [bits(x) for x in b], topic
                series = bags.imu_series if fast.msgtype(topic) == IMU else bags.pose_series
                fast_w, ref_w = (replace(fast, messages={topic: x}) for x in (a, b))
                assert series_bits(series(fast_w, topic)) == series_bits(series(ref_w, topic))


# --------------------------------------------------------------------------- message bytes


def standard_messages(ros1: bool):
    """An Imu and an Odometry with distinct values and frame names of awkward lengths (so the
    CDR alignment padding is not zero), serialised by rosbags."""
    w = BagWriter.__new__(BagWriter)  # its message builders only, without a file
    w.ros1 = ros1
    w.ts = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    Vec = w.T("geometry_msgs/msg/Vector3")
    z9, z36 = np.arange(9.0) / 7, np.arange(36.0) / 11
    imu = w.T(IMU)(
        header=w.header(12.345678901, "imu"),
        orientation=w.quat((0.1, -0.2, 0.3, 0.9)),
        orientation_covariance=z9,
        angular_velocity=Vec(x=-0.0, y=1.0 / 3.0, z=-2.5e-7),
        angular_velocity_covariance=z9 + 1,
        linear_acceleration=Vec(x=0.5, y=-9.81, z=1e300),
        linear_acceleration_covariance=z9 + 2,
    )
    twist = w.T("geometry_msgs/msg/Twist")(
        linear=Vec(x=0.7, y=0.01, z=0.0), angular=Vec(x=0.0, y=-0.0, z=0.2)
    )
    odom = w.T(ODOMETRY)(
        header=w.header(1e9 + 0.5, "odom_x"),
        child_frame_id="base",
        pose=w.T("geometry_msgs/msg/PoseWithCovariance")(
            pose=w.pose(1.25, -3.5, 2.0), covariance=z36
        ),
        twist=w.T("geometry_msgs/msg/TwistWithCovariance")(twist=twist, covariance=z36 + 1),
    )
    return w.ts, [(IMU, imu), (ODOMETRY, odom)]


#: (ros1, little endian, msgtype): ROS 1, and CDR little- and big-endian, of each message
CASES = [
    (ros1, little, msgtype)
    for ros1, little in ((True, True), (False, True), (False, False))
    for msgtype in (IMU, ODOMETRY)
]


@pytest.fixture(scope="module")
def encoded():
    """(typestore, ros1, msgtype, raw bytes) per case of CASES (built here, not at collection:
    the type stores and serialisers take a while, and only this file's worker needs them)."""
    out = {}
    for ros1 in (True, False):
        ts, msgs = standard_messages(ros1)
        for msgtype, msg in msgs:
            for little in (True,) if ros1 else (True, False):
                if ros1:
                    raw = bytes(ts.serialize_ros1(msg, msgtype))
                else:
                    raw = bytes(ts.serialize_cdr(msg, msgtype, little_endian=little))
                out[ros1, little, msgtype] = (ts, ros1, msgtype, raw)
    return out


def _case_id(case) -> str:
    ros1, little, msgtype = case
    return f"{msgtype.rsplit('/', 1)[-1]}-{'ros1' if ros1 else 'cdr-le' if little else 'cdr-be'}"


def rosbags_record(ts, ros1, msgtype, raw):
    msg = ts.deserialize_ros1(raw, msgtype) if ros1 else ts.deserialize_cdr(raw, msgtype)
    return bag_decode.record(msgtype, msg)


@pytest.mark.parametrize("case", CASES, ids=_case_id)
def test_message_bytes_decode_as_rosbags(case, encoded):
    ts, ros1, msgtype, raw = encoded[case]
    if not ros1:  # the encapsulation header says which byte order
        assert raw[:2] in (b"\x00\x00", b"\x00\x01")
    dec = bag_decode.decoder(msgtype, ts, ros1)
    assert dec is not None
    got = dec(raw)
    assert bits(got) == bits(rosbags_record(ts, ros1, msgtype, raw))
    assert got.frame_id in ("imu", "odom_x")


def test_big_endian_cdr_is_decoded():
    ts, msgs = standard_messages(False)
    for msgtype, msg in msgs:
        le = bytes(ts.serialize_cdr(msg, msgtype, little_endian=True))
        be = bytes(ts.serialize_cdr(msg, msgtype, little_endian=False))
        assert be[:2] == b"\x00\x00" and be != le
        dec = bag_decode.decoder(msgtype, ts, False)
        assert bits(dec(be)) == bits(dec(le)) == bits(rosbags_record(ts, False, msgtype, be))


def damaged(raw: bytes, rng) -> list[bytes]:
    """Truncations at every length, trailing bytes, other string lengths, other encapsulation
    headers, random byte changes."""
    out = [raw[:n] for n in range(len(raw))]
    out += [raw + b"\x00" * k for k in range(1, 9)] + [raw + b"\x01"]
    for pos in (0, 1, 2, 3, 8, 12, 13, 16, 20, 24, 28):  # length fields sit around here
        for v in (0, 1, 2, 5, 7, 8, 9, 10, 11, 12, 255, 2**31):
            if pos + 4 <= len(raw):
                out.append(raw[:pos] + struct.pack("<I", v) + raw[pos + 4 :])
                out.append(raw[:pos] + struct.pack(">I", v) + raw[pos + 4 :])
    for _ in range(300):
        b = bytearray(raw)
        for i in rng.integers(0, len(raw), rng.integers(1, 4)):
            b[i] = int(rng.integers(0, 256))
        out.append(bytes(b))
    return out


@pytest.mark.parametrize("case", CASES, ids=_case_id)
def test_damaged_bytes_decode_as_rosbags_or_fall_back(case, encoded):
    """Whatever the bytes, the decoder gives rosbags' numbers or None (then rosbags decides);
    it never decodes what rosbags refuses."""
    ts, ros1, msgtype, raw = encoded[case]
    dec = bag_decode.decoder(msgtype, ts, ros1)
    taken = refused = 0
    for bad in damaged(raw, np.random.default_rng(len(raw))):
        got = dec(bad)
        try:
            want = rosbags_record(ts, ros1, msgtype, bad)
        except Exception:  # noqa: BLE001 - rosbags refuses: so must the decoder
            assert got is None, bad.hex()
            refused += 1
            continue
        if got is not None:
            assert bits(got) == bits(want), bad.hex()
            taken += 1
    assert taken > 300 and refused > 300  # both sides were exercised


# --------------------------------------------------------------------------- custom types

# Same name, same size as the standard Imu, fields in another order: the standard layout would
# read the wrong bytes without a word.
SWAPPED_IMU = """std_msgs/Header header
geometry_msgs/Vector3 angular_velocity
float64[9] angular_velocity_covariance
geometry_msgs/Quaternion orientation
float64[9] orientation_covariance
geometry_msgs/Vector3 linear_acceleration
float64[9] linear_acceleration_covariance
"""
NO_RATE_IMU = """std_msgs/Header header
geometry_msgs/Quaternion orientation
"""


def custom_store(ros1: bool, definition: str):
    std = get_typestore(Stores.ROS1_NOETIC if ros1 else Stores.ROS2_HUMBLE)
    ts = get_typestore(Stores.EMPTY)
    ts.register({k: v for k, v in std.fielddefs.items() if k != IMU})
    ts.register(get_types_from_msg(definition, IMU))
    return ts


def write_custom_imu(path, kind: str, definition: str, rates) -> None:
    ros1 = kind == "ros1"
    ts = custom_store(ros1, definition)
    T = ts.types
    if ros1:
        writer = Writer1(path)
    else:
        plugin = StoragePlugin.MCAP if kind == "mcap" else StoragePlugin.SQLITE3
        writer = Writer2(path, version=9, storage_plugin=plugin)
    with writer as w:
        conn = w.add_connection("/imu", IMU, typestore=ts)
        for k, rate in enumerate(rates):
            stamp = T["builtin_interfaces/msg/Time"](sec=100 + k, nanosec=0)
            head = {"seq": k} if ros1 else {}
            fields = {
                "header": T["std_msgs/msg/Header"](**head, stamp=stamp, frame_id="imu"),
                "orientation": T["geometry_msgs/msg/Quaternion"](x=0.5, y=0.5, z=0.5, w=0.5),
            }
            if "angular_velocity" in definition:
                vec, z9 = T["geometry_msgs/msg/Vector3"], np.zeros(9)
                fields |= {
                    "angular_velocity": vec(x=rate, y=2 * rate, z=3 * rate),
                    "linear_acceleration": vec(x=0.0, y=0.0, z=9.81),
                    "orientation_covariance": z9,
                    "angular_velocity_covariance": z9 + 7.0,
                    "linear_acceleration_covariance": z9,
                }
            msg = T[IMU](**fields)
            ser = ts.serialize_ros1 if ros1 else ts.serialize_cdr
            w.write(conn, (100 + k) * 10**9, ser(msg, IMU))


@pytest.mark.parametrize("kind", KINDS)
def test_a_custom_type_of_the_standard_name_is_left_to_rosbags(kind, tmp_path, monkeypatch):
    path = bag_path(tmp_path, kind)
    rates = np.linspace(-0.3, 0.4, 8)
    write_custom_imu(path, kind, SWAPPED_IMU, rates)
    with AnyReader([path]) as r:  # the bag carries its own definition, rosbags uses it
        assert bag_decode.decoder(IMU, r.typestore, kind == "ros1") is None
    fast = assert_fast_equals_rosbags(path, monkeypatch, expect_fast=False)
    assert list(fast.messages) == ["/imu"]  # that read was read_bag(path, ["/imu"])
    s = bags.imu_series(fast, "/imu")
    np.testing.assert_array_equal(s.values["angular_velocity"], np.outer(rates, [1, 2, 3]))


def test_a_custom_type_without_the_read_fields_is_one_input_error(tmp_path):
    path = tmp_path / "norate.bag"
    write_custom_imu(path, "ros1", NO_RATE_IMU, [0.1, 0.2, 0.3])
    with pytest.raises(InputError, match="sensor_msgs/Imu of a non-standard definition: it has "
                       "no field 'angular_velocity'") as exc:  # fmt: skip
        bags.read_bag(path, ["/imu"])
    assert str(path) in str(exc.value) and "/imu" in str(exc.value)


# --------------------------------------------------------------------------- broken bytes in a bag


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_a_truncated_message_is_refused_as_before(kind, tmp_path):
    """One Imu message cut short inside an intact bag: the fast read falls back to rosbags and
    fails with the same one-line error as the rosbags-only read."""
    ros1 = kind == "ros1"
    ts, msgs = standard_messages(ros1)
    path = bag_path(tmp_path, kind)
    writer = Writer1(path) if ros1 else Writer2(path, version=9, storage_plugin=StoragePlugin.MCAP)
    with writer as w:
        conn = w.add_connection("/imu", IMU, typestore=ts)
        raw = bytes((ts.serialize_ros1 if ros1 else ts.serialize_cdr)(msgs[0][1], IMU))
        for k in range(5):
            w.write(conn, (10 + k) * 10**9, raw if k != 3 else raw[:-9])
    errors = []
    for fast in (True, False):
        with pytest.raises(InputError) as exc:
            bags.read_bag(path, ["/imu"], fast=fast)
        errors.append(str(exc.value))
    assert errors[0] == errors[1]
    assert "after 3 good messages, the last on '/imu'" in errors[0] and "corrupt" in errors[0]


# --------------------------------------------------------------------------- one open


@pytest.fixture
def opens(monkeypatch):
    count = [0]
    real = AnyReader.open

    def counting(self):
        count[0] += 1
        return real(self)

    monkeypatch.setattr(AnyReader, "open", counting)
    return count


def test_every_bag_reader_opens_the_bag_once(written, opens):
    path = written("ros1")
    load_bag_recording(path)
    assert opens[0] == 1
    fit_gyro_bag(path, odom_topic="/odom")
    assert opens[0] == 2
    with pytest.raises(InputError, match="no topic '/nope'"):  # picked on the open bag
        fit_gyro_bag(path, imu_topic="/nope")
    assert opens[0] == 3
    with pytest.raises(InputError, match="no /tf topic"):
        load_slam_bag(path)
    assert opens[0] == 4


def test_read_bag_with_a_choice_function(written, monkeypatch):
    path = written("ros1")
    refuse_records(monkeypatch)
    seen = []

    def choose(info):
        seen.append([t.name for t in info])
        return {
            "gyro": "/imu",
            "odometry": "/odom",
            "nothing": None,
            "tf": bags.present(info, "/tf"),
        }

    bag = bags.read_bag(path, choose)
    assert seen == [["/imu", "/joint_states", "/mocap/pose", "/odom", "/tf_static"]]
    assert bag.picked == {"gyro": "/imu", "odometry": "/odom"}
    assert sorted(bag.messages) == ["/imu", "/odom"]
    assert isinstance(bag.messages["/imu"][0][1], bag_decode.ImuRecord)
    with pytest.raises(InputError, match="no topic '/gone' in the bag"):
        bags.read_bag(path, lambda info: {"x": "/gone"})


def test_an_old_ros1_format_is_named_not_called_corrupt(tmp_path, cli):
    old = tmp_path / "old.bag"
    old.write_bytes(b"#ROSRECORD V1.2\n" + bytes(200))
    status, out, err = cli("bag-info", old)
    assert status == 2 and out == ""
    assert "unsupported ROS 1 bag format version 1.2" in err and "corrupt" not in err
    assert err.count("\n") == 1
