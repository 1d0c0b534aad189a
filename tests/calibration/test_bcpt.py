"""BCPT (reconstructed) and the circle fit: exactness, signs, real-data golden values, CLI."""

from __future__ import annotations

import json
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
from odocal.core.model import ModelError, Robot, SystematicError, WheelGeometry
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


# --- circle fit ------------------------------------------------------------------------------


@pytest.mark.parametrize("algebraic", ["kasa", "pratt"])
@pytest.mark.parametrize("geometric", [False, True])
@pytest.mark.parametrize("span", [2 * math.pi, math.pi / 2])
def test_circle_fit_exact_points(algebraic, geometric, span):
    t = np.linspace(0.3, 0.3 + span, 40)
    pts = np.c_[1.3 + 2.5 * np.cos(t), -0.7 + 2.5 * np.sin(t)]
    f = fit_circle(pts, algebraic, geometric)
    assert f.center_x_m == pytest.approx(1.3, abs=1e-10)
    assert f.center_y_m == pytest.approx(-0.7, abs=1e-10)
    assert f.radius_m == pytest.approx(2.5, abs=1e-10)
    assert f.rms_residual_m < 1e-10


def test_circle_fit_batched_matches_single():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * math.pi, 60)
    pts = np.c_[np.cos(t), np.sin(t)] * np.array([[1.0], [3.0]])[:, :, None] / 1.0
    pts = pts + 0.01 * rng.standard_normal(pts.shape)
    batch = fit_circle(pts)
    for i in range(2):
        single = fit_circle(pts[i])
        assert batch.radius_m[i] == pytest.approx(single.radius_m, rel=1e-12)


def test_circle_fit_noisy_semicircle_bias():
    # 400 seeded fits of 100 points on a semicircle of radius 2 m, sigma 2 cm per coordinate.
    # The standard error of the mean radius is std/sqrt(400) ~ 0.24 mm; the geometric and Pratt
    # fits must be unbiased to within 3 standard errors, while Kasa's known under-estimate of the
    # radius on arcs shows (about -1 mm here, more than 3 standard errors).
    rng = np.random.default_rng(7)
    t = np.linspace(0, math.pi, 100)
    pts = np.c_[2 * np.cos(t), 2 * np.sin(t)] + rng.normal(0, 0.02, (400, 100, 2))
    for algebraic, geometric in (("pratt", True), ("pratt", False)):
        r = fit_circle(pts, algebraic, geometric).radius_m
        sem = r.std(ddof=1) / math.sqrt(len(r))
        assert abs(r.mean() - 2.0) < 3 * sem
    r = fit_circle(pts, "kasa", False).radius_m
    assert r.mean() - 2.0 < -3 * r.std(ddof=1) / math.sqrt(len(r))


def test_circle_fit_rejects_degenerate_points():
    with pytest.raises(ModelError, match="at least 3"):
        fit_circle([[0, 0], [1, 1]])
    with pytest.raises(ModelError, match="circle"):
        fit_circle([[0, 0], [1, 1], [2, 2], [3, 3]])
    with pytest.raises(ModelError, match="finite"):
        fit_circle([[0, 0], [1, np.nan], [2, 0]])


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


# --- CLI -------------------------------------------------------------------------------------


def _write(path, text):
    path.write_text(text)
    return path


def test_cli_bcpt_json(cli, tmp_path):
    robot = _write(tmp_path / "robot.yaml", "wheel_diameter_m: 0.15\nwheelbase_m: 0.34\n")
    runs = _write(tmp_path / "runs.csv", "direction,radius_m,run\ncw,1.015798,1\nccw,1.004270,2\n")
    out = tmp_path / "params.yaml"
    status, stdout, stderr = cli(
        "calibrate",
        runs,
        "--method",
        "bcpt",
        "--radius",
        1.0,
        "--robot",
        robot,
        "--json",
        "--out",
        out,
    )
    assert status == 0, stderr
    doc = json.loads(stdout)
    assert doc["method"] == "bcpt"
    assert doc["E_b"] == pytest.approx(1.01, abs=2e-6)
    assert doc["wheelbase_m"] == pytest.approx(0.34 * 1.01, abs=1e-6)
    assert out.exists()
    status, stdout, _ = cli("calibrate", runs, "--method", "bcpt", "--radius", 1, "--robot", robot)
    assert status == 0 and "first order" in stdout


@pytest.mark.parametrize(
    "text, args, message",
    [
        ("direction,radius_m\ncw,1.01\nccw,1.0\n", [], "--radius"),
        ("direction,radius_m\ncw,abc\nccw,1.0\n", ["--radius", "1"], "line 2, field 'radius_m'"),
        ("direction,radius_m\ncw,-1\nccw,1.0\n", ["--radius", "1"], "line 2, field 'radius_m'"),
        ("direction,radius_m\nup,1.0\nccw,1.0\n", ["--radius", "1"], "line 2, field 'direction'"),
        ("direction,r\ncw,1.0\n", ["--radius", "1"], "missing column(s) radius_m"),
        ("direction,radius_m\ncw,1.0,9\n", ["--radius", "1"], "line 2"),
        ("direction,radius_m\n", ["--radius", "1"], "no runs"),
        ("direction,radius_m\ncw,1.0\ncw,1.1\n", ["--radius", "1"], "no CCW runs"),
        ("direction,radius_m\ncw,0.11\nccw,0.1\n", ["--radius", "0.1"], "half the wheelbase"),
        ("direction,radius_m\ncw,1.0\nccw,1.0\n", ["--radius", "0.1"], "a diameter for a radius"),
        ("direction,radius_m\ncw,1.0\nccw,1.0\n", ["--radius", "-2"], "--radius"),
    ],
)
def test_cli_bcpt_bad_input(cli, tmp_path, text, args, message):
    runs = _write(tmp_path / "runs.csv", text)
    out = tmp_path / "params.yaml"
    status, stdout, stderr = cli("calibrate", runs, "--method", "bcpt", *args, "--out", out)
    assert status == 2
    assert stderr.startswith("odocal: error:") and stderr.count("\n") == 1
    assert message in stderr
    assert "Traceback" not in stderr
    assert not out.exists()
    if "line" in message or "column" in message or "no runs" in message:
        assert str(runs) in stderr


def test_cli_radius_without_bcpt_is_an_error(cli, tmp_path):
    runs = _write(
        tmp_path / "runs.csv", "direction,x_m,y_m,theta_deg\ncw,0.1,0.1,1\nccw,0.1,-0.1,-1\n"
    )
    status, _, err = cli("calibrate", runs, "--radius", 1.0)
    assert status == 2 and err.count("\n") == 1
    assert "--radius is only used with --method bcpt" in err
