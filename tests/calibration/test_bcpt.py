"""BCPT (reconstructed): exactness, signs, recorded circles, real-data golden values."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.bcpt import (
    bcpt_factors,
    bcpt_first_order,
    calibrate_bcpt,
    calibrate_bcpt_recordings,
)
from odocal.calibration.circle_fit import fit_circle
from odocal.core.model import Robot, SystematicError, WheelGeometry
from odocal.core.recording import Recording
from odocal.core.runs import CircleRuns
from odocal.core.simulate import simulate
from odocal.core.tracks import circle
from odocal.errors import CalibrationError

NOMINAL = WheelGeometry.symmetric(0.15, 0.34)


def _radius(robot, radius, direction, integration="exact"):
    res = simulate(
        circle(radius, direction), robot, 1, None, trajectory=True, integration=integration
    )
    return fit_circle(res.trajectory[0, :, :2]).radius_m


# --- BCPT equations --------------------------------------------------------------------------


def test_tv5_exact_and_first_order():
    # methods-notes.md TV5: R_c = 1 m, b_n = 0.34 m, truth E_b = 1.01, E_d = 1.002. The radii are
    # printed to 1e-6 m, which moves E_b by ~1e-6 and E_d by ~2e-7.
    E_b, E_d = bcpt_factors(1.015798, 1.004270, 1.0, 0.34)
    assert float(E_b) == pytest.approx(1.010000, abs=2e-6)
    assert float(E_d) == pytest.approx(1.002000, abs=5e-7)
    lin_b, lin_d = bcpt_first_order(1.015798, 1.004270, 1.0, 0.34)
    assert float(lin_b) == pytest.approx(1.010034, abs=1e-6)
    assert float(lin_d) == pytest.approx(1.001960, abs=1e-6)


@pytest.mark.parametrize(
    "E_b, E_d, E_s, radius",
    [
        (1.01, 1.002, 1.0, 1.0),
        (0.97, 0.995, 1.03, 0.6),
        (1.028, 0.999, 0.98, 2.7),
        (1.0, 1.0, 1.0, 1.5),
    ],
)
def test_noise_free_simulated_circles_are_exact(E_b, E_d, E_s, radius):
    robot = Robot(NOMINAL, SystematicError(E_b, E_d, E_s))
    r_cw = _radius(robot, radius, "cw")
    r_ccw = _radius(robot, radius, "ccw")
    res = calibrate_bcpt(CircleRuns(("cw", "ccw"), np.array([r_cw, r_ccw])), radius, NOMINAL)
    assert res.E_b == pytest.approx(E_b, abs=1e-6)
    assert res.E_d == pytest.approx(E_d, abs=1e-6)
    true = robot.true_geometry
    assert res.corrected.wheelbase_m == pytest.approx(true.wheelbase_m, rel=1e-6)
    assert res.corrected.diameter_ratio == pytest.approx(true.diameter_ratio, rel=1e-6)


def test_midpoint_simulation_has_the_known_small_error():
    # With the default midpoint integration over 1 cm steps a circle's points lie on a circle of
    # radius (ds/2)/sin(dtheta/2) instead of ds/dtheta: relative error dtheta^2/24 with
    # dtheta ~ 0.01 m / 1 m, i.e. ~4e-6. E_b inherits it; E_d (a difference) almost cancels it.
    robot = Robot(NOMINAL, SystematicError(1.01, 1.002))
    r_cw = _radius(robot, 1.0, "cw", "midpoint")
    r_ccw = _radius(robot, 1.0, "ccw", "midpoint")
    E_b, E_d = bcpt_factors(r_cw, r_ccw, 1.0, 0.34)
    assert 1e-6 < float(E_b) - 1.01 < 1e-5
    assert abs(float(E_d) - 1.002) < 1e-6


def test_sign_conventions_cw_ccw():
    # E_d > 1 (right wheel larger) pulls left: the CCW circle tightens, the CW circle widens.
    robot = Robot(NOMINAL, SystematicError(1.0, 1.004))
    r_cw, r_ccw = _radius(robot, 1.0, "cw"), _radius(robot, 1.0, "ccw")
    assert r_ccw < 1.0 < r_cw
    E_b, E_d = bcpt_factors(r_cw, r_ccw, 1.0, 0.34)
    assert float(E_d) > 1.0 and float(E_b) == pytest.approx(1.0, abs=1e-9)
    # E_b > 1 widens both circles.
    robot = Robot(NOMINAL, SystematicError(1.02, 1.0))
    r_cw, r_ccw = _radius(robot, 1.0, "cw"), _radius(robot, 1.0, "ccw")
    assert r_cw > 1.0 and r_ccw > 1.0 and r_cw == pytest.approx(r_ccw, rel=1e-12)
    # Swapping the directions flips E_d to 1/E_d.
    E_b1, E_d1 = bcpt_factors(1.0158, 1.0043, 1.0, 0.34)
    E_b2, E_d2 = bcpt_factors(1.0043, 1.0158, 1.0, 0.34)
    assert float(E_d1) * float(E_d2) == pytest.approx(1.0, abs=1e-12)
    assert float(E_b1) == pytest.approx(float(E_b2), abs=1e-12)


def test_different_commanded_radii_per_direction_are_exact():
    robot = Robot(NOMINAL, SystematicError(1.015, 0.997, 1.02))
    r_cw = _radius(robot, 0.9, "cw")
    r_ccw = _radius(robot, 1.3, "ccw")
    E_b, E_d = bcpt_factors(r_cw, r_ccw, 0.9, 0.34, commanded_ccw_m=1.3)
    assert float(E_b) == pytest.approx(1.015, abs=1e-9)
    assert float(E_d) == pytest.approx(0.997, abs=1e-9)


def test_first_order_away_from_a_one_metre_radius():
    # radii of a robot with E_b 1.01, E_d 1.002 on R_c = 2 m (the exact relations of the module
    # docstring solved for R): the first-order forms are within 2e-4 of the truth there too
    b, e_b, e_d, rc = 0.34, 1.01, 1.002, 2.0
    h, g = e_b * b / 2, (rc + b / 2) / (rc - b / 2)
    r_ccw = h * (e_d * g + 1) / (e_d * g - 1)
    r_cw = h * (g / e_d + 1) / (g / e_d - 1)
    exact_b, exact_d = bcpt_factors(r_cw, r_ccw, rc, b)
    assert (float(exact_b), float(exact_d)) == pytest.approx((e_b, e_d), abs=1e-12)
    lin_b, lin_d = bcpt_first_order(r_cw, r_ccw, rc, b)
    assert float(lin_b) == pytest.approx(e_b, abs=2e-4)
    assert float(lin_d) == pytest.approx(e_d, abs=2e-5)


def test_calibration_errors():
    with pytest.raises(CalibrationError, match="half the wheelbase"):
        calibrate_bcpt(CircleRuns(("cw", "ccw"), np.array([1.0, 1.0])), 0.17, NOMINAL)
    with pytest.raises(CalibrationError, match="CCW"):
        calibrate_bcpt(CircleRuns(("cw",), np.array([1.0])), 1.0, NOMINAL)


# --- recorded runs ---------------------------------------------------------------------------


def _circle_recording(robot, radius, direction):
    # Ground truth from the exact simulator; wheel angles: the commanded (believed) rotations,
    # sampled every 1 mm so that dead reckoning them (midpoint rule) is a circle of radius
    # `radius` to (dtheta^2)/24 ~ 1e-7 relative.
    res = simulate(
        circle(radius, direction),
        robot,
        1,
        None,
        trajectory=True,
        integration="exact",
        max_step_m=0.001,
    )
    gt = res.trajectory[0]
    samples = len(gt)
    frac = np.arange(samples) / (samples - 1)
    psi = (1 if direction == "ccw" else -1) * 2 * math.pi
    b = robot.nominal.wheelbase_m
    s_r = (radius * abs(psi) + psi * b / 2) * frac
    s_l = (radius * abs(psi) - psi * b / 2) * frac
    return Recording(
        name=f"sim-{direction}",
        time_s=np.arange(samples) * 0.05,
        wheel_angle_right_rad=2 * s_r / robot.nominal.diameter_right_m,
        wheel_angle_left_rad=2 * s_l / robot.nominal.diameter_left_m,
        ground_truth=gt,
        ran_with=robot.nominal,
        label=direction,
    )


def test_recordings_radius_fit_is_exact():
    robot = Robot(NOMINAL, SystematicError(1.012, 0.998, 1.01))
    recs = [_circle_recording(robot, 0.8, d) for d in ("cw", "ccw")]
    res = calibrate_bcpt_recordings(recs)
    assert res.E_b == pytest.approx(1.012, abs=1e-6)
    assert res.E_d == pytest.approx(0.998, abs=1e-6)
    assert res.inputs["arcs"][0]["commanded_radius_cw_m"] == pytest.approx(0.8, rel=1e-6)
    # Splitting each run into half-turn arcs gives the same answer.
    res2 = calibrate_bcpt_recordings(recs, arc_rad=math.pi)
    assert len(res2.inputs["arcs"]) == 2
    assert res2.E_b == pytest.approx(1.012, abs=1e-6)


def test_recordings_with_a_given_commanded_radius():
    # the commanded radius given replaces the one fitted to the dead-reckoned runs
    robot = Robot(NOMINAL, SystematicError(1.012, 0.998, 1.01))
    recs = [_circle_recording(robot, 0.8, d) for d in ("cw", "ccw")]
    fitted = calibrate_bcpt_recordings(recs).inputs["arcs"][0]
    res = calibrate_bcpt_recordings(recs, commanded_radius_m=0.85)
    arc = res.inputs["arcs"][0]
    assert arc["commanded_radius_cw_m"] == arc["commanded_radius_ccw_m"] == 0.85
    e_b, e_d = bcpt_factors(fitted["radius_cw_m"], fitted["radius_ccw_m"], 0.85, 0.34)
    assert res.E_b == pytest.approx(float(e_b), abs=1e-12)
    assert res.E_d == pytest.approx(float(e_d), abs=1e-12)
    assert abs(res.E_b - 1.012) > 0.05  # a wrong commanded radius gives a wrong E_b


def test_optiodom_circle_golden(realdata):
    # OptiOdom circular/231220200121: 3 CW + 3 CCW runs, each four 180-degree arcs of
    # decreasing radius (odometric radii 0.857, 0.772, 0.700, 0.658 m); metadata 'L' is empty,
    # so the commanded radius comes from the dead-reckoned arcs. Golden values measured here;
    # SOURCE.md's whole-trajectory fit gives b ~ 0.2022 m on circles.
    from odocal.io.optiodom import load_optiodom_dataset

    recs = load_optiodom_dataset(realdata / "optiodom_diff" / "circular" / "231220200121")
    res = calibrate_bcpt_recordings(recs, arc_rad=math.pi)
    arcs = res.inputs["arcs"]
    assert [round(a["commanded_radius_cw_m"], 2) for a in arcs] == [0.86, 0.77, 0.70, 0.66]
    assert res.corrected.wheelbase_m == pytest.approx(0.20199, abs=2e-5)
    assert res.E_d == pytest.approx(0.99902, abs=2e-5)
    assert all(a["radius_ccw_m"] > a["radius_cw_m"] for a in arcs)  # E_d < 1 widens CCW
