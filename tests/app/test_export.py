"""``odocal.app.export.export``: a calibration of any command, or a calibrated geometry, written
as PARAMS.yaml and the ros2_control file through the one export path."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from odocal.app.calibrate import calibrate
from odocal.app.common import make_robot
from odocal.app.export import export
from odocal.app.simulate import simulate
from odocal.calibration.linear import fit_linear
from odocal.core.model import WheelGeometry
from odocal.errors import InputError
from odocal.io.robot_file import load_params
from odocal.io.ros2_export import read_ros2_params
from tests.support.recorded_runs import NOMINAL, TRUE, mixed_runs, values


def test_a_geometry_exports_with_the_nominal_base_values(tmp_path):
    cal = WheelGeometry(0.1497, 0.1503, 0.3911)
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    written = export(cal, ros2=ros2, out=out, nominal=NOMINAL, controller_name="my_ctrl")
    assert set(written) == {out, ros2}
    # nine significant digits in PARAMS.yaml; the ros2_control file reproduces the geometry
    np.testing.assert_allclose(values(load_params(out)), values(cal), rtol=1e-8)
    np.testing.assert_allclose(values(read_ros2_params(ros2, "my_ctrl")), values(cal), rtol=1e-12)
    doc = yaml.safe_load(ros2.read_text())["my_ctrl"]["ros__parameters"]
    assert doc["wheel_separation"] == NOMINAL.wheelbase_m  # the calibration is in the multipliers
    assert doc["wheel_radius"] == NOMINAL.mean_diameter_m / 2


def test_a_calibration_exports_the_file_its_command_writes(tmp_path):
    robot = make_robot(0.15, 0.385, E_b=1.028, E_d=0.999)
    runs = tmp_path / "runs.csv"
    simulate(robot, runs=3, seed=2, out=runs)
    res = calibrate(runs, robot, ros2=tmp_path / "by-calibrate.yaml")
    (path,) = export(res, ros2=tmp_path / "by-export.yaml")  # the nominal it carries
    assert path.read_bytes() == (tmp_path / "by-calibrate.yaml").read_bytes()
    # a fit of any estimator (a GeometryFit) exports its geometry
    lin = fit_linear(mixed_runs(), NOMINAL)
    (params,) = export(lin, out=tmp_path / "linear.yaml")
    np.testing.assert_allclose(values(load_params(params)), values(TRUE), rtol=1e-8)


def test_nothing_to_export_or_no_calibration_is_refused(tmp_path):
    with pytest.raises(InputError, match="nothing to export"):
        export(WheelGeometry(0.15, 0.15, 0.385))
    with pytest.raises(InputError, match="cannot export a str"):
        export("params.yaml", out=tmp_path / "p.yaml")
    with pytest.raises(InputError, match="nominal geometry"):
        export(WheelGeometry(0.15, 0.15, 0.385), ros2=tmp_path / "r.yaml")
    assert list(tmp_path.iterdir()) == []
