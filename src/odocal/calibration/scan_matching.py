"""2D scan matching: the rigid displacement of a laser scanner between two of its scans.

The matcher is a point-to-line ICP (the metric of Censi's PLICP, ICRA 2008) on
``scipy.spatial.cKDTree``; docs/scan-matching.md gives the method, why no packaged matcher was
used, its accuracy and its limits.

Frames and signs (docs/conventions.md): a scan's points are in the sensor frame at the time of
the scan, x forward, y left (m). The result of :func:`match_scans` is the pose (x_m, y_m,
theta_rad) of the CURRENT scan's sensor frame expressed in the REFERENCE scan's sensor frame,
i.e. the sensor's displacement over the interval, in the sensor frame at the interval's start:
a reference point p and the matching current point q satisfy p = R(theta) q + (x, y).

Method. The reference scan is prepared once (:func:`prepare_scan`): a k-d tree, and for every
point a line fitted by principal components to its nearest neighbours (corners and clusters get
none). Per iteration: transform the current points with the estimate; find each one's nearest
reference point within ``max_correspondence_m``; take its distance along that point's line
normal to the fitted line; weight these residuals (Huber, with a scale re-estimated from their
median absolute value; zero beyond ``outlier_sigmas`` scales and ``min_outlier_m``); take one
Gauss-Newton step in (x, y, theta), with no step along directions the scene does not constrain.
Stop when the step is negligible. The covariance comes from the Hessian and the residual
scatter at the solution (see ``_covariance``).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.parallel import can_fork, run_tasks, workers
from ..errors import CalibrationError, ModelError
from .relative_motions import RelativeMotions, wheel_increments
from .time_offset import TimeOffset, estimate_time_offset, resolve_offset

if TYPE_CHECKING:
    from scipy.spatial import cKDTree

__all__ = [
    "ScanMatch",
    "PreparedScan",
    "IntervalMatches",
    "scan_points",
    "prepare_scan",
    "match_scans",
    "match_intervals",
    "ScanIntervals",
    "scan_interval_motions",
    "MIN_POINTS",
    "MIN_MATCHED_INTERVALS",
]

MIN_POINTS = 20
"""Fewest valid points a scan must have to be matched (fewer cannot constrain a pose reliably)."""

_MAD_TO_SIGMA = 1.4826  # median absolute deviation -> standard deviation of a Gaussian
_HUBER_K = 1.345  # Huber threshold in scale units (95 % efficiency for Gaussian residuals)
STEP_SIGMAS = 0.1  # a step below this many predicted standard deviations counts as converged
DEGENERATE_RATIO = 1e-6  # smallest / largest eigenvalue of the scaled Hessian that counts


@dataclass(frozen=True)
class ScanMatch:
    """Outcome of one scan match.

    Attributes
    ----------
    motion : ndarray, shape (3,)
        (x_m, y_m, theta_rad): the current scan's sensor frame in the reference scan's sensor
        frame (the sensor's displacement over the interval, in the frame at its start).
    covariance : ndarray, shape (3, 3) or None
        Covariance of ``motion`` (m^2, m rad, rad^2) from the residual scatter and the
        Gauss-Newton Hessian at the solution, counting the range noise of both scans; None
        when the match did not converge or the geometry does not constrain every direction
        (``degenerate``). It does not hold errors of a wrong association (a match into the
        wrong place): docs/scan-matching.md gives how well it predicts the scatter.
    iterations : int
        Gauss-Newton iterations done.
    converged : bool
        The last step was below the tolerances before ``max_iterations``.
    degenerate : bool
        The scene leaves a direction of motion unconstrained (a corridor, a single wall, too
        few lines); that component of ``motion`` stays at the initial guess.
    inlier_fraction : float
        Share of the current scan's points that have a reference line within
        ``max_correspondence_m`` and a residual within ``outlier_sigmas`` scales at the
        solution: an overlap measure.
    rms_m : float
        Root-mean-square point-to-line residual of the inliers (m).
    """

    motion: np.ndarray
    covariance: np.ndarray | None
    iterations: int
    converged: bool
    degenerate: bool
    inlier_fraction: float
    rms_m: float


@dataclass(frozen=True, eq=False)
class PreparedScan:
    """A reference scan ready for matching: its points, a k-d tree and a line normal per point.

    Build with :func:`prepare_scan`; reusing one for several matches saves the tree and the
    line fits.

    Attributes
    ----------
    points_m : ndarray, shape (n, 2)
        Points (m) in the sensor frame.
    normals : ndarray, shape (n, 2)
        Unit normal of the line fitted to each point's neighbours; NaN where no line fits
        (fewer than 3 neighbours within the radius, or a corner or cluster).
    centroids_m : ndarray, shape (n, 2)
        A point (m) on each fitted line: the centroid of the neighbours it was fitted to.
    neighbor_count : ndarray of int, shape (n,)
        Points each line was fitted to.
    has_normal : ndarray of bool, shape (n,)
        The point lies on a fitted line.
    tree : scipy.spatial.cKDTree
        k-d tree of ``points_m``.
    matchable : ndarray of bool, shape (n + 1,)
        ``has_normal`` and False at index n (the index the tree gives a point with no neighbour
        within the correspondence gate): one lookup tells which correspondences count.
    """

    points_m: np.ndarray
    normals: np.ndarray
    centroids_m: np.ndarray
    neighbor_count: np.ndarray
    has_normal: np.ndarray
    tree: cKDTree = field(repr=False)
    matchable: np.ndarray = field(repr=False, default_factory=lambda: np.zeros(1, dtype=bool))

    def __post_init__(self) -> None:
        if len(self.matchable) != len(self.has_normal) + 1:
            ext = np.append(np.asarray(self.has_normal, dtype=bool), False)
            ext.setflags(write=False)
            object.__setattr__(self, "matchable", ext)


@dataclass(frozen=True)
class IntervalMatches:
    """Scan matches over chosen intervals of a scan sequence (one row per interval).

    Attributes
    ----------
    intervals : ndarray of int, shape (k, 2)
        (start, end) scan indices.
    start_time_s, end_time_s : ndarray, shape (k,)
        Times (s) of the start and end scans.
    motion : ndarray, shape (k, 3)
        Sensor displacement (x_m, y_m, theta_rad) over each interval in the sensor frame at its
        start (as :attr:`ScanMatch.motion`).
    covariance : ndarray, shape (k, 3, 3)
        As :attr:`ScanMatch.covariance`, NaN where that is None.
    converged, degenerate : ndarray of bool, shape (k,)
    iterations : ndarray of int, shape (k,)
    inlier_fraction, rms_m : ndarray, shape (k,)
    """

    intervals: np.ndarray
    start_time_s: np.ndarray
    end_time_s: np.ndarray
    motion: np.ndarray
    covariance: np.ndarray
    converged: np.ndarray
    degenerate: np.ndarray
    iterations: np.ndarray
    inlier_fraction: np.ndarray
    rms_m: np.ndarray

    @property
    def usable(self) -> np.ndarray:
        """Boolean mask, shape (k,): converged and not degenerate."""
        return self.converged & ~self.degenerate


def scan_points(
    ranges_m: ArrayLike,
    angle_min_rad: float,
    angle_increment_rad: float,
    range_min_m: float,
    range_max_m: float,
) -> np.ndarray:
    """Points (m) of one ``sensor_msgs/LaserScan`` in the sensor frame, shape (n, 2).

    Ray i points at ``angle_min_rad + i angle_increment_rad`` (rad, CCW from the sensor's +x).
    Ranges that are NaN, infinite, below ``range_min_m`` or above ``range_max_m`` are dropped
    (REP-117); the rest keep the scan order.
    """
    r = np.asarray(ranges_m, dtype=float)
    if r.ndim != 1:
        raise ModelError(f"ranges must be a 1-D array, got shape {r.shape}")
    for name, value in (
        ("angle_min_rad", angle_min_rad),
        ("angle_increment_rad", angle_increment_rad),
        ("range_min_m", range_min_m),
        ("range_max_m", range_max_m),
    ):
        if not math.isfinite(value):
            raise ModelError(f"{name} must be finite, got {value!r}")
    if not 0 <= range_min_m < range_max_m:
        raise ModelError(
            f"need 0 <= range_min_m < range_max_m, got {range_min_m!r} and {range_max_m!r}"
        )
    angles = angle_min_rad + angle_increment_rad * np.arange(r.size)
    with np.errstate(invalid="ignore"):
        valid = np.isfinite(r) & (r >= range_min_m) & (r <= range_max_m)
    r, angles = r[valid], angles[valid]
    return np.column_stack([r * np.cos(angles), r * np.sin(angles)])


def _check_points(name: str, points: ArrayLike) -> np.ndarray:
    p = np.asarray(points, dtype=float)
    if p.ndim != 2 or p.shape[1] != 2:
        raise ModelError(f"{name} must have shape (n, 2), got {p.shape}")
    p = p[np.all(np.isfinite(p), axis=1)]
    if p.shape[0] < MIN_POINTS:
        raise CalibrationError(
            f"the {name} has {p.shape[0]} valid point(s); scan matching needs at least "
            f"{MIN_POINTS} (is the laser blocked, or are its ranges all out of range?)"
        )
    return p


def prepare_scan(
    points_m: ArrayLike,
    *,
    normal_neighbors: int = 7,
    normal_radius_m: float = 0.3,
    max_line_ratio: float = 0.1,
) -> PreparedScan:
    """Build the k-d tree and the per-point line normals of a reference scan.

    Parameters
    ----------
    points_m : array_like, shape (n, 2)
        Scan points (m) in the sensor frame; rows with NaN or inf are dropped.
    normal_neighbors : int
        Points (including itself) a line is fitted to, by principal components.
    normal_radius_m : float
        Only neighbours within this distance (m) count; a point with fewer than 3 has no line.
    max_line_ratio : float
        A fit whose smaller to larger eigenvalue ratio exceeds this is not a line (a corner, a
        cluster) and gets no normal.

    Raises
    ------
    CalibrationError
        Fewer than :data:`MIN_POINTS` valid points.
    """
    if normal_neighbors < 3:
        raise ModelError(f"normal_neighbors must be >= 3, got {normal_neighbors}")
    from scipy.spatial import cKDTree  # here: scipy.spatial takes long to import

    p = _check_points("reference scan", points_m)
    tree = cKDTree(p)
    k = min(normal_neighbors, p.shape[0])
    dist, idx = tree.query(p, k=k, distance_upper_bound=normal_radius_m)
    found = np.isfinite(dist)  # (n, k); missing neighbours have index n
    nb = np.concatenate([p, np.zeros((1, 2))])[idx]  # (n, k, 2); a missing neighbour: 0.0
    count = found.sum(axis=1)
    total = nb[:, 0].copy()  # the neighbours' sum in order, as nb.sum(axis=1) adds them
    for i in range(1, k):
        total += nb[:, i]
    mean = total / count[:, None]
    d = nb - mean[:, None, :]
    d[~found] = 0.0
    sxx = np.einsum("nk,nk->n", d[..., 0], d[..., 0])
    syy = np.einsum("nk,nk->n", d[..., 1], d[..., 1])
    sxy = np.einsum("nk,nk->n", d[..., 0], d[..., 1])
    half_trace = 0.5 * (sxx + syy)
    root = np.hypot(0.5 * (sxx - syy), sxy)
    lam_max, lam_min = half_trace + root, half_trace - root
    phi = 0.5 * np.arctan2(2.0 * sxy, sxx - syy)  # direction of the line
    normals = np.column_stack([-np.sin(phi), np.cos(phi)])
    with np.errstate(invalid="ignore", divide="ignore"):
        is_line = (count >= 3) & (lam_min <= max_line_ratio * lam_max) & (lam_max > 0)
    normals[~is_line] = np.nan
    matchable = np.append(is_line, False)
    for a in (p, normals, mean, count, is_line, matchable):
        a.setflags(write=False)
    return PreparedScan(p, normals, mean, count, is_line, tree, matchable)


def match_scans(
    reference_points: ArrayLike | PreparedScan,
    current_points: ArrayLike,
    initial_guess: ArrayLike = (0.0, 0.0, 0.0),
    *,
    max_correspondence_m: float = 0.3,
    max_iterations: int = 50,
    tolerance_m: float = 1e-6,
    tolerance_rad: float = 1e-7,
    outlier_sigmas: float = 4.0,
    min_outlier_m: float = 0.05,
    min_scale_m: float = 1e-4,
    normal_neighbors: int = 7,
    normal_radius_m: float = 0.3,
    max_line_ratio: float = 0.1,
) -> ScanMatch:
    """Match ``current_points`` against ``reference_points`` (point-to-line ICP).

    Parameters
    ----------
    reference_points : array_like, shape (n, 2), or PreparedScan
        The earlier scan's points (m) in its sensor frame (see :func:`scan_points`).
    current_points : array_like, shape (m, 2)
        The later scan's points (m) in its sensor frame; rows with NaN or inf are dropped.
    initial_guess : (x_m, y_m, theta_rad)
        Starting estimate of the motion, e.g. from wheel odometry moved into the sensor frame.
        In the default room it converged to the right motion from errors of 0.2 m and 10 deg
        (docs/scan-matching.md).
    max_correspondence_m : float
        Current points farther (m) than this from every reference point get no correspondence
        (the parts of the scans that do not overlap). Must exceed the error of the guess.
    max_iterations : int
    tolerance_m, tolerance_rad : float
        Convergence: a Gauss-Newton step smaller than both (m, rad), or smaller than
        :data:`STEP_SIGMAS` predicted standard deviations in every component.
    outlier_sigmas : float
        Residuals beyond this many robust scales, and beyond ``min_outlier_m``, get zero
        weight; the others get Huber weights.
    min_outlier_m : float
        Residuals (m) up to this are never rejected, only down-weighted. Without it a scan whose
        lines mostly run one way can lock onto a wrong solution: when most residuals are near
        zero, the scale collapses and the few points that constrain the other direction look
        like outliers.
    min_scale_m : float
        Floor (m) of the robust residual scale (noise-free scans have residuals near zero).
    normal_neighbors, normal_radius_m, max_line_ratio
        Line fits of the reference scan (see :func:`prepare_scan`); ignored when
        ``reference_points`` is already a PreparedScan.

    Returns
    -------
    ScanMatch

    Raises
    ------
    CalibrationError
        A scan has fewer than :data:`MIN_POINTS` valid points, or the reference scan has no
        straight parts to fit lines to.
    ModelError
        Malformed arguments (shapes, non-finite guess, non-positive thresholds).
    """
    if isinstance(reference_points, PreparedScan):
        ref = reference_points
    else:
        ref = prepare_scan(
            reference_points,
            normal_neighbors=normal_neighbors,
            normal_radius_m=normal_radius_m,
            max_line_ratio=max_line_ratio,
        )
    cur = _check_points("current scan", current_points)
    guess = np.asarray(initial_guess, dtype=float)
    if guess.shape != (3,) or not np.all(np.isfinite(guess)):
        raise ModelError(
            "initial_guess must be three finite numbers (x_m, y_m, theta_rad), "
            f"got {initial_guess!r}"
        )
    settings = _Settings(
        max_correspondence_m,
        max_iterations,
        tolerance_m,
        tolerance_rad,
        outlier_sigmas,
        min_outlier_m,
        min_scale_m,
    )
    if not np.any(ref.has_normal):
        raise CalibrationError(
            "the reference scan has no straight parts to match against (all points are "
            "isolated or in clusters): scan matching needs walls or other flat surfaces"
        )
    return _match(ref, cur, guess, settings)


@dataclass(frozen=True)
class _Settings:
    """Validated options of :func:`match_scans`."""

    gate_m: float
    max_iterations: int
    tol_m: float
    tol_rad: float
    outlier_sigmas: float
    min_outlier_m: float
    min_scale_m: float

    def __post_init__(self) -> None:
        for name in (
            "gate_m",
            "tol_m",
            "tol_rad",
            "outlier_sigmas",
            "min_outlier_m",
            "min_scale_m",
        ):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                public = {
                    "gate_m": "max_correspondence_m",
                    "tol_m": "tolerance_m",
                    "tol_rad": "tolerance_rad",
                }.get(name, name)
                raise ModelError(f"{public} must be finite and > 0, got {value!r}")
        if not (isinstance(self.max_iterations, (int, np.integer)) and self.max_iterations >= 1):
            raise ModelError(f"max_iterations must be an integer >= 1, got {self.max_iterations!r}")


def _match(ref: PreparedScan, cur: np.ndarray, pose: np.ndarray, opt: _Settings) -> ScanMatch:
    """The ICP loop on validated inputs (see :func:`match_scans`)."""
    pose = pose.copy()
    # lever for comparing rotation with translation: the rms distance of the current points
    lever_m = max(float(np.sqrt(np.mean(np.sum(cur**2, axis=1)))), 1e-3)
    d = np.array([1.0, 1.0, 1.0 / lever_m])  # theta * lever is a length
    floor = np.array([opt.tol_m, opt.tol_m, opt.tol_rad])
    converged = degenerate = False
    iterations = 0
    while iterations < opt.max_iterations:
        iterations += 1
        lin = _linearise(ref, cur, pose, opt)
        if lin is None:  # no overlap left
            break
        step, degenerate, inverse_diag = _solve(lin.hessian(), lin.gradient(), d)
        pose -= step
        # Converged when the step is below the absolute tolerances or, for noisy scans whose
        # correspondences end up switching back and forth in a small cycle, below STEP_SIGMAS
        # predicted standard deviations: further steps would not change the result measurably.
        if np.all(
            np.abs(step) <= np.maximum(floor, STEP_SIGMAS * lin.scale * np.sqrt(inverse_diag))
        ):
            converged = True
            break

    lin = _linearise(ref, cur, pose, opt)
    if lin is None:
        return ScanMatch(pose, None, iterations, False, degenerate, 0.0, math.nan)
    inlier_fraction = float(np.count_nonzero(lin.weight > 0)) / cur.shape[0]
    rms = float(np.sqrt(np.mean(lin.residual[lin.weight > 0] ** 2)))
    covariance = None
    if converged and not degenerate:
        covariance = _covariance(lin, float(np.mean(ref.neighbor_count[lin.ref_index])))
    return ScanMatch(pose, covariance, iterations, converged, degenerate, inlier_fraction, rms)


class _Linearisation:
    """Weighted least-squares problem at one pose: residuals (m), Jacobian rows
    d residual / d (x, y, theta), robust weights, the robust scale (m), and the reference
    point of each correspondence."""

    __slots__ = ("residual", "jacobian", "weight", "scale", "ref_index")

    def __init__(
        self,
        residual: np.ndarray,
        jacobian: np.ndarray,
        weight: np.ndarray,
        scale: float,
        ref_index: np.ndarray,
    ) -> None:
        self.residual, self.jacobian, self.weight = residual, jacobian, weight
        self.scale, self.ref_index = scale, ref_index

    def hessian(self) -> np.ndarray:
        return self.jacobian.T @ (self.weight[:, None] * self.jacobian)

    def gradient(self) -> np.ndarray:
        return self.jacobian.T @ (self.weight * self.residual)


def _median(a: np.ndarray) -> float:
    """``np.median`` of a 1-D float array without NaN, the same number (the middle value, or
    the mean of the two middle values), without its general machinery."""
    n = a.size
    h = n // 2
    if n % 2:
        return float(np.partition(a, h)[h])
    part = np.partition(a, (h - 1, h))
    return float((part[h - 1] + part[h]) / 2.0)


def _linearise(
    ref: PreparedScan, cur: np.ndarray, pose: np.ndarray, opt: _Settings
) -> _Linearisation | None:
    """Correspondences, residuals, Jacobian and weights at ``pose``; None when fewer than 4
    current points have a reference line within the gate or none keeps a weight."""
    c, s = math.cos(pose[2]), math.sin(pose[2])
    rotated = cur @ np.array([[c, s], [-s, c]])  # rows R q
    moved = rotated + pose[:2]
    _, idx = ref.tree.query(moved, k=1, distance_upper_bound=opt.gate_m)
    ok = ref.matchable[idx]  # a neighbour within the gate (else index n), on a line
    m = np.count_nonzero(ok)
    if m < 4:
        return None
    j = idx[ok]
    normal = ref.normals[j]
    # distance along the normal to the line fitted through the neighbourhood of reference
    # point j (through its centroid: less noisy than the single point)
    res = np.einsum("ij,ij->i", normal, moved[ok] - ref.centroids_m[j])
    rq = rotated[ok]
    # d(R q + t)/d theta = perp(R q) = (-(R q)_y, (R q)_x)
    jac = np.empty((m, 3))
    jac[:, :2] = normal
    jac[:, 2] = normal[:, 1] * rq[:, 0] - normal[:, 0] * rq[:, 1]
    absr = np.abs(res)
    scale = max(_MAD_TO_SIGMA * _median(absr), opt.min_scale_m)
    huber = _HUBER_K * scale
    w = np.where(absr <= huber, 1.0, huber / np.maximum(absr, huber))
    w[absr > max(opt.outlier_sigmas * scale, opt.min_outlier_m)] = 0.0
    if not np.any(w > 0):
        return None
    return _Linearisation(res, jac, w, scale, j)


def _covariance(lin: _Linearisation, neighbors: float) -> np.ndarray | None:
    """Covariance of the motion, shape (3, 3), from the weighted residuals at the solution.

    The residual variance s^2 holds the current point's noise sigma^2 plus that of the fitted
    reference line, about sigma^2 / k for a fit to k points: sigma^2 = s^2 k / (k + 1). The
    reference scan's noise moves the whole reference geometry (its lines are fitted to shared
    neighbours), so it enters the motion as much as the current scan's does: twice the
    one-scan covariance sigma^2 H^-1 (both scans of similar geometry and noise).
    """
    dof = float(np.sum(lin.weight)) - 3.0
    if dof <= 0:
        return None
    s2 = float(np.sum(lin.weight * lin.residual**2)) / dof
    sigma2 = s2 * neighbors / (neighbors + 1.0)
    try:
        cov = 2.0 * sigma2 * np.linalg.inv(lin.hessian())
    except np.linalg.LinAlgError:
        return None
    return 0.5 * (cov + cov.T)


def _solve(
    hessian: np.ndarray, gradient: np.ndarray, d: np.ndarray
) -> tuple[np.ndarray, bool, np.ndarray]:
    """Gauss-Newton step (x, y, theta) from H step = g, whether a direction is unconstrained,
    and the diagonal of the (pseudo-)inverse of H. Directions the scene does not constrain
    (relative eigenvalue below DEGENERATE_RATIO, with theta scaled: ``d`` = (1, 1, 1 / lever))
    get no step."""
    vals, vecs = np.linalg.eigh(hessian * d[:, None] * d[None, :])
    if not vals[-1] > 0:
        return np.zeros(3), True, np.full(3, np.inf)
    good = vals > DEGENERATE_RATIO * vals[-1]
    v = vecs[:, good]
    step = v @ ((v.T @ (gradient * d)) / vals[good])
    inverse_diag = (v**2 / vals[good]).sum(axis=1) * d**2
    return step * d, not bool(np.all(good)), inverse_diag


def match_intervals(
    times_s: ArrayLike,
    scans: Sequence[np.ndarray],
    intervals: ArrayLike,
    initial_guesses: ArrayLike | None = None,
    **options: Any,
) -> IntervalMatches:
    """Match the scans at the two ends of each interval.

    Parameters
    ----------
    times_s : array_like, shape (N,)
        Scan times (s).
    scans : sequence of N arrays, shape (n_i, 2)
        Scan points (m) in the sensor frame (see :func:`scan_points`).
    intervals : array_like of int, shape (k, 2)
        (start, end) indices into ``scans``; the start scan is the reference.
    initial_guesses : array_like, shape (k, 3), optional
        Motion guess (x_m, y_m, theta_rad) per interval, e.g. from odometry; zero if omitted.
    **options
        Passed to :func:`match_scans` (and to :func:`prepare_scan` for the line fits).

    Each distinct start scan is prepared (tree, line fits) once, and kept only until its last
    interval. Many intervals are matched on the cores the process may use
    (:func:`odocal.core.parallel.run_tasks`, ``ODOCAL_THREADS``; the same numbers whatever
    their count). A scan with too few valid points raises :class:`CalibrationError` naming its
    index (the first such interval); a match that fails to converge is returned with
    ``converged`` False (see :attr:`IntervalMatches.usable`).
    """
    t = np.asarray(times_s, dtype=float).reshape(-1)
    if t.size != len(scans):
        raise ModelError(f"{t.size} scan times for {len(scans)} scans")
    iv = np.asarray(intervals)
    if iv.size == 0:
        iv = np.zeros((0, 2), dtype=int)
    if iv.ndim != 2 or iv.shape[1] != 2 or not np.issubdtype(iv.dtype, np.integer):
        raise ModelError(
            f"intervals must be integer (start, end) pairs, shape (k, 2), got {iv.dtype} {iv.shape}"
        )
    if iv.size and (iv.min() < 0 or iv.max() >= len(scans)):
        raise ModelError(f"interval indices must be in [0, {len(scans) - 1}]")
    k = iv.shape[0]
    guesses = np.zeros((k, 3)) if initial_guesses is None else np.asarray(initial_guesses, float)
    if guesses.shape != (k, 3):
        raise ModelError(f"initial_guesses must have shape ({k}, 3), got {guesses.shape}")

    prep_keys = ("normal_neighbors", "normal_radius_m", "max_line_ratio")
    prep_options = {key: options.pop(key) for key in prep_keys if key in options}
    bounds = _chunks(k)
    parts = run_tasks(
        [
            functools.partial(_match_rows, scans, iv, guesses, a, b, prep_options, options)
            for a, b in bounds
        ]
    )
    motion, cov, converged, degenerate, iterations, inliers, rms = (
        np.concatenate([part[f] for part in parts]) if parts else empty
        for f, empty in enumerate(
            (
                np.full((0, 3), np.nan),
                np.full((0, 3, 3), np.nan),
                np.zeros(0, dtype=bool),
                np.zeros(0, dtype=bool),
                np.zeros(0, dtype=int),
                np.zeros(0),
                np.full(0, np.nan),
            )
        )
    )
    return IntervalMatches(
        iv.astype(int),
        t[iv[:, 0]],
        t[iv[:, 1]],
        motion,
        cov,
        converged,
        degenerate,
        iterations,
        inliers,
        rms,
    )


#: Intervals below which match_intervals stays in this process (a worker costs about 0.1 s).
PARALLEL_MIN_INTERVALS = 200


def _chunks(k: int) -> list[tuple[int, int]]:
    """Rows [a, b) of the tasks the intervals are matched in: one task in this process for few
    intervals or one worker; else a few per worker (the faster worker takes more)."""
    n = workers() if k >= PARALLEL_MIN_INTERVALS and can_fork() else 1
    pieces = 1 if n == 1 else 4 * n
    edges = np.linspace(0, k, pieces + 1).round().astype(int)
    return [(int(a), int(b)) for a, b in zip(edges[:-1], edges[1:], strict=True) if b > a]


def _match_rows(
    scans: Any,
    iv: np.ndarray,
    guesses: np.ndarray,
    lo: int,
    hi: int,
    prep_options: dict,
    options: dict,
) -> tuple[np.ndarray, ...]:
    """Match intervals ``lo`` to ``hi`` (exclusive) of ``iv``: the columns of
    :class:`IntervalMatches` for those rows. A start scan is prepared once and kept only until
    its last interval here (a drive's intervals run in order: one at a time), not for the
    whole drive: an hour's prepared scans would take gigabytes."""
    k = hi - lo
    motion = np.full((k, 3), np.nan)
    cov = np.full((k, 3, 3), np.nan)
    converged = np.zeros(k, dtype=bool)
    degenerate = np.zeros(k, dtype=bool)
    iterations = np.zeros(k, dtype=int)
    inliers = np.zeros(k)
    rms = np.full(k, np.nan)
    rows = iv[lo:hi].tolist()
    last = {i0: r for r, (i0, _) in enumerate(rows)}  # the last row each start scan is used in
    prepared: dict[int, PreparedScan] = {}
    for r, (i0, i1) in enumerate(rows):
        try:
            if i0 not in prepared:
                prepared[i0] = prepare_scan(scans[i0], **prep_options)
            m = match_scans(prepared[i0], scans[i1], guesses[lo + r], **options)
        except CalibrationError as exc:
            raise CalibrationError(f"interval {lo + r} (scans {i0} -> {i1}): {exc}") from exc
        if last[i0] == r:
            del prepared[i0]
        motion[r] = m.motion
        if m.covariance is not None:
            cov[r] = m.covariance
        converged[r], degenerate[r] = m.converged, m.degenerate
        iterations[r], inliers[r], rms[r] = m.iterations, m.inlier_fraction, m.rms_m
    return motion, cov, converged, degenerate, iterations, inliers, rms


#: Fewest matched scan intervals a relative-motion fit takes from one drive.
MIN_MATCHED_INTERVALS = 10


@dataclass(frozen=True)
class ScanIntervals:
    """The scan-matched laser motions over intervals of one drive.

    Attributes
    ----------
    motions : RelativeMotions
        The matched intervals: wheel rotations, laser motion, wheel increments within each.
    interval_scans : int
        Scans from the start to the end of an interval.
    intervals, matched, not_converged, degenerate : int
        Intervals matched; usable ones; those whose match did not converge; degenerate ones.
    time_offset : TimeOffset
        How late the laser's stamps run behind the wheels' (applied: the wheel rotations of
        each interval are taken at the wheel clock).
    """

    motions: RelativeMotions
    interval_scans: int
    intervals: int
    matched: int
    not_converged: int
    degenerate: int
    time_offset: TimeOffset = field(default_factory=lambda: TimeOffset.given("laser", 0.0))


def scan_interval_motions(
    scan_time_s: np.ndarray,
    scan_points_m: Sequence[np.ndarray],
    joint_time_s: np.ndarray,
    right_rad: np.ndarray,
    left_rad: np.ndarray,
    nominal: WheelGeometry,
    mount: np.ndarray,
    interval_s: float,
    time_offset_s: float | None = 0.0,
) -> ScanIntervals:
    """Cut a drive into intervals between scans about ``interval_s`` apart (within the wheel
    joints' time span; intervals where the wheels hardly turn are left out) and match the scans
    at each interval's ends, starting from the motion the odometry of ``nominal`` predicts for
    the laser at ``mount`` (x_m, y_m, yaw_rad on the base).

    ``scan_time_s`` (N,) and ``scan_points_m`` (N arrays (n_i, 2), m) are the scans; the wheel
    angles ``right_rad``, ``left_rad`` (rad) are sampled at ``joint_time_s`` (s). The laser's
    stamps run ``time_offset_s`` late against the wheels' (None: estimated from the matched
    rotations, :mod:`odocal.calibration.time_offset`); the wheel rotations of an interval are
    taken at the wheel clock.
    CalibrationError when scans and joints hardly overlap or fewer than
    :data:`MIN_MATCHED_INTERVALS` intervals match."""
    from .censi import predict_sensor_motion

    t_j = joint_time_s
    inside = np.flatnonzero((scan_time_s >= t_j[0]) & (scan_time_s <= t_j[-1]))
    if len(inside) < 2:
        raise CalibrationError("the laser scans and the wheel joints hardly overlap in time")
    t_s = scan_time_s[inside]
    stride = max(1, int(round(interval_s / float(np.median(np.diff(t_s))))))
    starts = np.arange(0, len(inside) - stride, stride)
    iv = np.column_stack([inside[starts], inside[starts + stride]])
    wr, wl = np.interp(scan_time_s, t_j, right_rad), np.interp(scan_time_s, t_j, left_rad)
    phi_r, phi_l = wr[iv[:, 1]] - wr[iv[:, 0]], wl[iv[:, 1]] - wl[iv[:, 0]]
    moving = np.maximum(np.abs(phi_r), np.abs(phi_l)) > 1e-3
    iv, phi_r, phi_l = iv[moving], phi_r[moving], phi_l[moving]
    guesses = predict_sensor_motion(nominal, mount, phi_r, phi_l)
    matches = match_intervals(scan_time_s, scan_points_m, iv, guesses)
    ok = matches.usable
    if ok.sum() < MIN_MATCHED_INTERVALS:
        raise CalibrationError(
            f"only {int(ok.sum())} of {len(ok)} scan intervals matched; record a longer drive "
            "in a room with walls the laser sees"
        )
    a, b, motion = matches.start_time_s[ok], matches.end_time_s[ok], matches.motion[ok]
    offset = _laser_offset(t_j, right_rad, left_rad, a, b, motion, time_offset_s)
    d = offset.applied_s
    inc = wheel_increments(t_j, right_rad, left_rad, a - d, b - d)
    if d:
        phi_r, phi_l = inc[0].sum(axis=1), inc[1].sum(axis=1)
    else:  # the rotations as before, bit for bit
        phi_r, phi_l = phi_r[ok], phi_l[ok]
    return ScanIntervals(
        RelativeMotions(phi_r, phi_l, motion, inc, a - d, b - d),
        int(stride),
        int(len(ok)),
        int(ok.sum()),
        int((~matches.converged).sum()),
        int(matches.degenerate.sum()),
        offset,
    )


def _laser_offset(
    t_j: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
    motion: np.ndarray,
    given: float | None,
) -> TimeOffset:
    """The laser's clock offset: given, else registered on the matched rotations (the laser's
    rotation is the base's whatever its mounting)."""
    return resolve_offset(
        "laser",
        given,
        lambda: estimate_time_offset(
            t_j, right, left, start_s, end_s, motion[:, 2], source="laser"
        ),
    )
