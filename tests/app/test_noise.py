"""``odocal.app.noise`` on typed results: k from a RUNS.csv of repeated runs (``noise``), and from
recorded runs with the measured robot and the controller's covariances (``noise_recordings``),
golden on the OptiOdom squares."""

from __future__ import annotations

import math

import pytest
import yaml

from odocal.app.noise import cruise_speed_m_s, noise, noise_recordings
from odocal.core.model import WheelGeometry
from odocal.core.tracks import out_and_back
from odocal.errors import InputError
from odocal.io.robot_file import load_robot
from odocal.io.ros2_export import read_ros2_params
from odocal.io.runs_csv import write_runs
from tests.support.noise_runs import fwd_runs, noise_robot
from tests.support.recorded_runs import make_run


def test_k_from_repeated_out_and_back_runs(tmp_path):
    path = tmp_path / "k-runs.csv"
    write_runs(path, fwd_runs(noise_robot(), out_and_back(10.0), 12, seed=11))
    est = noise(path, "paper-fig5", track="out-and-back", distance_m=10.0)
    assert est.runs == 12 and est.track == "out-and-back" and est.distance_m == 10.0
    # the wheelbase of the estimators is the robot's true one
    assert est.wheelbase_m == pytest.approx(0.385 * 1.028)
    lo, hi = est.k_sum_ci95_m
    assert lo < est.k_sum_m < hi
    # out and back turns on the spot with both wheels alike: k_r and k_l cannot be told apart
    assert est.k_r_m is None and est.k_l_m is None and "not identifiable" in est.split_note


def test_k_of_the_optiodom_squares_and_the_measured_robot(realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square"
    robot, ros2 = tmp_path / "robot.yaml", tmp_path / "dd.yaml"
    res = noise_recordings(sq, robot_out=robot, ros2=ros2)
    est = res.measured.noise
    # golden (bench_real_experiment.py): k_r + k_l 2.44e-6 m from 40 repeated runs, 28 dof
    assert est.runs == 40 and est.dof == 28
    assert est.k_sum_m == pytest.approx(2.44e-6, rel=0.01)
    lo, hi = est.k_sum_ci95_m
    assert lo < est.k_sum_m < hi and hi / lo < 4
    assert est.k_r_m is None  # not identifiable from squares
    assert set(res.written) == {robot, ros2} and res.covariance is not None
    r = load_robot(robot)
    assert r.nominal == res.nominal == WheelGeometry(0.084, 0.084, 0.2)
    assert r.nonsystematic.k_r_m == pytest.approx(est.k_sum_m / 2, rel=1e-6)
    assert r.systematic.E_b == pytest.approx(1.00689, abs=1e-5)
    assert 0 < r.measurement.sigma_theta_rad < math.radians(0.5)
    params = yaml.safe_load(ros2.read_text())["diff_drive_controller"]["ros__parameters"]
    assert len(params["pose_covariance_diagonal"]) == 6
    assert params["twist_covariance_diagonal"][5] == pytest.approx(res.covariance.twist_diagonal[5])
    assert read_ros2_params(ros2).wheelbase_m == pytest.approx(
        res.measured.fit.geometry.wheelbase_m, rel=1e-12
    )


def test_the_cruise_speed_is_the_90th_percentile_of_the_moving_speed():
    run = make_run("line", [("straight", 2.0)])  # 0.01 m per 0.05 s: 0.2 m/s throughout
    g = run.ran_with
    assert cruise_speed_m_s([run], g) == pytest.approx(0.2)
    still = make_run("still", [("straight", 0.0)])
    with pytest.raises(InputError, match="do not move"):
        cruise_speed_m_s([still], g)
