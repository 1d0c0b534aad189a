"""The noise of a SLAM pose as ground truth, for the log check
(:func:`odocal.calibration.identifiability.check_recordings`): the robot file's where it states
it; the rest from the log's own residuals (a relative-motion fit of the intervals between the
SLAM's updates, then :func:`~odocal.calibration.interval_noise.estimate_interval_noise`: the
wheels' k, and the SLAM pose's noise as half the variance of a relative motion's); else
:data:`SLAM_POSE_NOISE` and the default k, said so.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..core.model import MeasurementNoise, NonSystematicError, Robot, WheelGeometry
from ..core.odometry import dead_reckon_rows
from ..errors import CalibrationError
from .censi import fit_censi
from .identifiability import NoiseModel
from .interval_noise import IntervalNoise, estimate_interval_noise, predicted_covariance
from .relative_motions import RelativeMotions

__all__ = ["SLAM_POSE_NOISE", "SlamNoise", "slam_noise_model"]

#: The stated noise of a SLAM pose when the log's own residuals cannot give it: scan matching
#: places a pose to a centimetre or two and a degree.
SLAM_POSE_NOISE = MeasurementNoise(0.02, math.radians(1.0))


@dataclass(frozen=True)
class SlamNoise:
    """The noise of a SLAM-truth check.

    Attributes
    ----------
    model : NoiseModel
        The wheels' k and the SLAM pose's noise.
    description : str
        Where each part came from (the robot file, the log's residuals, a stated default).
    covariance : ndarray, shape (3, 3), or None
        The covariance of (D_R, D_L, b) that the SLAM route's relative-motion fit would have
        with that noise, at the geometry given (None without one).
    """

    model: NoiseModel
    description: str
    covariance: np.ndarray | None


#: Below these residuals (RMS over the intervals) a log has no noise to estimate: they are the
#: arithmetic's (a simulated log without noise), and a noise estimated from them would make the
#: check's verdict a matter of the last bits.
ARITHMETIC_RESIDUAL = MeasurementNoise(1e-9, 1e-9)


def _residuals(m: RelativeMotions, g: WheelGeometry) -> np.ndarray:
    """The intervals' residuals (x, y, theta) at ``g``, shape (n, 3)."""
    assert m.increments is not None
    pred = dead_reckon_rows(m.increments[0], m.increments[1], g)[:, :, -1].T
    return np.asarray(m.sensor_motion, dtype=float) - pred


def _inliers(e: np.ndarray) -> np.ndarray:
    """The intervals whose residual is within 5 robust spreads on every component (the
    outliers a fit trims would count as noise)."""
    spread = 1.4826 * np.median(np.abs(e - np.median(e, axis=0)), axis=0)
    return np.flatnonzero(np.all(np.abs(e) <= 5.0 * np.maximum(spread, 1e-12), axis=1))


def _from_residuals(m: RelativeMotions) -> tuple[IntervalNoise | None, str]:
    """The noise estimated from the intervals' residuals after a relative-motion fit (the
    truth frame is the base), or None and why not."""
    assert m.increments is not None and m.start_s is not None
    try:
        # the residuals' geometry from a sample of the intervals is as good for three numbers
        n = len(m.phi_right_rad)
        some = np.unique(np.linspace(0, n - 1, min(n, 1500)).round().astype(int))
        inc = (m.increments[0][some], m.increments[1][some])
        fit = fit_censi(m.phi_right_rad[some], m.phi_left_rad[some], m.sensor_motion[some],
                        sensor_pose=(0, 0, 0), wheel_increments=inc)  # fmt: skip
        e = _residuals(m, fit.geometry)
        rms = np.sqrt(np.mean(e**2, axis=0))
        if max(rms[:2]) < ARITHMETIC_RESIDUAL.sigma_xy_m and (
            rms[2] < ARITHMETIC_RESIDUAL.sigma_theta_rad
        ):
            return None, (
                f"its residuals are {rms.max():.1g} at most, the arithmetic's, not a sensor's: "
                "a log without noise"
            )
        keep = _inliers(e)
        est = estimate_interval_noise(
            m.increments[0][keep], m.increments[1][keep], m.sensor_motion[keep], fit.geometry,
            m.start_s[keep], end_s=None if m.end_s is None else m.end_s[keep],
        )  # fmt: skip
    except CalibrationError as exc:
        return None, str(exc)
    return est, ""


def _describe(
    k_sum: float,
    meas: MeasurementNoise,
    given_k: bool,
    given_m: bool,
    est: IntervalNoise | None,
    problem: str,
) -> str:
    """Where each part of the noise came from, in words."""
    parts = [
        "ROBOT.yaml nonsystematic" if given_k else (
            f"k {0.5 * k_sum:.3g} m per wheel" if est is not None else "default k"
        ),
        "ROBOT.yaml measurement" if given_m else (
            f"SLAM pose {1e3 * meas.sigma_xy_m:.3g} mm and "
            f"{math.degrees(meas.sigma_theta_rad):.3g} deg"
            + ("" if est is not None else " (stated default)")
        ),
    ]  # fmt: skip
    where = (
        f" (from the log's own residuals over {est.intervals} SLAM intervals)"
        if est is not None
        else f"; the log's own residuals could not give it ({problem})"
    )
    return ", ".join(parts) + where


def _prediction(
    m: RelativeMotions, geometry: WheelGeometry, k_sum: float, meas: MeasurementNoise
) -> np.ndarray:
    """The covariance of (D_R, D_L, b) of the relative-motion fit of ``m`` with this noise
    (:func:`~odocal.calibration.interval_noise.predicted_covariance` at ``geometry``)."""
    assert m.increments is not None
    per_interval = IntervalNoise(
        k_sum, (k_sum, k_sum), math.sqrt(2.0) * meas.sigma_xy_m,
        math.sqrt(2.0) * meas.sigma_theta_rad, len(m.phi_right_rad), 0,
    )  # fmt: skip
    return predicted_covariance(m.increments[0], m.increments[1], geometry, per_interval)


def slam_noise_model(
    motions: RelativeMotions, robot: Robot | None, geometry: WheelGeometry | None = None
) -> SlamNoise:
    """The noise of a SLAM-truth check (module docstring) from the intervals between the SLAM's
    updates (``motions``, with their wheel increments and times), the robot's stated noise where
    it gives one (a part left at zero is estimated), and with ``geometry`` the covariance the
    SLAM route's fit would have."""
    given_k = robot is not None and not robot.nonsystematic.is_zero
    given_m = robot is not None and not robot.measurement.is_zero
    est, problem = _from_residuals(motions)
    if robot is not None and given_k:
        k_sum = robot.nonsystematic.k_sum_m
    else:
        k_sum = NoiseModel().wheel.k_sum_m if est is None else est.k_sum_m
    if robot is not None and given_m:
        meas = robot.measurement
    elif est is None:
        meas = SLAM_POSE_NOISE
    else:
        meas = MeasurementNoise(est.truth_sigma_xy_m / math.sqrt(2.0),
                                est.truth_sigma_theta_rad / math.sqrt(2.0))  # fmt: skip
    model = NoiseModel(NonSystematicError(0.5 * k_sum, 0.5 * k_sum), meas)
    cov = None if geometry is None else _prediction(motions, geometry, k_sum, meas)
    return SlamNoise(model, _describe(k_sum, meas, given_k, given_m, est, problem), cov)
