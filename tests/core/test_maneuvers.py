"""The maneuver vocabulary and its simulator (core/maneuvers.py)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.maneuvers import (
    GyroNoise,
    arc,
    as_recording,
    command_series,
    figure_eight,
    pause,
    simulate_recordings,
    spin,
    square,
    straight,
)
from odocal.core.model import MeasurementNoise, ModelError, NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon

NOMINAL = WheelGeometry(0.15, 0.15, 0.4)
TRUE = WheelGeometry(0.1508, 0.1497, 0.412)
QUIET = NonSystematicError()
EXACT = MeasurementNoise()


def test_amounts_are_exact_at_any_rate():
    # 0.7 s at 0.3 rad/s is not a whole number of 50 Hz samples: the rate is scaled instead
    mans = [
        straight(1.3, 0.37),
        spin(-math.radians(100), 0.3),
        arc(0.8, math.pi, 0.25),
        pause(1.01),
    ]
    for rate in (50.0, 7.0):
        s = command_series(mans, rate)
        dt = s.dt_s
        for i, m in enumerate(mans):
            sel = s.maneuver_index == i
            dist = float(np.sum(np.abs(s.v_m_s[sel]) * dt[sel]))
            yaw = float(np.sum(s.omega_rad_s[sel] * dt[sel]))
            ccw, cw = m.yaw_rad
            assert dist == pytest.approx(m.distance_m, rel=1e-12)
            assert yaw == pytest.approx(ccw - cw, abs=1e-12)


def test_noise_free_drive_with_true_parameters_ends_where_commanded():
    s = command_series(
        [square(1.5, 0.4, 0.6, "cw"), figure_eight(0.7, 0.3), spin(2 * math.pi, 1.0)]
    )
    _, truth, _ = simulate_recordings(s, NOMINAL, NOMINAL, QUIET, EXACT, 1, None)
    np.testing.assert_allclose(truth[0, -1, :2], 0.0, atol=1e-9)
    # the square turns -2 pi, the figure-eight 0, the spin +2 pi
    assert truth[0, -1, 2] == pytest.approx(0.0, abs=1e-9)
    assert np.min(truth[0, :, 2]) == pytest.approx(-2 * math.pi, abs=1e-9)


def test_truth_is_the_recorded_wheels_dead_reckoned_with_the_true_geometry():
    # an independent integration (the midpoint update of core.odometry) of the encoders with
    # the true geometry: one 50 Hz step's midpoint error apart
    s = command_series([straight(2, 0.5), arc(1.0, 2.0, 0.3), spin(-3.0, 0.8)])
    angles, truth, _ = simulate_recordings(s, TRUE, NOMINAL, QUIET, EXACT, 1, None)
    np.testing.assert_allclose(dead_reckon(angles[:, 0], angles[:, 1], TRUE), truth[0], atol=1e-5)
    # the encoders record what the believed geometry commands: 2 m straight = 2 / (D/2) rad
    first = int(np.sum(s.maneuver_index == 0))
    assert angles[first, 0] == pytest.approx(2.0 / 0.075, rel=1e-12)


def test_noise_has_the_stated_variance():
    rng = np.random.default_rng(3)
    s = command_series([straight(4.0, 0.5)], 5.0)  # the variance does not depend on the rate
    k = 1e-5
    _, truth, _ = simulate_recordings(
        s, NOMINAL, NOMINAL, NonSystematicError(k, k), EXACT, 10000, rng
    )
    # the heading is linear in the wheel noise: var(theta_end) = (k_R + k_L) |s| / b^2;
    # 10000 trials: the variance is known to 1.4 % (one sigma), so 7 % cannot fail by chance
    var = float(np.var(truth[:, -1, 2]))
    assert var == pytest.approx(2 * k * 4.0 / 0.4**2, rel=0.07)
    s = command_series([pause(100.0)], 1.0)
    _, _, gyro = simulate_recordings(
        s, NOMINAL, NOMINAL, QUIET, EXACT, 10000, rng, gyro=GyroNoise(1e-3, 0.0)
    )
    assert gyro is not None
    # angle random walk: var = arw^2 T
    assert float(np.var(gyro[:, -1])) == pytest.approx(1e-6 * 100.0, rel=0.07)


def test_time_offset_shifts_the_truth():
    s = command_series([straight(2.0, 0.5)])
    _, truth, _ = simulate_recordings(s, NOMINAL, NOMINAL, QUIET, EXACT, 1, None, time_offset_s=0.2)
    # the truth runs 0.2 s ahead: at t = 1 s it says 0.6 m
    i = int(np.searchsorted(s.time_s, 1.0))
    assert truth[0, i, 0] == pytest.approx(0.6, abs=1e-9)


def test_recording_is_in_its_start_frame():
    s = command_series([straight(1.0, 0.5)])
    angles, truth, _ = simulate_recordings(
        s, NOMINAL, NOMINAL, QUIET, MeasurementNoise(0.01, 0.05), 1, np.random.default_rng(0)
    )
    rec = as_recording(s, angles, truth[0])
    assert rec.ground_truth is not None
    np.testing.assert_allclose(rec.ground_truth[0], 0.0, atol=1e-15)
    assert len(rec) == len(s.time_s)


@pytest.mark.parametrize(
    "bad",
    [lambda: straight(0, 1), lambda: spin(1, -1), lambda: arc(0, 1, 1), lambda: pause(math.nan),
     lambda: square(1, 1, 1, "up"), lambda: command_series([])],
)  # fmt: skip
def test_bad_maneuvers_are_refused(bad):
    with pytest.raises(ModelError):
        bad()
