"""Simulated fleets for ``odocal fleet`` (tests and benchmarks/bench_fleet.py): one folder per
robot with its robot.yaml and small synthetic ROS 2 bags (tests/support/synthetic_robot.py: the
room tour once, joint states and odometry at 50 Hz, a SLAM ``map -> odom`` at 2 Hz with noise,
an 8-ray laser the scan route declines, no IMU): about 0.36 MB and 0.2-0.3 s of
``fit --method auto`` each."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import numpy as np

from odocal.core.model import WheelGeometry
from tests.support.synthetic_robot import Laser, default_track, simulate_robot, write_ros2_bag

NOMINAL = WheelGeometry.symmetric(0.050, 0.250)
DAY_NS = 86400 * 10**9


def robot_yaml(folder: Path, nominal: WheelGeometry = NOMINAL) -> Path:
    """Write ``folder/robot.yaml`` with the nominal geometry (the robot runs with it)."""
    folder.mkdir(parents=True, exist_ok=True)
    path = folder / "robot.yaml"
    path.write_text(
        f"wheel_diameter_right_m: {nominal.diameter_right_m!r}\n"
        f"wheel_diameter_left_m: {nominal.diameter_left_m!r}\n"
        f"wheel_diameter_m: {nominal.mean_diameter_m!r}\nwheelbase_m: {nominal.wheelbase_m!r}\n"
    )
    return path


def write_bag(
    path: Path,
    true: WheelGeometry,
    day: int,
    rng: np.random.Generator,
    *,
    believed: WheelGeometry = NOMINAL,
    slam_noise: tuple[float, float] = (0.002, 0.001),
) -> Path:
    """One bag of a robot whose true geometry is ``true``, recorded ``day`` days after the
    simulation's epoch (its stamps shifted)."""
    run = simulate_robot(default_track(), true, believed, laser=Laser(every=10, n_rays=8))
    run = replace(run, time_ns=run.time_ns + day * DAY_NS)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_ros2_bag(path, run, map_odom_every=25, imu=False, slam_noise=slam_noise, rng=rng)
    return path
