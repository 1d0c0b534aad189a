"""First-order covariance of the final pose (paper eqs. (8)-(10); Siegwart eqs. 5.9-5.11).

A track is executed exactly as :func:`odocal.core.simulate.drive` executes it (the robot turns
each segment into wheel rotations with the geometry it BELIEVES, the TRUE geometry turns them into
wheel travel, same increments), and the covariance of the true pose is propagated through the
midpoint update (8)::

    P' = F_p P F_p^T + F_d Sigma_d F_d^T,   Sigma_d = diag(k_r |ds_r|, k_l |ds_l|)     (9), (10)

along the MEAN (noise-free) trajectory. Because every F_p has the form I + u e_theta^T, the product
of the F_p after increment i is I + [-(y_N - y_i), x_N - x_i, 0]^T e_theta^T, so the whole sum is
evaluated at once over all increments (no Python loop per increment). This is exact for the
linearised model; the only approximation is first order in the noise (docs/nonsystematic-errors.md).

Poses are (x_m, y_m, theta_rad) in the start frame (+x start heading, +y left, theta CCW +,
unwrapped); covariances are 3 x 3 in (x, y, theta) with units m^2, m rad, rad^2.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from .model import MeasurementNoise, ModelError, NonSystematicError, Robot, WheelGeometry
from .odometry import Chord, arc_step, body_increments, midpoint_path, wheel_jacobian
from .simulate import increments_per_segment, odometric_pose
from .tracks import Track

__all__ = [
    "PosePrediction",
    "propagate",
    "propagate_increments",
    "predict",
    "mean_final_pose",
    "measurement_covariance",
    "straight_line_covariance",
    "correlation",
    "OdometryCovariance",
    "odometry_covariance",
    "UNMEASURED_VARIANCE",
]


@dataclass(frozen=True)
class PosePrediction:
    """Predicted distribution of the final pose of one run.

    Attributes
    ----------
    mean : ndarray, shape (3,) or (B, 3) for a batch
        Mean true final pose (x_m, y_m, theta_rad), start frame, theta unwrapped.
    odometric : ndarray, shape (3,) or (B, 3)
        The pose the robot believes it reached (the commanded one).
    covariance : ndarray, shape (3, 3) or (B, 3, 3)
        Covariance of the true final pose from wheel-travel noise (m^2, m rad, rad^2).
    measurement_covariance : ndarray, shape (3, 3)
        Covariance the ground-truth instrument adds to a MEASURED final pose (diagonal).
    """

    mean: np.ndarray
    odometric: np.ndarray
    covariance: np.ndarray
    measurement_covariance: np.ndarray

    @property
    def error_mean(self) -> np.ndarray:
        """Mean final pose error, actual - odometric, shape (3,)."""
        return self.mean - self.odometric

    @property
    def measured_covariance(self) -> np.ndarray:
        """Covariance of a measured final pose error: run noise + instrument noise, (3, 3)."""
        return self.covariance + self.measurement_covariance

    def std(self, measured: bool = True) -> np.ndarray:
        """Standard deviations (x_m, y_m, theta_rad), shape (3,) (or (B, 3))."""
        c = self.measured_covariance if measured else self.covariance
        return np.sqrt(np.maximum(np.diagonal(c, axis1=-2, axis2=-1), 0.0))


def measurement_covariance(measurement: MeasurementNoise) -> np.ndarray:
    """diag(sigma_xy^2, sigma_xy^2, sigma_theta^2), shape (3, 3)."""
    s = measurement
    return np.diag([s.sigma_xy_m**2, s.sigma_xy_m**2, s.sigma_theta_rad**2])


def correlation(covariance: np.ndarray) -> np.ndarray:
    """Correlation matrix of a covariance matrix (0 where a variance is 0), shape (3, 3)."""
    c = np.asarray(covariance, dtype=float)
    s = np.sqrt(np.maximum(np.diag(c), 0.0))
    with np.errstate(divide="ignore", invalid="ignore"):
        r = c / np.outer(s, s)
    r = np.where(np.outer(s, s) > 0, r, 0.0)
    np.fill_diagonal(r, np.where(s > 0, 1.0, 0.0))
    return r


def _increments(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    max_step_m: float | None,
    steps_per_segment: int | None,
) -> tuple[np.ndarray, np.ndarray]:
    """True wheel travel per increment (dr, dl), shape (B..., K), as drive() makes them.

    As in drive(), a segment has the same number of increments for every batch element (set by
    the longest wheel travel in the batch).
    """
    f_r = np.asarray(true.diameter_right_m / believed.diameter_right_m, dtype=float)
    f_l = np.asarray(true.diameter_left_m / believed.diameter_left_m, dtype=float)
    b_hat = believed.wheelbase_m
    drs, dls = [], []
    for seg in track.segments:
        s_hat_r, s_hat_l = seg.wheel_travel(b_hat)
        s_r, s_l = np.broadcast_arrays(s_hat_r * f_r, s_hat_l * f_l)
        n = increments_per_segment(s_r, s_l, max_step_m, steps_per_segment)
        drs.append(np.repeat((s_r / n)[..., None], n, axis=-1))
        dls.append(np.repeat((s_l / n)[..., None], n, axis=-1))
    batch = np.broadcast_shapes(*(d.shape[:-1] for d in drs + dls))
    dr = np.concatenate([np.broadcast_to(d, batch + d.shape[-1:]) for d in drs], axis=-1)
    dl = np.concatenate([np.broadcast_to(d, batch + d.shape[-1:]) for d in dls], axis=-1)
    return dr, dl


def propagate(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    *,
    measurement: MeasurementNoise | None = None,
    max_step_m: float | None = 0.01,
    steps_per_segment: int | None = None,
    integration: str = "midpoint",
    initial_covariance: np.ndarray | None = None,
) -> PosePrediction:
    """Mean and covariance of the final pose of ``track`` (see the module docstring).

    Parameters
    ----------
    track : Track
        Segments in the robot's belief. Segment values may be arrays of shape (B,) (a batch of
        tracks, e.g. candidate sizes), as in :func:`odocal.core.simulate.drive`.
    true, believed : WheelGeometry
        True and believed geometry; scalars or arrays of shape (B,).
    noise : NonSystematicError
        k_r_m, k_l_m in METRES (variance k |ds| per increment of wheel travel ds).
    measurement : MeasurementNoise, optional
        Instrument noise of a measured final pose (kept separately in the result).
    max_step_m, steps_per_segment, integration
        As in :func:`odocal.core.simulate.drive` (same increments). 'exact' integrates the MEAN
        pose along exact arcs; the Jacobians are the midpoint ones in both cases (their difference
        is of second order in the increment).
    initial_covariance : ndarray, shape (3, 3), optional
        Covariance of the start pose (default 0).

    Returns
    -------
    PosePrediction whose ``mean`` has shape (3,) and ``covariance`` (3, 3), or (B, 3) and
    (B, 3, 3) for a batch.
    """
    if integration not in ("midpoint", "exact"):
        raise ModelError(f"integration must be 'midpoint' or 'exact', got {integration!r}")
    if steps_per_segment is None and not (max_step_m and max_step_m > 0):
        raise ModelError(f"max_step_m must be > 0, got {max_step_m!r}")
    dr, dl = _increments(track, true, believed, max_step_m, steps_per_segment)
    mean, cov = propagate_increments(dr, dl, true.wheelbase_m, noise, integration=integration)
    x_n, y_n = mean[..., 0:1], mean[..., 1:2]
    if initial_covariance is not None:
        phi = np.zeros(mean.shape[:-1] + (3, 3))
        phi[..., :, :] = np.eye(3)
        phi[..., 0, 2] = -y_n[..., 0]
        phi[..., 1, 2] = x_n[..., 0]
        cov = cov + phi @ np.asarray(initial_covariance, dtype=float) @ np.swapaxes(phi, -1, -2)
    cov = 0.5 * (cov + np.swapaxes(cov, -1, -2))
    meas = measurement_covariance(measurement or MeasurementNoise())
    odo = np.broadcast_to(np.asarray(odometric_pose(track), dtype=float), mean.shape)
    return PosePrediction(mean, odo, cov, meas)


def propagate_increments(
    dr: ArrayLike,
    dl: ArrayLike,
    wheelbase_m: float | np.ndarray,
    noise: NonSystematicError,
    *,
    integration: str = "midpoint",
) -> tuple[np.ndarray, np.ndarray]:
    """Final pose and its first-order covariance for given TRUE wheel-travel increments.

    ``dr``, ``dl``: wheel travel per increment (m), shape (B..., K); ``wheelbase_m`` the true
    wheelbase (scalar or shape (B...,)). Returns the noise-free final pose, shape (B..., 3), and
    its covariance from wheel noise, shape (B..., 3, 3) (module docstring). Used by
    :func:`propagate` for tracks and directly for recorded runs (their wheel increments).
    """
    dr = np.asarray(dr, dtype=float)
    dl = np.asarray(dl, dtype=float)
    b = np.asarray(wheelbase_m, dtype=float)[..., None]
    dr, dl, b = np.broadcast_arrays(dr, dl, b)
    ds, dth = body_increments(dr, dl, b)
    chord: Chord = "exact" if integration == "exact" else "none"
    x_after, y_after, theta_after, c, s = midpoint_path(ds, dth, chord=chord)
    x_n, y_n = x_after[..., -1:], y_after[..., -1:]
    mean = np.stack([x_n[..., 0], y_n[..., 0], theta_after[..., -1]], axis=-1)

    # F_d (eq. 5.11), columns (right, left), per increment: shape (B..., K, 3, 2)
    g = wheel_jacobian(ds, c, s, b)
    # transport to the end: rows x and y pick up -(y_N - y_i) and (x_N - x_i) times the theta row
    g[..., 0, :] -= (y_n - y_after)[..., None] * g[..., 2, :]
    g[..., 1, :] += (x_n - x_after)[..., None] * g[..., 2, :]
    q = np.stack([noise.k_r_m * np.abs(dr), noise.k_l_m * np.abs(dl)], axis=-1)  # (B..., K, 2)
    g *= np.sqrt(q)[..., None, :]
    aw = np.moveaxis(g, -2, -3).reshape(ds.shape[:-1] + (3, -1))  # (B..., 3, 2K)
    cov = aw @ np.swapaxes(aw, -1, -2)
    return mean, cov


def predict(track: Track, robot: Robot, **options: Any) -> PosePrediction:
    """:func:`propagate` for ``robot`` (true geometry from its systematic errors, believed
    geometry from ``robot.believed`` or nominal, its wheel noise and instrument noise)."""
    return propagate(
        track,
        robot.true_geometry,
        robot.believed_geometry,
        robot.nonsystematic,
        measurement=robot.measurement,
        **options,
    )


def mean_final_pose(track: Track, true: WheelGeometry, believed: WheelGeometry) -> np.ndarray:
    """Noise-free true final pose, integrated exactly segment by segment.

    Every segment is a constant-curvature motion of the true robot too, so this is exact (it
    equals :func:`drive` with ``integration='exact'`` and no noise). Geometry and segment values
    may be arrays; they broadcast and the result has shape (..., 3).
    """
    f_r = true.diameter_right_m / believed.diameter_right_m
    f_l = true.diameter_left_m / believed.diameter_left_m
    pose = np.zeros(3)
    for seg in track.segments:
        s_hat_r, s_hat_l = seg.wheel_travel(believed.wheelbase_m)
        s_r, s_l = np.asarray(s_hat_r * f_r), np.asarray(s_hat_l * f_l)
        pose = arc_step(pose, *body_increments(s_r, s_l, true.wheelbase_m))
    return pose


def straight_line_covariance(
    distance_m: float, wheelbase_m: float, k_r_m: float, k_l_m: float
) -> np.ndarray:
    """Closed-form covariance of a straight run of ``distance_m`` from zero covariance.

    In the robot frame (f forward, s left, theta), with K+ = k_r + k_l, K- = k_r - k_l (metres;
    model.md): P_ff = K+ d/4, P_fs = K- d^2/(4b), P_ftheta = K- d/(2b), P_ss = K+ d^3/(3 b^2),
    P_stheta = K+ d^2/(2 b^2), P_thetatheta = K+ d/b^2. Returns shape (3, 3).
    """
    d, b = float(distance_m), float(wheelbase_m)
    kp, km = k_r_m + k_l_m, k_r_m - k_l_m
    return np.array(
        [
            [kp * d / 4, km * d**2 / (4 * b), km * d / (2 * b)],
            [km * d**2 / (4 * b), kp * d**3 / (3 * b**2), kp * d**2 / (2 * b**2)],
            [km * d / (2 * b), kp * d**2 / (2 * b**2), kp * d / b**2],
        ]
    )


#: Variance written for what planar wheel odometry does not measure (z, roll, pitch and their
#: rates): large, so that a filter never trusts them (robot_localization's two_d_mode ignores
#: them anyway).
UNMEASURED_VARIANCE = 1.0e6


@dataclass(frozen=True)
class OdometryCovariance:
    """Covariances a robot stack asks for, from the wheel noise k (model.md), for a stated
    motion: straight driving at ``speed_m_s``.

    Attributes
    ----------
    pose_diagonal : tuple of 6 float
        (x, y, z, roll, pitch, yaw) variances of the odometry pose after ``distance_m`` of
        straight travel from an exactly known start (m^2, rad^2), x along the motion:
        (k_r + k_l) d / 4, (k_r + k_l) d^3 / (3 b^2), unmeasured, unmeasured, unmeasured,
        (k_r + k_l) d / b^2 (:func:`straight_line_covariance`).
    twist_diagonal : tuple of 6 float
        (vx, vy, vz, wx, wy, wz) variances of the velocity measured from the wheel travel over a
        window of ``window_s`` at ``speed_m_s``: (k_r + k_l) v / (4 T) and (k_r + k_l) v / (b^2 T)
        ((m/s)^2, (rad/s)^2); vy is 0 for a differential drive (it cannot move sideways: a
        small value is written instead of 0 so that a filter's matrix stays invertible).
    process_noise_per_s : dict
        Growth rate of the odometry's own uncertainty while driving at ``speed_m_s``: x and y
        (k_r + k_l) v / 4 (m^2/s; along-track, the cross-track part grows through the heading),
        yaw (k_r + k_l) v / b^2 (rad^2/s): a floor for robot_localization's
        ``process_noise_covariance`` entries of x, y and yaw (it multiplies them by the time step).
    """

    k_r_m: float
    k_l_m: float
    wheelbase_m: float
    speed_m_s: float
    distance_m: float
    window_s: float
    pose_diagonal: tuple[float, ...]
    twist_diagonal: tuple[float, ...]
    process_noise_per_s: dict

    def as_dict(self) -> dict:
        """The JSON of these covariances (the ``ros2_covariance`` object of ``odocal noise
        --json``)."""
        return {
            "k_r_m": self.k_r_m,
            "k_l_m": self.k_l_m,
            "wheelbase_m": self.wheelbase_m,
            "speed_m_s": self.speed_m_s,
            "distance_m": self.distance_m,
            "window_s": self.window_s,
            "pose_covariance_diagonal": list(self.pose_diagonal),
            "twist_covariance_diagonal": list(self.twist_diagonal),
            "process_noise_per_s": dict(self.process_noise_per_s),
        }


def odometry_covariance(
    k_r_m: float,
    k_l_m: float,
    wheelbase_m: float,
    *,
    speed_m_s: float,
    distance_m: float = 1.0,
    window_s: float = 0.2,
) -> OdometryCovariance:
    """The covariances of :class:`OdometryCovariance` (k in METRES, b in m, speed in m/s,
    distance in m, window in s)."""
    for name, v in (
        ("wheelbase_m", wheelbase_m),
        ("distance_m", distance_m),
        ("window_s", window_s),
        ("speed_m_s", speed_m_s),
    ):
        if not (math.isfinite(v) and v > 0):
            raise ModelError(f"{name} must be a finite number > 0, got {v!r}")
    for name, v in (("k_r_m", k_r_m), ("k_l_m", k_l_m)):
        if not (math.isfinite(v) and v >= 0):
            raise ModelError(f"{name} must be a finite number >= 0, got {v!r}")
    b = float(wheelbase_m)
    p = straight_line_covariance(distance_m, b, k_r_m, k_l_m)
    kp = k_r_m + k_l_m
    big = UNMEASURED_VARIANCE
    var_v = kp * speed_m_s / (4.0 * window_s)
    var_w = kp * speed_m_s / (b * b * window_s)
    pose = (float(p[0, 0]), float(p[1, 1]), big, big, big, float(p[2, 2]))
    # vy: not a degree of freedom; a tiny fraction of var_v keeps a filter's matrix invertible
    twist = (float(var_v), float(var_v * 1e-6), big, big, big, float(var_w))
    process = {"x": kp * speed_m_s / 4.0, "y": kp * speed_m_s / 4.0, "yaw": kp * speed_m_s / b**2}
    return OdometryCovariance(
        float(k_r_m),
        float(k_l_m),
        b,
        float(speed_m_s),
        float(distance_m),
        float(window_s),
        pose,
        twist,
        {k: float(v) for k, v in process.items()},
    )
