"""Recorded runs built from motion primitives (straight, spin, arc) as a controller with a
believed geometry commands them, the ground truth dead-reckoned with the true geometry: the fits'
test data."""

from __future__ import annotations

import math

import numpy as np

from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording

NOMINAL = WheelGeometry(0.15, 0.15, 0.385)
TRUE = NOMINAL.with_systematic(SystematicError(E_b=1.02, E_d=1.004, E_s=0.99))


def wheel_angles(primitives, believed: WheelGeometry, step_m=0.01):
    """Cumulative wheel angles (rad) of an open-loop run of (kind, a, b) primitives as the
    controller with ``believed`` geometry commands them: ('straight', d), ('spin', psi),
    ('arc', rho, psi)."""
    r_list, l_list = [np.zeros(1)], [np.zeros(1)]
    b = believed.wheelbase_m
    for p in primitives:
        if p[0] == "straight":
            s_r = s_l = p[1]
        elif p[0] == "spin":
            s_r, s_l = p[1] * b / 2, -p[1] * b / 2
        else:
            rho, psi = p[1], p[2]
            s_r, s_l = (rho + b / 2) * psi, (rho - b / 2) * psi
        n = max(2, int(math.ceil(max(abs(s_r), abs(s_l)) / step_m)))
        f = np.arange(1, n + 1) / n
        r_list.append(r_list[-1][-1] + f * 2 * s_r / believed.diameter_right_m)
        l_list.append(l_list[-1][-1] + f * 2 * s_l / believed.diameter_left_m)
    return np.concatenate(r_list), np.concatenate(l_list)


def make_run(name, primitives, true=TRUE, believed=NOMINAL, label=None, noise=None, side=None):
    right, left = wheel_angles(primitives, believed)
    gt = dead_reckon(right, left, true)
    if noise is not None:
        gt = gt + noise
    return Recording(
        name=name,
        time_s=np.arange(len(right)) * 0.05,
        wheel_angle_right_rad=right,
        wheel_angle_left_rad=left,
        ground_truth=gt,
        ran_with=believed,
        label=label,
        meta={"side_m": side} if side else {},
    )


def square(direction, side=2.0):
    s = 1 if direction == "ccw" else -1
    return [p for _ in range(4) for p in (("straight", side), ("spin", s * math.pi / 2))]


def mixed_runs(true=TRUE):
    return [
        make_run("straight", [("straight", 3.0)], true),
        make_run("spin-ccw", [("spin", math.pi)], true),
        make_run("arc-cw", [("arc", 1.0, -math.pi)], true),
        make_run("arc-ccw", [("arc", 0.7, 1.5 * math.pi), ("straight", 1.0)], true),
        make_run("sq-cw", square("cw"), true),
        make_run("sq-ccw", square("ccw"), true),
    ]


def values(g):
    return np.array([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m], dtype=float)
