"""Routes' answers compared in combined standard errors (calibration.cross_check): only what
both routes measured; a held parameter is never compared, tied diameters through their mean."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.cross_check import KEYS, MAX_Z, MEAN_DIAMETER, CrossCheck, cross_checks
from odocal.calibration.route_answer import route_answer
from odocal.core.model import WheelGeometry

SE = (1e-3, 1e-3, 2e-3)


def test_every_pair_on_every_shared_quantity():
    a = route_answer("slam", "full", WheelGeometry(0.100, 0.100, 0.500), SE)
    b = route_answer("scan", "full", WheelGeometry(0.101, 0.100, 0.490), SE)
    c = route_answer("trajectory", "full", WheelGeometry(0.100, 0.100, 0.500), (None, 1e-3, 2e-3))
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
    a = route_answer("slam", "full", WheelGeometry(0.1, 0.1, 0.5), (0.0, 0.0, None))
    b = route_answer("scan", "full", WheelGeometry(0.1, 0.1, 0.5), (0.0, 1e-3, 1e-3))
    assert [x.quantity for x in cross_checks([a, b])] == [KEYS[1]]
    assert cross_checks([a]) == ()
    assert CrossCheck(("a", "b"), KEYS[0], -MAX_Z).agree


def test_a_held_wheelbase_is_no_measurement():
    # the MIT half-1 case: the scan route settled on the 'scale' model, which holds b at the
    # nominal 0.5 m with a standard error of 0; the SLAM route measured 0.4868 +- 0.0043 m
    slam = route_answer("slam", "full", WheelGeometry(0.8140, 0.8178, 0.48682),
                        (2.29e-3, 2.80e-3, 4.28e-3))  # fmt: skip
    scan = route_answer("scan", "scale", WheelGeometry(0.8161, 0.8161, 0.5),
                        (1.94e-3, 1.94e-3, 0.0))  # fmt: skip
    assert scan.parameters[2].status == "held" and scan.parameters[2].std_error is None
    assert scan.held == ("wheelbase_m",)
    checks = cross_checks([slam, scan])
    assert "wheelbase_m" not in [x.quantity for x in checks]
    # the tied diameters are compared through their mean only, with the full fit's covariance
    cov = np.diag([2.29e-3, 2.80e-3, 4.28e-3]) ** 2
    slam = route_answer("slam", "full", slam.geometry, slam.stderr, cov)
    (x,) = cross_checks([slam, scan])
    assert x.quantity == MEAN_DIAMETER
    se_slam = 0.5 * math.hypot(2.29e-3, 2.80e-3)
    assert x.z == pytest.approx((0.5 * (0.8140 + 0.8178) - 0.8161) / math.hypot(se_slam, 1.94e-3))


def test_the_gyro_is_left_out_when_a_route_measured_the_diameters():
    gyro = route_answer("gyro", "heading-ratio", WheelGeometry(0.1, 0.1, 0.6), (None, None, 1e-3))
    slam = route_answer("slam", "full", WheelGeometry(0.1, 0.1, 0.5), SE)
    scan = route_answer("scan", "full", WheelGeometry(0.1, 0.1, 0.5), SE)
    assert all("gyro" not in x.routes for x in cross_checks([slam, gyro, scan]))
    # two gyro answers compare their turning
    other = route_answer("gyro", "heading-ratio", WheelGeometry(0.1, 0.1, 0.5), (None, None, 1e-3))
    (x,) = cross_checks([gyro, other])
    assert x.quantity == "wheelbase_m" and x.z == pytest.approx(0.1 / math.hypot(1e-3, 1e-3))
