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
the fitted runs; :func:`odocal.calibration.turning.wheelbase_for_mix`) of the band wheelbases
fitted here, and ``motion_mix`` says what it costs per band. This is the ONE way odocal computes
a wheelbase for a motion mix (``--motion-mix`` fits the banded model). Its standard error is the
delta method on the band wheelbases' covariance, cluster-robust over the same groups as the
trajectory fit's (data sets, else runs, else time blocks). A stated mix with a share in a band
the runs did not excite is refused (InputError): nothing measured how the robot turns there.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from dataclasses import replace
from typing import Any

import numpy as np

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from .fit_settings import DEFAULT_TRAJECTORY, TrajectorySettings
from .result import BandedDetails, GeometryFit, check_physical, stderr_dict
from .robust_covariance import cluster_covariance
from .trajectory import _row_clusters, fit_trajectory, optimizer_report, solve_lm
from .turning import (
    BANDS,
    MIN_ROTATION_RAD,
    MIN_RUNS,
    MIN_SEGMENTS,
    MixChoice,
    band_of_increments,
    disagreeing_bands,
    effective_wheelbase,
    nearest_estimated_band,
    wheelbase_for_mix,
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


def _one_wheelbase_hint(motion_mix: Mapping[str, float] | None) -> str:
    """How to get one wheelbase when the runs excite one band: for a stated mix (all of it in
    that band, else it was refused before), the plain fit is that band's wheelbase."""
    if motion_mix:
        return (
            "leave out --motion-mix: the plain fit's wheelbase is the one of the band these "
            "runs turn in"
        )
    return "fit one wheelbase (--wheelbase-model constant)"


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
    _refuse_unmeasured(settings.motion_mix, excited, min_rotation_rad)
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
            f"drives, next to spot turns), or {_one_wheelbase_hint(settings.motion_mix)}"
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
    cov, formal, how, dof = _band_covariance(sol, prepared, runs, warnings)
    stderr = (
        [None] * len(sol.x)
        if cov is None
        else [float(math.sqrt(max(v, 0.0))) for v in np.diag(cov)]
    )
    fitted = {BANDS[i]: float(sol.x[2 + excited.index(i)]) for i in excited}
    used_by = {name: BANDS[nearest[i]] for i, name in enumerate(BANDS)}
    mix = table.motion_mix if settings.motion_mix is None else dict(settings.motion_mix)
    for name, share in mix.items():
        if share > 0 and name not in fitted:  # the runs' own mix only (a stated one is refused)
            warnings.append(
                f"the runs turn {100 * share:.0f} % of their rotation in band '{name}', which "
                f"they do not excite: the model uses the '{used_by[name]}' wheelbase there"
            )
    per_band = {n: fitted[used_by[n]] for n in BANDS}
    choice = wheelbase_for_mix(per_band, mix)
    # the exported geometry (D_R, D_L, b of the mix) and its covariance by the delta method
    grad = np.zeros((3, len(sol.x)))
    grad[0, 0] = grad[1, 1] = 1.0
    grad[2, 2:] = _mix_gradient(choice, per_band, used_by, excited)
    cov3 = None if cov is None else grad @ cov @ grad.T
    formal3 = None if formal is None else grad @ formal @ grad.T
    se3 = stderr_dict(cov3)
    choice = replace(choice, wheelbase_stderr_m=se3["wheelbase_m"])
    geometry = WheelGeometry(float(sol.x[0]), float(sol.x[1]), choice.wheelbase_m)
    return GeometryFit(
        method="trajectory",
        geometry=geometry,
        stderr=se3,
        covariance=cov3,
        uncertainty=how,
        covariance_formal=formal3,
        dof=dof,
        runs=[r.name for r in runs],
        warnings=warnings,
        banded=BandedDetails(
            band_wheelbase_m=fitted,
            band_wheelbase_stderr_m={BANDS[i]: stderr[2 + k] for k, i in enumerate(excited)},
            band_uses=used_by,
            residual_rms=float(math.sqrt(2.0 * sol.cost / max(len(sol.fun), 1))),
            optimizer=optimizer_report(sol),
        ),
        effective_wheelbase=table,
        motion_mix=choice,
    )


def _refuse_unmeasured(
    mix: Mapping[str, float] | None, excited: list[int], min_rotation_rad: float
) -> None:
    """A stated motion mix may only name bands the runs excite (InputError otherwise)."""
    if not mix:
        return
    missing = [k for k, w in mix.items() if w > 0 and BANDS.index(k) not in excited]
    if missing:
        seen = ", ".join(BANDS[i] for i in excited) or "none"
        raise InputError(
            f"these runs did not measure how the robot turns in band(s) "
            f"{', '.join(missing)} (a band needs {MIN_SEGMENTS} segments of "
            f"{min_rotation_rad:g} rad or more from {MIN_RUNS} runs, {MIN_ROTATION_RAD:.3g} rad "
            f"in all; excited here: {seen}); add runs that turn that way or leave those bands "
            "out of the mix",
            field="motion-mix",
        )


def _band_covariance(
    sol: Any, prepared: Sequence[_Run], runs: Sequence[Recording], warnings: list[str]
) -> tuple[np.ndarray | None, np.ndarray | None, str, int | None]:
    """The covariance of (D_R, D_L, band wheelbases): cluster-robust over the trajectory fit's
    groups when it can be formed (then also the formal one), else formal; None (with a warning)
    when singular."""
    m, p = len(sol.fun), len(sol.x)
    if m <= p:
        return None, None, "formal", None
    try:
        formal = 2.0 * sol.cost / (m - p) * np.linalg.inv(sol.jac.T @ sol.jac)
    except np.linalg.LinAlgError:
        warnings.append("the band wheelbases are not all identifiable from these runs")
        return None, None, "formal", None
    clusters, what = _row_clusters(prepared, runs, "pose")  # type: ignore[arg-type]
    if len(clusters) == m:
        try:
            cc = cluster_covariance(sol.jac, sol.fun, clusters)
        except CalibrationError:
            return formal, None, "formal", None
        return cc.covariance, formal, f"cluster-robust over {what}", cc.dof
    return formal, None, "formal", None


def _mix_gradient(
    choice: MixChoice, values: dict[str, float], used_by: dict[str, str], excited: list[int]
) -> np.ndarray:
    """d b_mix / d b_k for every fitted band wheelbase b_k (``values``: band -> the wheelbase
    it uses): with b = sum w_j b_j^2 / sum w_j b_j, W_k (2 b_k - b) / sum w_j b_j, W_k the
    share of the bands that use b_k."""
    b = choice.wheelbase_m
    num = sum(w * values[n] for n, w in choice.mix.items())
    out = np.zeros(len(excited))
    for n, w in choice.mix.items():
        out[excited.index(BANDS.index(used_by[n]))] += w * (2.0 * values[n] - b) / num
    return out


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
    effective wheelbase per band of motion (:func:`with_bands`), or
    with ``settings.wheelbase_model`` 'banded' or a ``settings.motion_mix`` the banded model
    started from it (:func:`banded_after_constant`; the single wheelbase for the mix comes from
    its band wheelbases)."""
    fit = fit_trajectory(recordings, nominal=nominal, settings=settings)
    used = [r for r in recordings if r.name in set(fit.runs)]
    if settings.wheelbase_model == "banded" or settings.motion_mix:
        return banded_after_constant(fit, used, nominal, settings)
    return with_bands(fit, used)


def with_bands(fit: GeometryFit, runs: Sequence[Recording]) -> GeometryFit:
    """A constant-wheelbase trajectory ``fit`` of ``runs`` with its effective wheelbase per band
    of motion (``effective_wheelbase``) and a warning when excited bands disagree. (A single
    wheelbase for a motion mix comes from the banded model's band wheelbases:
    :mod:`odocal.calibration.banded`.)"""
    table = effective_wheelbase(runs, fit.geometry)
    warnings = list(fit.warnings) + disagreeing_bands(table)
    return replace(fit, warnings=warnings, effective_wheelbase=table)
