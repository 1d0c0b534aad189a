"""Trajectory calibration: nonlinear least squares of dead-reckoned runs against ground truth.

Estimates D_R, D_L and b (m), scale included, from any runs with ground truth (squares, lines,
spins, circles, free paths), with ``scipy.optimize.least_squares`` started from the linear
estimator (``calibration.linear``).

Residuals (``residual=``):

- ``'pose'`` (default): the pose error ground truth - odometry at up to ``samples_per_run``
  evenly spaced samples of each run, position (m) and heading times ``heading_weight_m`` (m/rad).
  It keeps the accumulated heading drift that the final error of a long run is made
  of. Its samples are strongly correlated along a run, so late samples (which carry the whole
  drift) dominate within a run, and the formal standard errors are optimistic.
- ``'segment'``: the OptiOdom idea (Sousa et al. 2022): cut every run into segments of
  ``segment_m`` of travel (travel = mean absolute wheel travel, so spins count too) and compare
  the relative displacement over each segment, expressed in the segment's start frame
  (dx, dy, heading_weight_m * dtheta). Errors do not accumulate across segments, so one bad
  stretch (a slip, a tracking glitch) cannot bend the rest of the run; segment residuals are
  closer to independent.

Run weights (``run_weight=``): each run's residual block is scaled so that its total weight is
its travel in metres (``'travel'``, default: a run carries information on the systematic
parameters in proportion to how far it drives, and many short spins must not outvote a few long
runs) or 1 (``'equal'``). Travel = mean absolute wheel travel, so spot turns count.

Standard errors: cov = s^2 (J^T J)^-1 at the solution, s^2 = SSR / (m - 3), with J the Jacobian
of the (weighted) residuals. This assumes independent residuals of equal variance and a locally
linear model; trajectory residuals are correlated along a run, so treat the errors as a lower
bound (the spread between runs, ``per_run``, is the honest check).

Outliers: the RMS of each run's SEGMENT residuals at the solution (whatever ``residual`` the fit
used: every segment has the same travel, so short and long runs are comparable; the RMS of a
whole-run pose residual grows with the run's length and would flag long runs), robust z-score
z = 0.6745 (rms - median) / MAD; runs with z > ``outlier_z`` (default 3.5, Iglewicz & Hoaglin)
are flagged. ``drop_outliers=True`` refits once without them; ``exclude`` leaves named runs out.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from scipy.optimize import least_squares

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon
from ..errors import CalibrationError
from .linear import fit_linear
from .result import GeometryFit, check_physical, stderr_dict

__all__ = [
    "fit_trajectory",
    "RESIDUALS",
    "RUN_WEIGHTS",
    "RunResiduals",
    "relative_poses",
    "robust_z",
    "match_runs",
]

RESIDUALS = ("pose", "segment")
RUN_WEIGHTS = ("travel", "equal")


def robust_z(values) -> np.ndarray:
    """Robust z-scores 0.6745 (v - median) / MAD (0 where MAD is 0), shape like ``values``."""
    v = np.asarray(values, dtype=float)
    med = np.median(v)
    mad = np.median(np.abs(v - med))
    if mad == 0:
        return np.zeros_like(v)
    return 0.6745 * (v - med) / mad


def match_runs(names, patterns) -> list[str]:
    """Names matched by any pattern: the full name, its file name, or a substring of it."""
    out = []
    for n in names:
        for p in patterns:
            if p == n or p == Path(n).name or p in n:
                out.append(n)
                break
    return out


class RunResiduals:
    """Pre-computed arrays of one run for fast residual evaluation."""

    def __init__(self, rec, kind, samples, segment_m, start: WheelGeometry, run_weight="travel"):
        self.name = rec.name
        self.phi_r = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        self.phi_l = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        self.gt = np.asarray(rec.ground_truth, dtype=float)
        n = len(self.gt)
        # travel = mean absolute wheel travel (m) with the start geometry: spins count too
        travel = np.concatenate(
            [
                [0.0],
                np.cumsum(
                    0.25
                    * (
                        np.abs(np.diff(self.phi_r)) * start.diameter_right_m
                        + np.abs(np.diff(self.phi_l)) * start.diameter_left_m
                    )
                ),
            ]
        )
        self.travel_m = float(travel[-1])
        if kind == "pose":
            self.idx = np.unique(np.linspace(1, n - 1, min(samples, n - 1)).round().astype(int))
            count = len(self.idx)
        else:
            if travel[-1] / segment_m > 10 * n:
                # segments shorter than the samples: every sample that moved starts one (what the
                # grid below gives in that limit, without a grid of billions of points)
                marks = np.r_[0, np.flatnonzero(np.diff(travel) > 0) + 1]
            else:
                marks = np.searchsorted(travel, np.arange(0.0, travel[-1], segment_m))
            marks = np.unique(np.append(marks, n - 1))
            if len(marks) < 2:
                marks = np.array([0, n - 1])
            self.i0, self.i1 = marks[:-1], marks[1:]
            self.gt_rel = relative_poses(self.gt, self.i0, self.i1)
            count = len(self.i0)
        # a run's block is scaled so that its total weight is 1 ('equal') or its travel in m
        # ('travel'), however many residual rows it has
        total = 1.0 if run_weight == "equal" else max(self.travel_m, 1e-9)
        self.weight = float(np.sqrt(total / count))


def relative_poses(P, i0, i1):
    d = P[i1, :2] - P[i0, :2]
    c, s = np.cos(P[i0, 2]), np.sin(P[i0, 2])
    return np.column_stack(
        [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], P[i1, 2] - P[i0, 2]]
    )


def _run_residual(run: RunResiduals, p, kind, w_head) -> np.ndarray:
    odo = dead_reckon(run.phi_r, run.phi_l, WheelGeometry.unchecked(*p))
    if kind == "pose":
        e = run.gt[run.idx] - odo[run.idx]
    else:
        e = run.gt_rel - relative_poses(odo, run.i0, run.i1)
    e = e.copy()
    e[:, 2] *= w_head
    return e.ravel()


def _solve(runs, x0, kind, w_head):
    def fun(p):
        return np.concatenate([r.weight * _run_residual(r, p, kind, w_head) for r in runs])

    scale = np.abs(np.asarray(x0)) * 1e-2
    with np.errstate(all="ignore"):
        sol = least_squares(fun, x0, x_scale=scale, method="lm", xtol=1e-12, ftol=1e-12)
    return sol


# Largest heading weight (m of residual per rad): 1 km/rad already ignores the positions.
MAX_HEADING_WEIGHT_M = 1e3


def fit_trajectory(
    recordings,
    start: WheelGeometry | None = None,
    *,
    nominal: WheelGeometry | None = None,
    residual: str = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    samples_per_run: int = 200,
    exclude=(),
    drop_outliers: bool = False,
    outlier_z: float = 3.5,
    run_weight: str = "travel",
) -> GeometryFit:
    """Fit (D_R, D_L, b) to the ground truth of ``recordings`` (module docstring).

    start : starting point (default: the linear estimate, else ``nominal``).
    heading_weight_m : metres of residual per radian of heading error (0 = position only).
    exclude : run names (or file names, or substrings) to leave out.
    """
    if run_weight not in RUN_WEIGHTS:
        raise CalibrationError(
            f"run_weight must be one of {', '.join(RUN_WEIGHTS)}, got {run_weight!r}"
        )
    if residual not in RESIDUALS:
        raise CalibrationError(f"residual must be one of {', '.join(RESIDUALS)}, got {residual!r}")
    if not 0.0 <= heading_weight_m <= MAX_HEADING_WEIGHT_M:  # also rejects NaN
        raise CalibrationError(
            f"heading_weight_m must be between 0 and {MAX_HEADING_WEIGHT_M:g} m/rad (beyond, the "
            f"position no longer counts and the squares overflow), got {heading_weight_m!r}"
        )
    names = [r.name for r in recordings]
    excluded = match_runs(names, list(exclude))
    unmatched = [p for p in exclude if not match_runs(names, [p])]
    if unmatched:
        raise CalibrationError(f"--exclude {unmatched[0]!r} matches no run")
    use = [r for r in recordings if r.name not in excluded]
    if not use:
        raise CalibrationError("trajectory: every run is excluded")
    warnings: list[str] = []
    starts = []
    linear_start = "not used (start given)"
    if start is not None:
        starts.append(start)
    else:
        try:
            starts.append(fit_linear(use, nominal).geometry)
            linear_start = "used"
        except CalibrationError as exc:
            # Closed tracks (squares, spins) leave the linear estimator singular; that is no
            # problem for this fit, which then starts from nominal, so it is recorded, not warned.
            linear_start = f"unavailable: {exc}"
        if nominal is not None:
            starts.append(nominal)
        if not starts:
            raise CalibrationError(
                f"trajectory: no starting point (linear {linear_start}); give the nominal "
                "geometry (--robot)"
            )

    def fit(rs):
        # every start is tried and the lowest cost kept: the linear estimate is usually best,
        # but it can be far off when the runs' end poses alone condition it badly
        best = None
        for g in starts:
            x0 = np.array([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m], float)
            runs = [
                RunResiduals(r, residual, samples_per_run, segment_m, starts[0], run_weight)
                for r in rs
            ]
            sol = _solve(runs, x0, residual, heading_weight_m)
            if np.all(np.isfinite(sol.x)) and np.all(sol.x > 0):
                if best is None or sol.cost < best[1].cost:
                    best = (runs, sol, x0)
            elif best is None:
                best = (runs, sol, x0)
        return best[0], best[1]

    runs, sol = fit(use)
    # outlier statistic: RMS of the SEGMENT residuals whatever residual the fit used, because
    # segments have the same travel in every run, so short and long runs are comparable
    seg_runs = [RunResiduals(r, "segment", samples_per_run, segment_m, starts[0]) for r in use]
    rms = np.array(
        [
            np.sqrt(np.mean(_run_residual(r, sol.x, "segment", heading_weight_m) ** 2))
            for r in seg_runs
        ]
    )
    z = robust_z(rms) if len(rms) >= 3 else np.zeros(len(rms))
    outliers = [r.name for r, zi in zip(runs, z, strict=True) if zi > outlier_z]
    per_run = [
        {
            "name": r.name,
            "segment_rms": float(v),
            "robust_z": float(zi),
            "outlier": bool(zi > outlier_z),
        }
        for r, v, zi in zip(runs, rms, z, strict=True)
    ]
    if drop_outliers and outliers:
        kept = [r for r in use if r.name not in outliers]
        if kept:
            excluded = excluded + outliers
            use = kept
            runs, sol = fit(use)
    elif outliers:
        warnings.append(
            f"{len(outliers)} run(s) fit much worse than the rest (robust z > {outlier_z:g}): "
            + ", ".join(Path(n).name for n in outliers)
            + "; refit with --drop-outliers or --exclude RUN"
        )
    warnings += check_physical(sol.x, nominal, "trajectory")
    m = len(sol.fun)
    cov = None
    if m > 3:
        s2 = 2.0 * sol.cost / (m - 3)
        JtJ = sol.jac.T @ sol.jac
        try:
            cov = s2 * np.linalg.inv(JtJ)
        except np.linalg.LinAlgError:
            warnings.append("the parameters are not all identifiable from these runs")
    return GeometryFit(
        method="trajectory",
        geometry=WheelGeometry(*sol.x),
        stderr=stderr_dict(cov),
        covariance=cov,
        runs=[r.name for r in use],
        per_run=per_run,
        outliers=outliers,
        excluded=excluded,
        warnings=warnings,
        extras={
            "residual": residual,
            "segment_m": segment_m if residual == "segment" else None,
            "heading_weight_m": heading_weight_m,
            "run_weight": run_weight,
            "residual_rms": float(np.sqrt(2.0 * sol.cost / max(m, 1))),
            "optimizer": {"nfev": int(sol.nfev), "status": int(sol.status)},
            "starts_tried": len(starts),
            "linear_start": linear_start,
        },
    )
