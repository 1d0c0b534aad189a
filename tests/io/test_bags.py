"""ROS bag loading (io.bags, io.bag_recording, the gyro fit's reader): synthetic bags written into
tmp_path, the real Husky bags, bad input.

The synthetic bags (tests/support/bag_files.py) hold a known simulated run: wheel angles
(JointState), true poses (PoseStamped), a gyro (Imu, mounted as on the Husky, with bias and
noise), the wheel odometry (Odometry) and the IMU mounting (/tf_static).
"""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from odocal.app.fit import fit_gyro_bag
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.errors import InputError
from odocal.io import bags
from odocal.io.bag_recording import load_bag_recording
from tests.support.bag_files import (
    E_B,
    GYRO_BIAS,
    KINDS,
    NOMINAL,
    TRACK,
    TRUE,
    BagWriter,
    Run,
    bag_path,
    lazy_bags,
    make_run,
    world,
    write_bag,
)


@pytest.fixture(scope="module")
def run() -> Run:
    return make_run(TRACK)


@pytest.fixture(scope="module")
def written(tmp_path_factory, run):
    """kind -> the bag of ``run`` of that kind, with the odometry (written on first use)."""
    return lazy_bags(tmp_path_factory, run, odom=True)


@pytest.fixture(params=KINDS)
def synthetic(request, written):
    """(kind, path) of each bag kind: for the tests of what is read."""
    return request.param, written(request.param)


# --------------------------------------------------------------------------- happy paths


def test_list_topics_and_table(synthetic, run):
    kind, path = synthetic
    topics = bags.list_topics(path)
    by = {t.name: t for t in topics}
    assert by["/joint_states"].msgtype == "sensor_msgs/msg/JointState"
    assert by["/mocap/pose"].msgtype == "geometry_msgs/msg/PoseStamped"
    assert by["/imu"].msgtype == "sensor_msgs/msg/Imu"
    assert by["/tf_static"].count == 1
    n = len(run.time_s)
    assert by["/joint_states"].count == n
    if kind != "ros1":  # a ROS 2 storage file can be opened without its folder
        storage = next(p for p in path.iterdir() if p.suffix in (".mcap", ".db3"))
        assert bags.list_topics(storage) == topics
    from odocal.app.text import format_topics

    table = format_topics(topics)
    assert (
        "/joint_states" in table and str(n) in table and table.splitlines()[0].startswith("topic")
    )


def test_recording_matches_the_simulated_run(synthetic, run):
    kind, path = synthetic
    rec = load_bag_recording(path, ran_with=NOMINAL)
    assert rec.meta["right_joint"] == "right_wheel_joint"
    assert rec.meta["left_joint"] == "left_wheel_joint"
    # wheel angles exactly as written (float64 round trip), starting at 0; time from 0
    np.testing.assert_allclose(rec.wheel_angle_right_rad, run.right - run.right[0], atol=1e-12)
    np.testing.assert_allclose(rec.wheel_angle_left_rad, run.left - run.left[0], atol=1e-12)
    np.testing.assert_allclose(rec.time_s, run.time_s - run.time_s[0], atol=2e-9)
    # ground truth written in the world frame comes back in the start frame; 1e-9 allows for
    # the nanosecond stamps and the yaw -> quaternion -> yaw round trip
    np.testing.assert_allclose(rec.ground_truth, run.true_pose, atol=1e-9)
    # dead reckoning the loaded wheel angles with the TRUE geometry reproduces the ground truth:
    # the simulator used the same midpoint update on the same increments
    odo = dead_reckon(rec.wheel_angle_right_rad, rec.wheel_angle_left_rad, TRUE)
    np.testing.assert_allclose(odo, rec.ground_truth, atol=1e-9)
    # gyro heading: mounting from /tf_static, bias removed from the 2 x 3 s still periods.
    # At the end the error is the integrated white noise, 0.002 rad/s x sqrt(T x 0.01 s) ~
    # 1.7e-3 rad over T ~ 15 s, plus the bias estimate's error (~1e-4 rad/s) x T; 5e-3 rad is
    # > 2.5 sigma of both together. During turns the 100 Hz samples of a rate that steps at the
    # 50 Hz wheel stamps make the resampled integral lead or lag by up to (rate step) x (one
    # sample) = 3.7 rad/s x 10 ms: compared where the robot does not turn.
    assert rec.meta["imu_mounting"].startswith("tf_static")
    assert rec.meta["gyro_bias_source"] == "still"
    # bias estimate from 600 samples of 0.002 rad/s noise: se ~ 8e-5 rad/s; 5e-4 is > 6 se
    assert rec.meta["gyro_bias_rad_s"] == pytest.approx(GYRO_BIAS, abs=5e-4)
    assert rec.gyro_yaw_rad[-1] == pytest.approx(run.true_pose[-1, 2], abs=5e-3)
    steps = np.abs(np.diff(run.true_pose[:, 2])) < 1e-12
    calm = np.r_[True, steps] & np.r_[steps, True]
    assert calm.sum() > len(calm) // 3
    np.testing.assert_allclose(rec.gyro_yaw_rad[calm], run.true_pose[calm, 2], atol=5e-3)


def test_ground_truth_is_interpolated_at_wheel_times(tmp_path, run):
    """Poses at 1/4 of the joint rate, joints outside the pose span are dropped."""
    path = tmp_path / "coarse.bag"
    with BagWriter(path, "ros1") as w:
        for t, r, lft in zip(run.time_s, run.right, run.left, strict=True):
            w.joints("/joint_states", t, ("left_wheel_joint", "right_wheel_joint"), [lft, r])
        for k in range(2, len(run.time_s) - 2, 4):
            w.pose_stamped("/gt", run.time_s[k], *world(run.true_pose)[k])
    rec = load_bag_recording(path)
    first = 2
    keep = slice(first, first + len(rec.time_s))
    assert rec.meta["wheel_samples_dropped"] == len(run.time_s) - len(rec.time_s)
    expect = run.true_pose[keep] - run.true_pose[first]
    c, s = math.cos(run.true_pose[first, 2]), math.sin(run.true_pose[first, 2])
    dx, dy = expect[:, 0].copy(), expect[:, 1].copy()
    expect[:, 0], expect[:, 1] = c * dx + s * dy, -s * dx + c * dy
    # poses 4 increments apart, aligned with the segment ends: the heading is linear in time
    # within each segment, so it interpolates exactly; positions are exact on straights and spot
    # turns, and on the r = 0.6 m circle (2 pi / 40 per increment, so pi / 5 between poses) they
    # lie on the chord, at most the sagitta r (1 - cos(pi / 10)) = 29 mm inside the arc
    np.testing.assert_allclose(rec.ground_truth[:, 2], expect[:, 2], atol=1e-9)
    sagitta = 0.6 * (1 - math.cos(math.pi / 10))
    err = np.hypot(*(rec.ground_truth[:, :2] - expect[:, :2]).T)
    assert err.max() <= sagitta + 1e-9
    assert err.max() > 0.5 * sagitta  # the arc really is there


def test_gyro_from_joint_states_recovers_the_wheelbase(synthetic):
    kind, path = synthetic
    res = fit_gyro_bag(path, joint_topic="/joint_states", wheel_geometry=NOMINAL)
    # every turn really turns 1/E_b of the odometry's belief (E_d = 1): ratio = 1/E_b exactly;
    # noise: integrated white noise ~1.5e-3 rad and bias error ~1e-4 rad/s x 70 s over a net
    # rotation of 5 pi: ~3e-4 relative; 2e-3 is > 5 sigma
    assert res.rotation_ratio == pytest.approx(1 / E_B, abs=2e-3)
    assert res.wheelbase_multiplier == pytest.approx(E_B, abs=2e-3)
    assert res.meta["wheelbase_corrected_m"] == pytest.approx(TRUE.wheelbase_m, rel=2e-3)
    assert res.mounting_source == "tf_static"
    assert res.axis == "y"
    assert res.bias_source == "still"
    assert res.bias_rad_s == pytest.approx(GYRO_BIAS, abs=5e-4)
    assert res.odometry_rotation_rad == pytest.approx(TRACK.rotation_rad, rel=1e-9)
    assert res.meta["odometry_source"] == "joint_states"
    d = res.as_dict()
    assert d["method"] == "gyro" and d["rotation_ratio"] == res.rotation_ratio


def test_gyro_from_odometry_topic(synthetic):
    kind, path = synthetic
    res = fit_gyro_bag(path, odom_topic="/odom")
    assert res.meta["odometry_source"] == "pose_yaw"
    # the 10 Hz odometry ends within one sample of the joints; same tolerance as above
    assert res.rotation_ratio == pytest.approx(1 / E_B, abs=2e-3)


def test_gyro_axis_detected_without_tf_static(tmp_path, run):
    path = write_bag(tmp_path / "notf.bag", "ros1", run, tf=False)
    res = fit_gyro_bag(path, wheel_geometry=NOMINAL)
    assert res.mounting_source == "detected" and res.axis == "y"
    assert any("detected" in w for w in res.warnings)
    assert res.rotation_ratio == pytest.approx(1 / E_B, abs=2e-3)
    # the flag wins over detection; the wrong sign is an error naming the bag and topics
    with pytest.raises(InputError, match="opposite directions") as exc:
        fit_gyro_bag(path, wheel_geometry=NOMINAL, imu_axis="-y")
    assert "notf.bag" in str(exc.value) and "/imu" in str(exc.value)


def test_wrapped_wheel_angles_are_unwrapped(tmp_path, run):
    wrapped = np.column_stack([run.right, run.left])
    wrapped = (wrapped + math.pi) % (2 * math.pi) - math.pi  # a driver reporting (-pi, pi]
    path = write_bag(tmp_path / "wrap.bag", "ros1", run, positions=wrapped, imu=False)
    rec = load_bag_recording(path)
    assert rec.meta["wraps_unwrapped"] > 10
    np.testing.assert_allclose(rec.wheel_angle_right_rad, run.right - run.right[0], atol=1e-9)
    np.testing.assert_allclose(rec.wheel_angle_left_rad, run.left - run.left[0], atol=1e-9)


def test_ticks_per_rev(tmp_path, run):
    ticks = np.round(np.column_stack([run.right, run.left]) / (2 * math.pi) * 4096)
    path = write_bag(tmp_path / "ticks.bag", "ros1", run, positions=ticks, imu=False)
    rec = load_bag_recording(path, ticks_per_rev=4096)
    # quantisation: half a tick = pi / 4096 rad
    np.testing.assert_allclose(rec.wheel_angle_right_rad, run.right, atol=math.pi / 4096 + 1e-12)


def test_husky_has_no_joint_states(realdata):
    # its wheels are the controller's odometry, inverted through the geometry it ran with
    bag = realdata / "husky" / "husky_test1.bag"
    with pytest.raises(InputError, match="no wheel joint states.*--robot") as exc:
        load_bag_recording(bag)
    assert "husky_test1.bag" in str(exc.value) and "/husky_velocity_controller/odom" in str(
        exc.value
    )
    run = load_bag_recording(bag, ran_with=WheelGeometry.symmetric(0.33, 0.555))
    assert run.ground_truth is None and run.meta["joint_topic"] == "/husky_velocity_controller/odom"
    assert "inverted through the geometry the controller ran with" in run.meta["wheels"]
    assert np.ptp(run.wheel_angle_right_rad) > 100  # 359 m on 0.33 m wheels: ~2000 rad


# --------------------------------------------------------------------------- bad input


def one_line_error(cli, *argv):
    status, out, err = cli(*argv)
    assert status == 2 and out == ""
    assert err.startswith("odocal: error: ") and err.count("\n") == 1 and "Traceback" not in err
    return err


@pytest.fixture(scope="module")
def plain_ros1(tmp_path_factory, run):
    """A ROS 1 bag of ``run`` without the IMU, only read by the tests that use it (the damaged
    copies they need are written beside their own tmp_path)."""
    return write_bag(tmp_path_factory.mktemp("plain") / "full.bag", "ros1", run, imu=False)


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
def test_truncated_bag(tmp_path, run, kind, cli, plain_ros1):
    if kind == "ros1":
        path = plain_ros1
    else:
        path = write_bag(bag_path(tmp_path, kind, "full"), kind, run, imu=False)
    src = path if kind == "ros1" else next(path.glob("*.mcap"))
    data = src.read_bytes()
    cut = tmp_path / ("cut.bag" if kind == "ros1" else "cut.mcap")
    cut.write_bytes(data[: len(data) // 2])
    with pytest.raises(InputError, match="truncated or corrupt") as exc:
        load_bag_recording(cut)
    assert str(cut) in str(exc.value)
    err = one_line_error(cli, "bag-info", cut)
    assert str(cut) in err


def test_corrupt_bag_body(tmp_path, plain_ros1):
    """Garbage in the middle of a ROS 1 bag (index intact): an InputError, not a traceback."""
    path = tmp_path / "c.bag"
    data = bytearray(plain_ros1.read_bytes())
    mid = len(data) // 2
    data[mid : mid + 4000] = (
        np.random.default_rng(3).integers(0, 256, 4000, dtype=np.uint8).tobytes()
    )
    path.write_bytes(bytes(data))
    with pytest.raises(InputError, match=r"c\.bag: cannot read the bag after \d+ good messages"):
        load_bag_recording(path)


def test_not_a_bag(tmp_path, cli):
    p = tmp_path / "run.csv"
    p.write_text("a,b\n")
    with pytest.raises(InputError, match="not a ROS bag"):
        bags.list_topics(p)
    one_line_error(cli, "bag-info", tmp_path / "missing.bag")
    d = tmp_path / "folder"
    d.mkdir()
    assert "metadata.yaml" in one_line_error(cli, "bag-info", d)


def test_missing_and_wrong_topics(synthetic):
    kind, path = synthetic
    with pytest.raises(InputError, match="no topic '/nope'.*/joint_states") as exc:
        load_bag_recording(path, joint_topic="/nope")
    assert str(path) in str(exc.value)
    with pytest.raises(InputError, match="topic '/imu' has type sensor_msgs/Imu, expected"):
        load_bag_recording(path, joint_topic="/imu")
    with pytest.raises(InputError, match="topic '/joint_states' has type .*expected nav_msgs"):
        fit_gyro_bag(path, odom_topic="/joint_states")
    with pytest.raises(InputError, match="needs the nominal wheel geometry"):
        fit_gyro_bag(path, joint_topic="/joint_states")


def test_several_candidate_topics(tmp_path, run):
    def second_pose(w):
        w.pose_stamped("/other_pose", run.time_s[0], 0, 0, 0)
        w.pose_stamped("/other_pose", run.time_s[1], 0, 0, 0)

    path = write_bag(tmp_path / "two.bag", "ros1", run, imu=False, extra=second_pose)
    with pytest.raises(InputError, match="several .* ground truth: /mocap/pose, /other_pose"):
        load_bag_recording(path)
    rec = load_bag_recording(path, truth_topic="/mocap/pose")
    assert rec.meta["truth_topic"] == "/mocap/pose"


def test_non_monotonic_time(tmp_path, run):
    t = run.time_s.copy()
    t[100], t[101] = t[101], t[100]
    path = write_bag(tmp_path / "time.bag", "ros1", run, times=t, imu=False)
    with pytest.raises(InputError, match=r"field '/joint_states'.*goes backwards at message 101"):
        load_bag_recording(path)


def test_nan_position(tmp_path, run):
    pos = np.column_stack([run.right, run.left])
    pos[57, 1] = np.nan
    path = write_bag(tmp_path / "nan.bag", "ros1", run, positions=pos, imu=False)
    with pytest.raises(InputError, match=r"nan.bag.*'/joint_states'.*message 57.*not finite"):
        load_bag_recording(path)


def test_encoder_glitch_is_rejected(tmp_path, run):
    pos = np.column_stack([run.right, run.left])
    pos[300:, 0] += 5.0  # a jump of 5 rad (not a wrap: the angle spans many revolutions)
    path = write_bag(tmp_path / "jump.bag", "ros1", run, positions=pos, imu=False)
    with pytest.raises(
        InputError, match=r"joint 'right_wheel_joint' jumps by \+5\.\d+ rad at message 300"
    ):
        load_bag_recording(path)


def test_mirrored_wheel_is_detected(tmp_path, run):
    pos = np.column_stack([run.right, -run.left])  # left joint axis mirrored in the URDF
    path = write_bag(tmp_path / "mirror.bag", "ros1", run, positions=pos, imu=False)
    with pytest.raises(InputError, match="left wheel joint 'left_wheel_joint' turns backwards"):
        load_bag_recording(path)
    rec = load_bag_recording(path, invert_left=True)
    np.testing.assert_allclose(rec.wheel_angle_left_rad, run.left - run.left[0], atol=1e-12)


def test_mirrored_wheel_with_a_rotated_mocap_body(tmp_path, run):
    """With the ground truth's body frame turned 90 deg, the opposite wheel signs on straight
    stretches are still detected (the check does not rely on the ground truth's heading)."""
    rotated = run.true_pose.copy()
    rotated[:, 2] += math.pi / 2
    turned = Run(run.time_s, run.right, run.left, rotated, run.odo_pose)
    pos = np.column_stack([-run.right, run.left])
    path = write_bag(tmp_path / "mirror90.bag", "ros1", turned, positions=pos, imu=False)
    with pytest.raises(InputError, match="turn in opposite directions while the robot drives"):
        load_bag_recording(path)


def test_backwards_mocap_body_warns(tmp_path, run):
    rotated = run.true_pose.copy()
    rotated[:, 2] += math.pi
    turned = Run(run.time_s, run.right, run.left, rotated, run.odo_pose)
    path = write_bag(tmp_path / "back.bag", "ros1", turned, imu=False)
    rec = load_bag_recording(path)
    assert any("points backwards" in w for w in rec.meta["warnings"])


def test_swapped_wheels_are_detected(plain_ros1):
    with pytest.raises(InputError, match="wheels look swapped"):
        load_bag_recording(
            plain_ros1, right_joint="left_wheel_joint", left_joint="right_wheel_joint"
        )


def test_gyro_with_swapped_joints_says_so(written):
    path = written("mcap")  # the fit's verdict on what was read: one kind (reads: above)
    with pytest.raises(InputError, match="opposite directions.*or the wheel joints are swapped"):
        fit_gyro_bag(
            path,
            joint_topic="/joint_states",
            wheel_geometry=NOMINAL,
            right_joint="left_wheel_joint",
            left_joint="right_wheel_joint",
        )


def test_joint_names(tmp_path, run):
    path = write_bag(tmp_path / "names.bag", "ros1", run, imu=False, names=("wheel_a", "wheel_b"))
    with pytest.raises(InputError, match="no right-wheel joint among wheel_a, wheel_b"):
        load_bag_recording(path)
    with pytest.raises(InputError, match="no joint 'nope'; joints: wheel_a, wheel_b"):
        load_bag_recording(path, right_joint="nope", left_joint="wheel_a")
    rec = load_bag_recording(path, right_joint="wheel_b", left_joint="wheel_a")
    np.testing.assert_allclose(rec.wheel_angle_right_rad, run.right - run.right[0], atol=1e-12)


def test_gyro_export_composes_with_what_the_controller_ran_with(written, tmp_path, cli):
    # the controller integrated /odom with b = 0.5 m, i.e. its nominal 0.49 m times a
    # wheel_separation_multiplier of 1.0204: the correction applies to the 0.5 m it ran with.
    # The export of what was read: one bag kind (test_gyro_from_odometry_topic reads each)
    path = written("sqlite3")
    robot = tmp_path / "robot.yaml"
    robot.write_text(
        "wheel_diameter_m: 0.2\nwheelbase_m: 0.49\n"
        "believed: {wheel_diameter_right_m: 0.2, wheel_diameter_left_m: 0.2, wheelbase_m: 0.5}\n"
    )
    ros2 = tmp_path / "dd.yaml"
    status, out, err = cli(
        "fit", path, "--method", "gyro", "--odom-topic", "/odom", "--robot", robot,
        "--ros2", ros2, "--json",
    )  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    assert d["calibrated_wheelbase_m"] == pytest.approx(TRUE.wheelbase_m, abs=2e-3)
    assert d["calibrated_from"] == "the geometry the controller ran with"
    assert "wheel_separation_multiplier" in ros2.read_text()
    mult = float(ros2.read_text().split("wheel_separation_multiplier:")[1].split()[0])
    assert mult == pytest.approx(TRUE.wheelbase_m / 0.49, abs=5e-3)
    assert set(d["time_offsets_s"]) == {"imu"}


def test_gyro_text_without_a_still_period(written):
    # its standard error is None: the text says why instead of a TypeError
    from dataclasses import replace

    from odocal.app.fit_gyro import GyroFitResult

    path = written("ros1")  # the text of a result: one bag kind
    res = GyroFitResult(replace(fit_gyro_bag(path, odom_topic="/odom"),
                                rotation_ratio_stderr=None), None, None)  # fmt: skip
    assert "too short to estimate" in str(res)  # the text odocal fit prints


def test_the_wheel_odometry_is_never_its_own_ground_truth(tmp_path, run, cli):
    path = write_bag(tmp_path / "odom_only.bag", "ros1", run, truth=False, odom=True)
    status, out, err = cli("fit", path, "--method", "trajectory")
    assert status == 2 and err.count("\n") == 1
    assert "cannot be its own reference" in err and "--truth-topic" in err
    assert "This bag allows: gyro" in err  # the routes it does allow, with why
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.2\nwheelbase_m: 0.5\n")
    status, out, err = cli("check", path, "--robot", robot)
    assert status in (0, 3) and "cannot be its own reference" in err  # a warning: wheels only


# --------------------------------------------------------------------------- transforms, scans


def _tf_bag(tmp_path, run, stamps):
    """A bag whose /tf holds odom -> base_link at ``stamps`` (s), in that order."""

    def extra(w):
        for k, t in enumerate(stamps):
            tr = w.T("geometry_msgs/msg/Transform")(
                translation=w.vec(0.1 * k, 0, 0), rotation=w.quat((0.0, 0.0, 0.0, 1.0))
            )
            ts = w.T("geometry_msgs/msg/TransformStamped")(
                header=w.header(t, "odom"), child_frame_id="base_link", transform=tr
            )
            msg = w.T("tf2_msgs/msg/TFMessage")(transforms=[ts])
            w.write("/tf", "tf2_msgs/msg/TFMessage", 10.0 + k, msg)  # logged in order

    path = write_bag(tmp_path / "tf.bag", "ros1", run, imu=False, truth=False, extra=extra)
    return bags.read_bag(path, lambda info: {"tf": "/tf", "tf_static": "/tf_static"})


def test_tf_stamps_going_backwards_are_refused_like_any_topics(tmp_path, run):
    # sorted in silently before, then reported as loop closures by the SLAM route
    bag = _tf_bag(tmp_path, run, [1.0, 1.1, 1.3, 1.2, 1.4])
    with pytest.raises(InputError, match=r"tf.bag, field '/tf': message 3: .*'odom -> base_link' "
                       r"go backwards") as info:  # fmt: skip
        bags.transform_buffer(bag)
    assert "\n" not in str(info.value)


def test_transform_buffer_errors_name_the_bag_and_the_topic(tmp_path, run):
    bag = _tf_bag(tmp_path, run, [1.0, 1.1, 1.2])
    buf = bags.transform_buffer(bag)
    t = bags.tf_messages(bag)[("odom", "base_link")].time_s  # relative to the bag's start
    with pytest.raises(InputError, match=r"tf.bag, field '/tf': no frame 'laser'"):
        buf.lookup("base_link", "laser", t[0])
    with pytest.raises(InputError, match=r"tf.bag, field '/tf': cannot look up"):
        buf.lookup("odom", "base_link", t[-1] + 5.0)
    assert buf.lookup("odom", "base_link", t[0] + 0.05).planar()[0, 0] == pytest.approx(0.05)


@pytest.fixture(scope="module")
def laser_run():
    # the scan header checks need a few scans, not the 8 m tour: 0.5 m and a quarter turn (23
    # scans of 100 rays)
    from odocal.core.tracks import Track, spot_turn, straight
    from tests.support.synthetic_robot import Laser, simulate_robot

    short = Track("short", (straight(0.5), spot_turn(math.pi / 2)))
    return simulate_robot(short, TRUE, NOMINAL, laser=Laser(n_rays=100), still_s=0.2)


@pytest.mark.parametrize(
    ("options", "beams"),
    [({"scan_mirrored": "ranges"}, "198 beams"), ({"scan_increment_scale": 1.01}, "0.98 beams")],
)
def test_a_scan_header_that_disagrees_with_itself_is_refused(tmp_path, laser_run, options, beams):
    # an upside-down laser's reversed rays with angle_min/angle_max not swapped (the wheelbase
    # came out 18 % too large), or an angle_increment 1 % off (b moved by 15 standard errors)
    from tests.support.synthetic_robot import write_ros2_bag

    write_ros2_bag(tmp_path / "bag", laser_run, imu=False, **options)
    bag = bags.read_bag(tmp_path / "bag", lambda info: {"scan": "/scan"})
    with pytest.raises(InputError, match=rf"field '/scan': message 0: .*disagrees.*{beams}"):
        bags.scan_series(bag, "/scan")


def test_a_mirrored_laser_whose_header_says_so_gives_the_same_points(tmp_path, laser_run):
    # a negative angle_increment (rays clockwise, angle_min > angle_max) is a consistent header
    from tests.support.synthetic_robot import write_ros2_bag

    points = []
    for name, mirrored in (("upright", None), ("mirrored", "header")):
        write_ros2_bag(tmp_path / name, laser_run, imu=False, scan_mirrored=mirrored)
        bag = bags.read_bag(tmp_path / name, lambda info: {"scan": "/scan"})
        points.append(bags.scan_series(bag, "/scan").points_m[7])
    np.testing.assert_allclose(points[1][::-1], points[0], atol=1e-6)


@pytest.mark.parametrize(
    "broken, said",
    [
        ("twice", "every message appears twice"),
        ("reset", "a clock reset?"),
        ("backwards", "time goes backwards at message"),
        ("names", "two joints named the same"),
    ],
)
def test_a_broken_bag_is_an_error_not_a_verdict(tmp_path, run, cli, broken, said):
    # before: exit 3 with the reason inside a verdict ('no route could calibrate this bag')
    t = run.time_s.copy()
    names = ("left_wheel_joint", "right_wheel_joint")
    if broken == "twice":
        t = np.repeat(t[::2], 2)[: len(t)]
    elif broken == "reset":
        t[len(t) // 2 :] -= 100.0
    elif broken == "backwards":
        t[10], t[11] = t[11], t[10]
    else:
        names = ("left_wheel_joint", "left_wheel_joint")
    path = write_bag(tmp_path / "broken.bag", "ros1", run, times=t, names=names)
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.2\nwheelbase_m: 0.5\n")
    status, out, err = cli("fit", path, "--robot", robot, "--method", "auto")
    assert status == 2 and out == "", (status, out, err)
    assert err.count("\n") == 1 and said in err
    assert "broken.bag" in err and "/joint_states" in err


def test_a_bag_no_route_can_read_is_an_error(tmp_path, run, cli):
    path = write_bag(tmp_path / "nothing.bag", "ros1", run, joints=False, truth=False, imu=False)
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.2\nwheelbase_m: 0.5\n")
    status, out, err = cli("fit", path, "--robot", robot)
    assert status == 2 and err.count("\n") == 1
    assert "no route can read this bag" in err and "nothing.bag" in err
