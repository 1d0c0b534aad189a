"""The noise of a SLAM truth for the log check, from the log's residuals
(calibration.slam_noise)."""

from __future__ import annotations

import math
import re

import numpy as np
import pytest

from odocal.calibration.identifiability import NoiseModel
from odocal.calibration.slam_noise import SLAM_POSE_NOISE, slam_noise_model
from odocal.core.model import MeasurementNoise, NonSystematicError, Robot
from tests.support.relative_intervals import NOMINAL, TRUE, motions


def test_the_noise_from_the_log_s_own_residuals():
    m = motions(n=300, noise=(0.004, 0.004, 0.002))
    noise = slam_noise_model(m, None, NOMINAL)
    assert noise.description.startswith("k ")
    assert re.search(
        r"\(from the log's own residuals over \d+ SLAM intervals\)$", noise.description
    )
    # the pose's noise is half the variance of a relative motion's
    assert noise.model.measurement.sigma_xy_m == pytest.approx(0.004 / math.sqrt(2), rel=0.4)
    assert noise.covariance is not None and noise.covariance.shape == (3, 3)
    assert np.all(np.diag(noise.covariance) > 0)
    assert slam_noise_model(m, None).covariance is None


def test_the_robot_file_s_noise_wins_and_a_short_log_takes_the_defaults():
    m = motions(n=300)
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
