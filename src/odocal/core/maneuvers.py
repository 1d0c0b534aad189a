"""A vocabulary of calibration maneuvers and the recordings they make (docs/design.md, "Routes").

A maneuver is a short piece of driving a person can teleoperate or a robot can execute from a
velocity-command file: a straight line, a spin on the spot at a chosen rate (either way), an arc
of a chosen radius, a figure-eight, a square, or a pause (standing still, for a gyro's bias).
Each maneuver is a list of constant commands (duration_s, v_m_s, omega_rad_s); a sequence of
maneuvers becomes one :class:`CommandSeries` sampled at a fixed rate (default 50 Hz). Each
command's duration is rounded to whole samples and its speed scaled so that the commanded
amount (metres, radians) is exact.

:func:`simulate_recordings` executes a series on the model of ``model.md``: the robot turns its
wheels by what the commanded motion needs with the parameters it BELIEVES (open loop on its
encoders, as :mod:`odocal.core.simulate` drives a track); the encoders record those rotations; the
true wheel travel is rotation x TRUE radius plus Gaussian noise of variance k |ds| per sample
(k in metres); the true pose follows the exact-arc update with the TRUE wheelbase
(:func:`odocal.core.odometry.arc_step` per sample, vectorised over samples and trials by
cumulative sums). The truth is measured with the route's pose noise (sigma_xy_m, sigma_theta_rad
on every sample) and a time offset; an optional gyro measures the true heading rate with a
scale factor, a constant bias and white noise (angle random walk).

Commands are followed instantly (no acceleration limits) and the wheels do not slip beyond the
noise k: a real robot ramps its speed, which changes the samples, not the amounts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .model import MeasurementNoise, ModelError, NonSystematicError, WheelGeometry
from .recording import Recording

__all__ = [
    "Maneuver",
    "ManeuverKind",
    "MANEUVER_KINDS",
    "CommandSeries",
    "GyroNoise",
    "straight",
    "spin",
    "arc",
    "figure_eight",
    "square",
    "pause",
    "command_series",
    "commanded",
    "simulate_recordings",
    "as_recording",
    "exact_arc_poses",
    "DEFAULT_RATE_HZ",
]

ManeuverKind = Literal["straight", "spin", "arc", "figure-eight", "square", "pause", "commands"]
MANEUVER_KINDS: tuple[ManeuverKind, ...] = (
    "straight",
    "spin",
    "arc",
    "figure-eight",
    "square",
    "pause",
    "commands",
)

#: Default command rate (Hz) of a series.
DEFAULT_RATE_HZ = 50.0

# Bounds that make an absurd request a clear error instead of a memory blow-up.
MAX_SERIES_S = 3600.0


@dataclass(frozen=True)
class Maneuver:
    """One piece of driving: its kind, a description and its constant commands.

    Attributes
    ----------
    kind : str
        One of :data:`MANEUVER_KINDS`.
    label : str
        What to drive, in words (e.g. 'spin 360 deg CCW at 0.5 rad/s').
    commands : tuple of (duration_s, v_m_s, omega_rad_s)
        Constant commands in order (s, m/s, rad/s).
    """

    kind: ManeuverKind
    label: str
    commands: tuple[tuple[float, float, float], ...]

    @property
    def duration_s(self) -> float:
        """Total duration (s)."""
        return float(sum(c[0] for c in self.commands))

    @property
    def distance_m(self) -> float:
        """Path length of the centre (m)."""
        return float(sum(c[0] * abs(c[1]) for c in self.commands))

    @property
    def yaw_rad(self) -> tuple[float, float]:
        """Heading turned CCW and CW (rad, both >= 0)."""
        ccw = sum(c[0] * c[2] for c in self.commands if c[2] > 0)
        cw = -sum(c[0] * c[2] for c in self.commands if c[2] < 0)
        return float(ccw), float(cw)

    def as_dict(self) -> dict:
        """JSON-ready."""
        ccw, cw = self.yaw_rad
        return {
            "kind": self.kind,
            "label": self.label,
            "duration_s": self.duration_s,
            "distance_m": self.distance_m,
            "yaw_ccw_deg": math.degrees(ccw),
            "yaw_cw_deg": math.degrees(cw),
        }


def _positive(name: str, value: float) -> float:
    v = float(value)
    if not (math.isfinite(v) and v > 0):
        raise ModelError(f"{name} must be a finite number > 0, got {value!r}")
    return v


def straight(distance_m: float, speed_m_s: float) -> Maneuver:
    """Drive ``distance_m`` (m; negative: backwards) at ``speed_m_s`` (m/s, > 0)."""
    v = _positive("speed_m_s", speed_m_s)
    d = float(distance_m)
    if not (math.isfinite(d) and d != 0):
        raise ModelError(f"distance_m must be finite and nonzero, got {distance_m!r}")
    how = "forward" if d > 0 else "backward"
    return Maneuver("straight", f"straight {abs(d):g} m {how} at {v:g} m/s",
                    ((abs(d) / v, math.copysign(v, d), 0.0),))  # fmt: skip


def spin(angle_rad: float, rate_rad_s: float) -> Maneuver:
    """Turn on the spot by ``angle_rad`` (rad; positive CCW) at ``rate_rad_s`` (rad/s, > 0)."""
    w = _positive("rate_rad_s", rate_rad_s)
    a = float(angle_rad)
    if not (math.isfinite(a) and a != 0):
        raise ModelError(f"angle_rad must be finite and nonzero, got {angle_rad!r}")
    way = "CCW" if a > 0 else "CW"
    label = f"spin {math.degrees(abs(a)):g} deg {way} at {w:g} rad/s"
    return Maneuver("spin", label, ((abs(a) / w, 0.0, math.copysign(w, a)),))


def arc(radius_m: float, angle_rad: float, speed_m_s: float) -> Maneuver:
    """Drive forward along an arc of ``radius_m`` (m, > 0) turning ``angle_rad`` (rad; positive
    CCW) at ``speed_m_s`` (m/s)."""
    r = _positive("radius_m", radius_m)
    v = _positive("speed_m_s", speed_m_s)
    a = float(angle_rad)
    if not (math.isfinite(a) and a != 0):
        raise ModelError(f"angle_rad must be finite and nonzero, got {angle_rad!r}")
    way = "CCW" if a > 0 else "CW"
    w = v / r
    label = f"arc radius {r:g} m, {math.degrees(abs(a)):g} deg {way} at {v:g} m/s ({w:.3g} rad/s)"
    return Maneuver("arc", label, ((abs(a) / w, v, math.copysign(w, a)),))


def figure_eight(radius_m: float, speed_m_s: float) -> Maneuver:
    """A full circle CCW then a full circle CW, both of ``radius_m`` (m) at ``speed_m_s``."""
    a, b = arc(radius_m, 2 * math.pi, speed_m_s), arc(radius_m, -2 * math.pi, speed_m_s)
    label = f"figure-eight of two {radius_m:g} m circles at {speed_m_s:g} m/s"
    return Maneuver("figure-eight", label, a.commands + b.commands)


def square(side_m: float, speed_m_s: float, rate_rad_s: float, direction: str = "ccw") -> Maneuver:
    """A square of ``side_m`` (m): four straights with a 90 deg spin after each, turning CCW or
    CW (``direction``)."""
    if direction not in ("ccw", "cw"):
        raise ModelError(f"direction must be 'ccw' or 'cw', got {direction!r}")
    s = straight(side_m, speed_m_s)
    t = spin((1 if direction == "ccw" else -1) * math.pi / 2, rate_rad_s)
    label = (
        f"square {side_m:g} m {direction.upper()} at {speed_m_s:g} m/s, turns {rate_rad_s:g} rad/s"
    )
    return Maneuver("square", label, (s.commands + t.commands) * 4)


def pause(duration_s: float) -> Maneuver:
    """Stand still for ``duration_s`` (s)."""
    d = _positive("duration_s", duration_s)
    return Maneuver("pause", f"stand still {d:g} s", ((d, 0.0, 0.0),))


def commanded(
    time_s: np.ndarray, v_m_s: np.ndarray, omega_rad_s: np.ndarray, label: str
) -> Maneuver:
    """A command file's driving as one maneuver: command i (m/s, rad/s) holds from
    ``time_s[i]`` to ``time_s[i + 1]`` (s, strictly increasing; the last row's command is not
    driven). Runs of equal commands are merged."""
    t = np.asarray(time_s, float)
    v = np.asarray(v_m_s, float)
    w = np.asarray(omega_rad_s, float)
    if t.ndim != 1 or len(t) < 2 or v.shape != t.shape or w.shape != t.shape:
        raise ModelError("a command file needs at least two rows of t, v, omega")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(v)) and np.all(np.isfinite(w))):
        raise ModelError("commands must be finite numbers")
    if not np.all(np.diff(t) > 0):
        raise ModelError("command times must increase strictly")
    out: list[tuple[float, float, float]] = []
    for dt, vi, wi in zip(np.diff(t), v[:-1], w[:-1], strict=True):
        if out and out[-1][1] == vi and out[-1][2] == wi:
            out[-1] = (out[-1][0] + float(dt), out[-1][1], out[-1][2])
        else:
            out.append((float(dt), float(vi), float(wi)))
    return Maneuver("commands", label, tuple(out))


@dataclass(frozen=True)
class CommandSeries:
    """Velocity commands at a fixed rate.

    Attributes
    ----------
    time_s : ndarray, shape (K + 1,)
        Sample times (s) from 0; command i holds over [time_s[i], time_s[i + 1]).
    v_m_s, omega_rad_s : ndarray, shape (K,)
        Forward speed (m/s) and turn rate (rad/s, CCW +) of each interval.
    maneuver_index : ndarray of int, shape (K,)
        Which maneuver of ``maneuvers`` each interval belongs to.
    maneuvers : tuple of Maneuver
    """

    time_s: np.ndarray
    v_m_s: np.ndarray
    omega_rad_s: np.ndarray
    maneuver_index: np.ndarray
    maneuvers: tuple[Maneuver, ...]

    @property
    def duration_s(self) -> float:
        """Total duration (s)."""
        return float(self.time_s[-1])

    @property
    def dt_s(self) -> np.ndarray:
        """Interval lengths (s), shape (K,)."""
        return np.diff(self.time_s)

    def rows(self) -> np.ndarray:
        """(t, v, omega) rows, shape (K + 1, 3): each interval's start and command, then the
        end time with a stop command."""
        v = np.append(self.v_m_s, 0.0)
        w = np.append(self.omega_rad_s, 0.0)
        return np.column_stack([self.time_s, v, w])


def command_series(
    maneuvers: Sequence[Maneuver], rate_hz: float = DEFAULT_RATE_HZ
) -> CommandSeries:
    """The maneuvers one after the other as commands sampled at ``rate_hz`` (module docstring)."""
    rate = _positive("rate_hz", rate_hz)
    maneuvers = tuple(maneuvers)
    if not maneuvers:
        raise ModelError("a recording needs at least one maneuver")
    total = sum(m.duration_s for m in maneuvers)
    if not total <= MAX_SERIES_S:
        raise ModelError(f"{total:.0f} s of commands is too long (at most {MAX_SERIES_S:.0f} s)")
    v, w, idx = [], [], []
    dt = 1.0 / rate
    for i, m in enumerate(maneuvers):
        for duration, speed, turn in m.commands:
            n = max(1, round(duration * rate))
            scale = duration / (n * dt)  # the amount stays exact
            v.append(np.full(n, speed * scale))
            w.append(np.full(n, turn * scale))
            idx.append(np.full(n, i))
    vv, ww = np.concatenate(v), np.concatenate(w)
    t = np.arange(len(vv) + 1) * dt
    return CommandSeries(t, vv, ww, np.concatenate(idx), maneuvers)


@dataclass(frozen=True)
class GyroNoise:
    """A yaw gyro's errors.

    Attributes
    ----------
    arw_rad_sqrt_s : float
        Angle random walk (rad/sqrt(s)): white rate noise of spectral density arw^2.
    bias_rad_s : float
        Constant rate bias (rad/s).
    scale : float
        Scale factor (measured rate / true rate).
    """

    arw_rad_sqrt_s: float = math.radians(0.3) / 60.0  # 0.3 deg/sqrt(h), a MEMS gyro
    bias_rad_s: float = 0.0
    scale: float = 1.0


def exact_arc_poses(ds: np.ndarray, dth: np.ndarray) -> np.ndarray:
    """Poses after every increment of exact arcs (ds, dtheta along the last axis), from the
    origin: shape (..., K + 1, 3)."""
    theta = np.concatenate([np.zeros((*ds.shape[:-1], 1)), np.cumsum(dth, axis=-1)], axis=-1)
    mid = theta[..., :-1] + 0.5 * dth
    half = 0.5 * dth
    small = np.abs(half) < 1e-8
    chord = np.where(small, 1.0 - half**2 / 6.0, np.sin(half) / np.where(small, 1.0, half))
    step = ds * chord
    x = np.concatenate([np.zeros((*ds.shape[:-1], 1)), np.cumsum(step * np.cos(mid), axis=-1)], -1)
    y = np.concatenate([np.zeros((*ds.shape[:-1], 1)), np.cumsum(step * np.sin(mid), axis=-1)], -1)
    return np.stack([x, y, theta], axis=-1)


def simulate_recordings(
    series: CommandSeries,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    measurement: MeasurementNoise,
    trials: int,
    rng: np.random.Generator | None,
    *,
    time_offset_s: float = 0.0,
    gyro: GyroNoise | None = None,
    name: str = "simulated",
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Execute ``series`` ``trials`` times (module docstring).

    Returns
    -------
    angles : ndarray, shape (K + 1, 2)
        Cumulative wheel rotations (right, left; rad) the encoders record (the same in every
        trial: the robot drives open loop on them).
    truth : ndarray, shape (trials, K + 1, 3)
        Measured true poses (x_m, y_m, theta_rad; start frame) at the sample times, with the
        measurement noise; with ``time_offset_s`` the truth at t + offset (its clock runs
        ``time_offset_s`` ahead), held at the ends.
    gyro_yaw : ndarray, shape (trials, K + 1) or None
        Integrated gyro heading (rad) when ``gyro`` is given.
    """
    if trials < 1:
        raise ModelError(f"trials must be >= 1, got {trials}")
    if rng is None and not (noise.is_zero and measurement.is_zero and gyro is None):
        raise ModelError("a numpy.random.Generator is needed to simulate noise")
    dt = series.dt_s
    b_hat = float(believed.wheelbase_m)
    # wheel rotations the robot commands with its believed geometry
    s_hat_r = (series.v_m_s + 0.5 * b_hat * series.omega_rad_s) * dt
    s_hat_l = (series.v_m_s - 0.5 * b_hat * series.omega_rad_s) * dt
    dphi_r = 2.0 * s_hat_r / float(believed.diameter_right_m)
    dphi_l = 2.0 * s_hat_l / float(believed.diameter_left_m)
    angles = np.column_stack(
        [np.concatenate([[0.0], np.cumsum(dphi_r)]), np.concatenate([[0.0], np.cumsum(dphi_l)])]
    )
    ds_r = np.broadcast_to(dphi_r * 0.5 * float(true.diameter_right_m), (trials, len(dt))).copy()
    ds_l = np.broadcast_to(dphi_l * 0.5 * float(true.diameter_left_m), (trials, len(dt))).copy()
    if not noise.is_zero and rng is not None:
        ds_r += rng.standard_normal(ds_r.shape) * np.sqrt(noise.k_r_m * np.abs(ds_r))
        ds_l += rng.standard_normal(ds_l.shape) * np.sqrt(noise.k_l_m * np.abs(ds_l))
    ds = 0.5 * (ds_r + ds_l)
    dth = (ds_r - ds_l) / float(true.wheelbase_m)
    poses = exact_arc_poses(ds, dth)  # (trials, K + 1, 3)
    t = series.time_s
    if time_offset_s:
        shifted = np.clip(t + float(time_offset_s), t[0], t[-1])
        poses = np.stack(
            [np.stack([np.interp(shifted, t, p[:, c]) for c in range(3)], -1) for p in poses]
        )
    truth = poses.copy()
    if not measurement.is_zero and rng is not None:
        truth[..., :2] += measurement.sigma_xy_m * rng.standard_normal(truth[..., :2].shape)
        truth[..., 2] += measurement.sigma_theta_rad * rng.standard_normal(truth[..., 2].shape)
    gyro_yaw = None
    if gyro is not None and rng is not None:
        rate = gyro.scale * dth / dt + gyro.bias_rad_s
        rate = rate + gyro.arw_rad_sqrt_s / np.sqrt(dt) * rng.standard_normal(rate.shape)
        gyro_yaw = np.concatenate([np.zeros((trials, 1)), np.cumsum(rate * dt, axis=-1)], axis=-1)
    return angles, truth, gyro_yaw


def as_recording(
    series: CommandSeries,
    angles: np.ndarray,
    truth: np.ndarray | None,
    gyro_yaw: np.ndarray | None = None,
    *,
    ran_with: WheelGeometry | None = None,
    name: str = "simulated",
) -> Recording:
    """One trial of :func:`simulate_recordings` as a :class:`~odocal.core.recording.Recording`
    (``truth`` of shape (K + 1, 3), relative to its first pose as a loader gives it)."""
    gt = None
    if truth is not None:
        t0 = truth[0]
        c, s = math.cos(t0[2]), math.sin(t0[2])
        dx, dy = truth[:, 0] - t0[0], truth[:, 1] - t0[1]
        gt = np.column_stack([c * dx + s * dy, -s * dx + c * dy, truth[:, 2] - t0[2]])
    return Recording(
        name=name,
        time_s=np.asarray(series.time_s, float),
        wheel_angle_right_rad=np.asarray(angles[:, 0], float),
        wheel_angle_left_rad=np.asarray(angles[:, 1], float),
        ground_truth=gt,
        gyro_yaw_rad=None if gyro_yaw is None else np.asarray(gyro_yaw, float),
        ran_with=ran_with,
        label=" + ".join(m.kind for m in series.maneuvers),
    )
