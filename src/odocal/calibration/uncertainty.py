"""Uncertainty of a calibration from the run-to-run spread (first order, the delta method).

A calibration from CW and CCW runs is a function g(z) of the MEAN measured quantities z of each
direction (mean final headings for the heading-error method, mean final positions for UMBmark,
mean radii for BCPT). The runs of one direction are independent repetitions, so the covariance of
their mean is S_d = C_d / n_d, with C_d the sample covariance (ddof = 1) of the n_d runs. The
instrument's noise is in the spread, so it is in the uncertainty too. To first order

    Cov(E_b, E_d) = sum_d J_d S_d J_d^T,          J_d = dg/dz_d (numeric, central differences)

and the corrected geometry (D_R, D_L, b) = h(E_b, E_d) (``WheelGeometry.corrected``) gets
H Cov H^T. The 95 % intervals are value +- t(0.975, nu) x stderr, with nu the Welch-Satterthwaite
degrees of freedom of the two directions' contributions: with 5 runs per direction nu is 4 to 8,
and t is 2.3 to 2.8, not 1.96. A direction needs at least 2 runs for a spread.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.jsonable import finite_or_none
from ..core.model import WheelGeometry
from ..core.stats import student_t_quantile

__all__ = ["NAMES", "CalibrationUncertainty", "spread_uncertainty"]

#: The quantities an uncertainty covers, in order.
NAMES = ("E_b", "E_d", "wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


@dataclass(frozen=True)
class CalibrationUncertainty:
    """Standard errors, degrees of freedom and 95 % intervals of E_b, E_d and the corrected
    geometry (m), from the spread of the runs.

    Attributes
    ----------
    values : ndarray, shape (5,)
        E_b, E_d, D_R (m), D_L (m), b (m), in the order of :data:`NAMES`.
    stderr : ndarray, shape (5,)
    dof : ndarray, shape (5,)
        Welch-Satterthwaite degrees of freedom of each standard error.
    covariance : ndarray, shape (5, 5)
    runs : dict of str to int
        Runs per direction behind the spread.
    """

    values: np.ndarray
    stderr: np.ndarray
    dof: np.ndarray
    covariance: np.ndarray
    runs: dict

    def ci95(self) -> dict[str, tuple[float, float]]:
        """name -> (low, high): value +- t(0.975, dof) stderr."""
        out = {}
        for name, v, s, nu in zip(NAMES, self.values, self.stderr, self.dof, strict=True):
            q = student_t_quantile(0.975, float(nu)) if np.isfinite(nu) and nu > 0 else math.nan
            out[name] = (float(v - q * s), float(v + q * s))
        return out

    def as_dict(self) -> dict:
        """JSON-ready: standard errors, 95 % intervals and degrees of freedom by name (non-finite
        values as None), the runs per direction and the method."""
        ci = self.ci95()
        return {
            "stderr": {n: finite_or_none(s) for n, s in zip(NAMES, self.stderr, strict=True)},
            "ci95": {n: [finite_or_none(ci[n][0]), finite_or_none(ci[n][1])] for n in NAMES},
            "dof": {n: finite_or_none(v) for n, v in zip(NAMES, self.dof, strict=True)},
            "runs": dict(self.runs),
            "method": "delta method on the run-to-run spread of the CW and CCW means; 95 % "
            "intervals with Student t at Welch-Satterthwaite dof",
        }


def _jacobian(fun: Callable[[np.ndarray], np.ndarray], z: np.ndarray) -> np.ndarray:
    cols = []
    for k in range(z.size):
        h = 1e-6 * max(1.0, abs(float(z[k])))
        dz = np.zeros_like(z)
        dz[k] = h
        cols.append((fun(z + dz) - fun(z - dz)) / (2.0 * h))
    return np.stack(cols, axis=-1)


def spread_uncertainty(
    factors: Callable[[np.ndarray], tuple],
    groups: Sequence[tuple[str, np.ndarray]],
    ran_with: WheelGeometry,
    center: np.ndarray | None = None,
) -> CalibrationUncertainty | None:
    """The uncertainty (module docstring) of ``factors(z) -> (E_b, E_d)``.

    ``groups``: (direction, samples of shape (n, k)) per direction; z is the concatenation of the
    groups' column means, or ``center`` (e.g. circular means of headings) when given. Returns
    None when a direction has fewer than 2 runs (no spread).
    """
    if any(len(s) < 2 for _, s in groups):
        return None
    if center is None:
        z = np.concatenate([np.asarray(s, dtype=float).mean(axis=0) for _, s in groups])
    else:
        z = np.asarray(center, dtype=float).ravel()

    def full(zz: np.ndarray) -> np.ndarray:
        E_b, E_d = (float(v) for v in factors(zz))
        g = ran_with.corrected(E_b, E_d)
        return np.array(
            [E_b, E_d, float(g.diameter_right_m), float(g.diameter_left_m), float(g.wheelbase_m)]
        )

    values = full(z)
    J = _jacobian(full, z)
    cov = np.zeros((len(NAMES), len(NAMES)))
    parts = []
    start = 0
    for _, s in groups:
        s = np.asarray(s, dtype=float)
        k = s.shape[1]
        Jd = J[:, start : start + k]
        Sd = np.atleast_2d(np.cov(s, rowvar=False, ddof=1)) / len(s)
        part = Jd @ Sd @ Jd.T
        cov += part
        parts.append((np.diag(part), len(s)))
        start += k
    var = np.diag(cov)
    with np.errstate(divide="ignore", invalid="ignore"):
        denom = sum(p**2 / (n - 1) for p, n in parts)
        dof = np.where(denom > 0, var**2 / denom, math.inf)
    runs = {d: len(s) for d, s in groups}
    return CalibrationUncertainty(values, np.sqrt(np.maximum(var, 0.0)), dof, cov, runs)
