"""Repeated runs of a robot with wheel noise, the runs the k estimators read: straight or
out-and-back runs as final pose errors (``noise_robot``, ``fwd_runs``), and recorded squares whose
ground truth carries the noise of the wheels' travel (``noisy_run``, true geometry ``TRUE``, k_r =
k_l = ``K``)."""

from __future__ import annotations

import math

import numpy as np

from odocal.core.model import (
    MeasurementNoise,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import measure, simulate
from odocal.presets import TETRA_DS2


def noise_robot(k_r=2e-6, k_l=2e-6, meas=None):
    """TETRA_DS2 with wheel noise k_r, k_l (m) and the instrument ``meas``."""
    # systematic errors present on purpose: they must not leak into k. The nominal wheelbase
    # is the true one (E_b = 1) so the estimators' b is exact.
    meas = meas or MeasurementNoise()
    return Robot(TETRA_DS2, SystematicError(1.0, 1.004), NonSystematicError(k_r, k_l), meas)


def fwd_runs(robot, track, n, seed):
    """``n`` measured runs of ``track`` (direction 'fwd'), seeded."""
    rng = np.random.default_rng(seed)
    e = measure(simulate(track, robot, n, rng, max_step_m=0.05).errors, robot, rng)
    return EndPoseRuns(("fwd",) * n, e)


# recorded squares
TRUE = WheelGeometry(0.0837, 0.0838, 0.2015)
K = 2.0e-6  # k_r = k_l (m)


def commanded(direction: str, side=1.5, step=0.01):
    """Wheel angles of a square driven open loop (the encoders read exactly these)."""
    sign = 1 if direction == "ccw" else -1
    r, lft = [0.0], [0.0]
    for _ in range(4):
        for s_r, s_l in ((side, side), (sign * math.pi / 4 * TRUE.wheelbase_m,
                                        -sign * math.pi / 4 * TRUE.wheelbase_m)):  # fmt: skip
            n = int(math.ceil(max(abs(s_r), abs(s_l)) / step))
            for _ in range(n):
                r.append(r[-1] + 2 * s_r / n / TRUE.diameter_right_m)
                lft.append(lft[-1] + 2 * s_l / n / TRUE.diameter_left_m)
    return np.array(r), np.array(lft)


def noisy_run(name, dataset, direction, rng, k=K):
    """A recorded run: the commanded wheel angles, and the ground truth of the true wheel travel
    with noise of variance k |ds| per increment (model.md)."""
    right, left = commanded(direction)
    ds_r = np.diff(right) * TRUE.diameter_right_m / 2
    ds_l = np.diff(left) * TRUE.diameter_left_m / 2
    ds_r = ds_r + np.sqrt(k * np.abs(ds_r)) * rng.standard_normal(ds_r.shape)
    ds_l = ds_l + np.sqrt(k * np.abs(ds_l)) * rng.standard_normal(ds_l.shape)
    true_r = np.r_[0, np.cumsum(ds_r)] * 2 / TRUE.diameter_right_m
    true_l = np.r_[0, np.cumsum(ds_l)] * 2 / TRUE.diameter_left_m
    gt = dead_reckon(true_r, true_l, TRUE)
    return Recording(
        name, np.arange(len(right)) * 0.05, right, left, ground_truth=gt, label=direction,
        meta={"dataset": dataset},
    )  # fmt: skip
