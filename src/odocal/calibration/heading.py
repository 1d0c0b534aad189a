"""The heading-error method (Jung & Chung 2012; the paper's calibration method).

Calibrates E_b and E_d from the mean final HEADING errors of CW and CCW runs on a regular N-gon,
with no small-angle approximation (exact under the model of docs/conventions.md):

    alpha = (eps_cw - eps_ccw) / (2N)     per-turn under-rotation (rad)
    beta  = (eps_cw + eps_ccw) / (2N)     per-leg curvature (rad)
    E_b   = (2 pi/N) / (2 pi/N - alpha)
    q     = beta E_b b / (2 L),  E_d = (1 + q) / (1 - q)

Only a heading sensor is needed (a gyro suffices).
"""

from __future__ import annotations

import math

import numpy as np

from ..core.model import WheelGeometry
from ..core.plausibility import wrap_heading_error
from ..core.runs import EndPoseRuns, check_both_directions
from .result import CalibrationResult
from .uncertainty import spread_uncertainty

__all__ = ["heading_factors", "calibrate_heading"]


def heading_factors(
    theta_cw_rad: float | np.ndarray,
    theta_ccw_rad: float | np.ndarray,
    sides: int,
    side_m: float | np.ndarray,
    wheelbase_m: float | np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """E_b, E_d from mean final heading errors (rad); arrays broadcast (vectorised design).

    ``wheelbase_m`` is the wheelbase the robot ran with (b in the equations above).
    Returns NaN where an equation is undefined.
    """
    turn = 2.0 * math.pi / sides
    alpha = (np.asarray(theta_cw_rad) - theta_ccw_rad) / (2 * sides)
    beta = (np.asarray(theta_cw_rad) + theta_ccw_rad) / (2 * sides)
    with np.errstate(divide="ignore", invalid="ignore"):
        E_b = np.where(turn - alpha > 0, turn / (turn - alpha), np.nan)
        q = beta * E_b * wheelbase_m / (2.0 * np.asarray(side_m))
        E_d = np.where(np.abs(q) < 1, (1.0 + q) / (1.0 - q), np.nan)
    return E_b, E_d


def calibrate_heading(
    runs: EndPoseRuns, sides: int, side_m: float, ran_with: WheelGeometry
) -> CalibrationResult:
    """The heading-error method from measured runs (see module docstring), with standard errors
    from the spread of the runs (:mod:`odocal.calibration.uncertainty`)."""
    check_both_directions(runs)
    th_cw = runs.mean("cw")[2]
    th_ccw = runs.mean("ccw")[2]
    E_b, E_d = heading_factors(th_cw, th_ccw, sides, side_m, ran_with.wheelbase_m)
    # spread about the circular means (the deviations wrapped, so a full turn is no spread)
    groups = [
        (d, (m + wrap_heading_error(runs.select(d)[:, 2] - m))[:, None])
        for d, m in (("cw", th_cw), ("ccw", th_ccw))
    ]
    unc = spread_uncertainty(
        lambda z: heading_factors(z[0], z[1], sides, side_m, ran_with.wheelbase_m),
        groups,
        ran_with,
        center=np.array([th_cw, th_ccw]),
    )
    return CalibrationResult.from_factors(
        "heading",
        float(E_b),
        float(E_d),
        ran_with,
        unc,
        sides=sides,
        side_m=side_m,
        runs_cw=runs.count("cw"),
        runs_ccw=runs.count("ccw"),
        mean_theta_cw_rad=float(th_cw),
        mean_theta_ccw_rad=float(th_ccw),
    )
