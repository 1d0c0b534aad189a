"""The simulated comparison (comparison.simulated): equal budget, exactness, determinism, spread,
the group data of the trajectory methods."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.comparison.methods import METHOD_REGISTRY as METHODS
from odocal.comparison.methods import Budget
from odocal.comparison.simulated import compare_simulated
from odocal.core.model import Robot, SystematicError
from odocal.presets import PRESETS, TETRA_DS2


@pytest.fixture(scope="module")
def noise_free():
    return compare_simulated(Robot(TETRA_DS2, SystematicError(1.028, 0.999)), trials=2, seed=0)


def test_equal_budget(noise_free):
    # Every method spends the same runs and the same mean wheel travel (UMBmark's 5+5 runs on
    # the 4 m square: 10 x (16 m + pi b)).
    budget = 10 * (16.0 + math.pi * 0.385)
    assert noise_free.budget_travel_m == pytest.approx(budget)
    for m in noise_free.methods:
        assert m.runs == 10
        assert m.travel_m == pytest.approx(budget, rel=1e-12)
    sizes = {m.name: m.sizes for m in noise_free.methods}
    assert sizes["heading"]["side_m"] == pytest.approx(4.0)
    assert sizes["bcpt"]["radius_m"] == pytest.approx(budget / 10 / (2 * math.pi))
    # Ivanjko: 4 straights share what 3 + 3 half-turn spins (pi b / 2 each) leave.
    assert sizes["ivanjko"]["straight_m"] == pytest.approx((budget - 6 * math.pi * 0.385 / 2) / 4)


def test_noise_free_exactness_and_known_approximations(noise_free):
    by = {m.name: m for m in noise_free.methods}
    # Exact methods: heading (exact under the model), Ivanjko (exact predictor), BCPT (exact
    # equations; the simulator's 1 cm midpoint steps bend a 2.7 m circle's radius by ~1e-6).
    # Trajectory fits tracked poses sampled ~200 times per run (exact dead reckoning of the
    # samples); linear uses the same samples in its sums, whose discretisation on the 1 m arcs
    # costs ~3e-4.
    for name, tol in (
        ("heading", 1e-12),
        ("ivanjko", 1e-9),
        ("bcpt", 2e-6),
        ("trajectory", 1e-6),
        ("linear", 5e-4),
    ):
        assert np.all(np.abs(by[name].E_b_error) < tol), name
        assert np.all(np.abs(by[name].E_d_error) < tol), name
        assert np.all(by[name].systematic_error_m < 1e-4 if tol < 1e-5 else 2e-2), name
    # UMBmark: small-angle errors of opposite sign in the x- and y-forms; the mean is better.
    ex, ey, em = (by[f"umbmark-{f}"].E_b_error[0] for f in ("x", "y", "mean"))
    assert ex < -1e-3 and ey > 1e-3 and abs(em) < min(abs(ex), abs(ey))
    # Closed-track methods keep the mean diameter; Ivanjko estimates it (here it is right).
    assert np.all(np.abs(by["ivanjko"].E_s_error) < 1e-9)
    assert noise_free.nominal_systematic_error_m > 0.5  # the uncalibrated robot misses by ~0.6 m


def test_seeded_determinism_and_independent_streams():
    robot = PRESETS["paper-fig5"]
    # determinism and stream independence hold at any trial count: 3 trials per method suffice
    a = compare_simulated(robot, trials=3, seed=3)
    b = compare_simulated(robot, trials=3, seed=3)
    c = compare_simulated(robot, trials=3, seed=4)
    for ma, mb, mc in zip(a.methods, b.methods, c.methods, strict=True):
        np.testing.assert_array_equal(ma.final_error_m, mb.final_error_m)
        np.testing.assert_array_equal(ma.E_b_error, mb.E_b_error)
        assert not np.array_equal(ma.E_b_error, mc.E_b_error)
    # One stream per method name: running a subset changes no method's numbers.
    sub = compare_simulated(robot, trials=3, seed=3, methods=[METHODS[4]])
    np.testing.assert_array_equal(sub.methods[0].E_b_error, a.methods[4].E_b_error)


def test_monte_carlo_spread_is_plausible():
    # Heading method on paper-fig5, 200 trials: its E_b spread has an analytic first-order value:
    # sigma(alpha) = sqrt(2 sigma_theta^2 / 5) / 8 with sigma_theta^2 the variance of a square's
    # final heading (4 legs of 4 m: (k_r + k_l) 16 / b^2, plus 4 spot turns of pi/2:
    # 4 (k_r + k_l) (pi/2) / (2 b)), and E_b ~ 1 + alpha / (pi/2). The sample std of 200 trials
    # is within ~15 % of the truth (chi-square, 3 sigma), so allow 25 %.
    robot = PRESETS["paper-fig5"]
    res = compare_simulated(robot, trials=200, seed=1, methods=[METHODS[0]])
    k, b = 2 * 1.69e-6, 0.385
    var_theta = k * 16 / b**2 + 4 * k * (math.pi / 2) / (2 * b)
    sigma_eb = math.sqrt(2 * var_theta / 5) / 8 / (math.pi / 2)
    sd = float(np.std(res.methods[0].E_b_error, ddof=1))
    assert sd == pytest.approx(sigma_eb, rel=0.25)
    assert abs(np.mean(res.methods[0].E_b_error)) < 4 * sd / math.sqrt(200)


def test_budget_validation():
    from odocal.errors import CalibrationError

    with pytest.raises(CalibrationError):
        compare_simulated(PRESETS["paper-fig5"], trials=2, budget=Budget(runs=2))


def test_group_data_is_a_recording_for_trajectory_methods():
    # Extension point for trajectory/linear fits: for groups with points=True, dead reckoning the
    # encoder readings (wheel_angles_rad) with the TRUE geometry reproduces the tracked poses of a
    # noise-free robot. Headings agree to rounding; positions to the midpoint-rule error of the
    # ~200 coarser samples (chord error ~ R dtheta^3 / 24 per sample: ~5e-5 m on the 1 m circle).
    from odocal.comparison.methods import RunGroup
    from odocal.comparison.simulated import simulate_group
    from odocal.core.odometry import dead_reckon
    from odocal.core.tracks import circle, polygon

    robot = Robot(TETRA_DS2, SystematicError(1.02, 1.003))
    for track in (circle(1.0, "ccw"), polygon(4, 2.0, "cw")):
        g = simulate_group(RunGroup("x", track, 2, points=True), robot, 3, None, 0.01)
        assert g.trajectory.shape[:2] == (3, 2) and g.trajectory.shape[-1] == 3
        assert g.wheel_angles_rad.shape == (g.trajectory.shape[2], 2)
        odo = dead_reckon(g.wheel_angles_rad[:, 0], g.wheel_angles_rad[:, 1], robot.true_geometry)
        np.testing.assert_allclose(odo[:, :2], g.trajectory[0, 0, :, :2], atol=1e-4)
        np.testing.assert_allclose(odo[:, 2], g.trajectory[0, 0, :, 2], atol=1e-10)
        np.testing.assert_allclose(g.trajectory[0, 0, -1], g.final[0, 0], atol=1e-12)
