"""The bag routes' fast paths give what the plain versions gave (issue 22, item 9; the timings
themselves live in benchmarks/bench_bag_route.py)."""

from __future__ import annotations

import dataclasses
import math
import weakref

import numpy as np
import pytest

from odocal.app.check import check, check_loaded
from odocal.calibration.relative_motions import wheel_increments
from odocal.core.model import WheelGeometry
from odocal.core.tracks import Track, spot_turn, straight
from odocal.errors import CalibrationError
from odocal.io import bags
from odocal.io.bag_options import BagOptions
from odocal.io.bag_recording import load_bag_recording, without_gyro
from odocal.io.bag_scan import read_scan_bag
from tests.support.bag_files import Writer2, make_run, write_bag
from tests.support.synthetic_robot import write_ros2_bag


def _wheel_increments_loop(t, right, left, start_s, end_s):
    """The former implementation: one pass over every wheel sample per interval."""
    rows_r, rows_l = [], []
    for a, b in zip(start_s, end_s, strict=True):
        inside = t[(t > a) & (t < b)]
        tt = np.r_[a, inside, b]
        rows_r.append(np.diff(np.interp(tt, t, right)))
        rows_l.append(np.diff(np.interp(tt, t, left)))
    k = max((len(x) for x in rows_r), default=1)
    out_r, out_l = np.zeros((len(rows_r), k)), np.zeros((len(rows_r), k))
    for i, (x, y) in enumerate(zip(rows_r, rows_l, strict=True)):
        out_r[i, : len(x)], out_l[i, : len(y)] = x, y
    return out_r, out_l


def test_wheel_increments_equal_the_loop_on_random_intervals():
    rng = np.random.default_rng(22)
    for trial in range(30):
        n = int(rng.integers(2, 400))
        t = np.cumsum(rng.uniform(0.001, 0.05, n)) + rng.uniform(-5, 5)
        right = np.cumsum(rng.normal(0, 0.1, n))
        left = np.cumsum(rng.normal(0, 0.1, n))
        m = int(rng.integers(0, 40))
        a = rng.uniform(t[0] - 0.5, t[-1] + 0.5, m)
        b = a + rng.exponential(0.3, m) * (rng.random(m) < 0.9) - (rng.random(m) < 0.05)
        if trial % 3 == 0 and m:  # ends on the samples themselves, and empty intervals
            a[::2] = rng.choice(t, len(a[::2]))
            b[::3] = rng.choice(t, len(b[::3]))
            b[:1] = a[:1]
        want = _wheel_increments_loop(t, right, left, a, b)
        got = wheel_increments(t, right, left, a, b)
        for w, g in zip(want, got, strict=True):
            assert g.shape == w.shape
            np.testing.assert_array_equal(g, w)


def test_wheel_increments_of_no_interval_and_of_nan_ends():
    t = np.arange(10.0)
    r, lft = wheel_increments(t, t, -t, np.zeros(0), np.zeros(0))
    assert r.shape == lft.shape == (0, 1)
    a, b = np.array([np.nan, 1.5, 2.0]), np.array([3.0, np.nan, 5.5])
    want = _wheel_increments_loop(t, t, -t, a, b)
    got = wheel_increments(t, t, -t, a, b)
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(g, w)


# ------------------------------------------------------------------ what the routes read


@pytest.fixture(scope="module")
def scan_bags(tmp_path_factory):
    """A short drive with a 60-beam laser: the mounting on /tf_static (as written by the
    synthetic robot), and a copy whose mounting is published on /tf instead (in every tenth
    /tf message)."""
    from rosbags.highlevel import AnyReader

    from tests.support.synthetic_robot import Laser, simulate_robot

    g = WheelGeometry.symmetric(0.066, 0.16)
    track = Track("short", (straight(0.5), spot_turn(math.pi / 2), straight(0.3)))
    run = simulate_robot(track, g, g, laser=Laser(n_rays=60, mount=(0.15, 0.05, 0.1)))
    folder = tmp_path_factory.mktemp("scan")
    static = folder / "static"
    write_ros2_bag(static, run, map_odom_every=25)
    dynamic = folder / "dynamic"
    tf = "tf2_msgs/msg/TFMessage"
    with AnyReader([static]) as r, Writer2(dynamic, version=9) as w:
        ts = r.typestore
        conns = {
            c.id: w.add_connection(c.topic, c.msgtype, typestore=ts)
            for c in r.connections
            if c.topic != "/tf_static"
        }
        static_msg = next(
            ts.deserialize_cdr(raw, tf) for c, _, raw in r.messages() if c.topic == "/tf_static"
        )
        laser_tf = [t for t in static_msg.transforms if t.child_frame_id == "laser"]
        k = 0
        for c, t, raw in r.messages():
            if c.topic == "/tf" and k % 10 == 0:
                msg = ts.deserialize_cdr(raw, tf)
                msg.transforms.extend(laser_tf)
                raw = ts.serialize_cdr(msg, tf)
            k += c.topic == "/tf"
            if c.id in conns:
                w.write(conns[c.id], t, raw)
    return static, dynamic


def _topics_read(monkeypatch) -> list:
    read = []
    real = bags._Bag.read

    def spy(self, topics, fast=True):
        read.append(sorted(topics))
        return real(self, topics, fast)

    monkeypatch.setattr(bags._Bag, "read", spy)
    return read


def test_the_scan_route_reads_tf_only_when_tf_static_lacks_the_mounting(scan_bags, monkeypatch):
    static, dynamic = scan_bags
    read = _topics_read(monkeypatch)
    a = read_scan_bag(static, BagOptions(), None)
    assert read == [["/joint_states", "/scan", "/tf_static"]]  # no /tf
    b = read_scan_bag(dynamic, BagOptions(), None)
    assert read[1:] == [["/joint_states", "/scan"], ["/tf"]]  # then /tf, on the same open bag
    np.testing.assert_allclose(a.mount, [0.15, 0.05, 0.1], atol=1e-12)
    np.testing.assert_array_equal(a.mount, b.mount)
    assert a.mount_source == b.mount_source == "tf (base_link -> laser)"
    # what reading /tf too would have given
    full = bags.read_bag(static, ["/tf", "/tf_static"])
    buf = bags.transform_buffer(full)
    want = buf.lookup("base_link", "laser", a.scans.time_s[:1], max_extrapolation_s=1e9)
    np.testing.assert_array_equal(a.mount, want.planar()[0])


def test_check_does_not_read_the_imu(tmp_path, monkeypatch):
    # which topics are read does not depend on the drive: a straight and a spot turn
    short = Track("short", (straight(0.5), spot_turn(math.pi / 2)))
    path = write_bag(tmp_path / "run.bag", "ros1", make_run(short))
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.2\nwheelbase_m: 0.5\n")
    read = _topics_read(monkeypatch)
    res = check(path, robot=robot)
    assert read == [["/joint_states", "/mocap/pose"]]
    assert load_bag_recording(path).gyro_yaw_rad is not None  # outside check, as before
    assert read[1] == ["/imu", "/joint_states", "/mocap/pose", "/tf_static"]
    with without_gyro():
        assert load_bag_recording(path).gyro_yaw_rad is None
    # what the check says does not depend on the gyro
    with_gyro = check_loaded([load_bag_recording(path)], WheelGeometry.symmetric(0.2, 0.5))
    assert with_gyro.check.as_dict() == res.check.as_dict()


# ------------------------------------------------------------------------- the matcher's memory


def _sequence_scans(n=24):
    from odocal.calibration.scan_matching import scan_points
    from tests.support.room import Room, ray_cast

    rng = np.random.default_rng(4)
    steps = np.column_stack(
        [rng.uniform(0, 0.05, n), rng.uniform(-0.02, 0.02, n), rng.uniform(-0.05, 0.05, n)]
    )
    poses = np.cumsum(steps, axis=0) + [3.0, 2.5, 0.0]
    angles = -math.pi + 2 * math.pi / 180 * np.arange(180)
    scans = [
        scan_points(ray_cast(Room.default(), p, angles, 12.0, rng, 0.01), -math.pi,
                    2 * math.pi / 180, 0.05, 12.0)
        for p in poses
    ]  # fmt: skip
    return 0.1 * np.arange(n), scans


def test_match_intervals_prepares_each_start_once_and_keeps_few(monkeypatch):
    from odocal.calibration import scan_matching as sm

    times, scans = _sequence_scans()
    intervals = np.array([(i, i + 1) for i in range(20)] + [(0, 3), (5, 9), (0, 2)])
    made, alive, live = [], [], []
    real = sm.prepare_scan

    def counting(points, **kw):
        made.append(1)
        out = real(points, **kw)
        alive.append(weakref.ref(out))
        live.append(sum(r() is not None for r in alive))
        return out

    monkeypatch.setattr(sm, "prepare_scan", counting)
    res = sm.match_intervals(times, scans, intervals)
    assert len(made) == 20  # starts 0..19, each once (0 and 5 are used again later)
    assert max(live) <= 3  # not all 20: a start is dropped after its last interval
    monkeypatch.setattr(sm, "prepare_scan", real)
    want = [sm.match_scans(scans[i], scans[j]) for i, j in intervals]
    np.testing.assert_array_equal(res.motion, [m.motion for m in want])


def test_match_intervals_on_several_workers_gives_the_same_bytes(monkeypatch):
    from odocal.calibration import scan_matching as sm

    times, scans = _sequence_scans()
    intervals = np.array([(i, i + 1) for i in range(23)] + [(i, i + 4) for i in range(0, 20, 2)])
    monkeypatch.setenv("ODOCAL_THREADS", "1")
    one = sm.match_intervals(times, scans, intervals)
    monkeypatch.setenv("ODOCAL_THREADS", "2")
    monkeypatch.setattr(sm, "PARALLEL_MIN_INTERVALS", 4)
    assert len(sm._chunks(len(intervals))) == 8
    two = sm.match_intervals(times, scans, intervals)
    for f in dataclasses.fields(one):
        a, b = getattr(one, f.name), getattr(two, f.name)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), f.name
    bad = [*scans[:-1], scans[-1][:3]]  # too few points in the last scan: the same error
    with pytest.raises(CalibrationError, match=r"interval 22 \(scans 22 -> 23\)"):
        sm.match_intervals(times, bad, intervals)
