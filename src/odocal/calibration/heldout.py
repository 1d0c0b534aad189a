"""Does the calibration help on driving it has not seen? A blocked cross-validation.

A fit can lower its own residuals and still make the robot's dead reckoning worse: on the MIT
CSAIL log, calibrated on the first half by the SLAM route, a 0.45 % left/right diameter
difference (fitted to a slow heading drift the model cannot express) makes the second half's
dead reckoning end 41 m off, against 12 m with the nominal parameters. So every route that has
a truth track checks its answer on data it did not fit.

The data are relative-motion intervals in time order (the wheels' rotations as sampled within
each interval, and the measured motion of the base over it); consecutive intervals that share an
instant form a chain that can be dead-reckoned. The log is cut into ``folds`` contiguous time
blocks; for each block, each model is fitted on the other blocks and every chain of the block is
dead-reckoned from its first instant with the nominal and with the fitted parameters; the error
is the distance between the dead-reckoned and the measured end of the chain (the measured motions
composed). A model's held-out error is the mean of those end errors over all chains of all
blocks, and each chain's errors of two models are paired, so the comparison is a paired one.

Models (each a robust fit of the base motions: the soft-L1 loss, about quadratic within its
scale and linear beyond, on each component scaled by its robust spread):

- ``full``: D_R, D_L and b;
- ``equal-diameters``: D_R / D_L held at the nominal ratio (a common wheel scale and b);
- ``scale``: one factor on both diameters, b nominal.

The verdict decides on the paired difference (model minus nominal, chain by chain) and its
standard error, never on the sign alone: a model beats the nominal parameters when the mean
difference is below zero by more than :data:`DECIDE_Z` standard errors, and is worse when it is
above by as much; in between the held-out data cannot tell them apart. The standard error is
the larger of the chains' own (as if independent) and the one clustered by fold (the chains of
a block share the model fitted without it): on the MIT CSAIL log the former rule (one standard
error, chains independent) called the whole log's calibration worse (+0.11 m, 0.6 standard
errors) and the same log thinned to every second SLAM update better. The full model is kept
when it beats the nominal; otherwise the restricted model with the lowest held-out error that
beats the nominal is preferred; when none does, the full model is kept if it is not worse (the
log cannot show that it helps: the verdict says so), and when it is worse the calibration is
not trustworthy (the caller refuses to export it without ``--force``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace
from typing import Literal, cast

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon, dead_reckon_rows
from ..core.path_drift import PathDrift, path_drift, path_length, piece_length_for, pool_drift
from ..core.recording import Recording
from ..core.transforms import se2_relative
from ..errors import CalibrationError
from .robust_covariance import cluster_covariance
from .time_offset import time_blocks

__all__ = [
    "MODELS",
    "DECIDE_Z",
    "paired_difference",
    "Model",
    "HeldOut",
    "ModelScore",
    "BaseMotionFit",
    "heldout_check",
    "fit_base_motion",
    "intervals_of_runs",
    "heldout_runs",
]

Model = Literal["full", "equal-diameters", "scale"]
MODELS: tuple[Model, ...] = ("full", "equal-diameters", "scale")
#: A model beats (or is worse than) the nominal parameters when their mean paired difference is
#: this many standard errors below (or above) zero.
DECIDE_Z = 2.0
#: Fewest chain ends a held-out comparison needs.
MIN_CHAINS = 4
#: Fewest usable intervals (each fold fits on the others).
MIN_INTERVALS = 20
#: The folds' fits (and the restricted models' fits on all the data) use at most this many
#: intervals, spread evenly over the log: three parameters are determined long before, and an
#: hour-long bag would otherwise fit 14 times on 7000 intervals.
MAX_FIT_INTERVALS = 400


def _finite(x: float) -> float | None:
    """``x``, or None when not finite (JSON has no NaN)."""
    return float(x) if math.isfinite(x) else None


def _spread(idx: np.ndarray, most: int) -> np.ndarray:
    """At most ``most`` of ``idx``, evenly spread."""
    if len(idx) <= most:
        return idx
    return idx[np.linspace(0, len(idx) - 1, most).round().astype(int)]


@dataclass(frozen=True)
class ModelScore:
    """One model on the held-out blocks.

    Attributes
    ----------
    model : str
    geometry : WheelGeometry
        Fitted on all the data (the answer this model gives).
    mean_final_error_m : float
        Mean end-of-chain position error over the held-out chains (m).
    beats_nominal : bool
        Lower held-out error than the nominal parameters, chain by chain (paired: the mean
        paired difference is below zero by more than :data:`DECIDE_Z` standard errors).
    fit : BaseMotionFit or None
        The model fitted on all the data, with its cluster-robust covariance (restricted
        models; the full model's answer is the route's own).
    worse_than_nominal : bool
        Higher held-out error than the nominal, by more than :data:`DECIDE_Z` standard errors.
    difference_m, difference_stderr_m : float
        The mean paired difference (this model minus the nominal, m) and its standard error
        (the larger of the chains' and the folds' clustered one).
    """

    model: str
    geometry: WheelGeometry
    mean_final_error_m: float
    beats_nominal: bool
    fit: BaseMotionFit | None = None
    worse_than_nominal: bool = False
    difference_m: float = math.nan
    difference_stderr_m: float = math.nan

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {
            "model": self.model,
            **self.geometry.as_dict(),
            "mean_final_error_m": self.mean_final_error_m,
            "difference_m": _finite(self.difference_m),
            "difference_stderr_m": _finite(self.difference_stderr_m),
            "beats_nominal": self.beats_nominal,
            "worse_than_nominal": self.worse_than_nominal,
        }


@dataclass(frozen=True)
class HeldOut:
    """The held-out check of a calibration.

    Attributes
    ----------
    folds : int
        Contiguous time blocks, each held out once.
    chains : int
        Chains dead-reckoned (their ends are the compared points).
    chain_seconds : float
        Median duration of a chain (s).
    nominal_final_error_m : float
        Mean end error with the nominal parameters (m).
    calibrated_final_error_m : float
        Mean end error with the full model, fitted without the block (m).
    models : tuple of ModelScore
        Every model, ``full`` first.
    preferred : str or None
        The model the held-out data prefer among those that beat the nominal; the full model
        when none does and it is not worse; None when it is worse and none beats the nominal.
    drift : tuple of (str, PathDrift or None)
        The KITTI-style drift of the held-out runs with the nominal and the full model (runs
        with a truth; empty for chains of relative motions).
    """

    folds: int
    chains: int
    chain_seconds: float
    nominal_final_error_m: float
    calibrated_final_error_m: float
    models: tuple[ModelScore, ...]
    preferred: str | None
    drift: tuple[tuple[str, PathDrift | None], ...] = ()

    @property
    def calibration_helps(self) -> bool:
        """The full calibration beats the nominal parameters on the held-out data."""
        return bool(self.models[0].beats_nominal)

    def verdict(self) -> str:
        """One line for the user."""
        nom, cal = self.nominal_final_error_m, self.calibrated_final_error_m
        full = self.models[0]
        diff = ""
        if math.isfinite(full.difference_m) and math.isfinite(full.difference_stderr_m):
            diff = f", difference {full.difference_m:+.3g} +- {full.difference_stderr_m:.2g} m"
        head = (
            f"held out ({self.folds} time blocks, {self.chains} chains of median "
            f"{self.chain_seconds:.0f} s): dead-reckoning error {cal:.3g} m calibrated against "
            f"{nom:.3g} m nominal{diff}"
        )
        if self.calibration_helps:
            return head + ": the calibration helps"
        how = (
            "makes it WORSE"
            if full.worse_than_nominal
            else f"is no measurable gain (within {DECIDE_Z:g} standard errors)"
        )
        if self.preferred == "full":
            return (
                head + f": the calibration {how}, and no model beats it there: kept (it is not "
                "worse on data it did not fit; the log cannot show that it helps)"
            )
        if self.preferred is not None:
            return (
                head + f": the full calibration {how}; the held-out data prefer the "
                f"'{self.preferred}' model"
            )
        return (
            head + f": the calibration {how}, and NO model beats the nominal parameters on "
            "data it did not fit"
        )

    def drift_line(self) -> str | None:
        """The held-out runs' KITTI-style drift in one line (None without it)."""
        d = dict(self.drift)
        full, nom = d.get("full"), d.get("nominal")
        if full is None or nom is None:
            return None
        return (
            f"held-out drift: {full.median_pct:.2f} % calibrated against {nom.median_pct:.2f} % "
            f"nominal (median of {full.pieces} pieces of {full.length_m:g} m of truth path, each "
            "re-anchored to the truth at its start)"
        )

    def as_dict(self) -> dict:
        """JSON-ready (the ``heldout`` object of ``fit --json``)."""
        return {
            "folds": self.folds,
            "chains": self.chains,
            "chain_seconds": self.chain_seconds,
            "nominal_final_error_m": self.nominal_final_error_m,
            "calibrated_final_error_m": self.calibrated_final_error_m,
            "calibration_helps": self.calibration_helps,
            "preferred_model": self.preferred,
            "models": [m.as_dict() for m in self.models],
            "drift_percent_per_10m": {
                k: None if d is None else d.contract() for k, d in self.drift
            },
            "verdict": self.verdict(),
        }


def _geometry(model: Model, q: np.ndarray, nominal: WheelGeometry) -> WheelGeometry:
    if model == "full":
        return WheelGeometry.unchecked(float(q[0]), float(q[1]), float(q[2]))
    if model == "equal-diameters":
        return WheelGeometry.unchecked(
            nominal.diameter_right_m * q[0], nominal.diameter_left_m * q[0], float(q[1])
        )
    return WheelGeometry.unchecked(
        nominal.diameter_right_m * q[0], nominal.diameter_left_m * q[0], nominal.wheelbase_m
    )


def _start(model: Model, nominal: WheelGeometry) -> np.ndarray:
    if model == "full":
        return np.array([nominal.diameter_right_m, nominal.diameter_left_m, nominal.wheelbase_m])
    if model == "equal-diameters":
        return np.array([1.0, nominal.wheelbase_m])
    return np.array([1.0])


def _predict(g: WheelGeometry, inc_r: np.ndarray, inc_l: np.ndarray) -> np.ndarray:
    """Base motion over each interval (n, 3), dead-reckoned over its sampled increments."""
    poses = dead_reckon_rows(inc_r, inc_l, g)
    return poses[:, :, -1].T


@dataclass(frozen=True)
class BaseMotionFit:
    """One model fitted to base motions.

    Attributes
    ----------
    model : str
    geometry : WheelGeometry
    covariance : ndarray, shape (3, 3), or None
        Of (D_R, D_L, b) (m^2): cluster-robust over time blocks
        (:mod:`odocal.calibration.robust_covariance`) when the intervals' times were given,
        None otherwise or when singular.
    dof : int
        Degrees of freedom of its standard errors (time blocks - 1; 0 without).
    """

    model: str
    geometry: WheelGeometry
    covariance: np.ndarray | None = None
    dof: int = 0

    @property
    def stderr(self) -> np.ndarray | None:
        """Standard errors of (D_R, D_L, b) (m), or None."""
        return None if self.covariance is None else np.sqrt(np.diag(self.covariance))


def _mapping(model: Model, nominal: WheelGeometry) -> np.ndarray:
    """d(D_R, D_L, b) / d(model parameters), shape (3, p)."""
    if model == "full":
        return np.eye(3)
    if model == "equal-diameters":
        return np.array([[nominal.diameter_right_m, 0.0], [nominal.diameter_left_m, 0.0],
                         [0.0, 1.0]])  # fmt: skip
    return np.array([[nominal.diameter_right_m], [nominal.diameter_left_m], [0.0]])


def fit_base_motion(
    model: Model,
    inc_r: np.ndarray,
    inc_l: np.ndarray,
    motion: np.ndarray,
    nominal: WheelGeometry,
    start_s: np.ndarray | None = None,
) -> BaseMotionFit:
    """Fit ``model`` (module docstring) to measured base motions (n, 3) over intervals whose
    wheel increments are ``inc_r``, ``inc_l`` (n, K), rows zero padded. With the intervals'
    ``start_s`` (s) the result carries a cluster-robust covariance over time blocks (the Cauchy
    loss's weights in the bread and the scores)."""
    from scipy.optimize import least_squares  # here: a slow import

    nom_pred = _predict(nominal, inc_r, inc_l)
    e0 = nom_pred - motion
    scale = np.maximum(1.4826 * np.median(np.abs(e0 - np.median(e0, axis=0)), axis=0), 1e-6)

    def fun(q: np.ndarray) -> np.ndarray:
        g = _geometry(model, q, nominal)
        return ((_predict(g, inc_r, inc_l) - motion) / scale).ravel()

    q0 = _start(model, nominal)
    sol = least_squares(fun, q0, loss="soft_l1", x_scale=np.abs(q0))
    # once more with the scale of the fitted model's residuals
    e1 = (fun(sol.x).reshape(-1, 3)) * scale
    scale = np.maximum(1.4826 * np.median(np.abs(e1 - np.median(e1, axis=0)), axis=0), 1e-6)
    sol = least_squares(fun, sol.x, loss="soft_l1", x_scale=np.abs(q0))
    geometry = _geometry(model, sol.x, nominal)
    if start_s is None:
        return BaseMotionFit(model, geometry)
    cov, dof = _robust_covariance(fun, sol.x, np.asarray(start_s, dtype=float))
    if cov is None:
        return BaseMotionFit(model, geometry)
    m = _mapping(model, nominal)
    return BaseMotionFit(model, geometry, m @ cov @ m.T, dof)


def _robust_covariance(
    fun: Callable[[np.ndarray], np.ndarray], q: np.ndarray, start_s: np.ndarray
) -> tuple[np.ndarray | None, int]:
    """The cluster-robust covariance of the M-estimate with the soft-L1 loss at ``q``
    (psi(r) = r / sqrt(1 + r^2), psi'(r) = (1 + r^2)^-3/2), over time blocks."""
    f = fun(q)
    jac = np.empty((len(f), len(q)))
    for j in range(len(q)):
        h = 1e-6 * max(abs(q[j]), 1e-3)
        qp, qm = q.copy(), q.copy()
        qp[j] += h
        qm[j] -= h
        jac[:, j] = (fun(qp) - fun(qm)) / (2 * h)
    root = np.sqrt(1.0 + f * f)
    clusters = np.repeat(time_blocks(start_s), 3)
    try:
        cc = cluster_covariance(jac, f / root, clusters, curvature=1.0 / root**3)
    except CalibrationError:
        return None, 0
    return cc.covariance, cc.dof


def _chains(start_s: np.ndarray, end_s: np.ndarray, gap_s: float) -> list[np.ndarray]:
    """Runs of consecutive intervals that share their instants (index arrays)."""
    breaks = np.flatnonzero(np.abs(start_s[1:] - end_s[:-1]) > gap_s) + 1
    return [c for c in np.split(np.arange(len(start_s)), breaks) if len(c) > 0]


def _chain_ends(chains: list[np.ndarray], motion: np.ndarray) -> np.ndarray:
    """End position (x, y) of each chain of consecutive motions composed from its start,
    shape (len(chains), 2): every chain at once (heading before each motion, its increment
    rotated by it, summed per chain)."""
    lengths = np.array([len(c) for c in chains])
    idx = np.concatenate(chains)
    first = np.concatenate([[0], np.cumsum(lengths)[:-1]])
    m = motion[idx]
    after = np.cumsum(m[:, 2])
    before = after - m[:, 2]
    phi = before - np.repeat(before[first], lengths)
    c, s = np.cos(phi), np.sin(phi)
    dx = c * m[:, 0] - s * m[:, 1]
    dy = s * m[:, 0] + c * m[:, 1]
    return np.column_stack([np.add.reduceat(dx, first), np.add.reduceat(dy, first)])


def _chain_end_errors(
    chains: list[np.ndarray],
    g: WheelGeometry,
    inc_r: np.ndarray,
    inc_l: np.ndarray,
    motion: np.ndarray,
) -> np.ndarray:
    """End position error (m) of each chain dead-reckoned with ``g``."""
    idx = np.concatenate(chains)
    pred = np.zeros_like(motion)
    pred[idx] = _predict(g, inc_r[idx], inc_l[idx])
    d = _chain_ends(chains, motion) - _chain_ends(chains, pred)
    return np.hypot(d[:, 0], d[:, 1])


def _split_long(chains: list[np.ndarray], max_intervals: int) -> list[np.ndarray]:
    out = []
    for c in chains:
        out.extend(np.array_split(c, max(1, math.ceil(len(c) / max_intervals))))
    return out


def heldout_check(
    start_s: ArrayLike,
    end_s: ArrayLike,
    inc_r: ArrayLike,
    inc_l: ArrayLike,
    motion: ArrayLike,
    nominal: WheelGeometry,
    calibrated: WheelGeometry,
    *,
    fit_mask: ArrayLike | None = None,
    folds: int = 4,
    chain_s: float | None = None,
    fit_full: Callable[[np.ndarray], WheelGeometry] | None = None,
) -> HeldOut:
    """The blocked cross-validation of the module docstring.

    Parameters
    ----------
    start_s, end_s : ndarray, shape (n,)
        Interval bounds (s), in time order.
    inc_r, inc_l : ndarray, shape (n, K)
        Wheel rotations within each interval as sampled (rad; rows zero padded).
    motion : ndarray, shape (n, 3)
        Measured base motion over each interval, in the base frame at its start.
    fit_mask : ndarray of bool, shape (n,), optional
        The intervals the fits may use (default all). The others (dropped as jumps or
        outliers) still carry the chains: the truth over a held-out stretch is the composition
        of all its measured motions, as dead reckoning is of all its wheel rotations.
    nominal : WheelGeometry
        What the robot ran with (the baseline).
    calibrated : WheelGeometry
        The route's own answer on all the data (the full model's geometry in the result).
    folds : int
        Contiguous blocks (>= 2).
    chain_s : float, optional
        Chains longer than this are cut into pieces of about this duration (s): one loop
        closure-free stretch of many minutes would otherwise count as one point. Default: a
        24th of the log, within 5-60 s (about 6 pieces per block or more).
    fit_full : callable, optional
        The route's own estimator of the full model on the intervals of the given indices
        (default: the soft-L1 fit of the base motions); the restricted models are always
        the latter.
    """
    a, b = np.asarray(start_s, dtype=float), np.asarray(end_s, dtype=float)
    r, lft, m = np.asarray(inc_r, float), np.asarray(inc_l, float), np.asarray(motion, float)
    n = len(a)
    usable = np.ones(n, dtype=bool) if fit_mask is None else np.asarray(fit_mask, dtype=bool)
    if folds < 2:
        raise CalibrationError(f"the held-out check needs at least 2 folds, got {folds}")
    dt = float(np.median(b - a)) if n else 0.0
    if chain_s is None:
        chain_s = min(60.0, max(5.0, float(b.max() - a.min()) / 24.0)) if n else 60.0
    block = np.minimum((folds * (a - a.min()) / max(float(b.max() - a.min()), 1e-9)), folds - 1)
    block = block.astype(int)
    per_chain = max(2, int(round(chain_s / dt))) if dt > 0 else 2
    chains_by_fold = []
    for f in range(folds):
        idx = np.flatnonzero(block == f)
        local = _chains(a[idx], b[idx], 1e-6 + 1e-3 * dt)
        chains_by_fold.append([idx[c] for c in _split_long(local, per_chain)])
    total = sum(len(c) for c in chains_by_fold)
    if (
        total < MIN_CHAINS
        or any(len(c) == 0 for c in chains_by_fold)
        or int(usable.sum()) < MIN_INTERVALS
    ):
        raise CalibrationError(
            f"the log is too short for a held-out check: {int(usable.sum())} usable intervals "
            f"(need {MIN_INTERVALS}), {total} chains of consecutive intervals in {folds} time "
            f"blocks (need {MIN_CHAINS}, and every block some)"
        )

    def fold_errors(models: Sequence[str]) -> dict[str, list[np.ndarray]]:
        out: dict[str, list[np.ndarray]] = {k: [] for k in models}
        for f in range(folds):
            test = chains_by_fold[f]
            train = _spread(np.flatnonzero((block != f) & usable), MAX_FIT_INTERVALS)
            for mod in models:
                try:
                    if mod == "nominal":
                        g = nominal
                    elif mod == "full" and fit_full is not None:
                        g = fit_full(train)
                    else:
                        g = fit_base_motion(
                            cast(Model, mod), r[train], lft[train], m[train], nominal
                        ).geometry
                except (CalibrationError, ValueError, np.linalg.LinAlgError):
                    g = nominal
                out[mod].append(_chain_end_errors(test, g, r, lft, m))
        return out

    def whole_fit(mod: Model) -> BaseMotionFit:
        whole = _spread(np.flatnonzero(usable), MAX_FIT_INTERVALS)
        return fit_base_motion(mod, r[whole], lft[whole], m[whole], nominal, a[whole])

    durations = [float(b[c[-1]] - a[c[0]]) for f in range(folds) for c in chains_by_fold[f]]
    errors = fold_errors(("nominal", "full"))
    wholes: dict[str, BaseMotionFit] = {"full": BaseMotionFit("full", calibrated)}
    if not _beats(errors["full"], errors["nominal"]):  # only then the restricted models
        errors.update(fold_errors(MODELS[1:]))
        wholes.update({mod: whole_fit(mod) for mod in MODELS[1:]})
    return _verdict(errors, wholes, folds, durations)


def paired_difference(
    model: Sequence[np.ndarray], nominal: Sequence[np.ndarray]
) -> tuple[float, float]:
    """The mean paired difference of a model's held-out errors and the nominal's (one array per
    fold, chain by chain; m) and its standard error: the larger of the chains' own (as if
    independent) and the one clustered by fold (with the small-sample factor G / (G - 1)); inf
    with fewer than two chains."""
    pairs = zip(model, nominal, strict=True)
    per_fold = [np.asarray(a, float) - np.asarray(b, float) for a, b in pairs]
    d = np.concatenate(per_fold)
    n = len(d)
    if n < 2:
        return (float(np.mean(d)) if n else math.nan), math.inf
    mean = float(np.mean(d))
    iid = float(np.std(d, ddof=1) / math.sqrt(n))
    folds = [f for f in per_fold if len(f)]
    g = len(folds)
    clustered = 0.0
    if g > 1:
        sums = np.array([float(np.sum(f - mean)) for f in folds])
        clustered = math.sqrt(float(np.sum(sums**2)) * g / (g - 1)) / n
    return mean, max(iid, clustered)


def _beats(model: list[np.ndarray], nominal: list[np.ndarray]) -> bool:
    """The model's held-out errors below the nominal's, paired, by more than
    :data:`DECIDE_Z` standard errors (:func:`paired_difference`)."""
    diff, se = paired_difference(model, nominal)
    return bool(diff < -DECIDE_Z * se)


def _verdict(
    errors: dict[str, list[np.ndarray]],
    wholes: dict[str, BaseMotionFit],
    folds: int,
    durations: list[float],
) -> HeldOut:
    """Pair every model's held-out errors with the nominal's, chain by chain: the full model
    is kept when it beats the nominal (the restricted models are then not tried); else the
    restricted model with the lowest error among those that do; else none."""
    e = {k: np.concatenate(v) for k, v in errors.items()}
    scores = []
    for mod in (x for x in MODELS if x in e):
        diff, se = paired_difference(errors[mod], errors["nominal"])
        beats, worse = diff < -DECIDE_Z * se, diff > DECIDE_Z * se
        whole = wholes[mod]
        scores.append(ModelScore(mod, whole.geometry, float(np.mean(e[mod])), beats, whole, worse,
                                 diff, se))  # fmt: skip
    winners = [s for s in scores[1:] if s.beats_nominal]
    preferred = min(winners, key=lambda s: s.mean_final_error_m).model if winners else None
    full = scores[0]
    if full.beats_nominal or (preferred is None and not full.worse_than_nominal):
        preferred = "full"  # it helps, or no model can be told from the nominal and it is not worse
    return HeldOut(
        folds,
        len(e["nominal"]),
        float(np.median(durations)),
        float(np.mean(e["nominal"])),
        float(np.mean(e["full"])),
        tuple(scores),
        preferred,
    )


def heldout_runs(
    recordings: Sequence[Recording],
    nominal: WheelGeometry,
    calibrated: WheelGeometry,
    fit_model: Callable[[Sequence[Recording], Model], WheelGeometry],
    *,
    folds: int = 4,
) -> HeldOut:
    """The blocked cross-validation of a calibration from runs with a ground truth: the runs
    (in the order given, i.e. as recorded) are cut into ``folds`` contiguous blocks; each model
    is fitted by the route's own estimator ``fit_model(runs, model)`` on the other blocks, and
    every run of the block is dead-reckoned from its start with the nominal and the fitted
    parameters; the error is its final position error (as ``odocal validate`` measures it).
    ``calibrated`` is the route's answer on all the runs (the full model)."""
    runs = [r for r in recordings if r.ground_truth is not None]
    folds = min(folds, len(runs))
    if folds < 2 or len(runs) < MIN_CHAINS:
        raise CalibrationError(
            f"too few runs for a held-out check: {len(runs)} with a ground truth (need "
            f"{MIN_CHAINS}; a single long run: cut it into runs, or record more)"
        )
    block = (np.arange(len(runs)) * folds) // len(runs)

    length = piece_length_for(
        [float(path_length(np.asarray(r.ground_truth)[:, :2])[-1]) for r in runs]
    )
    drift: dict[str, list[PathDrift]] = {"nominal": [], "full": []}

    def fold_errors(models: Sequence[str]) -> dict[str, list[np.ndarray]]:
        out: dict[str, list[np.ndarray]] = {k: [] for k in models}
        for f in range(folds):
            test = [r for r, b in zip(runs, block, strict=True) if b == f]
            train = [r for r, b in zip(runs, block, strict=True) if b != f]
            for mod in models:
                try:
                    g = nominal if mod == "nominal" else fit_model(train, cast(Model, mod))
                except (CalibrationError, ValueError, np.linalg.LinAlgError):
                    g = nominal
                out[mod].append(np.array([_final_error(r, g) for r in test]))
                if mod in drift:
                    drift[mod] += [_run_drift(r, g, length) for r in test]
        return out

    durations = [float(r.time_s[-1] - r.time_s[0]) for r in runs]
    errors = fold_errors(("nominal", "full"))
    wholes = {"full": BaseMotionFit("full", calibrated)}
    if not _beats(errors["full"], errors["nominal"]):  # only then the restricted models
        errors.update(fold_errors(MODELS[1:]))
        for mod in MODELS[1:]:
            try:
                wholes[mod] = BaseMotionFit(mod, fit_model(runs, mod))
            except (CalibrationError, ValueError, np.linalg.LinAlgError):
                wholes[mod] = BaseMotionFit(mod, nominal)
    held = _verdict(errors, wholes, folds, durations)
    return replace(held, drift=tuple((k, pool_drift(v)) for k, v in drift.items()))


def _run_drift(recording: Recording, g: WheelGeometry, length_m: float) -> PathDrift:
    """The KITTI-style drift of a run dead-reckoned with ``g`` (:mod:`odocal.core.path_drift`)."""
    assert recording.ground_truth is not None  # the caller keeps runs with a truth
    est = dead_reckon(recording.wheel_angle_right_rad, recording.wheel_angle_left_rad, g)
    return path_drift(recording.ground_truth, est, length_m=length_m)


def _final_error(recording: Recording, g: WheelGeometry) -> float:
    """The final position error (m) of a run dead-reckoned with ``g``."""
    assert recording.ground_truth is not None  # the caller keeps runs with a truth
    pose = dead_reckon(recording.wheel_angle_right_rad, recording.wheel_angle_left_rad, g)[-1]
    return math.hypot(
        float(recording.ground_truth[-1, 0] - pose[0]),
        float(recording.ground_truth[-1, 1] - pose[1]),
    )


def intervals_of_runs(
    recordings: Sequence[Recording], window_s: float = 1.0
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Runs with a ground truth as consecutive intervals of about ``window_s``, for
    :func:`heldout_check`: (start_s, end_s, inc_r, inc_l, motion). The runs are strung on one
    clock with a gap between them, so that a chain never crosses from one run to the next;
    ``motion`` is the truth's motion over each interval in the base frame at its start."""
    starts, ends, rows_r, rows_l, motions = [], [], [], [], []
    clock = 0.0
    for rec in recordings:
        gt = rec.ground_truth
        if gt is None or len(rec.time_s) < 3:
            continue
        t = np.asarray(rec.time_s, dtype=float)
        dt = float(np.median(np.diff(t)))
        step = max(1, int(round(window_s / dt))) if dt > 0 else 1
        k = np.arange(0, len(t), step)
        if k[-1] != len(t) - 1:
            k = np.r_[k, len(t) - 1]
        a, b = k[:-1], k[1:]
        right = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        left = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        width = int(np.max(b - a))
        idx = a[:, None] + np.arange(width + 1)[None, :]
        idx = np.minimum(idx, b[:, None])  # past the interval's end: no more increments
        rows_r.append(np.diff(right[idx], axis=1))
        rows_l.append(np.diff(left[idx], axis=1))
        motions.append(se2_relative(gt[a], gt[b], wrap=False))
        starts.append(t[a] - t[0] + clock)
        ends.append(t[b] - t[0] + clock)
        clock = float(ends[-1][-1]) + 1.0
    if not starts:
        raise CalibrationError("no run with a ground truth for the held-out check")
    width = max(r.shape[1] for r in rows_r)

    def pad(x: np.ndarray) -> np.ndarray:
        return np.pad(x, ((0, 0), (0, width - x.shape[1])))

    return (
        np.concatenate(starts),
        np.concatenate(ends),
        np.concatenate([pad(x) for x in rows_r]),
        np.concatenate([pad(x) for x in rows_l]),
        np.concatenate(motions),
    )
