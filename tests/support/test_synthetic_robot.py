"""The synthetic robot bag (tests/support/synthetic_robot.py): it is a readable ROS 2 bag whose
messages agree with the simulated truth, and the scans in it match back to the true laser
motion."""

from __future__ import annotations

import math

import numpy as np
import pytest
from rosbags.highlevel import AnyReader

from odocal.calibration.scan_matching import match_intervals, scan_points
from odocal.core.model import NonSystematicError, WheelGeometry
from tests.support.synthetic_robot import (
    TOPICS,
    Gyro,
    Laser,
    compose,
    default_track,
    relative,
    simulate_robot,
    write_ros2_bag,
)

NOMINAL = WheelGeometry.symmetric(0.2, 0.5)  # believed: D = 0.2 m, b = 0.5 m
TRUE = WheelGeometry(0.2 * 1.01, 0.2 * 0.99, 0.5 * 1.04)  # E_d ~ 1.02, E_b = 1.04
LASER = Laser(mount=(0.15, 0.05, 0.1), sigma_m=0.01)
GYRO = Gyro(bias_rad_s=0.01, sigma_rad_s=0.002)
MAP_ODOM_EVERY = 25  # increments: 2 Hz at 50 Hz


@pytest.fixture(scope="module")
def run():
    return simulate_robot(
        default_track(),
        TRUE,
        NOMINAL,
        laser=LASER,
        gyro=GYRO,
        noise=NonSystematicError(1e-5, 1e-5),
        rng=np.random.default_rng(42),
    )


@pytest.fixture(scope="module")
def bag(run, tmp_path_factory):
    path = tmp_path_factory.mktemp("robot") / "run"
    counts = write_ros2_bag(path, run, map_odom_every=MAP_ODOM_EVERY)
    return path, counts


@pytest.fixture(scope="module")
def contents(bag):
    """The bag read once with rosbags and only inspected by the tests: the connections' counts
    and types, and topic -> [(log time ns, message)] in recording order."""
    with AnyReader([bag[0]]) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
        types = {c.topic: c.msgtype for c in reader.connections}
        messages: dict[str, list] = {topic: [] for topic in counts}
        for c, t, raw in reader.messages():
            messages[c.topic].append((t, reader.deserialize(raw, c.msgtype)))
    return counts, types, messages


def stamp_ns(msg) -> int:
    return msg.header.stamp.sec * 10**9 + msg.header.stamp.nanosec


def yaw(q) -> float:
    return 2.0 * math.atan2(q.z, q.w)


def test_the_run_stays_in_the_room_and_turns_both_ways(run):
    assert run.room.distance_to_walls(run.true_pose[:, :2]).min() > 0.8
    rates = np.diff(run.true_pose[:, 2])
    assert rates.max() > 0 and rates.min() < 0
    assert run.true_pose.shape == (len(run.time_ns), 3)
    # standing still 1 s at both ends
    np.testing.assert_array_equal(run.true_pose[0], run.true_pose[49])
    np.testing.assert_array_equal(run.true_pose[-1], run.true_pose[-50])


def test_without_errors_the_odometry_is_the_true_path():
    exact = simulate_robot(default_track(), NOMINAL, NOMINAL, laser=Laser(n_rays=8))
    np.testing.assert_allclose(
        compose(exact.true_pose[0], exact.odom_pose), exact.true_pose, atol=1e-12
    )


def test_message_counts(run, bag, contents):
    _, counts = bag
    k, s = len(run.time_ns), len(run.scan_index)
    expected = {
        TOPICS["joints"]: k,
        TOPICS["tf"]: k,
        TOPICS["scan"]: s,
        TOPICS["imu"]: k - 1,
        TOPICS["tf_static"]: 1,
    }
    assert counts == expected
    in_bag, types, messages = contents
    assert in_bag == expected
    assert {topic: len(m) for topic, m in messages.items()} == expected
    assert types[TOPICS["scan"]] == "sensor_msgs/msg/LaserScan"
    assert types[TOPICS["joints"]] == "sensor_msgs/msg/JointState"
    assert types[TOPICS["imu"]] == "sensor_msgs/msg/Imu"


def test_static_transform_is_the_laser_mounting(contents):
    ((_, msg),) = contents[2][TOPICS["tf_static"]]
    laser = next(t for t in msg.transforms if t.child_frame_id == "laser")
    assert laser.header.frame_id == "base_link"
    tr = laser.transform
    assert (tr.translation.x, tr.translation.y) == pytest.approx(LASER.mount[:2])
    assert yaw(tr.rotation) == pytest.approx(LASER.mount[2])


def test_tf_carries_the_odometry_and_the_map_correction(run, contents):
    msgs = contents[2][TOPICS["tf"]]
    k = 600
    t, msg = msgs[k]
    assert t == stamp_ns(msg.transforms[0]) == run.time_ns[k]
    odom = msg.transforms[0]
    assert (odom.header.frame_id, odom.child_frame_id) == ("odom", "base_link")
    got = (odom.transform.translation.x, odom.transform.translation.y, yaw(odom.transform.rotation))
    assert got[:2] == pytest.approx(run.odom_pose[k, :2], abs=1e-12)
    assert math.remainder(got[2] - run.odom_pose[k, 2], 2 * math.pi) == pytest.approx(0, abs=1e-9)
    # map -> odom every MAP_ODOM_EVERY increments; with odom -> base_link it gives the truth
    corrections = [(i, m.transforms[1]) for i, (_, m) in enumerate(msgs) if len(m.transforms) == 2]
    assert [i for i, _ in corrections] == list(range(0, len(msgs), MAP_ODOM_EVERY))
    i, corr = corrections[24]
    assert (corr.header.frame_id, corr.child_frame_id) == ("map", "odom")
    map_odom = (
        corr.transform.translation.x,
        corr.transform.translation.y,
        yaw(corr.transform.rotation),
    )
    base = compose(np.array(map_odom), run.odom_pose[i])
    assert base[:2] == pytest.approx(run.true_pose[i, :2], abs=1e-9)
    assert math.remainder(base[2] - run.true_pose[i, 2], 2 * math.pi) == pytest.approx(0, abs=1e-9)


def test_joint_states_and_gyro(run, contents):
    joints = contents[2][TOPICS["joints"]]
    t, msg = joints[300]
    assert stamp_ns(msg) == t == run.time_ns[300]
    assert list(msg.name) == ["right_wheel_joint", "left_wheel_joint"]
    np.testing.assert_allclose(
        msg.position, [run.wheel_angle_right_rad[300], run.wheel_angle_left_rad[300]]
    )
    imu = contents[2][TOPICS["imu"]]
    wz = np.array([m.angular_velocity.z for _, m in imu])
    assert imu[0][1].header.frame_id == "imu_link"
    # standing still for the first 49 samples: the mean is the bias (noise 0.002 / sqrt(49))
    assert wz[:49].mean() == pytest.approx(GYRO.bias_rad_s, abs=0.0015)
    # integrated, the gyro minus its bias gives the true heading change (noise: 0.002 rad/s
    # x 0.02 s x sqrt(1272) = 1.4 mrad)
    total = np.sum((wz - GYRO.bias_rad_s) * 0.02)
    assert total == pytest.approx(run.true_pose[-1, 2] - run.true_pose[0, 2], abs=6e-3)


def test_scans_in_the_bag_match_back_to_the_true_laser_motion(run, contents):
    scans = contents[2][TOPICS["scan"]]
    first = scans[0][1]
    assert first.header.frame_id == "laser"
    assert first.angle_increment == pytest.approx(2 * math.pi / LASER.n_rays)
    np.testing.assert_array_equal(first.ranges, run.scan_ranges_m[0].astype(np.float32))
    times = np.array([stamp_ns(m) for _, m in scans])
    np.testing.assert_array_equal(times, run.scan_time_ns)
    points = [
        scan_points(m.ranges, m.angle_min, m.angle_increment, m.range_min, m.range_max)
        for _, m in scans
    ]
    # intervals of 1 and of 10 scans (0.1 s and 1 s); the guess is the wheel odometry moved
    # into the laser frame (a few per cent off: the believed geometry is wrong)
    n = len(points)
    intervals = np.array(
        [(i, i + 1) for i in range(0, n - 1, 6)] + [(i, i + 10) for i in range(0, n - 10, 10)]
    )
    laser_odo = compose(run.odom_pose[run.scan_index], np.asarray(LASER.mount))
    guesses = relative(laser_odo[intervals[:, 0]], laser_odo[intervals[:, 1]])
    res = match_intervals((times - times[0]) * 1e-9, points, intervals, guesses)
    truth = np.array([run.laser_motion(i, j) for i, j in intervals])
    assert res.usable.all()
    err = res.motion - truth
    # 1 cm range noise, 720 rays: errors of about 1 mm and 0.02 deg (test_scan_matching);
    # the worst of 68 matches (along the whole tour) within 5 mm and 0.1 deg
    assert np.hypot(err[:, 0], err[:, 1]).max() < 5e-3
    assert np.abs(err[:, 2]).max() < math.radians(0.1)


def test_the_bag_writer_without_fsync_writes_rosbags_bytes(tmp_path, monkeypatch):
    # every sqlite3 bag of the tests is written with PRAGMA synchronous = OFF (bag_files.Writer2):
    # the same files as rosbags' own writer, byte for byte
    from rosbags.rosbag2 import Writer

    import tests.support.bag_files as bag_files
    from odocal.core.tracks import Track, spot_turn, straight

    short = Track("short", (straight(0.3), spot_turn(math.pi / 2)))
    run = simulate_robot(short, TRUE, NOMINAL, laser=Laser(n_rays=8), gyro=Gyro(0.01))
    write_ros2_bag(tmp_path / "ours" / "bag", run, map_odom_every=5)
    monkeypatch.setattr(bag_files, "Writer2", Writer)
    write_ros2_bag(tmp_path / "rosbags" / "bag", run, map_odom_every=5)
    files = sorted(p.name for p in (tmp_path / "ours" / "bag").iterdir())
    assert files == ["bag.db3", "metadata.yaml"]
    for name in files:
        ours, theirs = (tmp_path / d / "bag" / name for d in ("ours", "rosbags"))
        assert ours.read_bytes() == theirs.read_bytes(), name
