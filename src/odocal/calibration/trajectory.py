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
from ..core.recording import Recording
from ..errors import CalibrationError
from .fit_methods import RESIDUALS, RUN_WEIGHTS, RunWeight
from .fit_settings import DEFAULT_TRAJECTORY, MAX_HEADING_WEIGHT_M, TrajectorySettings
from .linear import fit_linear
from .result import (
    GeometryFit,
    OptimizerReport,
    TrajectoryDetails,
    check_physical,
    stderr_dict,
)
from .robust_covariance import Consistency, cluster_covariance, group_consistency
from .trajectory_residuals import (
    RunResiduals,
    TrajectoryResiduals,
    block_weight,
    cumulative_travel,
    pose_samples,
    relative_poses,
)

__all__ = [
    "fit_trajectory_model",
    "fit_trajectory",
    "fit_trajectory_geometry",
    "fit_trajectory_trials",
    "RESIDUALS",
    "RUN_WEIGHTS",
    "MAX_HEADING_WEIGHT_M",
    "RunResiduals",
    "relative_poses",
    "robust_z",
    "match_runs",
    "solve_lm",
    "optimizer_report",
]


def robust_z(values: Any) -> np.ndarray:
    """Robust z-scores 0.6745 (v - median) / MAD (0 where MAD is 0), shape like ``values``."""
    v = np.asarray(values, dtype=float)
    med = np.median(v)
    mad = np.median(np.abs(v - med))
    if mad == 0:
        return np.zeros_like(v)
    return 0.6745 * (v - med) / mad


def match_runs(names: Iterable[str], patterns: Iterable[str]) -> list[str]:
    """Names matched by any pattern: the full name, its file name, or a substring of it."""
    out = []
    patterns = list(patterns)
    for n in names:
        for p in patterns:
            if p == n or p == Path(n).name or p in n:
                out.append(n)
                break
    return out


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


def optimizer_report(sol: Any) -> OptimizerReport:
    """What a fit reports of its :func:`solve_lm` solution: scipy's ``nfev``, every residual
    evaluation (its Jacobian's too) and scipy's status."""
    return OptimizerReport(int(sol.nfev), int(sol.evaluations), int(sol.status))


# The linear estimate is a starting point only if its largest relative standard error is below
# this: it is 0.2-2 % on open arcs and 6-360 % on closed squares, where its position step is
# singular (calibration.linear).
MAX_LINEAR_START_STDERR = 0.05


def _relative_stderr(fit: GeometryFit) -> float:
    """Largest standard error of a fit relative to its value (0 when it has none)."""
    g = fit.geometry.as_dict()
    rel = [e / abs(g[k]) for k in g if (e := fit.stderr.get(k)) is not None]
    return max(rel, default=0.0)


def _runs_to_fit(
    recordings: Sequence[Recording], exclude: Sequence[str]
) -> tuple[list[Recording], list[str]]:
    """The runs to fit and the names of those ``exclude`` leaves out."""
    names = [r.name for r in recordings]
    excluded = match_runs(names, list(exclude))
    unmatched = [p for p in exclude if not match_runs(names, [p])]
    if unmatched:
        raise CalibrationError(f"--exclude {unmatched[0]!r} matches no run")
    use = [r for r in recordings if r.name not in excluded]
    if not use:
        raise CalibrationError("trajectory: every run is excluded")
    return use, excluded


def _starting_points(
    use: Sequence[Recording], start: WheelGeometry | None, nominal: WheelGeometry | None
) -> tuple[list[WheelGeometry], str]:
    """The geometries the fit starts from (``start``; else the informative linear estimate and
    ``nominal``) and what became of the linear estimate."""
    if start is not None:
        return [start], "not used (start given)"
    starts = []
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
    return starts, linear_start


def _best_fit(
    rs: Sequence[Recording],
    starts: Sequence[WheelGeometry],
    gauge: WheelGeometry,
    s: TrajectorySettings,
) -> tuple[list[RunResiduals], Any]:
    """The runs' residual rows and the solution of the lowest cost over ``starts``."""
    # every start is tried and the lowest cost kept: the linear estimate is usually best,
    # but it can be far off when the runs' end poses alone condition it badly
    best = None
    runs = [
        RunResiduals(r, s.residual, s.samples_per_run, s.segment_m, gauge, s.run_weight) for r in rs
    ]
    fun = TrajectoryResiduals(runs, s.residual, s.heading_weight_m)
    for g in starts:
        x0 = np.array([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m], float)
        sol = solve_lm(fun, x0, xtol=1e-12, ftol=1e-12, gtol=1e-15)
        if np.all(np.isfinite(sol.x)) and np.all(sol.x > 0):
            if best is None or sol.cost < best[1].cost:
                best = (runs, sol, x0)
        elif best is None:
            best = (runs, sol, x0)
    assert best is not None  # at least one start
    return best[0], best[1]


def _outlier_runs(
    use: Sequence[Recording],
    runs: Sequence[RunResiduals],
    sol: Any,
    gauge: WheelGeometry,
    s: TrajectorySettings,
) -> tuple[list[str], list[dict[str, Any]]]:
    """The runs whose segment residuals stand out (robust z > ``s.outlier_z``) and every run's
    statistics."""
    # outlier statistic: RMS of the SEGMENT residuals whatever residual the fit used, because
    # segments have the same travel in every run, so short and long runs are comparable
    seg_runs = [RunResiduals(r, "segment", s.samples_per_run, s.segment_m, gauge) for r in use]
    segments = TrajectoryResiduals(seg_runs, "segment", s.heading_weight_m, weighted=False)
    rms = np.array([np.sqrt(np.mean(e**2)) for e in segments.per_run(segments(sol.x))])
    z = robust_z(rms) if len(rms) >= 3 else np.zeros(len(rms))
    outliers = [r.name for r, zi in zip(runs, z, strict=True) if zi > s.outlier_z]
    per_run = [
        {
            "name": r.name,
            "segment_rms": float(v),
            "robust_z": float(zi),
            "outlier": bool(zi > s.outlier_z),
        }
        for r, v, zi in zip(runs, rms, z, strict=True)
    ]
    return outliers, per_run


def _covariance(sol: Any, warnings: list[str]) -> np.ndarray | None:
    """cov = s^2 (J^T J)^-1 at the solution (module docstring); None without redundancy or when
    singular (then a warning)."""
    m = len(sol.fun)
    cov = None
    if m > 3:
        s2 = 2.0 * sol.cost / (m - 3)
        JtJ = sol.jac.T @ sol.jac
        try:
            cov = s2 * np.linalg.inv(JtJ)
        except np.linalg.LinAlgError:
            warnings.append("the parameters are not all identifiable from these runs")
    return cov


#: Fewest groups for a cluster-robust covariance over data sets or runs (else time blocks).
MIN_CLUSTERS = 8


def _row_clusters(
    runs: Sequence[RunResiduals], use: Sequence[Recording], kind: str
) -> tuple[np.ndarray, str]:
    """The independent group of every residual row, and what the groups are: the data sets
    (sessions) when there are enough of them, else the runs, else contiguous time blocks of
    each run (its rows are in time order)."""
    counts = [len(r.idx) if kind == "pose" else len(r.i0) for r in runs]
    sets = [r.dataset for r in use]
    names = sorted(set(sets))
    if len(names) >= MIN_CLUSTERS:
        labels = [names.index(d) for d in sets]
        return np.repeat(np.repeat(labels, counts), 3), f"{len(names)} data sets"
    if len(runs) >= MIN_CLUSTERS:
        return np.repeat(np.repeat(np.arange(len(runs)), counts), 3), f"{len(runs)} runs"
    per_run = max(1, -(-2 * MIN_CLUSTERS // max(len(runs), 1)))  # ceil
    blocks = np.concatenate(
        [i * per_run + (np.arange(c) * per_run) // max(c, 1) for i, c in enumerate(counts)]
    )
    return np.repeat(blocks, 3), f"{len(np.unique(blocks))} time blocks of {len(runs)} run(s)"


def _consistency(
    sol: Any, runs: Sequence[RunResiduals], use: Sequence[Recording], kind: str
) -> Consistency | None:
    """Do the data sets agree (else the first and second half of the runs, else of the one
    run's samples)? Each group's subclusters are its runs (time blocks of a lone run)."""
    counts = [len(r.idx) if kind == "pose" else len(r.i0) for r in runs]
    sets = [r.dataset for r in use]
    names = list(dict.fromkeys(sets))
    if len(names) >= 2:
        group_of_run = [names.index(d) for d in sets]
        labels = {i: n for i, n in enumerate(names)}
    elif len(runs) >= 2:
        half = len(runs) // 2
        group_of_run = [0 if i < half else 1 for i in range(len(runs))]
        labels = {0: "first half of the runs", 1: "second half of the runs"}
    else:
        group_of_run = []
        labels = {0: "first half of the run", 1: "second half of the run"}
    # the subclusters are runs, independent of each other: their dispersion is pooled over the
    # groups; time blocks of one run are not (group_consistency's pooled)
    runs_apart = bool(group_of_run)
    if group_of_run:
        groups = np.repeat(group_of_run, counts)
        subs = np.repeat(np.arange(len(runs)), counts)
        # a group of one run: its time blocks are the subclusters
        for g in set(group_of_run):
            members = [i for i, x in enumerate(group_of_run) if x == g]
            if len(members) == 1:
                runs_apart = False
                sel = groups == g
                subs[sel] = 10_000 * (g + 1) + (np.arange(sel.sum()) * 8) // max(sel.sum(), 1)
    else:
        n = counts[0] if counts else 0
        groups = (np.arange(n) * 2) // max(n, 1)
        subs = (np.arange(n) * 16) // max(n, 1)
    if 3 * len(groups) != len(sol.fun):
        return None
    return group_consistency(
        sol.jac, sol.fun, sol.x, np.repeat(groups, 3), np.repeat(subs, 3), labels,
        pooled=runs_apart,
    )  # fmt: skip


def _robust_covariance(
    sol: Any, runs: Sequence[RunResiduals], use: Sequence[Recording], s: TrajectorySettings
) -> tuple[np.ndarray, str, int] | None:
    """The cluster-robust covariance of the fit (:func:`_row_clusters`), its description and
    degrees of freedom; None when it cannot be formed."""
    clusters, what = _row_clusters(runs, use, s.residual)
    if len(clusters) != len(sol.fun):
        return None
    try:
        cc = cluster_covariance(sol.jac, sol.fun, clusters)
    except CalibrationError:
        return None
    return cc.covariance, f"cluster-robust over {what}", cc.dof


def _inconsistent(c: Consistency) -> str:
    """The warning for groups that disagree beyond their own uncertainty."""
    k = int(np.argmax(c.statistic))
    name = ("D_R", "D_L", "b")[k]
    lo, hi = int(np.argmin(c.estimates[:, k])), int(np.argmax(c.estimates[:, k]))
    return (
        f"the log is inconsistent: its parts disagree beyond their own uncertainty ({name}: "
        f"Q = {c.statistic[k]:.1f} on {c.dof} degrees of freedom, p = {c.p_value[k]:.2g}; from "
        f"{1e3 * c.estimates[lo, k]:.3f} mm in {c.groups[lo]} to {1e3 * c.estimates[hi, k]:.3f} "
        f"mm in {c.groups[hi]}): the robot, the floor or the truth changed between them, and "
        "the stated uncertainty holds only if the parts are a random sample of such changes"
    )


def fit_trajectory(
    recordings: Sequence[Recording],
    start: WheelGeometry | None = None,
    *,
    nominal: WheelGeometry | None = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
) -> GeometryFit:
    """Fit (D_R, D_L, b) to the ground truth of ``recordings`` (module docstring).

    start : starting point (default: both the linear estimate and ``nominal``, the better fit
        kept; the linear estimate only where its standard errors are below
        MAX_LINEAR_START_STDERR of its values, as they are not on closed tracks).
    settings : the residual, its weights, the runs excluded and the outlier rule
        (:class:`~odocal.calibration.fit_settings.TrajectorySettings`; its wheelbase model and
        motion mix are for :mod:`odocal.calibration.banded` and :mod:`.turning`).
    """
    s = settings
    use, excluded = _runs_to_fit(recordings, s.exclude)
    warnings: list[str] = []
    starts, linear_start = _starting_points(use, start, nominal)
    # travel (run weights, segments) is measured with the first start: the informative linear
    # estimate, else nominal
    gauge = starts[0]
    runs, sol = _best_fit(use, starts, gauge, s)
    outliers, per_run = _outlier_runs(use, runs, sol, gauge, s)
    if s.drop_outliers and outliers:
        kept = [r for r in use if r.name not in outliers]
        if kept:
            excluded = excluded + outliers
            use = kept
            runs, sol = _best_fit(use, starts, gauge, s)
    elif outliers:
        warnings.append(
            f"{len(outliers)} run(s) fit much worse than the rest (robust z > {s.outlier_z:g}): "
            + ", ".join(Path(n).name for n in outliers)
            + "; refit with --drop-outliers or --exclude RUN"
        )
    warnings += check_physical(sol.x, nominal, "trajectory")
    formal = _covariance(sol, warnings)
    cov, how, dof = formal, "formal", None
    robust = _robust_covariance(sol, runs, use, s) if formal is not None else None
    if robust is not None:
        cov, how, dof = robust
    consistency = _consistency(sol, runs, use, s.residual)
    if consistency is not None and not consistency.consistent:
        warnings.append(_inconsistent(consistency))
    m = len(sol.fun)
    return GeometryFit(
        method="trajectory",
        geometry=WheelGeometry(*sol.x),
        stderr=stderr_dict(cov),
        covariance=cov,
        uncertainty=how,
        covariance_formal=None if robust is None else formal,
        dof=dof,
        consistency=consistency,
        runs=[r.name for r in use],
        per_run=per_run,
        outliers=outliers,
        excluded=excluded,
        warnings=warnings,
        trajectory=TrajectoryDetails(
            settings=s,
            residual_rms=float(np.sqrt(2.0 * sol.cost / max(m, 1))),
            optimizer=optimizer_report(sol),
            starts_tried=len(starts),
            linear_start=linear_start,
        ),
    )


def fit_trajectory_model(
    recordings: Sequence[Recording],
    model: str,
    nominal: WheelGeometry,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
) -> WheelGeometry:
    """The trajectory fit of one model of :mod:`odocal.calibration.heldout`: 'full' is
    :func:`fit_trajectory`; 'equal-diameters' keeps D_R / D_L at the nominal ratio (a common
    wheel scale and b); 'scale' fits one factor on both diameters with b nominal. Same residual,
    weights and runs as the full fit (no outlier rule)."""
    if model == "full":
        return fit_trajectory(recordings, nominal=nominal, settings=settings).geometry
    use, _ = _runs_to_fit(recordings, settings.exclude)
    runs = [
        RunResiduals(r, settings.residual, settings.samples_per_run, settings.segment_m, nominal,
                     settings.run_weight)
        for r in use
    ]  # fmt: skip
    fun = TrajectoryResiduals(runs, settings.residual, settings.heading_weight_m)
    d_r, d_l, b = nominal.diameter_right_m, nominal.diameter_left_m, nominal.wheelbase_m

    def geometry(q: np.ndarray) -> np.ndarray:
        if model == "equal-diameters":
            return np.array([d_r * q[0], d_l * q[0], q[1]])
        return np.array([d_r * q[0], d_l * q[0], b])

    q0 = np.array([1.0, b]) if model == "equal-diameters" else np.array([1.0])
    sol = solve_lm(lambda q: fun(geometry(q)), q0, xtol=1e-12, ftol=1e-12, gtol=1e-15)
    return WheelGeometry(*geometry(sol.x))


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
        self, angles: Any, truth: Any, start: WheelGeometry, samples: int, run_weight: RunWeight
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
        self.idx = pose_samples(len(angles), samples)
        travel = float(cumulative_travel(angles[:, 0], angles[:, 1], start)[-1])
        runs = truth.shape[1]
        # sum over the runs of w^2 |g_j - o|^2 = runs w^2 |mean g - o|^2 + const
        self.weight = block_weight(travel, len(self.idx), run_weight) * np.sqrt(runs)
        self.truth = np.moveaxis(truth[:, :, self.idx, :].mean(axis=1), -1, 0)  # (3, M, S)


def _normal_equations(
    groups: Sequence[_TrialGroup],
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
        if jac is not None:  # computed when ``jacobian``
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
    run_weight: RunWeight = "travel",
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


def fit_trajectory_geometry(
    recordings: Sequence[Recording],
    nominal: WheelGeometry | None = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
) -> WheelGeometry:
    """The geometry of :func:`fit_trajectory` (the same starts, residual and optimum; no
    outlier refit, covariance or consistency check): for procedures fitted many times, as the
    folds of :mod:`odocal.design.run_procedures`."""
    use, _ = _runs_to_fit(recordings, settings.exclude)
    starts, _ = _starting_points(use, None, nominal)
    _, sol = _best_fit(use, starts, starts[0], settings)
    return WheelGeometry(*sol.x)
