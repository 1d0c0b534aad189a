"""The skid-steer gyro route (issue 28): the effective track from the gyro's yaw rate against
the wheels' over 1 s intervals, on simulated skid-steer robots whose track, slip, gyro bias and
IMU clock offset are known."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.app.fit_skid_gyro import skid_gyro_fit
from odocal.calibration.skid_gyro import HeadingIntervals, fit_gyro_gain, rate_knots
from odocal.core.model import Robot, WheelGeometry
from odocal.core.skid_steer import SkidSteerModel
from odocal.errors import CalibrationError
from odocal.io.bag_options import BagOptions
from tests.support.skid_robot import simulate_skid_gyro_log

NOMINAL = WheelGeometry.symmetric(0.6, 1.08)
ROBOT = Robot(NOMINAL, kinematics="skid-steer")
TRUE_MULTIPLIER = 1.65


def _true() -> SkidSteerModel:
    return SkidSteerModel.from_geometry(NOMINAL, TRUE_MULTIPLIER)


def test_the_multiplier_its_error_and_the_imu_clock_offset_on_simulated_robots():
    """Twenty robots with slip (correlated over seconds: the wheels do not see it), a gyro bias
    and an IMU stamped 0.15 s late: the multiplier within its errors (rms z between 0.6 and 1.55
    with about 16 blocks each, t-like: 1.11 over 30 robots; errors 2x too small or too large
    would show), the offset recovered."""
    z, offsets = [], []
    for seed in range(20):
        rng = np.random.default_rng(seed)
        log = simulate_skid_gyro_log(_true(), rng, imu_offset_s=0.15, duration_s=240.0,
                                     slip=0.05, max_rate_rad_s=3.0)  # fmt: skip
        res = skid_gyro_fit([log], ROBOT, BagOptions())
        m, se = res.track_multiplier
        z.append((m - TRUE_MULTIPLIER) / se)
        offsets.append(res.offsets[0].offset_s)
    rms = float(np.sqrt(np.mean(np.square(z))))
    assert 0.6 < rms < 1.55, z
    assert abs(np.median(offsets) - 0.15) < 0.005 and np.allclose(offsets, 0.15, atol=0.03)
    assert res.heldout is not None and res.heldout.rms_deg["effective track"] < 0.2 * (
        res.heldout.rms_deg["nominal"]
    )
    assert "NOT estimated" in res.text() and res.as_dict()["held"]


def test_the_turn_rate_table_follows_a_track_that_widens_with_the_turn_rate():
    """A robot whose effective track grows with the turn rate: the table's multipliers rise
    with it, and the single multiplier lies within the table's range."""
    from odocal.core.skid_steer import TurnRateTable

    rng = np.random.default_rng(3)
    table = TurnRateTable((0.2, 0.8, 3.2), (1.5, 1.65, 1.8))
    true = _true().with_turn_rate(table)
    log = simulate_skid_gyro_log(true, rng, duration_s=400.0, max_rate_rad_s=4.0)
    res = skid_gyro_fit([log], ROBOT, BagOptions())
    rows = res.curve
    assert len(rows) >= 3
    mult = [r.multiplier for r in rows]
    steps = np.diff(mult)
    assert mult[-1] - mult[0] > 0.15 and np.all(steps > -0.03)
    assert min(mult) < res.track_multiplier[0] < max(mult)


def test_no_turning_no_track_and_one_rate_no_table():
    u = np.full(100, 0.0)
    iv = HeadingIntervals(u, u.copy(), np.ones(100), np.arange(100.0), np.arange(100) // 15,
                          np.zeros(100, dtype=int))  # fmt: skip
    with pytest.raises(CalibrationError, match="without turning"):
        fit_gyro_gain(iv)
    spin = np.full(100, 0.5)
    iv = HeadingIntervals(spin, 0.6 * spin, np.ones(100), np.arange(100.0),
                          np.arange(100) // 15, np.zeros(100, dtype=int))  # fmt: skip
    with pytest.raises(CalibrationError, match="two rates or more"):
        rate_knots(iv)


def test_a_multiplier_no_skid_steer_robot_has_is_refused():
    """The wheelbase given in the wrong units (0.108 for 1.08: the multiplier comes out 16):
    refused, nothing to export; with force, kept with the reason."""
    rng = np.random.default_rng(0)
    log = simulate_skid_gyro_log(_true(), rng, duration_s=120.0)
    wrong = Robot(WheelGeometry.symmetric(0.6, 0.108), kinematics="skid-steer")
    with pytest.raises(CalibrationError, match="no skid-steer robot's"):
        skid_gyro_fit([log], wrong, BagOptions())
    res = skid_gyro_fit([log], wrong, BagOptions(), force=True)
    assert not res.enough
