"""UMBmark (Borenstein & Feng 1996): squares only, small-angle equations.

From the mean final POSITION errors of CW and CCW runs on an L x L square:

    x-form: alpha = (x_cw + x_ccw)/(-4L),  beta = (x_cw - x_ccw)/(-4L)
    y-form: alpha = (y_cw - y_ccw)/(-4L),  beta = (y_cw + y_ccw)/(-4L)
    mean:   the average of the two (their approximation errors have opposite signs)
    E_b = (pi/2)/(pi/2 - alpha),  E_d = (L + b' sin(beta/2)) / (L - b' sin(beta/2))

b' is E_b b (default; the exact curvature relation uses the true wheelbase, and it is what the
published OptiOdom UMBmark results use) or b as in the book (``ed_wheelbase='nominal'``).
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import ModelError, WheelGeometry
from ..core.runs import EndPoseRuns, check_both_directions
from .result import CalibrationResult
from .uncertainty import spread_uncertainty

__all__ = ["umbmark_factors", "calibrate_umbmark", "UMBMARK_FORMS"]

UMBMARK_FORMS = ("x", "y", "mean")


def umbmark_factors(
    cw_xy: ArrayLike,
    ccw_xy: ArrayLike,
    side_m: float | np.ndarray,
    wheelbase_m: float | np.ndarray,
    form: str = "mean",
    ed_wheelbase: str = "calibrated",
) -> tuple[np.ndarray, np.ndarray]:
    """E_b, E_d from mean final position errors; ``cw_xy``/``ccw_xy`` are (..., 2) arrays (m).

    Returns NaN where an equation is undefined.
    """
    if form not in UMBMARK_FORMS:
        raise ModelError(f"UMBmark form must be one of {', '.join(UMBMARK_FORMS)}, got {form!r}")
    if ed_wheelbase not in ("calibrated", "nominal"):
        raise ModelError(f"ed_wheelbase must be 'calibrated' or 'nominal', got {ed_wheelbase!r}")
    cw = np.asarray(cw_xy, dtype=float)
    ccw = np.asarray(ccw_xy, dtype=float)
    k = -4.0 * np.asarray(side_m, dtype=float)
    alpha_x = (cw[..., 0] + ccw[..., 0]) / k
    beta_x = (cw[..., 0] - ccw[..., 0]) / k
    alpha_y = (cw[..., 1] - ccw[..., 1]) / k
    beta_y = (cw[..., 1] + ccw[..., 1]) / k
    alpha, beta = {
        "x": (alpha_x, beta_x),
        "y": (alpha_y, beta_y),
        "mean": (0.5 * (alpha_x + alpha_y), 0.5 * (beta_x + beta_y)),
    }[form]
    half_pi = 0.5 * math.pi
    with np.errstate(divide="ignore", invalid="ignore"):
        E_b = np.where(half_pi - alpha > 0, half_pi / (half_pi - alpha), np.nan)
        b = wheelbase_m * (E_b if ed_wheelbase == "calibrated" else 1.0)
        bs = b * np.sin(0.5 * beta)
        E_d = np.where(np.abs(bs) < side_m, (side_m + bs) / (side_m - bs), np.nan)
    return E_b, E_d


def calibrate_umbmark(
    runs: EndPoseRuns,
    side_m: float,
    ran_with: WheelGeometry,
    form: str = "mean",
    ed_wheelbase: str = "calibrated",
) -> CalibrationResult:
    """UMBmark from measured square runs (see module docstring)."""
    check_both_directions(runs)
    cw = runs.mean("cw")[:2]
    ccw = runs.mean("ccw")[:2]
    E_b, E_d = umbmark_factors(cw, ccw, side_m, ran_with.wheelbase_m, form, ed_wheelbase)
    b = ran_with.wheelbase_m
    unc = spread_uncertainty(
        lambda z: umbmark_factors(z[0:2], z[2:4], side_m, b, form, ed_wheelbase),
        [(d, runs.select(d)[:, :2]) for d in ("cw", "ccw")],
        ran_with,
    )
    return CalibrationResult.from_factors(
        "umbmark",
        float(E_b),
        float(E_d),
        ran_with,
        unc,
        form=form,
        side_m=side_m,
        runs_cw=runs.count("cw"),
        runs_ccw=runs.count("ccw"),
        mean_xy_cw_m=cw.tolist(),
        mean_xy_ccw_m=ccw.tolist(),
    )
