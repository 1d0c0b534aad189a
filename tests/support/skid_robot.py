"""A simulated skid-steer robot driving DRIVE-style random wheel-speed steps, logged as a
:class:`~odocal.calibration.skid_steer.SkidLog` (a helper for tests; not a test module).

The wheels' rates are piecewise constant over ``step_s`` steps (drawn uniformly in
+-``max_rate_rad_s``, with a share of spins and straight runs), ramped over ``ramp_s``; the true
motion is the TRUE model's dead reckoning at ``sim_hz`` (:func:`odocal.core.skid_steer.
dead_reckon_skid`) with optional slip: an AR(1) process (correlation time ``slip_tau_s``) added
to the body's heading rate and forward speed, in proportion to ``slip`` (rad/s and m/s at unit
scale). The log holds the wheel angles at ``wheel_hz`` and the truth at ``truth_hz``, stamped
``offset_s`` late (the truth stamped t saw the robot at t - offset_s; a number, or a function
of the true time for a latency that wanders), with white position and heading noise.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

from odocal.calibration.skid_steer import SkidLog
from odocal.core.skid_steer import (
    SkidSteerModel,
    integrate_body_increments,
    skid_body_increments,
)

__all__ = ["simulate_skid_log"]


def _ar1(n: int, dt: float, tau: float, rng: np.random.Generator) -> np.ndarray:
    """A unit-variance AR(1) series of n samples, correlation time tau (s)."""
    a = float(np.exp(-dt / tau))
    e = rng.standard_normal(n) * np.sqrt(1 - a * a)
    e[0] = rng.standard_normal()
    out = e.tolist()
    for k in range(1, n):  # a plain loop: 30 000 steps take a few ms
        out[k] += a * out[k - 1]
    return np.asarray(out)


def simulate_skid_log(
    true: SkidSteerModel,
    rng: np.random.Generator,
    *,
    duration_s: float = 300.0,
    step_s: float = 6.0,
    ramp_s: float = 0.5,
    max_rate_rad_s: float = 4.0,
    sim_hz: float = 100.0,
    wheel_hz: float = 20.0,
    truth_hz: float = 10.0,
    offset_s: float | Callable[[np.ndarray], np.ndarray] = 0.0,
    sigma_xy_m: float = 0.01,
    sigma_yaw_rad: float = 0.003,
    slip: float = 0.0,
    slip_tau_s: float = 2.0,
    name: str = "sim",
    group: str = "",
) -> SkidLog:
    """One simulated log (module docstring)."""
    dt = 1.0 / sim_hz
    n = int(round(duration_s * sim_hz)) + 1
    t = np.arange(n) * dt
    steps = int(np.ceil(duration_s / step_s)) + 1
    kind = rng.choice(3, size=steps, p=[0.2, 0.2, 0.6])  # spin, straight, arc
    a = rng.uniform(-max_rate_rad_s, max_rate_rad_s, size=steps)
    b = rng.uniform(-max_rate_rad_s, max_rate_rad_s, size=steps)
    right = np.where(kind == 0, a, np.where(kind == 1, a, a))
    left = np.where(kind == 0, -a, np.where(kind == 1, a, b))
    idx = np.minimum((t // step_s).astype(int), steps - 1)
    width = max(1, int(round(ramp_s * sim_hz)))
    kernel = np.ones(width) / width
    rate_r = np.convolve(right[idx], kernel, mode="same")
    rate_l = np.convolve(left[idx], kernel, mode="same")
    ang_r = np.concatenate([[0.0], np.cumsum(0.5 * (rate_r[1:] + rate_r[:-1]) * dt)])
    ang_l = np.concatenate([[0.0], np.cumsum(0.5 * (rate_l[1:] + rate_l[:-1]) * dt)])
    dx, dy, dth = skid_body_increments(true, np.diff(ang_r), np.diff(ang_l), np.full(n - 1, dt))
    if slip > 0:
        dth = dth + slip * dt * _ar1(n - 1, dt, slip_tau_s, rng)
        dx = dx + 0.2 * slip * dt * _ar1(n - 1, dt, slip_tau_s, rng)
    poses = integrate_body_increments(dx, dy, dth)
    wk = np.arange(0, n, int(round(sim_hz / wheel_hz)))
    tk = np.arange(0, n, int(round(sim_hz / truth_hz)))
    truth = poses[tk].copy()
    truth[:, :2] += sigma_xy_m * rng.standard_normal((len(tk), 2))
    truth[:, 2] += sigma_yaw_rad * rng.standard_normal(len(tk))
    late = offset_s(t[tk]) if callable(offset_s) else offset_s
    return SkidLog(name, t[wk], ang_r[wk], ang_l[wk], t[tk] + late, truth, group)


def simulate_skid_gyro_log(
    true: SkidSteerModel,
    rng: np.random.Generator,
    *,
    imu_offset_s: float = 0.0,
    bias_rad_s: float = 0.005,
    sigma_rate_rad_s: float = 0.02,
    imu_hz: float = 100.0,
    **kwargs: object,
):
    """The wheels of :func:`simulate_skid_log` and a gyro on the base's z axis at ``imu_hz``:
    the true yaw rate (its slip included) plus ``bias_rad_s`` and white noise, stamped
    ``imu_offset_s`` late, as a :class:`~odocal.io.bag_skid.SkidGyroLog`."""
    from odocal.io.bag_skid import SkidGyroLog

    log = simulate_skid_log(true, rng, truth_hz=imu_hz, sim_hz=imu_hz, sigma_xy_m=0.0,
                            sigma_yaw_rad=0.0, **kwargs)  # type: ignore[arg-type]  # fmt: skip
    t = np.asarray(log.truth_time_s)
    rate = np.gradient(np.asarray(log.truth_pose)[:, 2], t)
    rate = rate + bias_rad_s + sigma_rate_rad_s * rng.standard_normal(len(t))
    w = np.column_stack([np.zeros_like(t), np.zeros_like(t), rate])
    return SkidGyroLog(
        log.name, log.time_s, log.angle_right_rad, log.angle_left_rad, t + imu_offset_s, w,
        np.eye(3), "simulated", "joint_states", "/imu",
    )  # fmt: skip
