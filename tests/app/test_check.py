"""``odocal.app.check`` on its typed result: what the recorded motion lets a fit see, on the real
OptiOdom runs and on runs built here; the noise it assumed and where it came from."""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from odocal.app.check import check, check_loaded, noise_model
from odocal.calibration.identifiability import NoiseModel
from odocal.core.model import MeasurementNoise, NonSystematicError
from odocal.errors import InputError
from odocal.presets import PRESETS
from tests.support.recorded_runs import NOMINAL, make_run, mixed_runs


def _ivanjko(realdata, runs):
    d = realdata / "optiodom_diff" / "ivanjko" / "250620201738"
    return [d / f"250620201738_run-{i:02d}.csv" for i in runs]


def test_straight_runs_alone_are_not_enough(realdata):
    res = check(_ivanjko(realdata, range(1, 6)))
    c = res.check
    assert c.ok is False and res.recordings == 5
    assert c.flagged("straight-only")
    assert any("turns in both directions" in s for s in c.suggestions)
    # the wheelbase is the parameter a straight line cannot see
    assert c.stderr["wheelbase_m"] > 100 * c.stderr["wheel_diameter_right_m"]
    d = res.as_dict()
    assert d["ok"] is False and "straight-only" in {g["code"] for g in d["degeneracies"]}


def test_a_whole_data_set_is_enough(realdata):
    res = check(_ivanjko(realdata, range(1, 16)))
    assert res.check.ok is True and res.check.condition_number < 100
    assert res.noise_source.startswith("default")
    assert res.as_dict()["noise_source"] == res.noise_source


def test_runs_that_turn_both_ways_are_enough_and_spins_alone_are_not():
    res = check_loaded(mixed_runs(), NOMINAL)
    assert res.check.ok and res.recordings == 6
    assert set(res.check.stderr) == {
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
    }
    spins = [make_run("spin-ccw", [("spin", math.pi)]), make_run("spin-cw", [("spin", -math.pi)])]
    assert not check_loaded(spins, NOMINAL).check.ok


def test_the_noise_is_the_robot_s_where_it_gives_it():
    default = NoiseModel()
    assert noise_model(None)[0] == default
    robot = PRESETS["paper-experiment"]  # wheel noise, a perfect instrument
    assert robot.measurement.is_zero and not robot.nonsystematic.is_zero
    # a part left at zero keeps the default
    assert noise_model(robot) == (
        NoiseModel(robot.nonsystematic, default.measurement),
        "ROBOT.yaml nonsystematic, default tracker noise",
    )
    tracked = replace(robot, measurement=MeasurementNoise.from_degrees(0.002, 0.3))
    assert noise_model(tracked) == (
        NoiseModel(tracked.nonsystematic, tracked.measurement),
        "ROBOT.yaml nonsystematic, ROBOT.yaml measurement",
    )
    quiet = replace(robot, nonsystematic=NonSystematicError())
    assert noise_model(quiet) == (default, "default k, default tracker noise")


def test_runs_without_a_nominal_geometry_need_a_robot(tmp_path):
    run = tmp_path / "run.csv"
    run.write_text(
        "time_s,wheel_right_rad,wheel_left_rad\n"
        + "".join(f"{i / 10},{i / 5},{i / 5}\n" for i in range(20))
    )
    with pytest.raises(InputError, match="--robot"):
        check(run)
