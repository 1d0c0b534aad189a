"""`odocal fit` on real ROS bags: the gyro method and topic listing (the Husky recording), and
the gyro fit itself on both copies of it (odocal.app.fit.fit_gyro_bag): every Husky test in one
file, so that each bag is read once per test process."""

import io
import json
import math
from contextlib import redirect_stderr, redirect_stdout

import pytest
import yaml

from odocal.app.fit import fit_gyro_bag
from tests.support.bag_files import R_BASE_IMU, read_husky_once

BAGS = ["husky_test1.bag", "husky_test1_ros2"]


@pytest.fixture(scope="module")
def husky(realdata):
    return realdata / "husky"


@pytest.fixture(scope="module")
def gyro_fits(husky):
    """bag -> (status, stdout, stderr) of `odocal fit BAG --method gyro --json`, run once per bag
    in-process (as the cli fixture runs it) and only inspected by the tests."""
    from odocal.cli.main import main

    runs = {}
    with pytest.MonkeyPatch.context() as m:
        read_husky_once(m)  # the first read of each bag is a real one
        for bag in BAGS:
            out, err = io.StringIO(), io.StringIO()
            with redirect_stdout(out), redirect_stderr(err):
                status = main(["fit", str(husky / bag), "--method", "gyro", "--json"])
            runs[bag] = (status, out.getvalue(), err.getvalue())
    return runs


@pytest.mark.parametrize("bag", BAGS)
def test_gyro_rotation_ratio_on_husky(gyro_fits, bag):
    status, out, err = gyro_fits[bag]
    assert status == 0, err
    data = json.loads(out)
    assert data["method"] == "gyro"
    # SOURCE.md: gyro -206 deg against odometry -198 deg, a ratio of about 1.04
    assert data["rotation_ratio"] == pytest.approx(1.04, abs=0.005)
    assert data["wheelbase_multiplier"] == pytest.approx(1 / data["rotation_ratio"], rel=1e-12)
    assert data["axis"] == "y"
    # warnings go to stderr as lines, never into the JSON stream on stdout
    assert "odocal: warning:" in err


def test_gyro_ros1_and_ros2_agree(gyro_fits):
    a, b = (json.loads(gyro_fits[bag][1]) for bag in BAGS)
    assert a["rotation_ratio"] == pytest.approx(b["rotation_ratio"], rel=1e-9)


def test_gyro_export_scales_the_wheelbase(cli, husky, tmp_path, monkeypatch):
    read_husky_once(monkeypatch)  # what is tested here (--robot, --ros2) acts after the read
    ros2 = tmp_path / "dd.yaml"
    status, out, err = cli(
        "fit",
        husky / "husky_test1.bag",
        "--method",
        "gyro",
        "--robot",
        "paper-fig5",
        "--ros2",
        ros2,
        "--json",
    )
    assert status == 0, err
    ratio = json.loads(out)["rotation_ratio"]
    params = yaml.safe_load(ros2.read_text())["diff_drive_controller"]["ros__parameters"]
    effective = params["wheel_separation"] * params["wheel_separation_multiplier"]
    assert effective == pytest.approx(0.385 / ratio, rel=1e-9)


def test_list_topics_and_missing_topic(cli, husky, tmp_path):
    status, out, _ = cli("fit", husky / "husky_test1.bag", "--list-topics")
    assert status == 0
    assert "/imu/data" in out and "sensor_msgs/msg/Imu" in out
    status, out, err = cli(
        "fit",
        husky / "husky_test1.bag",
        "--method",
        "gyro",
        "--imu-topic",
        "/nope",
        "--ros2",
        tmp_path / "x.yaml",
        "--robot",
        "paper-fig5",
    )
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and "/nope" in err and "husky_test1.bag" in err
    assert not (tmp_path / "x.yaml").exists()


# ------------------------------------------------------------------ the app-level gyro fit


@pytest.fixture
def husky_read_once(monkeypatch):
    read_husky_once(monkeypatch)


@pytest.fixture(scope="module")
def husky_fits(husky):
    """The gyro fits of the ROS 1 bag and its ROS 2 copy (odocal.app.fit.fit_gyro_bag), made
    once and only inspected; each bag is read once per process (read_husky_once), here or by
    gyro_fits above."""
    d = husky
    with pytest.MonkeyPatch.context() as m:
        read_husky_once(m)
        return {
            "ros1": fit_gyro_bag(d / "husky_test1.bag"),
            "ros2": fit_gyro_bag(d / "husky_test1_ros2"),
        }


def test_husky_gyro_ratio_ros1_and_ros2(husky_fits):
    r1, r2 = husky_fits["ros1"], husky_fits["ros2"]
    # golden values: the IMU's y axis integrates to -206.3 deg, the odometry pose yaw to
    # -198.4 deg (SOURCE.md: -206 vs -198 deg); ROS 2 is a lossless conversion of ROS 1
    assert r1.rotation_ratio == pytest.approx(1.0398, abs=5e-4)
    assert r2.rotation_ratio == pytest.approx(r1.rotation_ratio, abs=1e-12)
    assert math.degrees(r1.odometry_rotation_rad) == pytest.approx(-198.4, abs=0.1)
    assert math.degrees(r1.gyro_rotation_rad) == pytest.approx(-206.3, abs=0.1)
    assert r1.wheelbase_multiplier == pytest.approx(1 / r1.rotation_ratio)
    for r in (r1, r2):
        assert r.axis == "y" and r.mounting_source == "detected"  # no /tf_static in the bag
        assert r.meta["odometry_source"] == "pose_yaw"
        # one 10 s still period (236-247 s); its bias is not significant (1.8 sigma): reported
        assert r.still_duration_s == pytest.approx(10.3, abs=0.1)
        assert r.bias_source.startswith("none")
        assert r.bias_estimate_rad_s == pytest.approx(-2.87e-4, abs=1e-6)
        assert r.rotation_ratio_bias_corrected == pytest.approx(1.0071, abs=5e-4)


def test_husky_forced_bias_and_axis_flag(husky, husky_read_once):
    path = husky / "husky_test1.bag"
    r = fit_gyro_bag(path, imu_axis="y", bias="still")
    assert r.mounting_source == "flag" and r.bias_source == "still"
    assert r.rotation_ratio == pytest.approx(1.0071, abs=5e-4)
    assert not any("detected" in w for w in r.warnings)


def test_husky_mount_from_the_test_launch(husky_fits, husky, husky_read_once):
    """robot_localization's launch: static_transform_publisher 0 -0.3 0.52 -pi/2 0 pi/2
    (yaw pitch roll) base_link imu_link; as a rotation it gives the detected result."""
    r = fit_gyro_bag(husky / "husky_test1_ros2", imu_rotation=R_BASE_IMU)
    assert r.mounting_source == "rotation" and r.axis == "y"
    assert r.rotation_ratio == pytest.approx(husky_fits["ros2"].rotation_ratio, abs=1e-12)
