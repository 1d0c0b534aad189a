"""``odocal.app.measured.measure_robot`` on its typed result: a robot measured from repeated
recorded squares (its systematic errors from the trajectory fit, k from the spread of the
repeats, the instrument from the tracker's jitter unless given)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.measured import measure_robot
from odocal.core.model import MeasurementNoise, WheelGeometry
from odocal.errors import InputError
from tests.support.noise_runs import TRUE, K, noisy_run

NOMINAL = WheelGeometry(0.084, 0.084, 0.2)


@pytest.fixture(scope="module")
def squares():
    """16 recorded squares: 4 repeats of each direction in two data sets (wheel noise k = K)."""
    rng = np.random.default_rng(11)
    return [
        noisy_run(f"{d}-{direction}-{i}", d, direction, rng)
        for d in ("set-a", "set-b")
        for direction in ("cw", "ccw")
        for i in range(4)
    ]


def test_the_robot_measured_from_repeated_squares(squares):
    m = measure_robot(squares, NOMINAL)
    r = m.robot
    assert r.nominal == NOMINAL and m.fit.method == "trajectory"
    # the systematic errors are the trajectory fit relative to nominal
    np.testing.assert_allclose(
        [r.true_geometry.diameter_right_m, r.true_geometry.diameter_left_m,
         r.true_geometry.wheelbase_m],
        [m.fit.geometry.diameter_right_m, m.fit.geometry.diameter_left_m,
         m.fit.geometry.wheelbase_m],
        rtol=1e-12,
    )  # fmt: skip
    # the fit sees the true geometry through the wheels' noise: within 0.5 %
    assert m.fit.geometry.wheelbase_m == pytest.approx(TRUE.wheelbase_m, rel=5e-3)
    # k from the repeats: the 95 % interval covers the truth (seeded), split evenly on squares
    lo, hi = m.noise.k_sum_ci95_m
    assert m.noise.runs == 16 and lo < 2 * K < hi
    assert m.noise.k_r_m is None
    assert r.nonsystematic.k_r_m == r.nonsystematic.k_l_m == pytest.approx(m.noise.k_sum_m / 2)
    # no instrument given: the tracker's jitter, counted at the start and at the end
    assert r.measurement.sigma_xy_m == pytest.approx(math.sqrt(2) * m.tracker.sigma_xy_m)
    assert r.measurement.sigma_theta_rad == pytest.approx(math.sqrt(2) * m.tracker.sigma_theta_rad)
    assert "jitter" in m.measurement_source
    assert m.describe()[0] == "measured from 16 recorded run(s) by odocal"
    d = m.as_dict()
    assert d["calibrated"] == m.fit.geometry.as_dict() and d["noise"] == m.noise.as_dict()


def test_a_given_instrument_and_fit_are_used_as_given(squares):
    first = measure_robot(squares, NOMINAL)
    given = MeasurementNoise.from_degrees(0.001, 0.2)
    m = measure_robot(squares, NOMINAL, measurement=given, fit=first.fit)
    assert m.fit is first.fit and m.robot.measurement == given
    assert m.measurement_source == "given"
    # the instrument's heading noise is subtracted from the spread: a larger one, a smaller k
    assert m.noise.k_sum_m < first.noise.k_sum_m
    with pytest.raises(InputError, match="no recorded runs"):
        measure_robot([], NOMINAL)
