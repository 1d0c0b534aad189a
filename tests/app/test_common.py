"""What the commands share (odocal.app.common): the robot they are given, the paths they read,
the refusal of an absurd calibration."""

from __future__ import annotations

from pathlib import Path

import pytest

from odocal.app.common import (
    input_paths,
    make_robot,
    optional_robot,
    refuse_absurd,
    resolve_robot,
    robot_label,
    write_exports,
)
from odocal.core.model import WheelGeometry
from odocal.errors import CalibrationError, InputError
from odocal.io.outputs import OutputPlan
from odocal.io.robot_file import load_robot, params_yaml
from odocal.presets import DEFAULT_ROBOT, PRESETS

ROBOT_YAML = """\
wheel_diameter_m: 0.15
wheelbase_m: 0.385
systematic: {E_b: 1.028, E_d: 0.999}
nonsystematic: {k_r_m: 1.69e-6, k_l_m: 1.69e-6}
measurement: {sigma_xy_m: 0.001, sigma_theta_deg: 0.1}
"""


def test_make_robot_is_the_robot_file_of_the_same_values(tmp_path):
    path = tmp_path / "robot.yaml"
    path.write_text(ROBOT_YAML)
    made = make_robot(
        0.15, 0.385, E_b=1.028, E_d=0.999, k_r_m=1.69e-6, sigma_xy_m=0.001, sigma_theta_deg=0.1
    )
    assert made == load_robot(path)
    # the file's checks: a diameter in millimetres against a wheelbase in metres cannot pass
    with pytest.raises(InputError, match="wheelbase_m"):
        make_robot(150.0, 0.385)


def test_the_robot_given_and_the_parameters_it_ran_with(tmp_path):
    assert resolve_robot() == PRESETS[DEFAULT_ROBOT]
    assert optional_robot(None) is None
    ran_with = WheelGeometry(0.151, 0.149, 0.39)
    r = resolve_robot("paper-experiment", ran_with)
    assert r.nominal == PRESETS["paper-experiment"].nominal and r.believed_geometry == ran_with
    params = tmp_path / "params.yaml"
    params.write_text(params_yaml(ran_with))
    assert resolve_robot("paper-experiment", params).believed_geometry == ran_with
    assert robot_label(None) == f"{DEFAULT_ROBOT} (built-in)"
    assert robot_label("robot.yaml", params) == f"robot.yaml running with {params}"
    assert robot_label(r) == "given robot"


def test_only_file_system_paths_are_inputs():
    g = WheelGeometry(0.15, 0.15, 0.385)
    assert input_paths(None, "paper-fig5", g, PRESETS["paper-fig5"], ["a.csv", ("b", None)]) == [
        Path("a.csv"),
        Path("b"),
    ]


def test_a_calibration_far_from_nominal_is_refused_unless_forced():
    nominal = WheelGeometry(0.15, 0.15, 0.385)
    assert refuse_absurd(WheelGeometry(0.151, 0.149, 0.39), nominal, force=False) == []
    absurd = WheelGeometry(0.15, 0.15, 0.6)
    with pytest.raises(CalibrationError, match="--force"):
        refuse_absurd(absurd, nominal, force=False)
    (problem,) = refuse_absurd(absurd, nominal, force=True)
    assert "wheelbase" in problem


def test_a_calibration_that_is_no_robot_is_refused_without_a_nominal_and_never_written(tmp_path):
    # 0.7 mm wheels on an 88 mm wheelbase: no nominal to compare with, but the robot-file reader
    # would refuse the PARAMS.yaml; with --force it is reported, still never written
    geometry = WheelGeometry(0.0007, 0.0007, 0.088)
    with pytest.raises(CalibrationError, match="not a plausible robot.*IMU"):
        refuse_absurd(geometry, None, force=False, hint="check the IMU")
    (problem,) = refuse_absurd(geometry, None, force=True)
    assert "0.00795 times the wheelbase" in problem
    out = tmp_path / "PARAMS.yaml"
    plan = OutputPlan([])
    plan.file(out, "--out")
    with pytest.raises(CalibrationError, match="nothing written"):
        write_exports(plan, geometry, None, out)
    assert not out.exists()


def test_exports_written_despite_doubts_say_so(tmp_path):
    # every route passes what --force accepted (its absurd-result or blind-log messages)
    from odocal.app.common import register_exports
    from odocal.io.robot_file import load_params

    g, nom = WheelGeometry(0.051, 0.050, 0.33), WheelGeometry.symmetric(0.050, 0.25)
    doubts = ("wheelbase_m = 0.33 m is +32 % from nominal 0.25 m: absurd for a calibration",)
    out, ros2 = tmp_path / "p.yaml", tmp_path / "dd.yaml"
    plan = OutputPlan([])
    register_exports(plan, out, ros2)
    write_exports(plan, g, nom, out, ros2, doubts=doubts)
    for path in (out, ros2):
        text = path.read_text()
        assert "# NOT TO BE TRUSTED: written with --force despite:" in text
        assert "#   - wheelbase_m = 0.33 m is +32 %" in text
    assert "trusted: false" in out.read_text()
    assert load_params(out).wheelbase_m == pytest.approx(0.33)
    # and a trusted one carries neither
    plan = OutputPlan([])
    register_exports(plan, tmp_path / "q.yaml")
    write_exports(plan, g, nom, tmp_path / "q.yaml")
    assert "TRUSTED" not in (tmp_path / "q.yaml").read_text()
