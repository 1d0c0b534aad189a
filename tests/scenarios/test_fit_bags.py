"""`odocal fit` on real ROS bags: the gyro method and topic listing (the Husky recording)."""

import io
import json
from contextlib import redirect_stderr, redirect_stdout

import pytest
import yaml

from tests.support.bag_files import read_husky_once

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
    )
    assert status == 2 and out == ""
    assert err.count("\n") == 1 and "/nope" in err and "husky_test1.bag" in err
    assert not (tmp_path / "x.yaml").exists()
