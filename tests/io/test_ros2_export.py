"""The ros2_control diff_drive_controller file (io.ros2_export): nominal base values, the
calibration in the multipliers, read back exactly."""

from __future__ import annotations

import numpy as np
import pytest
import yaml

from odocal.core.model import WheelGeometry
from odocal.io.ros2_export import read_ros2_params, ros2_params_yaml
from tests.support.recorded_runs import (
    NOMINAL,
    values,
)


def test_ros2_export_reproduces_the_geometry_exactly(tmp_path):
    cal = WheelGeometry(0.1497, 0.1503, 0.3911)
    path = tmp_path / "ros2.yaml"
    path.write_text(ros2_params_yaml(cal, NOMINAL, "my_ctrl"))
    doc = yaml.safe_load(path.read_text())["my_ctrl"]["ros__parameters"]
    assert doc["wheel_separation"] == NOMINAL.wheelbase_m
    assert doc["wheel_radius"] == NOMINAL.mean_diameter_m / 2
    # effective radius = wheel_radius x multiplier, separation = wheel_separation x multiplier;
    # values are written with repr (round-trip), so the products agree to an ulp or two
    eff = read_ros2_params(path, "my_ctrl")
    np.testing.assert_allclose(values(eff), values(cal), rtol=1e-15, atol=0)
    assert 2 * doc["wheel_radius"] * doc["right_wheel_radius_multiplier"] == pytest.approx(
        cal.diameter_right_m, rel=1e-15
    )
