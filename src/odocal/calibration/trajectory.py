"""Trajectory calibration: nonlinear least squares of dead-reckoned runs against ground truth.

Estimates D_R, D_L and b (m), scale included, from any runs with ground truth (squares, lines,
spins, circles, free paths), with ``scipy.optimize.least_squares`` started from the nominal
geometry and from the linear estimator (``calibration.linear``) where that one is informative
(not on closed tracks, where it is singular). :func:`fit_trajectory_trials` is the 'pose' fit of
many Monte-Carlo trials at once (exact Jacobian, one batched Levenberg-Marquardt).

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

from collections.abc import Callable, Iterable, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon, dead_reckon_rows
from ..core.recording import Recording
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


def robust_z(values: ArrayLike) -> np.ndarray:
    """Robust z-scores 0.6745 (v - median) / MAD (0 where MAD is 0), shape like ``values``."""
    v = np.asarray(values, dtype=float)
    med = np.median(v)
    mad = np.median(np.abs(v - med))
    if mad == 0:
        return np.zeros_like(v)
    return 0.6745 * (v - med) / mad


def match_runs(names: Iterable[str], patterns: Sequence[str]) -> list[str]:
    """Names matched by any pattern: the full name, its file name, or a substring of it."""
    out = []
    for n in names:
        for p in patterns:
            if p == n or p == Path(n).name or p in n:
                out.append(n)
                break
    return out


def _travel(phi_r: np.ndarray, phi_l: np.ndarray, geometry: WheelGeometry) -> np.ndarray:
    """Cumulative mean absolute wheel travel (m) at every sample, shape (K,): spins count too."""
    step = 0.25 * (
        np.abs(np.diff(phi_r)) * geometry.diameter_right_m
        + np.abs(np.diff(phi_l)) * geometry.diameter_left_m
    )
    return np.concatenate([[0.0], np.cumsum(step)])


def _pose_samples(n: int, samples: int) -> np.ndarray:
    """Indices of the (at most ``samples``) evenly spaced samples of a run of ``n`` samples that
    the 'pose' residual compares (the start, 0 = 0, is left out)."""
    return np.unique(np.linspace(1, n - 1, min(samples, n - 1)).round().astype(int))


def _block_weight(travel_m: float, count: int, run_weight: str) -> float:
    """Scale of a run's residual rows: total weight 1 ('equal') or its travel in m ('travel'),
    however many rows it has."""
    total = 1.0 if run_weight == "equal" else max(travel_m, 1e-9)
    return float(np.sqrt(total / count))


class RunResiduals:
    """Pre-computed arrays of one run for fast residual evaluation."""

    def __init__(
        self,
        rec: Recording,
        kind: str,
        samples: int,
        segment_m: float,
        start: WheelGeometry,
        run_weight: str = "travel",
    ) -> None:
        self.name = rec.name
        self.phi_r = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        self.phi_l = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        self.gt = np.asarray(rec.ground_truth, dtype=float)
        n = len(self.gt)
        travel = _travel(self.phi_r, self.phi_l, start)
        self.travel_m = float(travel[-1])
        if kind == "pose":
            self.idx = _pose_samples(n, samples)
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
        self.weight = _block_weight(self.travel_m, count, run_weight)


def relative_poses(P: np.ndarray, i0: np.ndarray, i1: np.ndarray) -> np.ndarray:
    d = P[i1, :2] - P[i0, :2]
    c, s = np.cos(P[i0, 2]), np.sin(P[i0, 2])
    return np.column_stack(
        [c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1], P[i1, 2] - P[i0, 2]]
    )


def _run_residual(run: RunResiduals, p: np.ndarray, kind: str, w_head: float) -> np.ndarray:
    """One run's (unweighted) residual at geometry ``p`` = (D_R, D_L, b): the definition that
    :class:`_Residuals` evaluates for many runs at once."""
    odo = dead_reckon(run.phi_r, run.phi_l, WheelGeometry.unchecked(*p))
    if kind == "pose":
        e = run.gt[run.idx] - odo[run.idx]
    else:
        e = run.gt_rel - relative_poses(odo, run.i0, run.i1)
    e = e.copy()
    e[:, 2] *= w_head
    return e.ravel()


# Blocks of runs dead-reckoned at once: at most this share of zero padding (extra work) and
# this many increments (temporaries of 128 KiB that stay in the cache; larger blocks are slower)
_MAX_PADDING = 0.1
_MAX_BLOCK = 2**14


class _Residuals:
    """The residual of ``runs`` at a geometry, bit for bit ``np.concatenate([r.weight *
    _run_residual(r, p, kind, w_head) for r in runs])`` (``weighted=False``: without r.weight).

    The runs are sorted by length and packed into blocks of similar length, each dead-reckoned
    at once by :func:`~odocal.core.odometry.dead_reckon_rows` (the operations of
    ``dead_reckon`` on every element); the compared samples are gathered per block and put back
    in the runs' order with one precomputed permutation.
    """

    def __init__(
        self, runs: list[RunResiduals], kind: str, w_head: float, weighted: bool = True
    ) -> None:
        self.kind, self.w_head = kind, w_head
        if kind == "pose":
            samples = [r.idx for r in runs]
            truth = [r.gt[r.idx] for r in runs]
        else:  # the starts, then the ends of a run's segments
            samples = [np.concatenate([r.i0, r.i1]) for r in runs]
            truth = [r.gt_rel for r in runs]
        self.truth = np.concatenate(truth)
        counts = [len(t) for t in truth]
        self.splits = 3 * np.cumsum(counts)[:-1]  # where each run's part of the residual starts
        self.weight = np.repeat([r.weight if weighted else 1.0 for r in runs], counts)[:, None]
        # where every run's samples go in self.poses
        sizes = [len(t) for t in samples]
        where = np.split(np.arange(sum(sizes)), np.cumsum(sizes)[:-1])
        if kind == "segment":
            self.i0 = np.concatenate([w[:n] for w, n in zip(where, counts, strict=True)])
            self.i1 = np.concatenate([w[n:] for w, n in zip(where, counts, strict=True)])
        lengths = [len(r.phi_r) - 1 for r in runs]
        by_length = sorted(range(len(runs)), key=lambda j: -lengths[j])
        self.blocks = []
        gathered = []
        while by_length:
            width = lengths[by_length[0]]
            n, work = 1, width
            while (
                n < len(by_length)
                and (n + 1) * width <= _MAX_BLOCK
                and (n + 1) * width <= (1 + _MAX_PADDING) * (work + lengths[by_length[n]])
            ):
                work += lengths[by_length[n]]
                n += 1
            block, by_length = by_length[:n], by_length[n:]
            inc_r = np.zeros((n, width))
            inc_l = np.zeros((n, width))
            for i, j in enumerate(block):
                inc_r[i, : lengths[j]] = np.diff(runs[j].phi_r)
                inc_l[i, : lengths[j]] = np.diff(runs[j].phi_l)
            flat = np.concatenate([i * (width + 1) + samples[j] for i, j in enumerate(block)])
            self.blocks.append((inc_r, inc_l, flat))
            gathered += [where[j] for j in block]
        gathered_at = np.concatenate(gathered)
        self.order = np.empty_like(gathered_at)
        self.order[gathered_at] = np.arange(len(gathered_at))

    def poses(self, p: np.ndarray) -> np.ndarray:
        """Dead-reckoned poses at the compared samples, shape (samples, 3), in the runs' order."""
        g = WheelGeometry.unchecked(*p)
        parts = [dead_reckon_rows(ri, li, g).reshape(3, -1)[:, k] for ri, li, k in self.blocks]
        return np.concatenate(parts, axis=1)[:, self.order].T

    def __call__(self, p: np.ndarray) -> np.ndarray:
        odo = self.poses(p)
        if self.kind == "pose":
            e = self.truth - odo
        else:
            e = self.truth - relative_poses(odo, self.i0, self.i1)
        e[:, 2] *= self.w_head
        return (self.weight * e).ravel()

    def per_run(self, residual: np.ndarray) -> list[np.ndarray]:
        """A residual of __call__ cut into the runs' parts."""
        return np.split(residual, self.splits)


def solve_lm(fun: Callable[[np.ndarray], np.ndarray], x0: np.ndarray, **tolerances: float) -> Any:
    """scipy's Levenberg-Marquardt (``least_squares``, parameters scaled by 1 % of |x0|) from
    ``x0``; ``sol.evaluations`` counts every evaluation of ``fun`` (scipy's ``nfev`` leaves out
    those of its finite-difference Jacobian). The trajectory and banded fits use it."""
    from scipy.optimize import least_squares  # here: a slow import

    evaluations = 0

    def counted(p: np.ndarray) -> np.ndarray:
        nonlocal evaluations
        evaluations += 1
        return fun(p)

    scale = np.abs(np.asarray(x0)) * 1e-2
    with np.errstate(all="ignore"):
        sol = least_squares(counted, x0, x_scale=scale, method="lm", **tolerances)
    sol.evaluations = evaluations
    return sol


def optimizer_report(sol: Any) -> dict:
    """What a fit reports of its :func:`solve_lm` solution: scipy's ``nfev``, every residual
    evaluation (its Jacobian's too) and scipy's status."""
    return {"nfev": int(sol.nfev), "evaluations": int(sol.evaluations), "status": int(sol.status)}


# Largest heading weight (m of residual per rad): 1 km/rad already ignores the positions.
MAX_HEADING_WEIGHT_M = 1e3

# The linear estimate is a starting point only if its largest relative standard error is below
# this: it is 0.2-2 % on open arcs and 6-360 % on closed squares, where its position step is
# singular (calibration.linear).
MAX_LINEAR_START_STDERR = 0.05


def _relative_stderr(fit: GeometryFit) -> float:
    """Largest standard error of a fit relative to its value (0 when it has none)."""
    g = fit.geometry.as_dict()
    rel = [fit.stderr[k] / abs(g[k]) for k in g if fit.stderr.get(k) is not None]
    return max(rel, default=0.0)


def fit_trajectory(
    recordings: Iterable[Recording],
    start: WheelGeometry | None = None,
    *,
    nominal: WheelGeometry | None = None,
    residual: str = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    samples_per_run: int = 200,
    exclude: Sequence[str] = (),
    drop_outliers: bool = False,
    outlier_z: float = 3.5,
    run_weight: str = "travel",
) -> GeometryFit:
    """Fit (D_R, D_L, b) to the ground truth of ``recordings`` (module docstring).

    start : starting point (default: both the linear estimate and ``nominal``, the better fit
        kept; the linear estimate only where its standard errors are below
        MAX_LINEAR_START_STDERR of its values, as they are not on closed tracks).
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
            lin = fit_linear(use, nominal)
            spread = _relative_stderr(lin)
            if nominal is not None and spread > MAX_LINEAR_START_STDERR:
                # Closed tracks (squares, circles) leave the linear position step singular: the
                # estimate is noise (standard errors of 6 % to 360 % on the OptiOdom squares),
                # a start far away that costs iterations and can end in a wrong minimum.
                linear_start = f"not used: degenerate (standard error {100 * spread:.0f} %)"
            else:
                starts.append(lin.geometry)
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

    # travel (run weights, segments) is measured with the first start: the informative linear
    # estimate, else nominal
    gauge = starts[0]

    def fit(rs: list[Recording]) -> tuple[Any, ...]:
        # every start is tried and the lowest cost kept: the linear estimate is usually best,
        # but it can be far off when the runs' end poses alone condition it badly
        best = None
        runs = [
            RunResiduals(r, residual, samples_per_run, segment_m, gauge, run_weight) for r in rs
        ]
        fun = _Residuals(runs, residual, heading_weight_m)
        for g in starts:
            x0 = np.array([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m], float)
            sol = solve_lm(fun, x0, xtol=1e-12, ftol=1e-12, gtol=1e-15)
            if np.all(np.isfinite(sol.x)) and np.all(sol.x > 0):
                if best is None or sol.cost < best[1].cost:
                    best = (runs, sol, x0)
            elif best is None:
                best = (runs, sol, x0)
        return best[0], best[1]

    runs, sol = fit(use)
    # outlier statistic: RMS of the SEGMENT residuals whatever residual the fit used, because
    # segments have the same travel in every run, so short and long runs are comparable
    seg_runs = [RunResiduals(r, "segment", samples_per_run, segment_m, gauge) for r in use]
    segments = _Residuals(seg_runs, "segment", heading_weight_m, weighted=False)
    rms = np.array([np.sqrt(np.mean(e**2)) for e in segments.per_run(segments(sol.x))])
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
            "optimizer": optimizer_report(sol),
            "starts_tried": len(starts),
            "linear_start": linear_start,
        },
    )


# --- every Monte-Carlo trial at once ------------------------------------------------------------


def _dead_reckon_trials(
    dphi_r: np.ndarray, dphi_l: np.ndarray, x: np.ndarray, jacobian: bool
) -> tuple[np.ndarray, np.ndarray | None]:
    """Dead reckoning (the operations of :func:`odocal.core.odometry.dead_reckon`) of one run's
    wheel-angle increments ``dphi_r``, ``dphi_l`` (rad, shape (K-1,)) with every geometry of
    ``x`` (shape (M, 3): D_R, D_L, b in m).

    Returns the poses after every increment, shape (3, M, K-1) (x, y, theta), and with
    ``jacobian`` their exact derivatives with respect to (D_R, D_L, b), shape (3, 3, M, K-1)
    (parameter, pose component, trial, increment); else None.
    """
    d_r, d_l, b = x[:, 0:1], x[:, 1:2], x[:, 2:3]
    dr = dphi_r * (0.5 * d_r)
    dl = dphi_l * (0.5 * d_l)
    ds = 0.5 * (dr + dl)
    dth = (dr - dl) / b
    theta = np.cumsum(dth, axis=1)
    before = np.zeros_like(theta)
    before[:, 1:] = theta[:, :-1]
    mid = before + 0.5 * dth
    c, s = np.cos(mid), np.sin(mid)
    dsc, dss = ds * c, ds * s
    poses = np.stack([np.cumsum(dsc, axis=1), np.cumsum(dss, axis=1), theta])
    if not jacobian:
        return poses, None
    # d(ds), d(dtheta) per increment and d(theta before the increment), for D_R, D_L, b
    inv2b = 0.5 / b
    phi_r_before = np.concatenate([[0.0], np.cumsum(dphi_r)[:-1]])
    phi_l_before = np.concatenate([[0.0], np.cumsum(dphi_l)[:-1]])
    parts = (
        (0.25 * dphi_r, dphi_r * inv2b, phi_r_before * inv2b),
        (0.25 * dphi_l, -dphi_l * inv2b, -phi_l_before * inv2b),
        (None, -dth / b, -before / b),
    )
    jac = np.empty((3, 3, *theta.shape))
    for p, (d_ds, d_dth, d_before) in enumerate(parts):
        d_mid = d_before + 0.5 * d_dth
        gx, gy = -dss * d_mid, dsc * d_mid
        if d_ds is not None:
            gx += d_ds * c
            gy += d_ds * s
        jac[p, 0] = np.cumsum(gx, axis=1)
        jac[p, 1] = np.cumsum(gy, axis=1)
        jac[p, 2] = np.cumsum(d_dth, axis=1)
    return poses, jac


class _TrialGroup:
    """One group of runs with the same wheel angles: increments, samples, weight and the
    (weighted) mean ground truth at the samples over the group's runs, per trial."""

    def __init__(
        self,
        angles: ArrayLike,
        truth: ArrayLike,
        start: WheelGeometry,
        samples: int,
        run_weight: str,
    ) -> None:
        angles = np.asarray(angles, dtype=float)
        truth = np.asarray(truth, dtype=float)
        if angles.ndim != 2 or angles.shape[1] != 2 or len(angles) < 2:
            raise CalibrationError("wheel angles must have shape (K >= 2, 2)")
        if truth.ndim != 4 or truth.shape[2:] != (len(angles), 3):
            raise CalibrationError(
                f"ground truth must have shape (trials, runs, {len(angles)}, 3), got {truth.shape}"
            )
        self.dphi_r = np.diff(angles[:, 0])
        self.dphi_l = np.diff(angles[:, 1])
        self.idx = _pose_samples(len(angles), samples)
        travel = float(_travel(angles[:, 0], angles[:, 1], start)[-1])
        runs = truth.shape[1]
        # sum over the runs of w^2 |g_j - o|^2 = runs w^2 |mean g - o|^2 + const
        self.weight = _block_weight(travel, len(self.idx), run_weight) * np.sqrt(runs)
        self.truth = np.moveaxis(truth[:, :, self.idx, :].mean(axis=1), -1, 0)  # (3, M, S)


def _normal_equations(
    groups: list[_TrialGroup],
    x: np.ndarray,
    trials: np.ndarray,
    w_head: float,
    jacobian: bool = True,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """cost (M,), J^T J (M, 3, 3) and J^T r (M, 3) of the weighted pose residuals of the trials
    ``trials`` at ``x`` (M, 3); r = ground truth - odometry, heading times ``w_head``."""
    scale = np.array([1.0, 1.0, w_head])[:, None, None]
    cost = np.zeros(len(x))
    jtj = np.zeros((len(x), 3, 3))
    jtr = np.zeros((len(x), 3))
    for g in groups:
        poses, jac = _dead_reckon_trials(g.dphi_r, g.dphi_l, x, jacobian)
        idx = g.idx - 1  # pose after increment k is sample k + 1
        r = g.weight * scale * (g.truth[:, trials] - poses[:, :, idx])  # (3, M, S)
        r = np.moveaxis(r, 1, 0).reshape(len(x), -1)  # (M, 3 S)
        cost += np.einsum("mn,mn->m", r, r)
        if jacobian:
            j = -g.weight * scale * jac[:, :, :, idx]  # (3, 3, M, S)
            j = np.moveaxis(j, 2, 0).reshape(len(x), 3, -1)  # (M, 3, 3 S)
            jtj += j @ np.swapaxes(j, 1, 2)
            jtr += (j @ r[:, :, None])[:, :, 0]
    return cost, jtj, jtr


# Relative rounding of the trials' cost (see fit_trajectory_trials).
_COST_ROUNDING = 1e-10


def fit_trajectory_trials(
    angles: Sequence[ArrayLike],
    truth: Sequence[ArrayLike],
    start: WheelGeometry,
    *,
    heading_weight_m: float = 0.1,
    samples_per_run: int = 200,
    run_weight: str = "travel",
    max_iterations: int = 100,
) -> np.ndarray:
    """The 'pose' fit of :func:`fit_trajectory` for many Monte-Carlo trials at once.

    Parameters
    ----------
    angles : sequence of ndarray, shape (K_g, 2)
        Per group of runs: the cumulative wheel angles (right, left; rad) that every run of the
        group and every trial shares (the commanded rotations of an open-loop drive).
    truth : sequence of ndarray, shape (M, R_g, K_g, 3)
        Per group: the ground-truth poses (x_m, y_m, theta_rad; start frame) of its R_g runs in
        each of M trials.
    start : WheelGeometry
        Scalar geometry every trial starts from (the one the robot ran with), also used to
        measure the run weights' travel. Never the linear estimate: it is singular on closed
        tracks (calibration.linear), where it starts far away and can end in a wrong minimum.
    heading_weight_m, samples_per_run, run_weight
        As in :func:`fit_trajectory`.

    Returns
    -------
    ndarray, shape (M, 3)
        D_R, D_L, b (m) per trial; NaN rows where a fit did not reach a finite, positive
        geometry.

    The runs of a group share their dead reckoning, so the sum of their squared residuals is
    R_g times that of the group's mean trajectory plus a constant: the fit is made to the mean
    (the same minimum, exactly). The Jacobian is exact (derivatives of the midpoint dead
    reckoning), and one Levenberg-Marquardt iteration (Marquardt's diagonal scaling) serves all
    trials at once, each with its own damping. A step is taken unless it raises the cost by more
    than its rounding (1e-10 relative, with margin); a trial stops when its step is below 1e-10
    of its parameters or the reduction its quadratic model still promises is below 1e-12 of its
    cost.
    """
    if run_weight not in RUN_WEIGHTS:
        raise CalibrationError(
            f"run_weight must be one of {', '.join(RUN_WEIGHTS)}, got {run_weight!r}"
        )
    groups = [
        _TrialGroup(a, t, start, samples_per_run, run_weight)
        for a, t in zip(angles, truth, strict=True)
    ]
    m = groups[0].truth.shape[1]
    x0 = np.array([start.diameter_right_m, start.diameter_left_m, start.wheelbase_m], float)
    x = np.tile(x0, (m, 1))
    everyone = np.arange(m)
    with np.errstate(all="ignore"):
        cost, jtj, jtr = _normal_equations(groups, x, everyone, heading_weight_m)
        damping = np.full(m, 1e-3)
        active = np.isfinite(cost)
        for _ in range(max_iterations):
            trials = np.flatnonzero(active)
            if trials.size == 0:
                break
            a = jtj[trials]
            diag = np.einsum("mii->mi", a)
            lhs = a + damping[trials, None, None] * (diag[:, :, None] * np.eye(3))
            try:
                step = np.linalg.solve(lhs, -jtr[trials][:, :, None])[:, :, 0]
            except np.linalg.LinAlgError:
                step = (np.linalg.pinv(lhs) @ -jtr[trials][:, :, None])[:, :, 0]
            new = x[trials] + step
            # reduction the local quadratic model predicts for the step
            g = jtr[trials]
            predicted = -np.einsum("mi,mi->m", g, step) - 0.5 * np.einsum(
                "mi,mij,mj->m", step, a, step
            )
            c_new, a_new, g_new = _normal_equations(groups, new, trials, heading_weight_m)
            # the cost is known to about 1e-12 relative (residuals of millimetres are sums of
            # hundreds of increments of metres): a step that raises it by less is taken
            better = np.isfinite(c_new) & (c_new <= cost[trials] * (1.0 + _COST_ROUNDING))
            took = trials[better]
            done = np.all(np.abs(step[better]) <= 1e-10 * np.abs(new[better]), axis=1) | (
                predicted[better] <= 1e-2 * _COST_ROUNDING * cost[took]
            )
            x[took], cost[took], jtj[took], jtr[took] = (
                new[better],
                c_new[better],
                a_new[better],
                g_new[better],
            )
            damping[took] = np.maximum(damping[took] * 0.1, 1e-15)
            failed = trials[~better]
            damping[failed] *= 10.0
            active[took[done]] = False
            active[failed[damping[failed] > 1e16]] = False
    bad = ~np.all(np.isfinite(x) & (x > 0), axis=1) | ~np.isfinite(cost)
    x[bad] = np.nan
    return x
