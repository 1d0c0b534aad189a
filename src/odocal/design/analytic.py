"""Analytic test-track design: first-order propagation instead of Monte Carlo.

For every candidate test track (regular N-gon of side L) this predicts what the Monte-Carlo design
measures over its trials, in milliseconds for a whole sweep:

1. The final pose errors of the CW and CCW test runs: mean (exact, noise free) and covariance
   (eqs. (8)-(10), :mod:`odocal.core.covariance`) plus the instrument's noise (ROBOT.yaml
   ``measurement``); the mean of n runs per direction has 1/n of that covariance.
2. The calibrated E_b, E_d: the calibration equations (``heading_factors`` or
   ``umbmark_factors``) at the mean errors, and their covariance J S J^T with J the numeric
   Jacobian of the equations with respect to the two mean end poses.
3. The final position error p (x, y; actual - odometric) of the validation track driven with the
   calibrated parameters: mean at the mean E_b, E_d (the systematic residual), covariance
   H Cov(E) H^T + P_run, where H is the numeric Jacobian of the noise-free validation error with
   respect to (E_b, E_d) and P_run the validation run's own noise covariance.
4. ||p|| for p ~ N(mean, covariance): its mean, std and 95 % interval from a fixed sample of
   2^14 points of the 2-D Gaussian: the Hammersley point set (a (0, 14, 2)-net) mapped by the
   Box-Muller transform (deterministic; relative error ~1e-4).

Assumptions (docs/nonsystematic-errors.md): noise small enough that everything is linear in it
over one standard deviation (the calibration equations and the validation error as functions of
the mean end poses and of E_b, E_d); Gaussian end poses (exact for the heading, which is linear in
the wheel noise); the mean of the calibrated parameters is taken as the equations at the mean
errors (no second-order bias). First order degrades when the test track is tiny and the noise
large: then the CW/CCW heading errors are dominated by noise, E_b = (2 pi/N)/(2 pi/N - alpha)
and E_d = (1 + q)/(1 - q) are curved over the spread, and the validation headings wander far
enough for sin/cos to bend.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from typing import TYPE_CHECKING

import numpy as np

from ..calibration.heading import heading_factors
from ..calibration.umbmark import umbmark_factors
from ..core.covariance import mean_final_pose, propagate
from ..core.model import ModelError, Robot, WheelGeometry
from ..core.simulate import odometric_pose
from ..core.tracks import Track, polygon
from .metrics import (
    leg_heading_noise_rad,
    leg_heading_systematic_rad,
    systematic_share,
    true_factors,
)
from .result import Candidate
from .spec import DesignSpec, Method

if TYPE_CHECKING:
    from .sweep import DesignResult

__all__ = [
    "analytic_design_result",
    "AnalyticReference",
    "analytic_design",
    "analytic_reference",
    "norm_stats",
]

_SAMPLE_LOG2 = 14


@functools.lru_cache(maxsize=1)
def _normal_sample() -> np.ndarray:
    """A fixed sample of the standard 2-D normal, shape (2^14, 2), the same on every machine: the
    Hammersley points u_i = ((i + 1/2) / N, (bit-reversed i + 1/2) / N) mapped by Box-Muller,
    radius sqrt(-2 ln(1 - u_1)) and angle 2 pi u_2 (numpy only: no scipy import)."""
    n = 1 << _SAMPLE_LOG2
    i = np.arange(n)
    reversed_i = np.zeros(n, dtype=np.int64)
    for bit in range(_SAMPLE_LOG2):
        reversed_i |= ((i >> bit) & 1) << (_SAMPLE_LOG2 - 1 - bit)
    radius = np.sqrt(-2.0 * np.log1p(-(i + 0.5) / n))
    angle = (2.0 * math.pi / n) * (reversed_i + 0.5)
    return np.column_stack([radius * np.cos(angle), radius * np.sin(angle)])


def norm_stats(
    mean_xy, cov_xy, *, quantiles: bool = True
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Mean, std, 2.5 % and 97.5 % quantiles of ||p|| for p ~ N(mean_xy, cov_xy).

    ``mean_xy`` has shape (..., 2), ``cov_xy`` shape (..., 2, 2) (m, m^2); results have shape
    (...). Computed on a fixed sample of 2^14 points (deterministic; :func:`_normal_sample`).
    ``quantiles=False`` gives NaN quantiles (they are a third of the time).
    """
    mu = np.asarray(mean_xy, dtype=float)
    c = np.asarray(cov_xy, dtype=float)
    shape = np.broadcast_shapes(mu.shape[:-1], c.shape[:-2])
    mu = np.broadcast_to(mu, (*shape, 2)).reshape(-1, 2)
    # symmetric square root (robust for singular covariances, unlike Cholesky)
    w, v = np.linalg.eigh(np.broadcast_to(c, (*shape, 2, 2)).reshape(-1, 2, 2))
    root = v * np.sqrt(np.maximum(w, 0.0))[..., None, :]
    z0, z1 = _normal_sample().T
    out = np.full((4, len(mu)), math.nan)
    # a few distributions per pass, so that the passes stay in the cache (each row's numbers
    # are the same however many rows a pass takes: the reductions run along the rows)
    for lo in range(0, len(mu), _ROWS_PER_PASS):
        m, r = mu[lo : lo + _ROWS_PER_PASS], root[lo : lo + _ROWS_PER_PASS]
        # p = mean + root z, component by component (a reduction over an axis of 2 is slow)
        px = m[:, 0, None] + r[:, 0, 0, None] * z0 + r[:, 0, 1, None] * z1
        py = m[:, 1, None] + r[:, 1, 0, None] * z0 + r[:, 1, 1, None] * z1
        norm = np.hypot(px, py)
        out[0, lo : lo + len(m)] = norm.mean(axis=-1)
        out[1, lo : lo + len(m)] = norm.std(axis=-1)
        if quantiles:
            out[2:, lo : lo + len(m)] = np.quantile(norm, [0.025, 0.975], axis=-1)
    mean, std, lo95, hi95 = out.reshape(4, *shape)
    return mean, std, lo95, hi95


# distributions per pass of norm_stats (4 x 2^14 points: 512 kB per array)
_ROWS_PER_PASS = 4


@dataclass(frozen=True)
class AnalyticReference:
    """The validation-track error with the TRUE parameters (the floor calibration can reach) and
    with the parameters the robot runs with before calibration (m)."""

    floor_m: float
    floor_std_m: float
    floor_ci95_m: tuple[float, float]
    uncalibrated_m: float
    uncalibrated_std_m: float
    uncalibrated_ci95_m: tuple[float, float]


def _validation_error(track: Track, true: WheelGeometry, believed: WheelGeometry) -> np.ndarray:
    """Noise-free final position error (x, y) of ``track``, shape (..., 2)."""
    return (mean_final_pose(track, true, believed) - odometric_pose(track))[..., :2]


def _cov_options(steps_per_segment: int) -> dict:
    return {"steps_per_segment": steps_per_segment, "integration": "exact"}


def analytic_reference(
    robot: Robot, validate_track: Track, *, steps: int = 64
) -> AnalyticReference:
    """Floor (believed = true geometry) and uncalibrated (the parameters the robot runs with:
    ROBOT.yaml's ``believed``, else nominal) final position error on ``validate_track``."""
    true = robot.true_geometry
    out = []
    for believed in (true, robot.believed_geometry):
        pred = propagate(validate_track, true, believed, robot.nonsystematic, **_cov_options(steps))
        m, s, lo, hi = norm_stats(pred.error_mean[:2], pred.covariance[:2, :2])
        out.append((float(m), float(s), (float(lo), float(hi))))
    return AnalyticReference(*out[0], *out[1])


def _calibration_function(method: Method, sides: int, side_m: np.ndarray, wheelbase_m, form: str):
    """g(z) -> (E_b, E_d) for z = (mean CW error (3), mean CCW error (3)), shape (..., 6)."""
    if method == "heading":
        return lambda z: heading_factors(z[..., 2], z[..., 5], sides, side_m, wheelbase_m)
    if method == "umbmark":
        if sides != 4:
            raise ModelError(f"UMBmark is defined for squares only (sides 4), got {sides}")
        return lambda z: umbmark_factors(z[..., 0:2], z[..., 3:5], side_m, wheelbase_m, form)
    raise ModelError(f"method must be 'heading' or 'umbmark', got {method!r}")


def _jacobian(fun, z: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """Central-difference Jacobian of fun: (..., m) -> tuple of arrays (...), shape (..., k, m)."""
    cols = []
    for j in range(z.shape[-1]):
        dz = np.zeros(z.shape[-1])
        dz[j] = steps[j]
        hi = np.stack(fun(z + dz), axis=-1)
        lo = np.stack(fun(z - dz), axis=-1)
        cols.append((hi - lo) / (2.0 * steps[j]))
    return np.stack(cols, axis=-1)


def analytic_design(
    robot: Robot,
    sides: int | Sequence[int],
    side_lengths_m,
    runs_per_direction: int = 5,
    method: Method = "heading",
    validate_track: Track | None = None,
    *,
    umbmark_form: str = "mean",
    measured_validation: bool = False,
    steps: int = 64,
    intervals: bool = True,
) -> list[Candidate]:
    """First-order prediction of the Monte-Carlo design for every (sides, side length) candidate.

    Parameters
    ----------
    robot : Robot
        True errors (systematic, nonsystematic k in m, instrument noise) and the parameters it
        runs with during the test runs (``believed``, else nominal).
    sides : int or sequence of int
        Polygon side counts to compare (N >= 3).
    side_lengths_m : array_like, shape (S,)
        Candidate side lengths (m).
    runs_per_direction : int
        n CW and n CCW test runs, averaged.
    method : {'heading', 'umbmark'}
    validate_track : Track
        The validation run (default: 4 m x 4 m square CCW, the paper's).
    umbmark_form : {'x', 'y', 'mean'}
    measured_validation : bool
        Also add the instrument's position noise to the validation error (default False: the
        true error, as the Monte-Carlo design reports it).
    steps : int
        Increments per segment of the covariance propagation (its discretisation error falls as
        1/steps^2: below 1e-3 relative at 64); the means are exact.
    intervals : bool
        False leaves ``post_error_ci95_m`` NaN, which saves a third of the time where only the
        means and standard deviations count (a recommendation, the range design).

    Returns
    -------
    list of Candidate (``trials`` None: no trials behind them), sides-major then side length,
    in the order given; ``leg_heading_systematic_rad`` is |beta| as in the Monte-Carlo design.
    """
    n = int(runs_per_direction)
    if n < 1:
        raise ModelError(f"runs_per_direction must be >= 1, got {runs_per_direction!r}")
    if validate_track is None:
        validate_track = polygon(4, 4.0, "ccw")
    sides_list = [int(sides)] if isinstance(sides, (int, np.integer)) else [int(s) for s in sides]
    L = np.atleast_1d(np.asarray(side_lengths_m, dtype=float))
    if L.ndim != 1 or not np.all(np.isfinite(L) & (L > 0)):
        raise ModelError(
            f"side lengths must be finite and > 0 m, got {np.asarray(side_lengths_m).tolist()}"
        )
    true, ran_with = robot.true_geometry, robot.believed_geometry
    meas = np.diag([robot.measurement.sigma_xy_m**2] * 2 + [robot.measurement.sigma_theta_rad**2])
    beta = leg_heading_systematic_rad(robot, L)
    sig = leg_heading_noise_rad(robot, L)
    share = systematic_share(beta, sig, n)
    out: list[Candidate] = []
    for N in sides_list:
        # 1. test runs: mean end-pose errors exactly, covariances by propagation
        z = np.empty((len(L), 6))
        S = np.zeros((len(L), 6, 6))
        for j, d in enumerate(("cw", "ccw")):
            pred = propagate(
                polygon(N, L, d), true, ran_with, robot.nonsystematic, **_cov_options(steps)
            )
            z[:, 3 * j : 3 * j + 3] = pred.error_mean
            S[:, 3 * j : 3 * j + 3, 3 * j : 3 * j + 3] = (pred.covariance + meas) / n
        # 2. calibrated factors
        g = _calibration_function(method, N, L, ran_with.wheelbase_m, umbmark_form)
        E_b, E_d = g(z)
        J = _jacobian(g, z, np.full(6, 1e-7))  # (S, 2, 6)
        cov_E = J @ S @ np.swapaxes(J, -1, -2)

        # 3. validation error: mean at the mean factors, linearised in the factors
        def val(eb, ed):
            return _validation_error(validate_track, true, ran_with.corrected(eb, ed))

        ok = np.isfinite(E_b) & np.isfinite(E_d) & (E_b > 0) & (E_d > 0)
        E_b = np.where(ok, E_b, math.nan)
        E_d = np.where(ok, E_d, math.nan)
        eb, ed = np.where(ok, E_b, 1.0), np.where(ok, E_d, 1.0)  # placeholders where undefined
        p0 = val(eb, ed)
        h = 1e-7
        H = np.stack(
            [
                (val(eb + h, ed) - val(eb - h, ed)) / (2 * h),
                (val(eb, ed + h) - val(eb, ed - h)) / (2 * h),
            ],
            axis=-1,
        )  # (S, 2, 2)
        C = H @ cov_E @ np.swapaxes(H, -1, -2)
        rm, rs, _, _ = norm_stats(
            np.where(ok[:, None], p0, 0.0), np.where(ok[:, None, None], C, 0.0), quantiles=False
        )
        run = propagate(
            validate_track,
            true,
            ran_with.corrected(eb, ed),
            robot.nonsystematic,
            **_cov_options(steps),
        )
        C += run.covariance[..., :2, :2]
        if measured_validation:
            C += meas[:2, :2]
        # 4. ||p||
        m, s, lo, hi = norm_stats(
            np.where(ok[:, None], p0, 0.0), np.where(ok[:, None, None], C, 0.0), quantiles=intervals
        )
        for i, side in enumerate(L):
            nan2 = (math.nan, math.nan)
            good = bool(ok[i])
            sd = np.sqrt(np.maximum(np.diag(cov_E[i]), 0.0)) if good else np.full(2, math.nan)
            out.append(
                Candidate(
                    sides=int(N),
                    side_m=float(side),
                    travel_m=float(N * side),
                    systematic_share=float(share[i]),
                    post_error_mean_m=float(m[i]) if good else math.nan,
                    post_error_std_m=float(s[i]) if good else math.nan,
                    post_error_ci95_m=(float(lo[i]), float(hi[i])) if good else nan2,
                    E_b_mean=float(E_b[i]),
                    E_b_std=float(sd[0]),
                    E_d_mean=float(E_d[i]),
                    E_d_std=float(sd[1]),
                    trials=None,
                    leg_heading_systematic_rad=abs(float(beta[i])),
                    leg_heading_noise_rad=float(sig[i]),
                    E_corr=float(cov_E[i, 0, 1] / (sd[0] * sd[1]))
                    if good and sd[0] > 0 and sd[1] > 0
                    else math.nan,
                    post_error_mean_xy_m=(float(p0[i, 0]), float(p0[i, 1])) if good else nan2,
                    post_error_cov_xy_m2=(
                        (float(C[i, 0, 0]), float(C[i, 0, 1])),
                        (float(C[i, 1, 0]), float(C[i, 1, 1])),
                    )
                    if good
                    else (nan2, nan2),
                    residual_error_mean_m=float(rm[i]) if good else math.nan,
                    residual_error_std_m=float(rs[i]) if good else math.nan,
                )
            )
    return out


def analytic_design_result(robot: Robot, spec: DesignSpec) -> DesignResult:
    """The whole design (``odocal design --analytic``) by first-order propagation.

    Same candidates (shapes compared at equal travel; sizes ``spec`` leaves open scaled to the
    robot), recommendation rule, report and JSON as :func:`odocal.design.sweep.run_design`,
    without Monte Carlo. The candidates are expected values (``trials`` None: no sampling
    error), so the rule compares their means directly ("exact"): the limit of the Monte-Carlo
    rule for infinitely many trials. ``spec.trials`` is ignored; ``spec.alpha`` plays no part.
    """
    from .recommend import other_criterion, recommend
    from .result import ErrorSummary
    from .sweep import DesignResult, equal_travel_side_lengths, gain_warnings

    spec = spec.for_wheelbase(float(robot.nominal.wheelbase_m))
    validation = spec.validation_track
    track = validation.track()
    candidates = []
    for N, lengths in equal_travel_side_lengths(spec.lengths_m, spec.sides).items():
        candidates += analytic_design(
            robot, N, lengths, spec.runs_per_direction, spec.method, track
        )
    ref = analytic_reference(robot, track)
    floor = ErrorSummary(ref.floor_m, ref.floor_std_m, ref.floor_ci95_m, 0)
    uncal = ErrorSummary(ref.uncalibrated_m, ref.uncalibrated_std_m, ref.uncalibrated_ci95_m, 0)
    rec = recommend(candidates, spec.alpha, spec.tolerance, spec.criterion)
    result = DesignResult(
        tuple(candidates),
        floor,
        uncal,
        rec,
        validation,
        spec.method,
        spec.runs_per_direction,
        None,
        None,
        truth_factors=true_factors(robot),
        other=other_criterion(candidates, rec),
    )
    return replace(result, warnings=gain_warnings(result))
