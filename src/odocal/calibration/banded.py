"""Trajectory calibration with a curvature-dependent effective wheelbase.

The model: D_R and D_L as usual, and one wheelbase per band of motion (:mod:`.turning`: spot
turns, tight arcs, wide arcs, near-straight). Every increment of a run is dead-reckoned with the
wheelbase of its band; a band the runs do not excite takes the wheelbase of the nearest band that
they do (near-straight driving barely depends on it). The parameters are fitted like
:func:`odocal.calibration.trajectory.fit_trajectory` (``residual='pose'``): the pose error at up
to ``samples_per_run`` evenly spaced samples per run, heading times ``heading_weight_m``, each
run's block weighted by its travel.

The fit REFUSES (CalibrationError, with the reason) unless at least two bands are excited
(:func:`odocal.calibration.turning.effective_wheelbase`): runs that turn only on the spot (squares,
spins) cannot tell how the robot turns on arcs, and a model fitted to them would extrapolate
silently.

For a controller that takes one wheelbase (ros2_control's ``wheel_separation_multiplier``), the
result's ``geometry`` holds the single value that is best for the motion mix (default: the mix of
the fitted runs; :func:`odocal.calibration.turning.wheelbase_for_mix`), and ``motion_mix`` says what
it costs per band.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon
from ..core.recording import Recording
from ..errors import CalibrationError
from .fit_settings import DEFAULT_TRAJECTORY, TrajectorySettings
from .result import BandedDetails, GeometryFit, check_physical
from .trajectory import fit_trajectory, optimizer_report, solve_lm
from .turning import (
    BANDS,
    MIN_ROTATION_RAD,
    MIN_RUNS,
    MIN_SEGMENTS,
    band_of_increments,
    effective_wheelbase,
    nearest_estimated_band,
    wheelbase_for_mix,
    with_bands,
)

__all__ = ["fit_banded", "banded_after_constant", "fit_trajectory_bands"]


class _Run:
    def __init__(
        self,
        rec: Recording,
        start: WheelGeometry,
        samples: int,
        band_param: np.ndarray,
        window_s: float,
    ) -> None:
        self.name = rec.name
        self.phi_r = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        self.phi_l = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        self.gt = np.asarray(rec.ground_truth, dtype=float)
        n = len(self.gt)
        self.idx = np.unique(np.linspace(1, n - 1, min(samples, n - 1)).round().astype(int))
        band = band_of_increments(self.phi_r, self.phi_l, rec.time_s, start, window_s)
        self.param = band_param[np.where(band < 0, 0, band)]  # index into the wheelbases
        travel = 0.25 * float(
            np.sum(
                np.abs(np.diff(self.phi_r)) * start.diameter_right_m
                + np.abs(np.diff(self.phi_l)) * start.diameter_left_m
            )
        )
        self.weight = math.sqrt(max(travel, 1e-9) / len(self.idx))

    def residual(self, p: Any, w_head: float) -> np.ndarray:
        b = np.asarray(p[2:])[self.param]
        odo = dead_reckon(self.phi_r, self.phi_l, WheelGeometry.unchecked(p[0], p[1], b))
        e = self.gt[self.idx] - odo[self.idx]
        e[:, 2] *= w_head
        return self.weight * e.ravel()


def fit_banded(
    recordings: Sequence[Recording],
    start: WheelGeometry,
    *,
    nominal: WheelGeometry | None = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    window_s: float = 0.5,
    min_rotation_rad: float = 0.3,
) -> GeometryFit:
    """Fit D_R, D_L and one wheelbase per excited band (module docstring).

    Parameters
    ----------
    recordings : sequence of Recording
        Runs with ground truth.
    start : WheelGeometry
        Starting point and reference (e.g. the constant-wheelbase trajectory fit of the same
        runs): its diameters classify the motion and its band table decides what is excited.
    settings : TrajectorySettings
        The heading weight and samples per run of the residual, and ``motion_mix`` (band ->
        share of the rotation) for the single exported wheelbase (default the runs' own).
    """
    heading_weight_m, samples_per_run = settings.heading_weight_m, settings.samples_per_run
    runs = [r for r in recordings]
    if not runs:
        raise CalibrationError("banded wheelbase: no runs")
    table = effective_wheelbase(runs, start, window_s=window_s, min_rotation_rad=min_rotation_rad)
    excited = [i for i, b in enumerate(table.bands) if b.excited]
    if len(excited) < 2:
        turned = ", ".join(
            f"{b.band} {b.segments} segment(s) from {b.runs} run(s), {b.rotation_rad:.2g} rad"
            for b in table.bands
            if b.segments
        )
        raise CalibrationError(
            "a curvature-dependent wheelbase needs runs that turn in at least two bands of "
            f"motion (each band: {MIN_SEGMENTS} segments of {min_rotation_rad:g} rad or more from "
            f"{MIN_RUNS} runs, {MIN_ROTATION_RAD:.3g} rad in all); these runs turn enough only "
            f"in: {', '.join(BANDS[i] for i in excited) or 'none'} ({turned or 'no segment'}). "
            "Add runs with the other kind of turning (e.g. circles or arcs of the radii the robot "
            "drives, next to spot turns), or fit one wheelbase (--wheelbase-model constant)"
        )
    nearest = nearest_estimated_band(excited)
    band_param = np.array([excited.index(nearest[i]) for i in range(len(BANDS))])
    prepared = [_Run(r, start, samples_per_run, band_param, window_s) for r in runs]

    def fun(p: np.ndarray) -> np.ndarray:
        return np.concatenate([r.residual(p, heading_weight_m) for r in prepared])

    x0 = np.array(
        [start.diameter_right_m, start.diameter_left_m] + [start.wheelbase_m] * len(excited),
        dtype=float,
    )
    sol = solve_lm(fun, x0, xtol=1e-12, ftol=1e-12)
    if not np.all(np.isfinite(sol.x)):
        raise CalibrationError("banded wheelbase: the fit did not converge")
    warnings: list[str] = []
    for b in sol.x[2:]:
        warnings += check_physical([sol.x[0], sol.x[1], b], nominal, "banded wheelbase")
    m = len(sol.fun)
    stderr: list[float | None] = [None] * len(sol.x)
    if m > len(sol.x):
        s2 = 2.0 * sol.cost / (m - len(sol.x))
        try:
            cov = s2 * np.linalg.inv(sol.jac.T @ sol.jac)
            stderr = [float(math.sqrt(max(v, 0.0))) for v in np.diag(cov)]
        except np.linalg.LinAlgError:
            warnings.append("the band wheelbases are not all identifiable from these runs")
    fitted = {BANDS[i]: float(sol.x[2 + excited.index(i)]) for i in excited}
    used_by = {name: BANDS[nearest[i]] for i, name in enumerate(BANDS)}
    mix = table.motion_mix if settings.motion_mix is None else dict(settings.motion_mix)
    for name, share in mix.items():
        if share > 0 and name not in fitted:
            warnings.append(
                f"the motion mix turns {100 * share:.0f} % in band '{name}', which these runs "
                f"do not excite: the model uses the '{used_by[name]}' wheelbase there"
            )
    choice = wheelbase_for_mix({n: fitted[used_by[n]] for n in BANDS}, mix)
    geometry = WheelGeometry(float(sol.x[0]), float(sol.x[1]), choice.wheelbase_m)
    return GeometryFit(
        method="trajectory",
        geometry=geometry,
        stderr={
            "wheel_diameter_right_m": stderr[0],
            "wheel_diameter_left_m": stderr[1],
            "wheelbase_m": None,
        },
        covariance=None,
        runs=[r.name for r in runs],
        warnings=warnings,
        banded=BandedDetails(
            band_wheelbase_m=fitted,
            band_wheelbase_stderr_m={BANDS[i]: stderr[2 + k] for k, i in enumerate(excited)},
            band_uses=used_by,
            residual_rms=float(math.sqrt(2.0 * sol.cost / max(m, 1))),
            optimizer=optimizer_report(sol),
        ),
        effective_wheelbase=table,
        motion_mix=choice,
    )


def banded_after_constant(
    constant: GeometryFit,
    runs: Sequence[Recording],
    nominal: WheelGeometry | None,
    settings: TrajectorySettings,
) -> GeometryFit:
    """The banded fit of ``runs`` (the runs the constant-wheelbase trajectory fit ``constant``
    used), started from that fit, with its exclusions, outliers, per-run statistics and warnings
    and the constant fit's geometry (``constant_fit``)."""
    banded = fit_banded(runs, constant.geometry, nominal=nominal, settings=settings)
    return replace(
        banded,
        excluded=constant.excluded,
        outliers=constant.outliers,
        per_run=constant.per_run,
        warnings=list(constant.warnings) + list(banded.warnings),
        constant_fit=constant.geometry,
    )


def fit_trajectory_bands(
    recordings: Sequence[Recording], nominal: WheelGeometry | None, settings: TrajectorySettings
) -> GeometryFit:
    """The trajectory fit (:func:`~odocal.calibration.trajectory.fit_trajectory`) with its
    effective wheelbase per band of motion (and the single wheelbase for a motion mix,
    :func:`~odocal.calibration.turning.with_bands`), or with ``settings.wheelbase_model``
    'banded' the banded model started from it (:func:`banded_after_constant`)."""
    fit = fit_trajectory(recordings, nominal=nominal, settings=settings)
    used = [r for r in recordings if r.name in set(fit.runs)]
    if settings.wheelbase_model == "banded":
        return banded_after_constant(fit, used, nominal, settings)
    return with_bands(fit, used, settings.motion_mix)
