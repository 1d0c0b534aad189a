"""Calibration results: factors relative to the parameters a robot ran with (``CalibrationResult``)
and geometries fitted to recorded runs (``GeometryFit``)."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import dataclass, field
from typing import Any, SupportsFloat

import numpy as np

from ..core.jsonable import finite_list
from ..core.model import WheelGeometry
from ..errors import CalibrationError
from .fit_methods import HeadingSource, UmbmarkForm, WheelbaseModel
from .fit_settings import TrajectorySettings
from .robust_covariance import Consistency
from .turning import EffectiveWheelbase, MixChoice
from .uncertainty import CalibrationUncertainty

__all__ = [
    "ABSURD_FRACTION",
    "CalibrationResult",
    "GeometryFit",
    "OptimizerReport",
    "LinearDetails",
    "DataSetCalibration",
    "SquaresDetails",
    "TrajectoryDetails",
    "BandedDetails",
    "check_physical",
    "far_from_nominal",
    "WHEELS_HINT",
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
        """The result of the factors ``E_b``, ``E_d`` for a robot that ran with ``ran_with``
        (CalibrationError when they are not finite and positive); ``inputs``: what they were
        computed from."""
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
class OptimizerReport:
    """What a fit reports of its Levenberg-Marquardt solution
    (:func:`odocal.calibration.trajectory.solve_lm`): scipy's ``nfev``, every residual
    evaluation (its finite-difference Jacobian's too) and scipy's status."""

    nfev: int
    evaluations: int
    status: int

    def as_dict(self) -> dict[str, int]:
        """JSON-ready (the ``optimizer`` object of ``odocal fit --json``)."""
        return {"nfev": self.nfev, "evaluations": self.evaluations, "status": self.status}


@dataclass(frozen=True)
class LinearDetails:
    """What the linear estimator (:mod:`odocal.calibration.linear`) adds to its fit.

    Attributes
    ----------
    coefficients : tuple of float
        (c_R1, c_L1, c_R2, c_L2): c_R1 = D_R / 4, c_L1 = D_L / 4 (m), c_R2 = D_R / (2 b),
        c_L2 = -D_L / (2 b).
    heading_step_condition_number : float
        cond(Phi^T Phi) of the heading step.
    wheelbase_from_right_m, wheelbase_from_left_m : float
        The wheelbase each wheel's coefficients give alone (m).
    """

    coefficients: tuple[float, float, float, float]
    heading_step_condition_number: float
    wheelbase_from_right_m: float
    wheelbase_from_left_m: float

    def as_dict(self) -> dict[str, Any]:
        """The linear fit's keys of ``odocal fit --json``: the coefficients by name, the condition
        number and the wheelbase from each wheel (m)."""
        return {
            "coefficients": dict(
                zip(("c_R1", "c_L1", "c_R2", "c_L2"), self.coefficients, strict=True)
            ),
            "heading_step_condition_number": self.heading_step_condition_number,
            "wheelbase_from_right_m": self.wheelbase_from_right_m,
            "wheelbase_from_left_m": self.wheelbase_from_left_m,
        }


@dataclass(frozen=True)
class DataSetCalibration:
    """One data set of a fit on recorded squares: its runs and its own calibration (relative to
    the parameters it ran with)."""

    data_set: str
    runs: int
    runs_cw: int
    runs_ccw: int
    calibration: CalibrationResult

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready (one entry of ``data_sets``): the runs, the factors, the parameters the runs
        ran with and the calibrated geometry (m)."""
        res = self.calibration
        return {
            "data_set": self.data_set,
            "runs": self.runs,
            "runs_cw": self.runs_cw,
            "runs_ccw": self.runs_ccw,
            "E_b": float(res.E_b),
            "E_d": float(res.E_d),
            "ran_with": res.ran_with.as_dict(),
            **{f"calibrated_{k}": v for k, v in res.corrected.as_dict().items()},
        }


#: How a fit on recorded squares pools its data sets.
SQUARES_POOLING = (
    "per data set, composed with its own ran-with parameters; pooled by run count through "
    "D_R/D_L and b/D, at the nominal mean diameter (scale not observable)"
)


@dataclass(frozen=True)
class SquaresDetails:
    """What UMBmark and the heading method on recorded squares
    (:mod:`odocal.calibration.squares`) add to their fit: each data set's own calibration and the
    settings used (``umbmark_form`` None for the heading method)."""

    data_sets: tuple[DataSetCalibration, ...]
    heading_source: HeadingSource
    sides: int
    umbmark_form: UmbmarkForm | None = None

    def as_dict(self) -> dict[str, Any]:
        """The squares fit's keys of ``odocal fit --json``: every data set, how they are pooled and
        the settings."""
        return {
            "data_sets": [d.as_dict() for d in self.data_sets],
            "pooling": SQUARES_POOLING,
            **({"umbmark_form": self.umbmark_form} if self.umbmark_form is not None else {}),
            "heading_source": self.heading_source,
            "sides": self.sides,
        }


@dataclass(frozen=True)
class TrajectoryDetails:
    """What the trajectory fit (:mod:`odocal.calibration.trajectory`) adds to its fit: its
    settings, the RMS of its residual (m) at the solution, the optimizer's report, how many
    starting points it tried and what became of the linear estimate as one."""

    settings: TrajectorySettings
    residual_rms: float
    optimizer: OptimizerReport
    starts_tried: int
    linear_start: str

    def as_dict(self) -> dict[str, Any]:
        """The trajectory fit's keys of ``odocal fit --json``: its settings (``segment_m`` None for
        the 'pose' residual), the residual RMS (m), the optimizer and its starts."""
        s = self.settings
        return {
            "residual": s.residual,
            "segment_m": s.segment_m if s.residual == "segment" else None,
            "heading_weight_m": s.heading_weight_m,
            "run_weight": s.run_weight,
            "residual_rms": self.residual_rms,
            "optimizer": self.optimizer.as_dict(),
            "starts_tried": self.starts_tried,
            "linear_start": self.linear_start,
        }


#: What a banded fit's ``wheelbase_m`` is.
BANDED_NOTE = (
    "wheelbase_m is the single value for the motion mix; the model itself uses band_wheelbase_m "
    "per band of motion"
)


@dataclass(frozen=True)
class BandedDetails:
    """The banded model (:mod:`odocal.calibration.banded`): one wheelbase per excited band (m),
    their standard errors (m; None where not estimable), the band whose wheelbase each band
    uses, the residual RMS (m) and the optimizer's report."""

    band_wheelbase_m: dict[str, float]
    band_wheelbase_stderr_m: dict[str, float | None]
    band_uses: dict[str, str]
    residual_rms: float
    optimizer: OptimizerReport


@dataclass(frozen=True)
class GeometryFit:
    """A calibrated geometry from recorded runs.

    Attributes
    ----------
    method : str
        'trajectory', 'linear', 'umbmark' or 'heading'.
    geometry : WheelGeometry
        Calibrated D_R, D_L (m), b (m). With a motion mix or the banded model, the wheelbase is
        the single value for the mix (``motion_mix``).
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
    linear, squares, trajectory : LinearDetails, SquaresDetails, TrajectoryDetails or None
        What the method that made the fit adds.
    banded : BandedDetails or None
        The banded wheelbase model's values (``wheelbase_model`` 'banded').
    effective_wheelbase : EffectiveWheelbase or None
        The effective wheelbase per band of motion of the runs used (trajectory fits).
    motion_mix : MixChoice or None
        The single wheelbase for a motion mix, and what it costs per band.
    constant_fit : WheelGeometry or None
        The constant-wheelbase fit behind a motion mix or a banded model.
    uncertainty : str
        How ``covariance`` was computed: 'formal' (s^2 (J^T J)^-1) or 'cluster-robust over N
        data sets / runs / time blocks' (:mod:`odocal.calibration.robust_covariance`).
    covariance_formal : ndarray, shape (3, 3), or None
        The formal covariance when ``covariance`` is the cluster-robust one.
    dof : int or None
        Degrees of freedom of the cluster-robust standard errors (clusters - 1).
    consistency : Consistency or None
        Whether the log's parts (data sets, halves) agree within their own uncertainty.
    """

    method: str
    geometry: WheelGeometry
    stderr: dict[str, float | None]
    covariance: np.ndarray | None
    runs: list[str]
    per_run: list[dict[str, Any]] = field(default_factory=list)
    outliers: list[str] = field(default_factory=list)
    excluded: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    linear: LinearDetails | None = None
    squares: SquaresDetails | None = None
    trajectory: TrajectoryDetails | None = None
    banded: BandedDetails | None = None
    effective_wheelbase: EffectiveWheelbase | None = None
    motion_mix: MixChoice | None = None
    constant_fit: WheelGeometry | None = None
    uncertainty: str = "formal"
    covariance_formal: np.ndarray | None = None
    dof: int | None = None
    consistency: Consistency | None = None

    @property
    def wheelbase_model(self) -> WheelbaseModel | None:
        """'banded', 'constant' (a trajectory fit with its band table) or None (no bands)."""
        if self.banded is not None:
            return "banded"
        return "constant" if self.effective_wheelbase is not None else None

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract of ``odocal fit --json``: the geometry and its uncertainty, the
        runs, then what the method adds."""
        cov = None if self.covariance is None else finite_list(self.covariance)
        out: dict[str, Any] = {
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
        }
        for part in (self.linear, self.squares, self.trajectory):
            if part is not None:
                out.update(part.as_dict())
        if self.covariance_formal is not None:
            out["uncertainty"] = self.uncertainty
            out["dof"] = self.dof
            out["stderr_formal"] = stderr_dict(self.covariance_formal)
        if self.consistency is not None:
            out["consistency"] = self.consistency.as_dict(_KEYS)
        return out | self._wheelbase_dict()

    def _wheelbase_dict(self) -> dict[str, Any]:
        """The wheelbase model, the band table and the motion mix, in the JSON's order."""
        out: dict[str, Any] = {}
        table = None if self.effective_wheelbase is None else self.effective_wheelbase.as_dict()
        mix = None if self.motion_mix is None else self.motion_mix.as_dict()
        if self.banded is not None:
            b = self.banded
            out["wheelbase_model"] = "banded"
            out["band_wheelbase_m"] = b.band_wheelbase_m
            out["band_wheelbase_stderr_m"] = b.band_wheelbase_stderr_m
            out["band_uses"] = b.band_uses
            out["motion_mix"] = mix
            out["effective_wheelbase"] = table
            out["residual_rms"] = b.residual_rms
            out["optimizer"] = b.optimizer.as_dict()
            out["note"] = BANDED_NOTE
        elif table is not None:
            out["wheelbase_model"] = "constant"
            out["effective_wheelbase"] = table
            if mix is not None:
                out["motion_mix"] = mix
        if self.constant_fit is not None:
            out["constant_fit"] = self.constant_fit.as_dict()
        return out


_KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def stderr_dict(cov: np.ndarray | None) -> dict[str, float | None]:
    """Standard errors (m) of D_R, D_L and b by their JSON keys, from the square roots of the
    diagonal of ``cov`` (None where not finite; all None without a covariance)."""
    if cov is None:
        return dict.fromkeys(_KEYS)
    d = np.sqrt(np.clip(np.diag(cov), 0, None))
    return {k: (float(v) if np.isfinite(v) else None) for k, v in zip(_KEYS, d, strict=True)}


def check_physical(
    values: Iterable[SupportsFloat], nominal: WheelGeometry | None, method: str
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


#: What a result far from nominal usually means, for runs of wheel angles (the default hint).
WHEELS_HINT = "check that the wheels are not swapped and the ticks per revolution"


def far_from_nominal(
    values: Iterable[SupportsFloat], nominal: WheelGeometry | None, hint: str = WHEELS_HINT
) -> list[str]:
    """One message per value of ``values`` (D_R, D_L, b in m) further than
    :data:`ABSURD_FRACTION` from ``nominal`` (none without a nominal geometry), ending with
    ``hint`` (what the caller's inputs can get wrong)."""
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
                f"absurd for a calibration; {unit_slip(n / v) or hint}"
            )
    return out


#: Unit factors a robot file may slip by: (file value / metres, the file's unit).
_UNIT_SLIPS = ((1000.0, "millimetres"), (100.0, "centimetres"), (1 / 0.0254, "inches"))


def unit_slip(ratio: float) -> str | None:
    """What a nominal value ``ratio`` times the measured one suggests (within 15 % of 1000,
    100 or 39.37: the robot file in millimetres, centimetres or inches), or None."""
    for factor, unit in _UNIT_SLIPS:
        if abs(ratio / factor - 1) < 0.15:
            return (
                f"the data say {ratio:.4g} times less than the robot file: is the file in "
                f"{unit}? (its lengths must be in metres)"
            )
    return None
