"""Skid-steer kinematics: wheel rotations -> body motion, and dead reckoning.

A skid-steer robot (four or six wheels per pair of sides, or tracks) turns by making its sides
slip sideways, so the track that makes the odometry turn right is wider than the physical one,
and it changes with how fast the robot turns, its load and the ground. This module is the
kinematics of that family; the identification from data is in
:mod:`odocal.calibration.skid_steer`. It is separate from the differential drive of
:mod:`odocal.core.odometry` (a new kinematics, not a flag on the old one), and reduces to it
exactly when the parameters are the ideal ones (tested).

**The model** (the instantaneous centres of rotation of the two sides and of the body, the
"extended differential drive" of Martinez et al. 2005 and Mandow et al. 2007; the form below is
DERIVED here from rigid-body kinematics, the names follow those papers). The two sides roll at
``v_R = r_R dphi_R/dt`` and ``v_L = r_L dphi_L/dt`` (``r`` the effective rolling radius of each
side). In the body frame (x forward, y left, REP-103) each side's ground contact has an
instantaneous centre of rotation at lateral coordinate ``y_L`` (left, > 0) and ``y_R`` (right,
< 0), and the body's own centre of rotation lies at longitudinal coordinate ``x_icr``. Then

    omega = (v_R - v_L) / (y_L - y_R)
    v_x   = (v_R y_L - v_L y_R) / (y_L - y_R)    (= v_L + omega y_L)
    v_y   = -x_icr omega

The effective track is ``y_L - y_R``; symmetric centres (``y_L = -y_R``) and ``x_icr = 0`` are a
differential drive of wheelbase ``y_L - y_R``, which is what ros2_control's
diff_drive_controller models with ``wheel_separation x wheel_separation_multiplier`` (and the
two wheel radius multipliers): :meth:`SkidSteerModel.ros2_multipliers`. ``y_L + y_R != 0`` makes a
spot turn creep forward or back; ``x_icr != 0`` makes the body slide sideways while it turns
(lateral slip, the centre of rotation ahead of or behind the reference point).

**Turn-rate dependence** (:class:`TurnRateTable`): the effective track may change with how fast
the robot turns. The table gives a multiplier ``m`` on both centres' coordinates (so on the
track) as a piecewise-linear function of the "wheel yaw rate" ``omega_w = (v_R - v_L) / (y_L -
y_R)``, the yaw rate the model reports without the table (for a model whose centres are the
nominal ones, the yaw rate the nominal odometry reports), constant beyond the first and last
knots. The true yaw rate at a knot is then ``omega_w / m``. The yaw rate of each increment is its
wheel rotation over its duration, so dead reckoning with a table needs the sample times.

**Dead reckoning** integrates each increment's body motion ``(dx, dy, dtheta)`` with the
midpoint rule, the body increment rotated by the heading at the middle of the increment
(``theta_before + dtheta / 2``): with ``dy = 0`` this is the update of
:func:`odocal.core.odometry.midpoint_poses` (tested equal).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError
from .model import WheelGeometry

__all__ = [
    "TurnRateTable",
    "SkidSteerModel",
    "skid_body_increments",
    "integrate_body_increments",
    "body_motion_end",
    "dead_reckon_skid",
]


@dataclass(frozen=True)
class TurnRateTable:
    """A multiplier on the effective track as a function of the wheel yaw rate.

    Attributes
    ----------
    rate_rad_s : tuple of float
        Knots of |wheel yaw rate| (rad/s), increasing, >= 0 (module docstring).
    multiplier : tuple of float
        The multiplier (> 0) at each knot; linear in between, constant beyond the ends.
    """

    rate_rad_s: tuple[float, ...]
    multiplier: tuple[float, ...]

    def __post_init__(self) -> None:
        k = np.asarray(self.rate_rad_s, dtype=float)
        m = np.asarray(self.multiplier, dtype=float)
        if k.ndim != 1 or len(k) < 1 or k.shape != m.shape:
            raise ModelError(
                f"a turn-rate table needs as many multipliers as knots (>= 1), got {len(k)} "
                f"knots and {m.size} multipliers"
            )
        if not (np.all(np.isfinite(k)) and np.all(k >= 0) and np.all(np.diff(k) > 0)):
            raise ModelError(f"turn-rate knots must be finite, >= 0 and increasing, got {k}")
        if not (np.all(np.isfinite(m)) and np.all(m > 0)):
            raise ModelError(f"turn-rate multipliers must be finite and > 0, got {m}")

    def at(self, wheel_yaw_rate_rad_s: ArrayLike) -> np.ndarray:
        """The multiplier at each |wheel yaw rate| (rad/s), of the input's shape."""
        w = np.abs(np.asarray(wheel_yaw_rate_rad_s, dtype=float))
        return np.interp(w, np.asarray(self.rate_rad_s), np.asarray(self.multiplier))

    def true_rate_rad_s(self) -> np.ndarray:
        """The true yaw rate at each knot, knot / multiplier (rad/s), shape (K,)."""
        return np.asarray(self.rate_rad_s) / np.asarray(self.multiplier)


@dataclass(frozen=True)
class SkidSteerModel:
    """The parameters of a skid-steer robot's kinematics (module docstring).

    Attributes
    ----------
    radius_right_m, radius_left_m : float
        Effective rolling radius of each side (m, > 0).
    y_icr_left_m, y_icr_right_m : float
        Lateral coordinates of the two sides' centres of rotation (m; left > right; the ideal
        differential drive has +-b/2).
    x_icr_m : float
        Longitudinal coordinate of the body's centre of rotation (m; 0: no lateral slip).
    turn_rate : TurnRateTable or None
        A multiplier on the track as a function of the wheel yaw rate (None: constant track).
    """

    radius_right_m: float
    radius_left_m: float
    y_icr_left_m: float
    y_icr_right_m: float
    x_icr_m: float = 0.0
    turn_rate: TurnRateTable | None = None

    def __post_init__(self) -> None:
        values = (self.radius_right_m, self.radius_left_m, self.y_icr_left_m, self.y_icr_right_m)
        if not all(math.isfinite(float(v)) for v in (*values, self.x_icr_m)):
            raise ModelError(f"skid-steer parameters must be finite, got {self}")
        if not (self.radius_right_m > 0 and self.radius_left_m > 0):
            raise ModelError(
                f"wheel radii must be > 0 (m), got {self.radius_right_m!r}, {self.radius_left_m!r}"
            )
        if not self.y_icr_left_m > self.y_icr_right_m:
            raise ModelError(
                "the left side's centre of rotation must lie left of the right side's "
                f"(y_icr_left_m > y_icr_right_m), got {self.y_icr_left_m!r} and "
                f"{self.y_icr_right_m!r}"
            )

    @classmethod
    def from_geometry(
        cls, geometry: WheelGeometry, track_multiplier: float = 1.0
    ) -> SkidSteerModel:
        """The ideal differential drive of ``geometry`` (radii D / 2, centres at +-b/2), with its
        track multiplied by ``track_multiplier`` (ros2 diff_drive_controller's
        ``wheel_separation_multiplier``)."""
        half = 0.5 * float(geometry.wheelbase_m) * float(track_multiplier)
        return cls(
            0.5 * float(geometry.diameter_right_m),
            0.5 * float(geometry.diameter_left_m),
            half,
            -half,
        )

    @property
    def track_m(self) -> float:
        """The effective track y_L - y_R (m), at multiplier 1 of a turn-rate table."""
        return float(self.y_icr_left_m - self.y_icr_right_m)

    def with_turn_rate(self, table: TurnRateTable | None) -> SkidSteerModel:
        """This model with ``table`` as its turn-rate dependence."""
        return replace(self, turn_rate=table)

    def ros2_multipliers(self, nominal: WheelGeometry) -> dict[str, float]:
        """The ros2_control diff_drive_controller multipliers that make its odometry this model
        as far as a differential drive can: ``wheel_separation_multiplier`` = track / b_nominal,
        ``left_wheel_radius_multiplier``, ``right_wheel_radius_multiplier`` = radius / (D_nominal
        / 2). The controller has no place for ``y_L + y_R``, ``x_icr`` or a turn-rate table
        (those are dropped)."""
        return {
            "wheel_separation_multiplier": self.track_m / float(nominal.wheelbase_m),
            "left_wheel_radius_multiplier": self.radius_left_m
            / (0.5 * float(nominal.diameter_left_m)),
            "right_wheel_radius_multiplier": self.radius_right_m
            / (0.5 * float(nominal.diameter_right_m)),
        }

    def as_dict(self) -> dict:
        """JSON-ready."""
        out: dict = {
            "radius_right_m": self.radius_right_m,
            "radius_left_m": self.radius_left_m,
            "y_icr_left_m": self.y_icr_left_m,
            "y_icr_right_m": self.y_icr_right_m,
            "x_icr_m": self.x_icr_m,
            "track_m": self.track_m,
        }
        if self.turn_rate is not None:
            out["turn_rate"] = {
                "rate_rad_s": list(self.turn_rate.rate_rad_s),
                "multiplier": list(self.turn_rate.multiplier),
            }
        return out


def skid_body_increments(
    model: SkidSteerModel,
    increment_right_rad: ArrayLike,
    increment_left_rad: ArrayLike,
    duration_s: ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The body's motion over each increment of the wheel angles, in the body frame at its
    start: (dx_m, dy_m, dtheta_rad), each of the broadcast shape of the inputs.

    ``duration_s`` (s, > 0) is each increment's duration; needed only when the model has a
    turn-rate table (the wheel yaw rate is the increment's rotation over it). Zero durations
    (no motion) are allowed: their multiplier is the table's first.
    """
    sr = np.asarray(increment_right_rad, dtype=float) * model.radius_right_m
    sl = np.asarray(increment_left_rad, dtype=float) * model.radius_left_m
    y_l, y_r = model.y_icr_left_m, model.y_icr_right_m
    track = y_l - y_r
    if model.turn_rate is None:
        dtheta = (sr - sl) / track
        scale: float | np.ndarray = 1.0
    else:
        if duration_s is None:
            raise ModelError("a model with a turn-rate table needs the increments' durations")
        dt = np.asarray(duration_s, dtype=float)
        with np.errstate(divide="ignore", invalid="ignore"):
            rate = np.where(dt > 0, (sr - sl) / (track * dt), 0.0)
        scale = model.turn_rate.at(rate)
        dtheta = (sr - sl) / (track * scale)
    dx = sl + dtheta * (y_l * scale)
    dy = -model.x_icr_m * dtheta
    return np.broadcast_arrays(dx, dy, dtheta)  # type: ignore[return-value]


def integrate_body_increments(
    dx_m: ArrayLike, dy_m: ArrayLike, dtheta_rad: ArrayLike
) -> np.ndarray:
    """Every pose of consecutive body increments along the last axis (shape (..., K)), from
    (0, 0, 0): shape (..., K + 1, 3) (x_m, y_m, theta_rad; index 0 the start). Each increment is
    rotated by the heading at its middle, theta_before + dtheta / 2."""
    dx = np.asarray(dx_m, dtype=float)
    dy = np.asarray(dy_m, dtype=float)
    dth = np.asarray(dtheta_rad, dtype=float)
    dx, dy, dth = np.broadcast_arrays(dx, dy, dth)
    theta = np.cumsum(dth, axis=-1)
    mid = theta - dth + 0.5 * dth
    c, s = np.cos(mid), np.sin(mid)
    out = np.zeros((*dx.shape[:-1], dx.shape[-1] + 1, 3))
    out[..., 1:, 0] = np.cumsum(dx * c - dy * s, axis=-1)
    out[..., 1:, 1] = np.cumsum(dx * s + dy * c, axis=-1)
    out[..., 1:, 2] = theta
    return out


def body_motion_end(dx_m: ArrayLike, dy_m: ArrayLike, dtheta_rad: ArrayLike) -> np.ndarray:
    """The end pose of :func:`integrate_body_increments` only (the motion over all the
    increments, in the frame at their start): shape (..., 3)."""
    dx = np.asarray(dx_m, dtype=float)
    dy = np.asarray(dy_m, dtype=float)
    dth = np.asarray(dtheta_rad, dtype=float)
    dx, dy, dth = np.broadcast_arrays(dx, dy, dth)
    theta = np.cumsum(dth, axis=-1)
    mid = theta - 0.5 * dth
    c, s = np.cos(mid), np.sin(mid)
    end = theta[..., -1] if theta.shape[-1] else np.zeros(theta.shape[:-1])
    return np.stack(
        [np.sum(dx * c - dy * s, axis=-1), np.sum(dx * s + dy * c, axis=-1), end], axis=-1
    )


def dead_reckon_skid(
    model: SkidSteerModel,
    angle_right_rad: ArrayLike,
    angle_left_rad: ArrayLike,
    time_s: ArrayLike | None = None,
) -> np.ndarray:
    """Integrate cumulative wheel angles (rad, shape (K,)) into poses with ``model``, shape
    (K, 3), starting at (0, 0, 0). ``time_s`` (s, shape (K,), increasing) is needed when the
    model has a turn-rate table."""
    right = np.asarray(angle_right_rad, dtype=float)
    left = np.asarray(angle_left_rad, dtype=float)
    if right.ndim != 1 or right.shape != left.shape:
        raise ModelError(
            f"wheel angles must be two arrays of one shape (K,), got {right.shape}, {left.shape}"
        )
    dt = None
    if time_s is not None:
        t = np.asarray(time_s, dtype=float)
        if t.shape != right.shape:
            raise ModelError(f"time_s must have shape {right.shape}, got {t.shape}")
        dt = np.diff(t)
    inc = skid_body_increments(model, np.diff(right), np.diff(left), dt)
    return integrate_body_increments(*inc)
