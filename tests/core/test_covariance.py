"""Covariance propagation (eqs. (8)-(10)): closed forms, the one-step test vector, Monte Carlo."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.covariance import (
    correlation,
    mean_final_pose,
    odometry_covariance,
    predict,
    propagate,
    straight_line_covariance,
)
from odocal.core.model import (
    MeasurementNoise,
    ModelError,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from odocal.core.simulate import drive, measure, simulate
from odocal.core.tracks import Track, arc, out_and_back, polygon, spot_turn, straight, straight_line

GEOM = WheelGeometry.symmetric(0.15, 0.5)


def test_straight_line_test_case_of_model_md():
    # model.md: k_r = k_l = 1e-6 m, b = 0.5 m, d = 2 m -> 1e4 P
    expected = np.array([[0.01, 0, 0], [0, 0.21333, 0.16], [0, 0.16, 0.16]])
    closed = straight_line_covariance(2.0, 0.5, 1e-6, 1e-6)
    np.testing.assert_allclose(1e4 * closed, expected, atol=5e-6)
    p = propagate(
        straight_line(2.0), GEOM, GEOM, NonSystematicError(1e-6, 1e-6), steps_per_segment=10_000
    )
    # midpoint discretisation error falls as 1/N^2: ~1e-9 relative at 10 000 steps
    np.testing.assert_allclose(1e4 * p.covariance, 1e4 * closed, atol=1e-7)
    np.testing.assert_allclose(p.mean, [2.0, 0.0, 0.0], atol=1e-12)


def test_straight_line_discretisation_and_unequal_k():
    # methods-notes 3.4: 10 steps give P_yy = 0.2128e-4 (the 1/N^2 discretisation error)
    p10 = propagate(
        straight_line(2.0), GEOM, GEOM, NonSystematicError(1e-6, 1e-6), steps_per_segment=10
    )
    assert 1e4 * p10.covariance[1, 1] == pytest.approx(0.2128, abs=5e-5)
    # K- terms: k_r != k_l, along the start frame's x axis the robot frame is the start frame
    p = propagate(
        straight_line(3.0), GEOM, GEOM, NonSystematicError(3e-6, 1e-6), steps_per_segment=5000
    )
    closed = straight_line_covariance(3.0, 0.5, 3e-6, 1e-6)
    np.testing.assert_allclose(p.covariance, closed, rtol=1e-6, atol=1e-14)


def test_one_step_test_vector_tv4b():
    # methods-notes TV4-b: ds_R = 0.0105, ds_L = 0.0095, b = 0.5, k = 1e-4, one step from zero.
    # Wheels 5 % large/small against a believed symmetric robot make a 1 cm straight exactly that.
    true = WheelGeometry(0.15 * 1.05, 0.15 * 0.95, 0.5)
    p = propagate(
        straight_line(0.01), true, GEOM, NonSystematicError(1e-4, 1e-4), steps_per_segment=1
    )
    np.testing.assert_allclose(p.mean, [9.999995e-3, 9.999998e-6, 2.0e-3], rtol=1e-6)
    expected = np.array(
        [
            [4.999985e-7, 9.997987e-10, 9.995995e-8],
            [9.997987e-10, 2.014998e-10, 4.009998e-8],
            [9.995995e-8, 4.009998e-8, 8.000000e-6],
        ]
    )
    np.testing.assert_allclose(p.covariance, expected, rtol=1e-6)


def test_initial_covariance_is_transported():
    # a pure heading uncertainty at the start becomes a lateral one after d metres: var(y) = d^2 s^2
    p0 = np.diag([0.0, 0.0, 1e-4])
    p = propagate(straight_line(3.0), GEOM, GEOM, NonSystematicError(), initial_covariance=p0)
    assert p.covariance[1, 1] == pytest.approx(9e-4, rel=1e-9)
    assert p.covariance[1, 2] == pytest.approx(3e-4, rel=1e-9)


def test_initial_covariance_is_transported_to_a_sideways_end():
    # turn left a quarter, drive 3 m: the end is (0, 3); a start heading error dtheta moves it
    # by (-3 dtheta, 0), so var(x) = 9 s^2 and cov(x, theta) = -3 s^2 (the sign of y_N matters)
    p0 = np.diag([0.0, 0.0, 1e-4])
    track = Track("left then straight", (spot_turn(0.5 * math.pi), straight(3.0)))
    p = propagate(track, GEOM, GEOM, NonSystematicError(), initial_covariance=p0)
    np.testing.assert_allclose(p.mean, [0.0, 3.0, 0.5 * math.pi], atol=1e-12)
    assert p.covariance[0, 0] == pytest.approx(9e-4, rel=1e-9)
    assert p.covariance[0, 2] == pytest.approx(-3e-4, rel=1e-9)
    assert p.covariance[1, 1] == pytest.approx(0.0, abs=1e-15)


def test_out_and_back_moments_used_by_the_k_estimators():
    # model.md: var(theta) = 2 K+ d / b^2, var(x) = K+ d / 2, var(y) = K+ 2 d^3 / (3 b^2),
    # cov(x, theta) = K- d / b
    k = NonSystematicError(3e-6, 1e-6)
    d, b = 10.0, 0.5
    c = propagate(out_and_back(d), GEOM, GEOM, k, steps_per_segment=4000).covariance
    kp, km = 4e-6, 2e-6
    assert c[2, 2] == pytest.approx(2 * kp * d / b**2, rel=1e-6)
    assert c[0, 0] == pytest.approx(kp * d / 2, rel=1e-6)
    assert c[1, 1] == pytest.approx(kp * 2 * d**3 / (3 * b**2), rel=1e-6)
    assert c[0, 2] == pytest.approx(km * d / b, rel=1e-6)


def test_mean_final_pose_matches_noise_free_drive():
    robot = Robot(GEOM, SystematicError(1.03, 1.01))
    tr = Track("mixed", (straight(2.0), spot_turn(1.0), arc(1.5, -2.0), straight(-1.0)))
    exact = drive(
        tr,
        robot.true_geometry,
        GEOM,
        NonSystematicError(),
        1,
        None,
        max_step_m=0.5,
        integration="exact",
    ).true_final[0]
    np.testing.assert_allclose(mean_final_pose(tr, robot.true_geometry, GEOM), exact, atol=1e-12)
    # the propagated mean follows drive()'s own increments (midpoint rule, same steps)
    mid = drive(
        tr, robot.true_geometry, GEOM, NonSystematicError(), 1, None, max_step_m=0.05
    ).true_final[0]
    np.testing.assert_allclose(predict(tr, robot, max_step_m=0.05).mean, mid, atol=1e-12)


def test_batch_equals_scalar_calls():
    robot = Robot(GEOM, SystematicError(1.02, 0.995), NonSystematicError(2e-6, 1e-6))
    sides = np.array([0.5, 2.0, 4.0])
    batch = propagate(
        polygon(5, sides, "cw"),
        robot.true_geometry,
        GEOM,
        robot.nonsystematic,
        steps_per_segment=40,
    )
    assert batch.covariance.shape == (3, 3, 3)
    for i, s in enumerate(sides):
        one = propagate(
            polygon(5, float(s), "cw"),
            robot.true_geometry,
            GEOM,
            robot.nonsystematic,
            steps_per_segment=40,
        )
        np.testing.assert_allclose(batch.covariance[i], one.covariance, rtol=1e-12, atol=1e-18)
        np.testing.assert_allclose(batch.error_mean[i], one.error_mean, atol=1e-12)


@pytest.mark.parametrize(
    ("sides", "side", "direction"), [(4, 4.0, "cw"), (3, 2.0, "ccw"), (8, 1.0, "cw")]
)
def test_polygons_agree_with_monte_carlo(sides, side, direction):
    # A deliberately noisy robot with systematic errors and instrument noise, so every covariance
    # term is well away from zero.
    robot = Robot(
        WheelGeometry.symmetric(0.15, 0.385),
        SystematicError(1.03, 1.005),
        NonSystematicError(2e-5, 1e-5),
        MeasurementNoise.from_degrees(0.01, 0.5),
    )
    runs = 4000
    rng = np.random.default_rng(42)
    track = polygon(sides, side, direction)
    res = simulate(track, robot, runs, rng, max_step_m=0.05)
    e = measure(res.errors, robot, rng)
    pred = predict(track, robot, max_step_m=0.05)
    c = pred.measured_covariance
    s = np.sqrt(np.diag(c))
    # means: 4 standard errors sigma / sqrt(runs), plus the second-order bias that the first-order
    # mean leaves out (a heading spread shrinks the mean of cos: e^(-var/2)): up to 0.04 sigma
    # for this robot on these tracks, measured with 400,000 runs
    assert np.all(np.abs(e.mean(axis=0) - pred.error_mean) < (4 / math.sqrt(runs) + 0.05) * s)
    # variances: the sample variance has relative standard error sqrt(2 / (runs - 1)) = 2.2 %;
    # 4 of them (9 %) plus ~1 % for the first-order (linearisation) error of the model
    ratio = np.var(e, axis=0, ddof=1) / np.diag(c)
    assert np.all(np.abs(ratio - 1) < 4 * math.sqrt(2 / (runs - 1)) + 0.01), ratio
    # correlations: Fisher z has standard error 1 / sqrt(runs - 3); 4 of them
    r_mc = np.corrcoef(e.T)
    r_pred = correlation(c)
    for i, j in ((0, 1), (0, 2), (1, 2)):
        dz = abs(np.arctanh(r_mc[i, j]) - np.arctanh(r_pred[i, j]))
        assert dz < 4 / math.sqrt(runs - 3), (i, j, r_mc[i, j], r_pred[i, j])


def test_measurement_noise_is_kept_apart():
    robot = Robot(
        GEOM,
        nonsystematic=NonSystematicError(1e-6, 1e-6),
        measurement=MeasurementNoise.from_degrees(0.002, 0.2),
    )
    p = predict(polygon(4, 1.0, "ccw"), robot)
    extra = p.measured_covariance - p.covariance
    np.testing.assert_allclose(np.diag(extra), [4e-6, 4e-6, math.radians(0.2) ** 2])
    assert p.std(measured=False)[2] < p.std(measured=True)[2]


def test_odometry_covariance_takes_a_noiseless_wheel():
    # k = 0 (an estimate clipped at zero) is a valid wheel noise: only a negative k is refused
    c = odometry_covariance(2e-6, 0.0, 0.5, speed_m_s=0.2)
    assert c.pose_diagonal[0] == pytest.approx(2e-6 / 4)
    assert c.pose_diagonal[5] == pytest.approx(2e-6 / 0.25)
    with pytest.raises(ModelError, match="k_l_m"):
        odometry_covariance(2e-6, -1e-9, 0.5, speed_m_s=0.2)
