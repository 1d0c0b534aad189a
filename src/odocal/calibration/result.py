"""Calibration results: factors relative to the parameters a robot ran with (``CalibrationResult``)
and geometries fitted to recorded runs (``GeometryFit``)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..errors import CalibrationError
from .uncertainty import CalibrationUncertainty

__all__ = [
    "ABSURD_FRACTION",
    "CalibrationResult",
    "GeometryFit",
    "check_physical",
    "far_from_nominal",
    "stderr_dict",
]


@dataclass(frozen=True)
class CalibrationResult:
    """A calibration: E_b, E_d relative to the parameters the robot ran with, and the corrected
    geometry (those parameters composed with the correction).

    Attributes
    ----------
    method : str
    E_b, E_d : float
        Wheelbase factor and diameter ratio relative to ``ran_with`` (dimensionless).
    ran_with : WheelGeometry
        The parameters the robot used during the test runs.
    corrected : WheelGeometry
        ``ran_with.corrected(E_b, E_d)``: what to install in the robot.
    inputs : dict
        What the result was computed from (track, run counts, mean errors, form ...).
    uncertainty : CalibrationUncertainty or None
        Standard errors and 95 % intervals of E_b, E_d and ``corrected`` from the run-to-run
        spread (None with fewer than 2 runs in a direction).
    """

    method: str
    E_b: float
    E_d: float
    ran_with: WheelGeometry
    corrected: WheelGeometry
    inputs: dict = field(default_factory=dict)
    uncertainty: CalibrationUncertainty | None = None

    @classmethod
    def from_factors(
        cls,
        method: str,
        E_b: float,
        E_d: float,
        ran_with: WheelGeometry,
        uncertainty: CalibrationUncertainty | None = None,
        **inputs: Any,
    ) -> CalibrationResult:
        if not (np.all(np.isfinite(E_b)) and np.all(np.isfinite(E_d))):
            raise CalibrationError(f"{method}: the equations are undefined for these errors")
        if not (np.all(np.asarray(E_b) > 0) and np.all(np.asarray(E_d) > 0)):
            raise CalibrationError(
                f"{method}: the errors give a non-physical result (E_b={E_b}, E_d={E_d}); "
                "check the direction labels, the signs (error = actual - odometric) and the units"
            )
        return cls(
            method, E_b, E_d, ran_with, ran_with.corrected(E_b, E_d), dict(inputs), uncertainty
        )

    def as_dict(self) -> dict:
        """The JSON contract of ``odocal calibrate --json``: the factors, the corrected geometry,
        their uncertainty (``stderr``, ``ci95``, ``dof``; null without a spread) and the
        parameters the robot ran with."""
        unc = self.uncertainty.as_dict() if self.uncertainty is not None else None
        return {
            "method": self.method,
            "E_b": float(self.E_b),
            "E_d": float(self.E_d),
            **self.corrected.as_dict(),
            "stderr": None if unc is None else unc["stderr"],
            "ci95": None if unc is None else unc["ci95"],
            "dof": None if unc is None else unc["dof"],
            "ran_with": self.ran_with.as_dict(),
        }


@dataclass(frozen=True)
class GeometryFit:
    """A calibrated geometry from recorded runs.

    Attributes
    ----------
    method : str
    geometry : WheelGeometry
        Calibrated D_R, D_L (m), b (m).
    stderr : dict
        Standard errors (m) of ``wheel_diameter_right_m``, ``wheel_diameter_left_m``,
        ``wheelbase_m`` (None where not estimable).
    covariance : ndarray, shape (3, 3) or None
        Covariance of (D_R, D_L, b) in m^2.
    runs : list of str
        Runs used.
    per_run : list of dict
        Per-run residual statistics (``name``, ``rms``, ``robust_z``, ``outlier``, ...).
    outliers, excluded : list of str
        Runs flagged as outliers; runs left out of the fit (by request or --drop-outliers).
    warnings : list of str
    extras : dict
        Method-specific facts (residual kind, iterations, cost ...).
    """

    method: str
    geometry: WheelGeometry
    stderr: dict
    covariance: np.ndarray | None
    runs: list
    per_run: list = field(default_factory=list)
    outliers: list = field(default_factory=list)
    excluded: list = field(default_factory=list)
    warnings: list = field(default_factory=list)
    extras: dict = field(default_factory=dict)

    def as_dict(self) -> dict:
        """The JSON contract of ``odocal fit --json`` (plus extras)."""
        cov = None if self.covariance is None else _finite_or_none(self.covariance)
        return {
            "method": self.method,
            **self.geometry.as_dict(),
            "stderr": self.stderr,
            "runs": list(self.runs),
            "covariance_m2": cov,
            "per_run": [
                {
                    k: (None if isinstance(v, float) and not np.isfinite(v) else v)
                    for k, v in row.items()
                }
                for row in self.per_run
            ],
            "outliers": list(self.outliers),
            "excluded": list(self.excluded),
            "warnings": list(self.warnings),
            **self.extras,
        }


def _finite_or_none(a: ArrayLike) -> list:
    """Nested lists of floats with non-finite entries as None (JSON has no NaN)."""
    return [
        _finite_or_none(v) if np.ndim(v) else (float(v) if np.isfinite(v) else None)
        for v in np.asarray(a, dtype=float)
    ]


_KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def stderr_dict(cov: np.ndarray | None) -> dict:
    if cov is None:
        return dict.fromkeys(_KEYS)
    d = np.sqrt(np.clip(np.diag(cov), 0, None))
    return {k: (float(v) if np.isfinite(v) else None) for k, v in zip(_KEYS, d, strict=True)}


def check_physical(
    values: Iterable[float | np.ndarray], nominal: WheelGeometry | None, method: str
) -> list[str]:
    """Raise CalibrationError for non-positive values (the classic sign of swapped wheels);
    return warnings for values far (> 25 %) from ``nominal``."""
    d_r, d_l, b = (float(v) for v in values)
    if not all(np.isfinite([d_r, d_l, b])):
        raise CalibrationError(f"{method}: the fit did not converge to finite values")
    if d_r <= 0 or d_l <= 0 or b <= 0:
        raise CalibrationError(
            f"{method}: non-physical result D_R={d_r:.6g} m, D_L={d_l:.6g} m, b={b:.6g} m; the "
            "left and right wheels may be swapped (or one wheel's sign reversed) in the input"
        )
    return far_from_nominal((d_r, d_l, b), nominal)


#: A calibrated value further than this (relative) from nominal is absurd for a calibration.
ABSURD_FRACTION = 0.25


def far_from_nominal(
    values: Iterable[float | np.ndarray], nominal: WheelGeometry | None
) -> list[str]:
    """One message per value of ``values`` (D_R, D_L, b in m) further than
    :data:`ABSURD_FRACTION` from ``nominal`` (none without a nominal geometry)."""
    if nominal is None:
        return []
    nominal_values = (
        float(nominal.diameter_right_m),
        float(nominal.diameter_left_m),
        float(nominal.wheelbase_m),
    )
    out = []
    for name, v, n in zip(_KEYS, (float(x) for x in values), nominal_values, strict=True):
        if abs(v / n - 1) > ABSURD_FRACTION:
            out.append(
                f"{name} = {v:.6g} m is {100 * (v / n - 1):+.0f} % from nominal {n:.6g} m: "
                "absurd for a calibration; check that the wheels are not swapped and the "
                "ticks per revolution"
            )
    return out
