"""Routes' answers compared in combined standard errors (calibration.cross_check)."""

from __future__ import annotations

import math

import pytest

from odocal.calibration.cross_check import KEYS, MAX_Z, CrossCheck, cross_checks
from odocal.core.model import WheelGeometry

SE = (1e-3, 1e-3, 2e-3)


def test_every_pair_on_every_shared_quantity():
    a = ("slam", WheelGeometry(0.100, 0.100, 0.500), SE)
    b = ("scan", WheelGeometry(0.101, 0.100, 0.490), SE)
    c = ("trajectory", WheelGeometry(0.100, 0.100, 0.500), (None, 1e-3, 2e-3))
    checks = cross_checks([a, b, c])
    assert [(x.routes, x.quantity) for x in checks] == [
        (("slam", "scan"), KEYS[0]), (("slam", "scan"), KEYS[1]), (("slam", "scan"), KEYS[2]),
        (("slam", "trajectory"), KEYS[1]), (("slam", "trajectory"), KEYS[2]),
        (("scan", "trajectory"), KEYS[1]), (("scan", "trajectory"), KEYS[2]),
    ]  # fmt: skip
    first = checks[0]
    assert first.z == pytest.approx(-0.001 / math.hypot(1e-3, 1e-3))
    assert first.agree
    b_slam_scan = checks[2]
    assert b_slam_scan.z == pytest.approx(0.010 / math.hypot(2e-3, 2e-3))
    assert not b_slam_scan.agree and abs(b_slam_scan.z) > MAX_Z
    assert b_slam_scan.as_dict() == {"routes": ["slam", "scan"], "quantity": "wheelbase_m",
                                     "z": b_slam_scan.z, "agree": False}  # fmt: skip


def test_no_error_no_comparison():
    a = ("slam", WheelGeometry(0.1, 0.1, 0.5), (0.0, 0.0, None))
    b = ("scan", WheelGeometry(0.1, 0.1, 0.5), (0.0, 1e-3, 1e-3))
    assert [x.quantity for x in cross_checks([a, b])] == [KEYS[1]]
    assert cross_checks([a]) == ()
    assert CrossCheck(("a", "b"), KEYS[0], -MAX_Z).agree


def test_the_gyro_is_left_out_when_a_route_measured_the_diameters():
    gyro = ("gyro", WheelGeometry(0.1, 0.1, 0.6), (None, None, 1e-3))
    slam = ("slam", WheelGeometry(0.1, 0.1, 0.5), SE)
    scan = ("scan", WheelGeometry(0.1, 0.1, 0.5), SE)
    assert all("gyro" not in x.routes for x in cross_checks([slam, gyro, scan]))
    # two gyro answers compare their turning
    other = ("gyro", WheelGeometry(0.1, 0.1, 0.5), (None, None, 1e-3))
    (x,) = cross_checks([gyro, other])
    assert x.quantity == "wheelbase_m" and x.z == pytest.approx(0.1 / math.hypot(1e-3, 1e-3))
