"""Laser scan matching end to end: a bag written by tests/support/synthetic_robot.py (wheel
joints and a 2D laser mounted off-centre in a synthetic room, 1 cm range noise), `odocal fit BAG
--method scan` recovers the wheel geometry and the laser's mounting."""

from __future__ import annotations

import json

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from tests.support.synthetic_robot import Laser, default_track, simulate_robot, write_ros2_bag

TRUE = WheelGeometry(0.0655, 0.0662, 0.163)
BELIEVED = WheelGeometry.symmetric(0.066, 0.160)
MOUNT = (0.15, 0.05, 0.1)


@pytest.fixture(scope="module")
def scan_bag(tmp_path_factory):
    folder = tmp_path_factory.mktemp("scan")
    run = simulate_robot(
        default_track(), TRUE, BELIEVED, laser=Laser(mount=MOUNT, sigma_m=0.01),
        rng=np.random.default_rng(1),
    )  # fmt: skip
    write_ros2_bag(folder / "bag", run, imu=False)
    robot = folder / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
    return folder / "bag", robot


def test_scan_route_recovers_wheels_and_mounting(cli, scan_bag):
    bag, robot = scan_bag
    status, out, err = cli("fit", bag, "--method", "scan", "--robot", robot, "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["method"] == "scan" and d["sensor_pose_fixed"] is False
    s = d["scan"][0]
    assert s["matched"] == s["intervals"] >= 30
    truth = {
        **TRUE.as_dict(),
        "sensor_x_m": MOUNT[0],
        "sensor_y_m": MOUNT[1],
        "sensor_yaw_rad": MOUNT[2],
    }
    for key, value in truth.items():
        se = d["stderr"][key]
        # within 4 standard errors, and the standard errors themselves small: with 1 cm range
        # noise about 0.03 mm on the diameters, 0.06 mm on b, 0.2 mm and 0.4 mrad on the mount
        assert abs(d[key] - value) < 4 * se, (key, d[key], value, se)
        assert se < (1e-3 if key == "sensor_yaw_rad" else 3e-4), (key, se)
    # the wheelbase the robot believed (0.160) is 20 standard errors away: this is a real fix
    assert abs(0.160 - d["wheelbase_m"]) > 20 * d["stderr"]["wheelbase_m"]


def test_scan_route_needs_the_nominal_geometry(cli, scan_bag):
    bag, _ = scan_bag
    cli("fit", bag, "--method", "scan").expect_error("--robot")


def test_scans_without_a_valid_range(cli, tmp_path):
    # a laser that sees nothing within its range (the room is farther than 0.1 m everywhere);
    # 8 rays per scan rather than 720, on a straight and a spot turn rather than the tour: the
    # same error on 33 scans
    from odocal.core.tracks import Track, spot_turn, straight

    short = Track("short", (straight(0.5), spot_turn(np.pi / 2)))
    run = simulate_robot(short, TRUE, BELIEVED, laser=Laser(range_max_m=0.1, n_rays=8))
    write_ros2_bag(tmp_path / "blind", run, imu=False)
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
    cli("fit", tmp_path / "blind", "--method", "scan", "--robot", robot).expect_error(
        "no scan has a valid range", "/scan"
    )
