"""Model values: validation and the true/corrected geometry relations of model.md."""

import numpy as np
import pytest

from odocal.core.model import (
    MeasurementNoise,
    ModelError,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from odocal.core.tracks import circle, out_and_back, polygon, straight_line


@pytest.mark.parametrize(
    "make",
    [
        lambda: WheelGeometry(0.0, 0.15, 0.4),
        lambda: WheelGeometry(0.15, -0.15, 0.4),
        lambda: WheelGeometry(0.15, 0.15, float("nan")),
        lambda: WheelGeometry(0.15, float("inf"), 0.4),
        lambda: SystematicError(E_b=0.0),
        lambda: SystematicError(E_d=float("nan")),
        lambda: NonSystematicError(k_r_m=-1e-6),
        lambda: MeasurementNoise(sigma_xy_m=float("inf")),
        lambda: polygon(2, 1.0, "cw"),
        lambda: polygon(4, 0.0, "cw"),
        lambda: polygon(4, 1.0, "left"),
        lambda: straight_line(-1.0),
        lambda: circle(0.0, "cw"),
    ],
)
def test_invalid_values_are_rejected(make):
    with pytest.raises(ModelError):
        make()


def test_true_geometry_from_systematic_errors():
    nominal = WheelGeometry.symmetric(0.15, 0.385)
    t = nominal.with_systematic(SystematicError(E_b=1.028, E_d=0.999, E_s=1.01))
    assert t.diameter_ratio == pytest.approx(0.999)
    assert t.mean_diameter_m == pytest.approx(0.15 * 1.01)
    assert t.wheelbase_m == pytest.approx(0.385 * 1.028)


def test_corrected_keeps_mean_and_multiplies_ratio():
    ran = WheelGeometry(0.151, 0.149, 0.38)
    c = ran.corrected(1.02, 1.004)
    assert c.diameter_ratio == pytest.approx(ran.diameter_ratio * 1.004, rel=1e-12)
    assert c.wheelbase_m == pytest.approx(0.38 * 1.02)
    # for a symmetric belief the mean diameter is kept exactly
    s = WheelGeometry.symmetric(0.15, 0.4).corrected(1.0, 1.01)
    assert s.mean_diameter_m == pytest.approx(0.15, rel=1e-12)


def test_batched_geometry_broadcasts_and_takes():
    g = WheelGeometry(np.array([0.15, 0.16]), 0.15, 0.4)
    assert g.take(1).diameter_right_m == pytest.approx(0.16)
    assert np.shape(g.corrected(np.array([1.0, 1.1]), 1.0).wheelbase_m) == (2,)


def test_tracks():
    sq = polygon(4, 2.0, "ccw")
    assert len(sq.segments) == 8 and sq.travel_m == pytest.approx(8.0)
    assert sq.rotation_rad == pytest.approx(2 * np.pi)
    assert polygon(3, 1.0, "cw").rotation_rad == pytest.approx(-2 * np.pi)
    ob = out_and_back(5.0)
    assert ob.travel_m == pytest.approx(10.0) and ob.rotation_rad == 0
    c = circle(1.0, "cw", turns=2)
    assert c.travel_m == pytest.approx(4 * np.pi) and c.rotation_rad == pytest.approx(-4 * np.pi)
    # believed wheel travel of a left arc: the right wheel is the outer one
    s_r, s_l = circle(1.0, "ccw").segments[0].wheel_travel(0.4)
    assert s_r == pytest.approx(2 * np.pi * 1.2) and s_l == pytest.approx(2 * np.pi * 0.8)


def test_robot_believed_defaults_to_nominal():
    nominal = WheelGeometry.symmetric(0.15, 0.385)
    r = Robot(nominal)
    assert r.believed_geometry is nominal
    other = WheelGeometry.symmetric(0.149, 0.39)
    assert r.with_believed(other).believed_geometry is other
