"""The noise of a SLAM truth for the log check, from the log's residuals
(calibration.slam_noise)."""

from __future__ import annotations

import re

import numpy as np
import pytest

from odocal.calibration.identifiability import NoiseModel
from odocal.calibration.slam_noise import SLAM_POSE_NOISE, slam_noise_model
from odocal.core.model import MeasurementNoise, NonSystematicError, Robot
from tests.support.relative_intervals import NOMINAL, TRUE, motions


def _with_pose_noise(m, sigma_xy: float, sigma_theta: float, seed: int = 5):
    """``m``'s motions measured as a SLAM measures them: the poses carry the noise (so that
    consecutive relative motions share it), not each motion independently."""
    from dataclasses import replace

    from odocal.core.transforms import se2_compose, se2_relative

    rng = np.random.default_rng(seed)
    poses = [np.zeros(3)]
    for mo in m.sensor_motion:
        poses.append(se2_compose(poses[-1], mo))
    p = np.array(poses) + rng.standard_normal((len(poses), 3)) * [sigma_xy, sigma_xy, sigma_theta]
    return replace(m, sensor_motion=se2_relative(p[:-1], p[1:], wrap=False))


def test_the_noise_from_the_log_s_own_residuals():
    m = _with_pose_noise(motions(n=300, noise=(0.0, 0.0, 0.0)), 0.003, 0.002)
    noise = slam_noise_model(m, None, NOMINAL)
    assert noise.description.startswith("k ")
    assert re.search(
        r"\(from the log's own residuals over \d+ SLAM intervals\)$", noise.description
    )
    # the pose's noise (half the variance of a relative motion's): 3 mm, 2 mrad
    assert noise.model.measurement.sigma_xy_m == pytest.approx(0.003, rel=0.3)
    assert noise.model.measurement.sigma_theta_rad == pytest.approx(0.002, rel=0.3)
    assert noise.covariance is not None and noise.covariance.shape == (3, 3)
    assert np.all(np.diag(noise.covariance) > 0)
    assert slam_noise_model(m, None).covariance is None


def test_the_robot_file_s_noise_wins_and_a_short_log_takes_the_defaults():
    m = motions(n=100)  # what wins is not a matter of the log's length (a short log: below)
    robot = Robot(TRUE, nonsystematic=NonSystematicError(2e-5, 2e-5),
                  measurement=MeasurementNoise(0.01, 0.02))  # fmt: skip
    noise = slam_noise_model(m, robot)
    assert noise.model.wheel == NonSystematicError(2e-5, 2e-5)
    assert noise.model.measurement == MeasurementNoise(0.01, 0.02)
    assert noise.description.startswith("ROBOT.yaml nonsystematic, ROBOT.yaml measurement (from")
    short = slam_noise_model(motions(n=12), None)
    assert short.model.measurement == SLAM_POSE_NOISE
    assert short.model.wheel.k_sum_m == pytest.approx(NoiseModel().wheel.k_sum_m)
    assert short.description.startswith("default k, SLAM pose 20 mm and 1 deg (stated default)")
    assert "; the log's own residuals could not give it (" in short.description


def test_a_log_without_noise_takes_the_defaults():
    """Residuals at the arithmetic's precision have no noise to estimate: the stated defaults,
    said so (an estimate from them made the check's verdict a matter of the last bits)."""
    # 100 intervals: the size of the residuals decides, not their number
    exact = motions(n=100, noise=(0.0, 0.0, 0.0))
    noise = slam_noise_model(exact, None, NOMINAL)
    assert noise.model.measurement == SLAM_POSE_NOISE
    assert noise.model.wheel.k_sum_m == pytest.approx(NoiseModel().wheel.k_sum_m)
    assert "the arithmetic's, not a sensor's: a log without noise" in noise.description
    # a micrometre of pose noise is a sensor's: estimated
    tiny = slam_noise_model(_with_pose_noise(exact, 1e-6, 1e-6), None, NOMINAL)
    assert tiny.description.startswith("k ")
