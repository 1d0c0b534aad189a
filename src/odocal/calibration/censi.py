"""Odometry and sensor-mounting calibration from relative motions (Censi, Franchi, Marchionni &
Oriolo, "Simultaneous calibration of odometry and sensor parameters for mobile robots", IEEE T-RO
29(2), 2013).

Input: n tuples, one per time interval k: the total rotation of each wheel over the interval
(``phi_right_rad``, ``phi_left_rad``, rad) and the rigid displacement of an exteroceptive sensor
over the same interval, expressed in the SENSOR frame at the start of the interval
(``sensor_motion[k] = (x_m, y_m, theta_rad)``): scan matching, consecutive SLAM poses, or a
motion-capture body whose origin is not the robot centre (``relative_motion`` turns a pose
sequence into such displacements). Output: the wheel diameters D_R, D_L and wheelbase b (m), the
sensor pose on the robot l = (x_m, y_m, yaw_rad) in the base frame (docs/conventions.md: +x
forward, +y left, yaw CCW), a covariance and the tuples dropped as outliers. See docs/censi.md.

Model (the paper's). Wheel velocities are constant within an interval, so the robot moves on an
arc (exact, not a small-step approximation)::

    theta = (D_R phi_R - D_L phi_L) / (2 b),     d = (D_R phi_R + D_L phi_L) / 4
    o = (d sin(theta)/theta, d (1 - cos(theta))/theta, theta)      (robot frame at the start)
    sensor motion s = (-l) (+) o (+) l,  i.e.  l (+) s = o (+) l    ((+): SE(2) composition)

Estimator:

1. Closed form (the paper's section V). With J21 = -r_L/b, J22 = r_R/b (r = D/2) the rotation is
   linear: theta_k = J21 phi_L,k + J22 phi_R,k; ordinary least squares on the measured sensor
   rotations. Then, with x = (b, l_x, l_y, cos l_yaw, sin l_yaw), the translation part of
   l (+) s = o (+) l is linear in x: L_k x = 0 (two rows per tuple), and x minimises x^T M x,
   M = sum L_k^T L_k (5x5), subject to x_4^2 + x_5^2 = 1. The Lagrange condition
   (M + lambda W) x = 0, W = diag(0, 0, 0, 1, 1), has det(M + lambda W) =
   det(M_aa) det(S + lambda I) with the Schur complement S = M_zz - M_az^T M_aa^-1 M_az (2x2), so
   the multipliers are minus the eigenvalues of S and the minimum is the eigenvector of S's smallest
   eigenvalue; x_a = -M_aa^-1 M_az z, sign chosen so that b > 0. Then r_L = -J21 b, r_R = J22 b.
2. Refinement (ours): ``scipy.optimize.least_squares`` on all six parameters of the residual
   predicted - measured sensor motion, each component divided by its noise standard deviation
   estimated from the residuals (two passes): the maximum-likelihood problem the paper states.

Outliers (the authors' published solver, verified against their results): ``outlier_iterations``
times, solve in closed form, compute each tuple's disagreement e = l (+) s - o (+) l (robot frame)
and drop the tuples whose |e_xy| or |e_theta| exceeds the value at rank round((1 - f) n) of its own
sorted list (f = ``outlier_fraction``, 1 % by default, 4 iterations: at most about 2 f n tuples a
round). The final estimate uses the tuples left after the last round.

Covariance: Gauss-Newton, (J^T Sigma^-1 J)^-1 at the solution over the tuples used, Sigma =
diag(sigma_x^2, sigma_y^2, sigma_theta^2), each sigma the larger of the residuals' RMS over the
tuples used and 1.4826 MAD over all tuples (``_noise_std``). ``covariance_paper`` is the authors'
version: the same Fisher information with the noise taken as the sample standard deviation over
the tuples left after the FIRST trimming round, summed over the tuples left after one more
trimming round than the estimate used. Outliers still inflate that noise estimate: on the l90 and
lmov data it is 10-20 times wider than the spread between their disjoint subsets; ours is about
10 times narrower there and consistent with that spread (docs/censi.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..core.jsonable import finite_list, finite_or_none
from ..core.model import ModelError, WheelGeometry
from ..core.odometry import (
    arc_displacement,
    arc_position,
    body_increments,
    midpoint_end_derivatives,
    midpoint_end_padded,
    wheel_travel,
)
from ..core.transforms import se2_compose, se2_conjugate, se2_relative, wrap_angle
from ..errors import CalibrationError
from .result import check_physical
from .robust_covariance import cluster_covariance

__all__ = [
    "PARAMETERS",
    "MIN_TUPLES",
    "MIN_WHEEL_ROTATION_RAD",
    "SensorOdometryFit",
    "fit_censi",
    "closed_form_censi",
    "predict_sensor_motion",
    "relative_motion",
]

#: Order of the parameter vector, the covariance rows and the ``stderr`` keys.
PARAMETERS = (
    "wheel_diameter_right_m",
    "wheel_diameter_left_m",
    "wheelbase_m",
    "sensor_x_m",
    "sensor_y_m",
    "sensor_yaw_rad",
)
#: Fewest tuples accepted (before and after outlier rejection).
MIN_TUPLES = 10
# Wheel-rotation excitation: the two singular values of the (n, 2) matrix of rotations must not
# differ by more than this factor (cond(Phi^T Phi) <= 1e6), else J21, J22 are not separable.
_MAX_WHEEL_COND = 1e3
#: Below this rotation (rad) in every tuple the wheels do not turn: finer than any encoder's tick
#: (and squares of such values underflow the least squares' normal equations).
MIN_WHEEL_ROTATION_RAD = 1e-6
# The turning coefficient J22 - J21 (= (r_R + r_L)/b) must be this many standard errors from 0.
_MIN_TURN_T = 10.0
# Floor of the residual noise estimate (m or rad): exact synthetic data have zero residuals.
_SIGMA_FLOOR = 1e-12


@dataclass(frozen=True)
class SensorOdometryFit:
    """Calibrated odometry and sensor pose from relative-motion tuples.

    Attributes
    ----------
    geometry : WheelGeometry
        Wheel diameters D_R, D_L (m) and wheelbase b (m).
    sensor_x_m, sensor_y_m, sensor_yaw_rad : float
        Sensor pose in the robot base frame (m, m, rad in [-pi, pi)).
    covariance : ndarray, shape (6, 6)
        Covariance of the parameters in ``PARAMETERS`` order (SI units squared); NaN rows and
        columns for parameters that were fixed, all NaN if singular.
    stderr : dict
        Square roots of the covariance diagonal by ``PARAMETERS`` key (None if not estimated).
    covariance_paper : ndarray, shape (6, 6) or None
        The authors' covariance (module docstring), same order and units.
    closed_form : ndarray, shape (6,)
        The closed-form (linear) estimate on the same tuples, ``PARAMETERS`` order.
    noise_std : ndarray, shape (3,)
        Noise standard deviation of the sensor motion (x_m, y_m, theta_rad) used for the weights
        and the covariance: the larger of the residuals' RMS over the tuples used and 1.4826 MAD
        over all tuples.
    tuples_total, tuples_used : int
    dropped_indices : tuple of int
        0-based indices (into the input arrays) of the tuples dropped as outliers, ascending.
    dropped_per_round : tuple of int
        How many tuples each trimming round dropped.
    outlier_iterations : int
    outlier_fraction : float
    refined : bool
        Whether the nonlinear refinement ran (else the estimate is the closed form).
    sensor_pose_fixed : bool
    warnings : tuple of str
    uncertainty : str
        How ``covariance`` was computed: 'formal' (the inverse Fisher information) or
        'cluster-robust over N time blocks' (:mod:`odocal.calibration.robust_covariance`).
    covariance_formal : ndarray, shape (6, 6), or None
        The formal covariance when ``covariance`` is the cluster-robust one.
    dof : int or None
        Degrees of freedom of the standard errors (blocks - 1), None for the formal ones.
    """

    geometry: WheelGeometry
    sensor_x_m: float
    sensor_y_m: float
    sensor_yaw_rad: float
    covariance: np.ndarray
    stderr: dict
    covariance_paper: np.ndarray | None
    closed_form: np.ndarray
    noise_std: np.ndarray
    tuples_total: int
    tuples_used: int
    dropped_indices: tuple[int, ...]
    dropped_per_round: tuple[int, ...]
    outlier_iterations: int
    outlier_fraction: float
    refined: bool
    sensor_pose_fixed: bool
    warnings: tuple[str, ...] = field(default_factory=tuple)
    uncertainty: str = "formal"
    covariance_formal: np.ndarray | None = None
    dof: int | None = None

    method = "relative"  # relative-motion calibration (Censi et al. 2013)

    @property
    def parameters(self) -> np.ndarray:
        """(D_R, D_L, b, x, y, yaw), shape (6,), in ``PARAMETERS`` order (m, m, m, m, m, rad)."""
        g = self.geometry
        return np.array(
            [
                float(g.diameter_right_m),
                float(g.diameter_left_m),
                float(g.wheelbase_m),
                self.sensor_x_m,
                self.sensor_y_m,
                self.sensor_yaw_rad,
            ]
        )

    @property
    def sensor_pose(self) -> np.ndarray:
        """(x_m, y_m, yaw_rad) of the sensor in the base frame, shape (3,)."""
        return np.array([self.sensor_x_m, self.sensor_y_m, self.sensor_yaw_rad])

    @property
    def tuples_dropped(self) -> int:
        """How many tuples the outlier rule dropped."""
        return len(self.dropped_indices)

    def as_dict(self) -> dict:
        """The JSON contract of ``odocal fit FILE.tuple --json`` (non-finite values as None)."""
        values = {k: finite_or_none(v) for k, v in zip(PARAMETERS, self.parameters, strict=True)}
        paper = self.covariance_paper
        return {
            "method": self.method,
            **values,
            "stderr": {k: finite_or_none(v) for k, v in self.stderr.items()},
            "stderr_paper": None if paper is None else _stderr(paper),
            "parameters": list(PARAMETERS),
            "covariance": finite_list(self.covariance),
            "covariance_paper": None if paper is None else finite_list(paper),
            "closed_form": {
                k: finite_or_none(v) for k, v in zip(PARAMETERS, self.closed_form, strict=True)
            },
            "noise_std": dict(
                zip(
                    ("x_m", "y_m", "theta_rad"),
                    (finite_or_none(v) for v in self.noise_std),
                    strict=True,
                )
            ),
            "tuples_total": self.tuples_total,
            "tuples_used": self.tuples_used,
            "tuples_dropped": self.tuples_dropped,
            "dropped_indices": list(self.dropped_indices),
            "outlier_rule": {
                "iterations": self.outlier_iterations,
                "fraction": self.outlier_fraction,
                "dropped_per_round": list(self.dropped_per_round),
            },
            "refined": self.refined,
            "sensor_pose_fixed": self.sensor_pose_fixed,
            "warnings": list(self.warnings),
            **self._uncertainty_dict(),
        }

    def _uncertainty_dict(self) -> dict:
        """How the standard errors were computed (only when not the formal ones, so that the
        formal output keeps its keys)."""
        if self.covariance_formal is None:
            return {}
        return {
            "uncertainty": self.uncertainty,
            "dof": self.dof,
            "stderr_formal": {
                k: finite_or_none(v) for k, v in _stderr(self.covariance_formal).items()
            },
        }


def _stderr(cov: np.ndarray) -> dict:
    d = np.diag(cov)
    return {
        k: (float(np.sqrt(v)) if np.isfinite(v) and v >= 0 else None)
        for k, v in zip(PARAMETERS, d, strict=True)
    }


def relative_motion(poses: ArrayLike) -> np.ndarray:
    """Displacements between consecutive poses, each in the frame of the earlier pose.

    Parameters
    ----------
    poses : array_like, shape (n + 1, 3)
        Absolute poses (x_m, y_m, theta_rad) of the sensor (a SLAM or motion-capture body frame)
        in any fixed world frame, at the interval boundaries.

    Returns
    -------
    ndarray, shape (n, 3)
        (-P_k) (+) P_k+1: the ``sensor_motion`` of ``fit_censi``; theta wrapped to [-pi, pi).
    """
    p = np.asarray(poses, dtype=float)
    if p.ndim != 2 or p.shape[1] != 3 or len(p) < 2:
        raise ModelError(f"poses must have shape (n + 1, 3) with n >= 1, got {p.shape}")
    return se2_relative(p[:-1], p[1:])


def _arc(p: np.ndarray, phi_r: np.ndarray, phi_l: np.ndarray) -> np.ndarray:
    """Robot displacement (n, 3) over each interval; p = (D_R, D_L, b, ...).

    1-D wheel rotations (n,): the exact arc (constant wheel speeds within the interval). 2-D
    wheel increments (n, K) (zero padded): the midpoint odometry over the increments, as
    ``core.odometry.dead_reckon`` integrates them (no constant-speed assumption)."""
    s_r, s_l = wheel_travel(phi_r, phi_l, WheelGeometry.unchecked(p[0], p[1], p[2]))
    if phi_r.ndim == 2:
        return midpoint_end_padded(*body_increments(s_r, s_l, p[2]))
    return arc_displacement(*body_increments(s_r, s_l, p[2]))


def _predict(p: np.ndarray, phi_r: np.ndarray, phi_l: np.ndarray) -> np.ndarray:
    o = _arc(p, phi_r, phi_l)
    lpose = np.broadcast_to(p[3:6], o.shape)
    return se2_conjugate(o, lpose)


def predict_sensor_motion(
    geometry: WheelGeometry,
    sensor_pose: ArrayLike,
    phi_right_rad: ArrayLike,
    phi_left_rad: ArrayLike,
) -> np.ndarray:
    """The sensor displacement over each interval predicted by the arc model.

    Parameters
    ----------
    geometry : WheelGeometry
        D_R, D_L, b (m).
    sensor_pose : array_like, shape (3,)
        (x_m, y_m, yaw_rad) of the sensor in the base frame.
    phi_right_rad, phi_left_rad : array_like, shape (n,)
        Total wheel rotation over each interval (rad), constant wheel speed within it.

    Returns
    -------
    ndarray, shape (n, 3)
        (x_m, y_m, theta_rad) of the sensor, in the sensor frame at the interval start.
    """
    pose = np.asarray(sensor_pose, dtype=float).reshape(3)
    p = np.array(
        [
            float(geometry.diameter_right_m),
            float(geometry.diameter_left_m),
            float(geometry.wheelbase_m),
            *pose,
        ]
    )
    r = np.atleast_1d(np.asarray(phi_right_rad, dtype=float))
    l_ = np.atleast_1d(np.asarray(phi_left_rad, dtype=float))
    return _predict(p, r, l_)


def _disagreement(
    p: np.ndarray, phi_r: np.ndarray, phi_l: np.ndarray, sm: np.ndarray
) -> np.ndarray:
    """The authors' outlier residual l (+) s - o (+) l, shape (n, 3), robot frame."""
    o = _arc(p, phi_r, phi_l)
    lpose = np.broadcast_to(p[3:6], o.shape)
    e = se2_compose(lpose, sm) - se2_compose(o, lpose)
    e[:, 2] = wrap_angle(e[:, 2])
    return e


def _residual(p: np.ndarray, phi_r: np.ndarray, phi_l: np.ndarray, sm: np.ndarray) -> np.ndarray:
    """Predicted - measured sensor motion, shape (n, 3), sensor frame (heading wrapped)."""
    e = _predict(p, phi_r, phi_l) - sm
    e[:, 2] = wrap_angle(e[:, 2])
    return e


# ----------------------------------------------------------------------------------------------
# Input checks


def _as_inputs(
    phi_right_rad: ArrayLike, phi_left_rad: ArrayLike, sensor_motion: ArrayLike
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    r = np.asarray(phi_right_rad, dtype=float)
    l_ = np.asarray(phi_left_rad, dtype=float)
    sm = np.asarray(sensor_motion, dtype=float)
    if r.ndim != 1 or l_.shape != r.shape:
        raise ModelError(
            "phi_right_rad and phi_left_rad must be 1-D arrays of one length, got shapes "
            f"{r.shape} and {l_.shape}"
        )
    if sm.shape != (len(r), 3):
        raise ModelError(f"sensor_motion must have shape ({len(r)}, 3), got {sm.shape}")
    for name, a in (("phi_right_rad", r), ("phi_left_rad", l_), ("sensor_motion", sm)):
        bad = ~np.isfinite(a)
        if bad.any():
            k = int(np.argwhere(bad)[0][0])
            raise ModelError(f"{name} must be finite, tuple {k} is not")
    if len(r) < MIN_TUPLES:
        raise CalibrationError(
            f"censi: {len(r)} tuples; at least {MIN_TUPLES} are needed for the six parameters"
        )
    return r, l_, sm


def _check_excitation(phi_r: np.ndarray, phi_l: np.ndarray) -> None:
    """CalibrationError naming the missing motion if J21, J22 cannot be separated."""
    phi = np.column_stack([phi_l, phi_r])
    largest = float(np.max(np.abs(phi))) if phi.size else 0.0
    if not largest >= MIN_WHEEL_ROTATION_RAD:
        raise CalibrationError(
            f"censi: the wheels do not turn in any tuple (largest rotation {largest:.3g} rad; a "
            "duration T in the wrong unit?)"
        )
    _, s, vt = np.linalg.svd(phi, full_matrices=False)
    if s[1] * _MAX_WHEEL_COND >= s[0]:
        return
    v = vt[0]  # dominant direction of (phi_L, phi_R)
    straight = abs(v[0] + v[1]) / np.sqrt(2)
    spin = abs(v[0] - v[1]) / np.sqrt(2)
    if straight > 0.99:
        what = (
            "the robot only drives straight (equal wheel rotations): no turning, so the "
            "wheelbase and the sensor position are not identifiable; add turns (spot turns or "
            "arcs) in both directions"
        )
    elif spin > 0.99:
        what = (
            "the robot only turns on the spot (opposite wheel rotations): no forward motion, so "
            "the wheel diameters are not identifiable separately; add straight segments or arcs"
        )
    else:
        what = (
            "every tuple drives the same curvature (proportional wheel rotations); add straight "
            "segments and turns of other radii"
        )
    raise CalibrationError(f"censi: degenerate motion: {what}")


def _step1(phi_r: np.ndarray, phi_l: np.ndarray, sm: np.ndarray) -> tuple[float, float]:
    """J21, J22 by least squares on the sensor rotations (rad per rad of wheel rotation)."""
    phi = np.column_stack([phi_l, phi_r])
    j, *_ = np.linalg.lstsq(phi, sm[:, 2], rcond=None)
    dof = len(phi) - 2
    res = sm[:, 2] - phi @ j
    s2 = float(res @ res) / dof if dof > 0 else 0.0
    cov = s2 * np.linalg.inv(phi.T @ phi)
    j21, j22 = float(j[0]), float(j[1])
    se21, se22 = np.sqrt(np.diag(cov))
    g = np.array([-1.0, 1.0])
    turn = j22 - j21  # (r_R + r_L)/b > 0
    se = float(np.sqrt(g @ cov @ g))
    t = _MIN_TURN_T
    if (j21 > t * se21 and j22 > t * se22) or (j21 < -t * se21 and j22 < -t * se22):
        wheel = "left" if j21 > 0 else "right"
        raise CalibrationError(
            f"censi: both wheels turn the robot the same way (J21 = {j21:.4g}, J22 = {j22:.4g} "
            f"rad/rad): the {wheel} wheel's rotation sign appears reversed in the input"
        )
    if turn < -t * se:
        raise CalibrationError(
            "censi: the sensor turns the opposite way to the wheels ((r_R + r_L)/b = "
            f"{turn:.4g}): the left and right wheels may be swapped, or the sensor's rotation "
            "sign reversed"
        )
    if not turn > t * se:
        raise CalibrationError(
            "censi: no rotation: the sensor's rotations are not explained by the wheels' turning "
            f"((r_R + r_L)/b = {turn:.3g} +- {se:.2g}); the wheelbase and the sensor position "
            "need turns in the data (and a sensor that reports them)"
        )
    if not (j21 < 0 < j22):
        raise CalibrationError(
            f"censi: non-physical rotation coefficients J21 = {j21:.4g}, J22 = {j22:.4g} rad/rad "
            "(expected J21 < 0 < J22); check the wheel signs"
        )
    return j21, j22


def _closed_form(
    phi_r: np.ndarray, phi_l: np.ndarray, sm: np.ndarray, fixed_pose: np.ndarray | None
) -> np.ndarray:
    """The paper's two linear steps; (D_R, D_L, b, x, y, yaw). Inputs already checked."""
    j21, j22 = _step1(phi_r, phi_l, sm)
    th = j21 * phi_l + j22 * phi_r
    k = 0.5 * (-j21 * phi_l + j22 * phi_r)
    cx, cy = arc_position(k, th)  # robot translation over b
    c, s = np.cos(th), np.sin(th)
    sx, sy = sm[:, 0], sm[:, 1]
    if fixed_pose is not None:
        lx, ly, lyaw = fixed_pose
        cl, sl = np.cos(lyaw), np.sin(lyaw)
        ex = (1 - c) * lx + s * ly + cl * sx - sl * sy
        ey = -s * lx + (1 - c) * ly + sl * sx + cl * sy
        den = float(cx @ cx + cy @ cy)
        if not den > 0:
            raise CalibrationError("censi: no forward motion, the wheel scale is not identifiable")
        b = float(cx @ ex + cy @ ey) / den
        pose = np.array([lx, ly, lyaw])
    else:
        rows_x = np.column_stack([-cx, 1 - c, s, sx, -sy])
        rows_y = np.column_stack([-cy, -s, 1 - c, sy, sx])
        m = rows_x.T @ rows_x + rows_y.T @ rows_y
        m_aa, m_az, m_zz = m[:3, :3], m[:3, 3:], m[3:, 3:]
        scale = np.sqrt(np.diag(m_aa))
        if not np.all(scale > 0) or np.linalg.cond(m_aa / np.outer(scale, scale)) > 1e12:
            raise CalibrationError(
                "censi: the wheelbase and sensor position are not identifiable from these "
                "tuples (the closed-form step is singular); drive turns and forward motion"
            )
        a_inv_b = np.linalg.solve(m_aa, m_az)
        schur = m_zz - m_az.T @ a_inv_b
        _, vec = np.linalg.eigh(0.5 * (schur + schur.T))
        z = vec[:, 0]  # smallest eigenvalue <=> the Lagrange multiplier of the minimum
        xa = -a_inv_b @ z
        if xa[0] < 0:
            xa, z = -xa, -z
        b = float(xa[0])
        pose = np.array([xa[1], xa[2], np.arctan2(z[1], z[0])])
    return np.array([2.0 * j22 * b, -2.0 * j21 * b, b, *pose])


def closed_form_censi(
    phi_right_rad: ArrayLike,
    phi_left_rad: ArrayLike,
    sensor_motion: ArrayLike,
    *,
    sensor_pose: ArrayLike | None = None,
) -> np.ndarray:
    """The paper's closed-form estimate on all tuples (no outlier rejection, no refinement).

    Parameters
    ----------
    phi_right_rad, phi_left_rad : array_like, shape (n,)
        Total wheel rotation over each interval (rad).
    sensor_motion : array_like, shape (n, 3)
        Sensor displacement (x_m, y_m, theta_rad) in the sensor frame at the interval start.
    sensor_pose : array_like, shape (3,), optional
        Known sensor pose (x_m, y_m, yaw_rad); then only D_R, D_L, b are estimated.

    Returns
    -------
    ndarray, shape (6,)
        (D_R, D_L, b, x, y, yaw) in ``PARAMETERS`` order (m, m, m, m, m, rad).
    """
    r, l_, sm = _as_inputs(phi_right_rad, phi_left_rad, sensor_motion)
    fixed = _as_pose(sensor_pose)
    _check_excitation(r, l_)
    p = _closed_form(r, l_, sm, fixed)
    check_physical(p[:3], None, "censi")
    p[5] = float(wrap_angle(p[5]))
    return p


def _as_pose(sensor_pose: ArrayLike | None) -> np.ndarray | None:
    if sensor_pose is None:
        return None
    pose = np.asarray(sensor_pose, dtype=float)
    if pose.shape != (3,) or not np.all(np.isfinite(pose)):
        raise ModelError(f"sensor_pose must be 3 finite numbers (x_m, y_m, yaw_rad), got {pose}")
    return pose


# ----------------------------------------------------------------------------------------------
# Refinement and covariance


def _jacobian(
    p: np.ndarray,
    free: list[int],
    phi_r: np.ndarray,
    phi_l: np.ndarray,
    sm: np.ndarray,
    weight: float | np.ndarray,
) -> np.ndarray:
    """Jacobian of the weighted residual w.r.t. p[free], shape (3n, k): central differences,
    or for wheel increments (2-D) :func:`_increments_jacobian`."""
    if phi_r.ndim == 2:
        return _increments_jacobian(p, free, phi_r, phi_l, weight)
    cols = []
    for j in free:
        scale = 1.0 if j == 5 else max(abs(p[2]), 1e-3)  # yaw in rad, lengths relative to b
        h = 1e-6 * (abs(p[j]) + 1e-2 * scale)
        pp, pm = p.copy(), p.copy()
        pp[j] += h
        pm[j] -= h
        d = (_residual(pp, phi_r, phi_l, sm) - _residual(pm, phi_r, phi_l, sm)) / (2 * h)
        cols.append((d * weight).ravel())
    return np.column_stack(cols)


def _increments_jacobian(
    p: np.ndarray,
    free: list[int],
    inc_r: np.ndarray,
    inc_l: np.ndarray,
    weight: float | np.ndarray,
) -> np.ndarray:
    """The Jacobian of :func:`_jacobian` for wheel increments (n, K): D_R, D_L and b analytic
    (:func:`~odocal.core.odometry.midpoint_end_derivatives`, chained through the sensor's
    conjugation), the sensor pose by central differences of the conjugation alone (the robot's
    motion does not depend on it). One integration instead of two per parameter."""
    d_r, d_l, b = float(p[0]), float(p[1]), float(p[2])
    s_r, s_l = wheel_travel(inc_r, inc_l, WheelGeometry.unchecked(d_r, d_l, b))
    ds, dth = body_increments(s_r, s_l, b)
    zero = np.zeros_like(ds)
    d_ds = np.stack([0.5 * s_r / d_r, 0.5 * s_l / d_l, zero])
    d_dth = np.stack([s_r / (d_r * b), -s_l / (d_l * b), -dth / b])
    o, do = midpoint_end_derivatives(ds, dth, d_ds, d_dth)  # (n, 3), (n, 3, 3)
    lx, ly, lth = (float(v) for v in p[3:6])
    c, s = math.cos(lth), math.sin(lth)
    rot = np.array([[c, s, 0.0], [-s, c, 0.0], [0.0, 0.0, 1.0]])  # R(-yaw) and the heading
    conj = np.broadcast_to(rot, (len(o), 3, 3)).copy()  # d conjugate / d motion
    co, so = np.cos(o[:, 2]), np.sin(o[:, 2])
    turn = np.stack([-so * lx - co * ly, co * lx - so * ly], axis=-1)  # dR(theta)/dtheta l_xy
    conj[:, :2, 2] = turn @ rot[:2, :2].T
    geo = conj @ do  # (n, 3, 3)
    cols = []
    for j in free:
        if j < 3:
            cols.append((geo[:, :, j] * weight).ravel())
            continue
        h = 1e-6 * (abs(p[j]) + 1e-2 * (1.0 if j == 5 else max(abs(b), 1e-3)))
        up, dn = p[3:6].copy(), p[3:6].copy()
        up[j - 3] += h
        dn[j - 3] -= h
        d = se2_conjugate(o, np.broadcast_to(up, o.shape)) - se2_conjugate(
            o, np.broadcast_to(dn, o.shape)
        )
        d[:, 2] = wrap_angle(d[:, 2])
        cols.append((d / (2 * h) * weight).ravel())
    return np.column_stack(cols)


def _noise_std(
    p: np.ndarray,
    phi_r: np.ndarray,
    phi_l: np.ndarray,
    sm: np.ndarray,
    n_free: int,
    everything: tuple[np.ndarray, np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Noise standard deviation per component (x_m, y_m, theta_rad), shape (3,).

    RMS residual over the tuples used, with the parameter count spread over the 3 components;
    with ``everything`` = (phi_r, phi_l, sm) of ALL tuples, at least 1.4826 MAD of their
    residuals: trimming removes the tails, so the RMS of the kept tuples is low for Gaussian noise
    (5-15 % with the default rule), while the MAD of all tuples is consistent for Gaussian
    inliers and robust to the outliers; on the authors' heavier-tailed real data the two agree
    within 7 %.
    """
    e = _residual(p, phi_r, phi_l, sm)
    dof = max(len(e) - n_free / 3.0, 1.0)
    sigma = np.sqrt(np.sum(e * e, axis=0) / dof)
    if everything is not None:
        a = _residual(p, *everything)
        mad = 1.4826 * np.median(np.abs(a - np.median(a, axis=0)), axis=0)
        sigma = np.maximum(sigma, mad)
    return np.maximum(sigma, _SIGMA_FLOOR)


def _refine(
    p0: np.ndarray,
    free: list[int],
    phi_r: np.ndarray,
    phi_l: np.ndarray,
    sm: np.ndarray,
    everything: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, bool]:
    from scipy.optimize import least_squares  # here: a slow import

    p = p0.copy()
    converged = True
    for _ in range(2):  # noise weights from the current estimate, then once more
        w = 1.0 / _noise_std(p, phi_r, phi_l, sm, len(free), everything)

        def fun(q: np.ndarray, w: np.ndarray = w, base: np.ndarray = p) -> np.ndarray:
            full = base.copy()
            full[free] = q
            return (_residual(full, phi_r, phi_l, sm) * w).ravel()

        def jac(q: np.ndarray, w: np.ndarray = w, base: np.ndarray = p) -> np.ndarray:
            full = base.copy()
            full[free] = q
            return _jacobian(full, free, phi_r, phi_l, sm, w)

        sol = least_squares(fun, p[free], jac=jac, method="lm", x_scale="jac")
        converged = converged and sol.status > 0
        p = p.copy()
        p[free] = sol.x
    return p, converged


def _fisher(
    p: np.ndarray,
    free: list[int],
    phi_r: np.ndarray,
    phi_l: np.ndarray,
    sm: np.ndarray,
    sigma: np.ndarray,
) -> np.ndarray:
    """Covariance (6, 6) as the inverse Fisher information, NaN for fixed or singular."""
    jw = _jacobian(p, free, phi_r, phi_l, sm, 1.0 / sigma)
    cov = np.full((6, 6), np.nan)
    info = jw.T @ jw
    d = np.sqrt(np.diag(info))
    if np.all(d > 0):
        norm = info / np.outer(d, d)
        if np.linalg.cond(norm) < 1e14:
            cov[np.ix_(free, free)] = np.linalg.inv(norm) / np.outer(d, d)
    return cov


# ----------------------------------------------------------------------------------------------
# Outlier trimming (the authors' rule)


def _trim(
    p: np.ndarray, phi_r: np.ndarray, phi_l: np.ndarray, sm: np.ndarray, fraction: float
) -> np.ndarray:
    """Mask of the tuples kept by one trimming round at estimate p."""
    e = _disagreement(p, phi_r, phi_l, sm)
    e_xy = np.hypot(e[:, 0], e[:, 1])
    e_th = np.abs(e[:, 2])
    n = len(e)
    rank = min(max(int(np.round((1.0 - fraction) * n)), 0), n - 1)
    return (e_xy <= np.sort(e_xy)[rank]) & (e_th <= np.sort(e_th)[rank])


def fit_censi(
    phi_right_rad: ArrayLike,
    phi_left_rad: ArrayLike,
    sensor_motion: ArrayLike,
    *,
    sensor_pose: ArrayLike | None = None,
    refine: bool = True,
    outlier_iterations: int = 4,
    outlier_fraction: float = 0.01,
    nominal: WheelGeometry | None = None,
    wheel_increments: tuple[ArrayLike, ArrayLike] | None = None,
    clusters: ArrayLike | None = None,
) -> SensorOdometryFit:
    """Calibrate wheel diameters, wheelbase and the sensor pose from relative-motion tuples.

    Parameters
    ----------
    phi_right_rad, phi_left_rad : array_like, shape (n,)
        Total rotation of each wheel over each interval (rad; forward positive). For tuples that
        carry average wheel speeds (the authors' ``.tuple`` files), multiply by the duration.
    sensor_motion : array_like, shape (n, 3)
        Rigid displacement (x_m, y_m, theta_rad) of the sensor over each interval, in the sensor
        frame at the interval start (``relative_motion`` builds it from absolute poses).
    sensor_pose : array_like, shape (3,), optional
        Known sensor pose (x_m, y_m, yaw_rad) in the base frame, e.g. zeros when the motion is the
        robot base's own; then only D_R, D_L, b are estimated.
    refine : bool
        Run the nonlinear maximum-likelihood refinement after the closed form (default True).
    outlier_iterations : int
        Trimming rounds (>= 0; default 4 as the authors).
    outlier_fraction : float
        Fraction f in [0, 0.5) of each sorted disagreement list above which tuples are dropped in
        each round (default 0.01 as the authors).
    nominal : WheelGeometry, optional
        Nominal geometry, only to warn about results more than 25 % away from it.
    wheel_increments : (ndarray, ndarray), each shape (n, K), optional
        The wheel rotations of each interval as they were sampled (rad; rows zero padded; row
        sums equal to ``phi_right_rad``, ``phi_left_rad``). With them the refinement, the
        outlier rule and the covariance integrate the odometry over the samples instead of
        assuming constant wheel speeds within an interval (the closed form still does): for
        intervals that mix straights, turns and arcs, e.g. between SLAM updates.
    clusters : array_like of int, shape (n,), optional
        Independent groups of the tuples (e.g. contiguous time blocks of a log,
        :func:`odocal.calibration.time_offset.time_blocks`). With them the covariance is the
        cluster-robust one over the tuples used (residuals correlated within a block, and a
        model that fits some stretches worse than others, widen it); ``covariance_formal`` keeps
        the inverse Fisher information.

    Returns
    -------
    SensorOdometryFit

    Raises
    ------
    ModelError
        Arrays of the wrong shape or with non-finite values; bad options.
    CalibrationError
        Too few tuples, motion that does not identify the parameters (naming what is missing),
        or a non-physical result (e.g. swapped wheels).
    """
    r, l_, sm = _as_inputs(phi_right_rad, phi_left_rad, sensor_motion)
    fixed = _as_pose(sensor_pose)
    outlier_iterations, outlier_fraction = _outlier_rule(outlier_iterations, outlier_fraction)
    _check_excitation(r, l_)
    # the wheel data the odometry is integrated from: rotations, or the sampled increments
    wr, wl = (r, l_) if wheel_increments is None else _as_increments(wheel_increments, r, l_)
    n = len(r)
    trimmed = _trimmed_closed_form(r, l_, sm, fixed, wr, wl, outlier_iterations, outlier_fraction)
    p, keep = trimmed.estimate, trimmed.keep
    warnings = check_physical(p[:3], None, "censi")
    closed = p.copy()
    closed[5] = float(wrap_angle(closed[5]))

    free = [0, 1, 2] if fixed is not None else [0, 1, 2, 3, 4, 5]
    rk, lk, smk = wr[keep], wl[keep], sm[keep]
    converged = True
    if refine:
        p, converged = _refine(p, free, rk, lk, smk, (wr, wl, sm))
        if not converged:
            warnings = [*warnings, "censi: the nonlinear refinement did not converge"]
    p[5] = float(wrap_angle(p[5]))
    warnings = [*warnings, *check_physical(p[:3], nominal, "censi")]

    sigma = _noise_std(p, rk, lk, smk, len(free), (wr, wl, sm))
    cov = _fisher(p, free, rk, lk, smk, sigma)
    robust = None if clusters is None else _robust(p, free, rk, lk, smk, sigma, clusters, keep)
    cov_paper = _paper_covariance(p, free, wr, wl, sm, trimmed.history, keep, outlier_fraction)
    if refine and wheel_increments is None:
        warnings += _far_from_closed_form(p, closed, cov, free)
    dropped = np.setdiff1d(np.arange(n), keep)
    formal = None
    how, dof = "formal", None
    if robust is not None:
        formal, (cov, how, dof) = cov, robust
    return SensorOdometryFit(
        geometry=WheelGeometry(float(p[0]), float(p[1]), float(p[2])),
        sensor_x_m=float(p[3]),
        sensor_y_m=float(p[4]),
        sensor_yaw_rad=float(p[5]),
        covariance=cov,
        stderr=_stderr(cov),
        covariance_paper=cov_paper,
        closed_form=closed,
        noise_std=sigma,
        tuples_total=n,
        tuples_used=len(keep),
        dropped_indices=tuple(int(i) for i in dropped),
        dropped_per_round=tuple(trimmed.dropped_per_round),
        outlier_iterations=outlier_iterations,
        outlier_fraction=outlier_fraction,
        refined=bool(refine),
        sensor_pose_fixed=fixed is not None,
        warnings=tuple(warnings),
        uncertainty=how,
        covariance_formal=formal,
        dof=dof,
    )


def _robust(
    p: np.ndarray,
    free: list[int],
    rk: np.ndarray,
    lk: np.ndarray,
    smk: np.ndarray,
    sigma: np.ndarray,
    clusters: ArrayLike,
    keep: np.ndarray,
) -> tuple[np.ndarray, str, int] | None:
    """The cluster-robust covariance (6, 6) over the tuples used, its description and degrees
    of freedom; None with fewer than 2 clusters or a singular problem."""
    labels = np.asarray(clusters)[keep]
    w = 1.0 / sigma
    jw = _jacobian(p, free, rk, lk, smk, w)
    res = (_residual(p, rk, lk, smk) * w).ravel()
    try:
        cc = cluster_covariance(jw, res, np.repeat(labels, 3))
    except CalibrationError:
        return None
    cov = np.full((6, 6), np.nan)
    cov[np.ix_(free, free)] = cc.covariance
    return cov, f"cluster-robust over {cc.clusters} time blocks", cc.dof


def _outlier_rule(iterations: object, fraction: object) -> tuple[int, float]:
    """The trimming rounds (0..100) and fraction ([0, 0.5)), checked."""
    if isinstance(iterations, bool) or not isinstance(iterations, int | np.integer):
        raise ModelError(f"outlier_iterations must be an integer, got {iterations!r}")
    if not 0 <= iterations <= 100:
        raise ModelError(f"outlier_iterations must be in 0..100, got {iterations}")
    if not isinstance(fraction, int | float | np.floating) or not (0.0 <= float(fraction) < 0.5):
        raise ModelError(f"outlier_fraction must be in [0, 0.5), got {fraction!r}")
    return int(iterations), float(fraction)


def _as_increments(
    wheel_increments: tuple[ArrayLike, ArrayLike], r: np.ndarray, l_: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The sampled wheel increments (n, K) of each interval, checked against the rotations."""
    wr, wl = (np.asarray(a, dtype=float) for a in wheel_increments)
    if wr.ndim != 2 or wr.shape != wl.shape or len(wr) != len(r):
        raise ModelError(
            f"wheel_increments must be two arrays of shape ({len(r)}, K), got "
            f"{wr.shape} and {wl.shape}"
        )
    if not (np.all(np.isfinite(wr)) and np.all(np.isfinite(wl))):
        raise ModelError("wheel_increments must be finite")
    scale = max(float(np.max(np.abs(r))), float(np.max(np.abs(l_))), 1e-12)
    if (
        np.max(np.abs(wr.sum(axis=1) - r)) > 1e-9 * scale
        or np.max(np.abs(wl.sum(axis=1) - l_)) > 1e-9 * scale
    ):
        raise ModelError("wheel_increments must sum to phi_right_rad and phi_left_rad")
    return wr, wl


@dataclass(frozen=True)
class _Trimmed:
    """The closed form after the authors' trimming rounds: the estimate, the tuples kept, the
    kept tuples before every round (``history[0]`` all of them) and the count dropped per
    round."""

    estimate: np.ndarray
    keep: np.ndarray
    history: list[np.ndarray]
    dropped_per_round: list[int]


def _trimmed_closed_form(
    r: np.ndarray,
    l_: np.ndarray,
    sm: np.ndarray,
    fixed: np.ndarray | None,
    wr: np.ndarray,
    wl: np.ndarray,
    iterations: int,
    fraction: float,
) -> _Trimmed:
    """The closed form, re-estimated after each trimming round (the outlier rule judges the
    odometry integrated from ``wr``, ``wl``)."""
    keep = np.arange(len(r))
    history = [keep]
    per_round = []
    p = _closed_form(r, l_, sm, fixed)
    for _ in range(iterations if fraction > 0 else 0):
        check_physical(p[:3], None, "censi")
        mask = _trim(p, wr[keep], wl[keep], sm[keep], fraction)
        per_round.append(int(np.count_nonzero(~mask)))
        keep = keep[mask]
        history.append(keep)
        if len(keep) < MIN_TUPLES:
            raise CalibrationError(
                f"censi: only {len(keep)} tuples left after outlier rejection; at least "
                f"{MIN_TUPLES} are needed"
            )
        _check_excitation(r[keep], l_[keep])
        p = _closed_form(r[keep], l_[keep], sm[keep], fixed)
    return _Trimmed(p, keep, history, per_round)


def _far_from_closed_form(
    p: np.ndarray, closed: np.ndarray, cov: np.ndarray, free: list[int]
) -> list[str]:
    """A warning when the refinement moved more than 3 standard errors from the closed form."""
    se = np.sqrt(np.diag(cov))
    if not np.all(np.isfinite(se[free])):
        return []
    far = [
        PARAMETERS[j]
        for j in free
        if abs(wrap_angle(p[j] - closed[j]) if j == 5 else p[j] - closed[j]) > 3 * se[j]
    ]
    if not far:
        return []
    return [
        "censi: the refined and closed-form estimates differ by more than 3 standard "
        f"errors in {', '.join(far)}; the arc model may not fit these tuples"
    ]


def _paper_covariance(
    p: np.ndarray,
    free: list[int],
    r: np.ndarray,
    l_: np.ndarray,
    sm: np.ndarray,
    history: list[np.ndarray],
    keep: np.ndarray,
    fraction: float,
) -> np.ndarray | None:
    """The authors' covariance: noise = sample std of the residuals over the tuples left after
    the first trimming round; Fisher information summed over ``keep`` trimmed once more."""
    noise_set = history[min(1, len(history) - 1)]
    e = _residual(p, r[noise_set], l_[noise_set], sm[noise_set])
    if len(e) < 2:
        return None
    sigma = np.maximum(np.std(e, axis=0, ddof=1), _SIGMA_FLOOR)
    last = keep
    if len(history) > 1 and fraction > 0:
        last = keep[_trim(p, r[keep], l_[keep], sm[keep], fraction)]
    return _fisher(p, free, r[last], l_[last], sm[last], sigma)
