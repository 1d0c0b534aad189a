"""The effective wheelbase per band of motion: the segment estimator, the banded fit, the single
wheelbase for a motion mix; synthetic robots whose wheelbase depends on the motion, and the real
OptiOdom robot."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.banded import fit_banded, fit_trajectory_bands
from odocal.calibration.fit_settings import TrajectorySettings
from odocal.calibration.turning import (
    BANDS,
    effective_wheelbase,
    parse_motion_mix,
    wheelbase_for_mix,
    wheelbase_per_increment,
)
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.errors import CalibrationError, InputError

D, B = 0.084, 0.200
REFERENCE = WheelGeometry(D, D, B)
# the "true" robot: it turns less per wheel rotation on arcs than on the spot (as OptiOdom)
TRUE_BANDS = {"spot": 0.2010, "tight": 0.2025, "wide": 0.2020, "straight": 0.2020}


def wheel_angles(primitives, step_m=0.005):
    """Cumulative wheel angles (rad) of ('straight', d), ('spin', psi), ('arc', rho, psi) at
    ``step_m`` of wheel travel per sample (20 Hz)."""
    r_list, l_list = [np.zeros(1)], [np.zeros(1)]
    for p in primitives:
        if p[0] == "straight":
            s_r = s_l = p[1]
        elif p[0] == "spin":
            s_r, s_l = p[1] * B / 2, -p[1] * B / 2
        else:
            rho, psi = p[1], p[2]
            s_r, s_l = (rho + B / 2) * psi, (rho - B / 2) * psi
        n = max(2, int(math.ceil(max(abs(s_r), abs(s_l)) / step_m)))
        f = np.arange(1, n + 1) / n
        r_list.append(r_list[-1][-1] + f * 2 * s_r / D)
        l_list.append(l_list[-1][-1] + f * 2 * s_l / D)
    return np.concatenate(r_list), np.concatenate(l_list)


def banded_run(name, primitives, bands=TRUE_BANDS):
    """A run whose ground truth turns with the wheelbase of each increment's band."""
    right, left = wheel_angles(primitives)
    bare = Recording(name, np.arange(len(right)) * 0.05, right, left)
    b = wheelbase_per_increment(bare, bands, REFERENCE)
    gt = dead_reckon(right, left, WheelGeometry.unchecked(D, D, b))
    return Recording(name, bare.time_s, right, left, ground_truth=gt, meta={"dataset": "syn"})


def mixed(sign):
    return [
        ("straight", 0.5),
        ("spin", sign * math.pi / 2),
        ("straight", 0.5),
        ("arc", 0.35, sign * math.pi),  # tight: R 0.35 m = 1.75 b
        ("straight", 0.5),
        ("arc", 1.0, -sign * math.pi / 2),  # wide: R 1 m = 5 b
        ("straight", 0.5),
        ("spin", -sign * math.pi),
    ]


@pytest.fixture(scope="module")
def runs():
    return [banded_run(f"r{i}", mixed(s)) for i, s in enumerate((1, -1, 1, -1))]


def test_the_estimator_recovers_each_band_exactly_without_noise(runs):
    table = effective_wheelbase(runs, REFERENCE)
    for name in ("spot", "tight", "wide"):
        b = table.band(name)
        assert b.excited, name
        # every segment lies in one band and its truth turns with that band's wheelbase, so the
        # ratio is exact up to rounding
        assert b.wheelbase_m == pytest.approx(TRUE_BANDS[name], rel=1e-9)
        assert b.ci95_m[0] <= b.wheelbase_m <= b.ci95_m[1]
        assert b.turning_gain == pytest.approx(D / TRUE_BANDS[name], rel=1e-9)
    # straight driving turns too little to show a wheelbase
    assert not table.band("straight").excited
    # radius ranges follow the wheelbase: spot R <= 0.625 b, tight up to 2.5 b, wide to 12.5 b
    assert table.band("tight").radius_range_m == pytest.approx((0.625 * B, 2.5 * B))
    assert table.band("straight").radius_range_m[1] is None
    assert sum(table.motion_mix.values()) == pytest.approx(1.0)


def test_a_one_wheelbase_robot_gives_one_value_in_every_band():
    flat = dict.fromkeys(BANDS, 0.2013)
    runs = [banded_run(f"f{i}", mixed(s), flat) for i, s in enumerate((1, -1, 1))]
    table = effective_wheelbase(runs, REFERENCE)
    for b in table.bands:
        if b.excited:
            assert b.wheelbase_m == pytest.approx(0.2013, rel=1e-9)


def test_tracker_noise_widens_the_interval_but_not_the_estimate(runs):
    rng = np.random.default_rng(5)
    noisy = []
    for r in runs * 3:
        gt = r.ground_truth.copy()
        gt[1:, 2] += rng.normal(0, math.radians(0.2), len(gt) - 1)  # 0.2 deg heading jitter
        noisy.append(
            Recording(
                r.name + "n",
                r.time_s,
                r.wheel_angle_right_rad,
                r.wheel_angle_left_rad,
                ground_truth=gt,
            )
        )
    table = effective_wheelbase(noisy, REFERENCE)
    spot = table.band("spot")
    # 0.2 deg per end of a 1.6-3.1 rad segment: about 0.2 % per segment, averaged over 24
    assert spot.wheelbase_m == pytest.approx(TRUE_BANDS["spot"], rel=2e-3)
    assert spot.ci95_m[0] < TRUE_BANDS["spot"] < spot.ci95_m[1]
    assert spot.ci95_m[1] - spot.ci95_m[0] > 1e-6


def test_banded_fit_recovers_the_bands_and_exports_the_mix(runs):
    fit = fit_banded(runs, WheelGeometry(0.0838, 0.0841, 0.2005), nominal=REFERENCE)
    bw = fit.banded.band_wheelbase_m
    assert set(bw) == {"spot", "tight", "wide"}
    for name, value in bw.items():
        assert value == pytest.approx(TRUE_BANDS[name], rel=1e-6)
    assert fit.geometry.diameter_right_m == pytest.approx(D, rel=1e-6)
    # the exported single value is the runs' own mix of the three bands
    mix = fit.motion_mix
    assert min(bw.values()) < fit.geometry.wheelbase_m < max(bw.values())
    assert fit.geometry.wheelbase_m == pytest.approx(mix.wheelbase_m)
    # a stated mix: all on arcs -> between the arcs' values
    arcs = fit_banded(
        runs, REFERENCE, settings=TrajectorySettings(motion_mix={"tight": 0.5, "wide": 0.5})
    )
    assert TRUE_BANDS["wide"] < arcs.geometry.wheelbase_m < TRUE_BANDS["tight"]


def test_the_trajectory_fit_with_its_bands_or_the_banded_model(runs):
    constant = fit_trajectory_bands(runs, REFERENCE, TrajectorySettings())
    assert constant.banded is None and constant.effective_wheelbase is not None
    assert all(constant.effective_wheelbase.band(n).excited for n in ("spot", "tight", "wide"))
    banded = fit_trajectory_bands(runs, REFERENCE, TrajectorySettings(wheelbase_model="banded"))
    assert banded.constant_fit == constant.geometry
    for name, value in banded.banded.band_wheelbase_m.items():
        assert value == pytest.approx(TRUE_BANDS[name], rel=1e-5)


def test_banded_fit_refuses_runs_that_turn_only_on_the_spot():
    square = [("straight", 1.0), ("spin", math.pi / 2)] * 4
    runs = [banded_run(f"s{i}", square) for i in range(4)]
    with pytest.raises(CalibrationError, match="at least two bands") as exc:
        fit_banded(runs, REFERENCE)
    assert "spot" in str(exc.value) and "circles or arcs" in str(exc.value)
    assert "--wheelbase-model constant" in str(exc.value)
    # a mix all in the one band these runs turn in: the plain fit is its wheelbase
    with pytest.raises(CalibrationError, match="leave out --motion-mix"):
        fit_banded(runs, REFERENCE, settings=TrajectorySettings(motion_mix={"spot": 1.0}))


def _noisy(runs, seed=7, heading_sd_rad=0.0017, position_sd_m=5e-4):
    """The runs with tracker noise on their ground truth (explicit generator), in 4 data sets."""
    rng = np.random.default_rng(seed)
    out = []
    for i, r in enumerate(runs):
        gt = r.ground_truth.copy()
        gt[1:, :2] += rng.normal(0, position_sd_m, (len(gt) - 1, 2))
        gt[1:, 2] += rng.normal(0, heading_sd_rad, len(gt) - 1)
        right, left = r.wheel_angle_right_rad, r.wheel_angle_left_rad
        meta = {"dataset": f"d{i % 4}"}
        out.append(Recording(f"n{i}", r.time_s, right, left, ground_truth=gt, meta=meta))
    return out


def test_a_motion_mix_is_one_way_the_banded_fit_with_its_own_uncertainty(runs):
    """Issue 20.7: --motion-mix with the constant model exported the band table's value (at the
    constant fit's diameters) with the plain fit's standard error; the banded model another
    value. Now both routes are the banded fit's bands, mixed, with the delta-method error."""
    noisy = _noisy(runs * 2)
    mix = {"spot": 0.3, "wide": 0.7}
    via_constant = fit_trajectory_bands(noisy, REFERENCE, TrajectorySettings(motion_mix=mix))
    via_banded = fit_trajectory_bands(
        noisy, REFERENCE, TrajectorySettings(wheelbase_model="banded", motion_mix=mix)
    )
    assert via_constant.banded is not None
    assert via_constant.geometry == via_banded.geometry
    bw = via_constant.banded.band_wheelbase_m
    assert via_constant.motion_mix.wheelbase_m == pytest.approx(
        (0.3 * bw["spot"] ** 2 + 0.7 * bw["wide"] ** 2) / (0.3 * bw["spot"] + 0.7 * bw["wide"]),
        rel=1e-12,
    )
    se = via_constant.stderr["wheelbase_m"]
    assert se is not None and se == pytest.approx(via_constant.motion_mix.wheelbase_stderr_m)
    # not the plain fit's error: the plain fit is a compromise over all bands
    plain = fit_trajectory_bands(noisy, REFERENCE, TrajectorySettings())
    assert se != pytest.approx(plain.stderr["wheelbase_m"], rel=0.05)
    # delta method: a mix all in one band has exactly that band's error
    spot = fit_trajectory_bands(noisy, REFERENCE, TrajectorySettings(motion_mix={"spot": 1.0}))
    band_se = spot.banded.band_wheelbase_stderr_m["spot"]
    assert spot.geometry.wheelbase_m == pytest.approx(spot.banded.band_wheelbase_m["spot"])
    assert spot.stderr["wheelbase_m"] == pytest.approx(band_se, rel=1e-9)
    assert spot.uncertainty.startswith("cluster-robust")


def test_a_motion_mix_in_bands_the_runs_did_not_measure_is_refused(runs):
    """Issue 20.7: a mix turning in a band no run excites used to take the nearest band's
    wheelbase and print 'RMS 0.00 deg per turn'."""
    square = [("straight", 1.0), ("spin", math.pi / 2)] * 4
    spins = [banded_run(f"s{i}", square) for i in range(4)]
    for model in ("constant", "banded"):
        settings = TrajectorySettings(wheelbase_model=model, motion_mix={"spot": 0.2, "wide": 0.8})
        with pytest.raises(InputError, match="did not measure how the robot turns") as exc:
            fit_trajectory_bands(spins, REFERENCE, settings)
        assert "wide" in str(exc.value) and "excited here: spot" in str(exc.value)
    # the runs' own mix (no mix stated) is not refused: the model assigns their straight band
    own = fit_banded(runs, REFERENCE)
    assert own.motion_mix is not None and own.motion_mix.wheelbase_stderr_m is not None


def test_wheelbase_for_a_mix():
    b1, b2 = 0.200, 0.204
    c = wheelbase_for_mix({"spot": b1, "wide": b2}, {"spot": 0.5, "wide": 0.5})
    # minimiser of sum w (1 - b_j / b)^2: b = sum w b_j^2 / sum w b_j
    assert c.wheelbase_m == pytest.approx((b1**2 + b2**2) / (b1 + b2))
    # spot turns (true b smaller) turn more than the odometry with the single value reads:
    # actual - odometric > 0; the arcs less
    assert c.heading_error_deg_per_turn["spot"] > 0 > c.heading_error_deg_per_turn["wide"]
    assert c.rms_heading_error_deg_per_turn == pytest.approx(360 * 0.01, rel=0.01)
    one = wheelbase_for_mix({"spot": b1, "wide": b2}, {"spot": 1.0})
    assert one.wheelbase_m == pytest.approx(b1, rel=1e-12)
    assert one.rms_heading_error_deg_per_turn == pytest.approx(0, abs=1e-9)
    with pytest.raises(CalibrationError, match="has an effective-wheelbase estimate"):
        wheelbase_for_mix({"spot": b1}, {"tight": 1.0})


@pytest.mark.parametrize(
    "text, msg",
    [
        ("spot", "BAND=SHARE"),
        ("curly=1", "BAND=SHARE"),
        ("spot=-1", ">= 0"),
        ("spot=0", "not all be 0"),
        ("spot=1,spot=2", "twice"),
        ("spot=x", "not a number"),
    ],
)
def test_motion_mix_parsing(text, msg):
    with pytest.raises(CalibrationError, match=msg):
        parse_motion_mix(text)
    assert parse_motion_mix("spot=1,wide=3") == {"spot": 0.25, "wide": 0.75}


def test_optiodom_arcs_turn_less_than_spot_turns(realdata):
    """The real robot: circles (both sessions) have a larger effective wheelbase than the spot
    turns of the squares, with 95 % intervals apart (README, docs/real-robots.md)."""
    from odocal.io.recordings import load_recordings

    base = realdata / "optiodom_diff"
    ref = WheelGeometry(0.083695, 0.083743, 0.201428)  # odocal fit of squares + Ivanjko
    squares = effective_wheelbase(load_recordings([base / "square"]), ref)
    circles = effective_wheelbase(load_recordings([base / "circular"]), ref)
    spot = squares.band("spot")
    assert squares.excited == ("spot",)
    assert spot.wheelbase_m == pytest.approx(0.20117, abs=3e-5)
    for name in ("tight", "wide"):
        arc = circles.band(name)
        assert arc.excited
        assert arc.ci95_m[0] > spot.ci95_m[1]
        assert 0.003 < arc.wheelbase_m / spot.wheelbase_m - 1 < 0.007
