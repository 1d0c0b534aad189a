"""design.route: the predicted standard errors of a recording checked by its own Monte Carlo,
the recommendation rules and the refusals."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest

from odocal.core.model import (
    MeasurementNoise,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from odocal.design.route import (
    RouteNoise,
    RouteSpec,
    Target,
    candidate_maneuvers,
    default_noise,
    design_route,
    mixes,
)
from odocal.errors import CalibrationError

ROBOT = Robot(
    WheelGeometry(0.15, 0.15, 0.4),
    systematic=SystematicError(E_b=1.02, E_d=1.003),
    nonsystematic=NonSystematicError(2e-6, 2e-6),
)


def _one(route, mix, duration, trials, seed, noise=None):
    spec = RouteSpec(route=route, durations_s=(duration,), trials=trials, confirm=1)
    noise = noise or default_noise(route, ROBOT)
    d = design_route(ROBOT, spec, noise, np.random.default_rng(seed))
    return d, [c for c in d.candidates if c.mix == mix]


@pytest.mark.parametrize(("route", "arw_deg_per_sqrt_h"), [("trajectory", None), ("slam", None),
                                                       ("gyro", 0.3), ("gyro", 10.0)])  # fmt: skip
def test_prediction_agrees_with_its_monte_carlo(route, arw_deg_per_sqrt_h):
    # the recommended candidate is simulated 400 times and calibrated by the route's own code
    # (the batched trajectory fit; gyro_calibration): the spread of 400 estimates is known to
    # about 1 / sqrt(2 x 400) = 3.5 %, so a prediction within 20 % of it is a real agreement.
    # A MEMS gyro (0.3 deg/sqrt(h)) adds little to the wheels' noise; a poor one (10) dominates
    noise = default_noise(route, ROBOT)
    if arw_deg_per_sqrt_h is not None:
        arw = math.radians(arw_deg_per_sqrt_h) / 60.0
        noise = replace(noise, gyro=replace(noise.gyro, arw_rad_sqrt_s=arw))
    d, _ = _one(route, None, 60.0, 400, 11, noise)
    rec = d.recommended
    assert rec.monte_carlo is not None and rec.monte_carlo.failed == 0
    for name, realised in rec.monte_carlo.realised_std_error.items():
        predicted = rec.predicted_std_error[name]
        assert realised == pytest.approx(predicted, rel=0.2), name


def test_gyro_sees_the_wheelbase_only_and_says_so():
    with pytest.raises(CalibrationError, match="wheel diameters are not observable"):
        design_route(
            ROBOT,
            RouteSpec(route="gyro", targets=(Target("wheel_diameter", 0.001, True),)),
            default_noise("gyro", ROBOT),
            np.random.default_rng(0),
        )
    d, _ = _one("gyro", None, 30.0, 20, 0)
    assert set(d.recommended.predicted_std_error) == {"wheelbase"}
    assert any("not observable" in s for s in d.not_estimated)


def test_gyro_prediction_shrinks_as_rotation_grows():
    # the ratio's error is noise over net rotation: more turning, smaller error (one way only)
    spec = RouteSpec(route="gyro", durations_s=(30.0, 120.0), trials=20, confirm=1)
    d = design_route(ROBOT, spec, default_noise("gyro", ROBOT), np.random.default_rng(1))
    spins = sorted((c for c in d.candidates if c.mix == "gyro-spins"), key=lambda c: c.duration_s)
    assert spins[1].relative_std_error["wheelbase"] < 0.7 * spins[0].relative_std_error["wheelbase"]
    for c in spins:
        ccw = sum(m.yaw_rad[0] for m in c.maneuvers)
        cw = sum(m.yaw_rad[1] for m in c.maneuvers)
        assert ccw > 0 and cw == 0


def test_target_picks_the_shortest_candidate_that_reaches_it():
    spec = RouteSpec(route="trajectory", durations_s=(30.0, 60.0, 120.0), trials=20, confirm=1)
    noise = default_noise("trajectory", ROBOT)
    free = design_route(ROBOT, spec, noise, np.random.default_rng(2))
    # a target between the best and the worst wheelbase error of the candidates
    errs = sorted(c.relative_std_error["wheelbase"] for c in free.candidates)
    target = Target("wheelbase", 0.5 * (errs[0] + errs[-1]), True)
    d = design_route(ROBOT, replace(spec, targets=(target,)), noise, np.random.default_rng(2))
    rec = d.recommended
    assert rec.relative_std_error["wheelbase"] <= target.value
    shorter = [c for c in d.candidates if c.duration_s < rec.duration_s]
    assert all(c.relative_std_error["wheelbase"] > target.value for c in shorter)


def test_unreachable_target_names_the_best_and_the_duration_needed():
    spec = RouteSpec(
        route="gyro", durations_s=(30.0,), max_duration_s=30.0,
        targets=(Target("wheelbase", 0.0004, True),), trials=20,
    )  # fmt: skip
    with pytest.raises(CalibrationError) as e:
        design_route(ROBOT, spec, default_noise("gyro", ROBOT), np.random.default_rng(0))
    msg = str(e.value)
    assert "no recording of up to" in msg and "the best reachable is wheelbase" in msg
    assert "would reach it" in msg or "no candidate up to" in msg


def test_more_pose_noise_means_larger_predicted_errors():
    quiet = RouteNoise(NonSystematicError(2e-6, 2e-6), MeasurementNoise(1e-3, math.radians(0.2)))
    loud = RouteNoise(NonSystematicError(2e-6, 2e-6), MeasurementNoise(2e-2, math.radians(1.0)))
    spec = RouteSpec(route="slam", durations_s=(60.0,), trials=20, confirm=1)
    a = design_route(ROBOT, spec, quiet, np.random.default_rng(0))
    b = design_route(ROBOT, spec, loud, np.random.default_rng(0))
    for ca, cb in zip(a.candidates, b.candidates, strict=True):
        assert cb.predicted_std_error["wheelbase"] > ca.predicted_std_error["wheelbase"]


def test_candidates_cover_the_mixes_and_stay_within_the_duration():
    for route in ("trajectory", "gyro"):
        for mix in mixes(route):
            m = candidate_maneuvers(route, mix, 120.0, 0.4, 0.3, 0.5)
            total = sum(x.duration_s for x in m)
            assert 0.5 * 120 <= total <= 1.6 * 120, (route, mix, total)


def test_several_runs_predicted_and_checked_by_their_monte_carlo():
    # 240 s of figure-eights also as two runs of 120 s; the Monte Carlo of the split candidate
    # simulates independent runs and fits them together (fit_trajectory_trials' run groups):
    # 300 trials know a spread to about 4 %, so 20 % is a real agreement
    spec = RouteSpec(route="trajectory", durations_s=(240.0,), trials=300, confirm=1)
    noise = default_noise("trajectory", ROBOT)
    # a target only the split candidates reach makes one of them the recommendation
    d = design_route(ROBOT, replace(spec, trials=2), noise, np.random.default_rng(5))
    split = [c for c in d.candidates if c.runs == 2]
    single = {c.mix: c for c in d.candidates if c.runs == 1}
    assert split and all(c.mix in single for c in split)
    target = Target("wheelbase", min(c.relative_std_error["wheelbase"] for c in split) * 1.01, True)
    d = design_route(ROBOT, replace(spec, targets=(target,)), noise, np.random.default_rng(5))
    rec = d.recommended
    assert rec.runs == 2 and rec.monte_carlo is not None
    for name, realised in rec.monte_carlo.realised_std_error.items():
        assert realised == pytest.approx(rec.predicted_std_error[name], rel=0.2), name
    # cutting a 4-minute drive in two helps the fit (one run's poses are a random walk)
    assert rec.relative_std_error["wheelbase"] < single[rec.mix].relative_std_error["wheelbase"]
