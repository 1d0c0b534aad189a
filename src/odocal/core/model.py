"""The robot model: wheel geometry, systematic and non-systematic errors, measurement noise.

Conventions follow docs/conventions.md (frames, signs, E_b and E_d, k in metres). Every length is
in metres and every angle in radians unless the name says otherwise.

Geometry values may be Python floats or numpy arrays of one shape (a batch of robots, e.g. one
calibrated parameter set per Monte-Carlo trial); arithmetic broadcasts.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError

__all__ = [
    "Kinematics",
    "KINEMATICS",
    "ModelError",
    "WheelGeometry",
    "wheel_factors",
    "SystematicError",
    "NonSystematicError",
    "MeasurementNoise",
    "Robot",
    "check_positive",
    "check_nonnegative",
]


def _show(value: ArrayLike, bad: np.ndarray) -> str:
    """``value`` for a one-line message: a scalar as is; of an array, the first bad element."""
    arr = np.asarray(value, dtype=float)
    if arr.ndim == 0:
        return repr(value)
    bad = np.broadcast_to(bad, arr.shape)
    return f"{float(arr[bad].flat[0])!r} ({int(bad.sum())} of {arr.size} values)"


def _finite(name: str, value: ArrayLike) -> None:
    arr = np.asarray(value, dtype=float)
    if not np.all(np.isfinite(arr)):
        raise ModelError(f"{name} must be finite, got {_show(value, ~np.isfinite(arr))}")


def check_positive(name: str, value: ArrayLike) -> None:
    """Raise ModelError unless every element of ``value`` is finite and > 0."""
    _finite(name, value)
    arr = np.asarray(value, dtype=float)
    if not np.all(arr > 0):
        raise ModelError(f"{name} must be > 0, got {_show(value, ~(arr > 0))}")


def check_nonnegative(name: str, value: ArrayLike) -> None:
    """Raise ModelError unless every element of ``value`` is finite and >= 0."""
    _finite(name, value)
    arr = np.asarray(value, dtype=float)
    if not np.all(arr >= 0):
        raise ModelError(f"{name} must be >= 0, got {_show(value, ~(arr >= 0))}")


def wheel_factors(E_d: float | np.ndarray) -> tuple[float | np.ndarray, float | np.ndarray]:
    """Per-wheel diameter factors (c_R, c_L) = (2 E_d / (E_d + 1), 2 / (E_d + 1)) of a diameter
    ratio ``E_d`` (dimensionless; float or array): they change the ratio by ``E_d`` and keep the
    mean diameter (docs/conventions.md). The one place this formula is written."""
    return 2.0 * E_d / (E_d + 1.0), 2.0 / (E_d + 1.0)


@dataclass(frozen=True)
class WheelGeometry:
    """Wheel diameters and wheelbase of a differential-drive robot.

    Used both for what a robot BELIEVES (the parameters in its controller and odometry) and for
    what is TRUE (the physical wheels).

    Attributes
    ----------
    diameter_right_m, diameter_left_m : float or ndarray
        Wheel diameters (m), not radii.
    wheelbase_m : float or ndarray
        Distance between the wheel contact points, b (m).
    """

    diameter_right_m: float | np.ndarray
    diameter_left_m: float | np.ndarray
    wheelbase_m: float | np.ndarray

    def __post_init__(self) -> None:
        check_positive("diameter_right_m", self.diameter_right_m)
        check_positive("diameter_left_m", self.diameter_left_m)
        check_positive("wheelbase_m", self.wheelbase_m)

    @classmethod
    def unchecked(
        cls,
        diameter_right_m: float | np.ndarray,
        diameter_left_m: float | np.ndarray,
        wheelbase_m: float | np.ndarray,
    ) -> WheelGeometry:
        """A geometry built without the checks (values may be batches, NaN or <= 0): for
        optimisers and Monte-Carlo batches, which check their results themselves."""
        obj = object.__new__(cls)
        object.__setattr__(obj, "diameter_right_m", diameter_right_m)
        object.__setattr__(obj, "diameter_left_m", diameter_left_m)
        object.__setattr__(obj, "wheelbase_m", wheelbase_m)
        return obj

    @classmethod
    def symmetric(cls, wheel_diameter_m: float, wheelbase_m: float) -> WheelGeometry:
        """Both wheels of diameter ``wheel_diameter_m`` (m), wheelbase ``wheelbase_m`` (m)."""
        return cls(wheel_diameter_m, wheel_diameter_m, wheelbase_m)

    @property
    def mean_diameter_m(self) -> float | np.ndarray:
        """Mean of the two wheel diameters (m)."""
        return 0.5 * (self.diameter_right_m + self.diameter_left_m)

    @property
    def diameter_ratio(self) -> float | np.ndarray:
        """D_R / D_L (dimensionless)."""
        return self.diameter_right_m / self.diameter_left_m

    def with_systematic(self, error: SystematicError) -> WheelGeometry:
        """The TRUE geometry of a robot whose nominal geometry is ``self`` (model.md).

        D_R = E_s D_n 2 E_d / (E_d + 1), D_L = E_s D_n 2 / (E_d + 1), b = E_b b_n, with D_n the
        mean nominal diameter. E_d is the absolute ratio of the true diameters.
        """
        d_n = self.mean_diameter_m * error.E_s
        c_r, c_l = wheel_factors(error.E_d)
        return WheelGeometry(d_n * c_r, d_n * c_l, self.wheelbase_m * error.E_b)

    def corrected(self, E_b: float | np.ndarray, E_d: float | np.ndarray) -> WheelGeometry:
        """Compose a calibration (E_b, E_d, relative to ``self``) with ``self``.

        c_R = 2 E_d/(E_d + 1), c_L = 2/(E_d + 1) multiply the diameters per wheel (so the new ratio
        is E_d times the old one and the mean scale is kept); the wheelbase is multiplied by E_b.
        """
        c_r, c_l = wheel_factors(E_d)
        return WheelGeometry(
            diameter_right_m=self.diameter_right_m * c_r,
            diameter_left_m=self.diameter_left_m * c_l,
            wheelbase_m=self.wheelbase_m * E_b,
        )

    def take(self, index: int | slice | np.ndarray) -> WheelGeometry:
        """Select one robot (or a sub-batch) from a batched geometry."""

        def pick(v: float | np.ndarray) -> float | np.ndarray:
            return np.asarray(v)[index] if np.ndim(v) else v

        return WheelGeometry(
            pick(self.diameter_right_m), pick(self.diameter_left_m), pick(self.wheelbase_m)
        )

    def as_dict(self) -> dict:
        """Plain-float dictionary (scalar geometry only)."""
        return {
            "wheel_diameter_right_m": float(self.diameter_right_m),
            "wheel_diameter_left_m": float(self.diameter_left_m),
            "wheelbase_m": float(self.wheelbase_m),
        }


@dataclass(frozen=True)
class SystematicError:
    """Borenstein's systematic error parameters (dimensionless).

    E_b = b_true / b_nominal, E_d = D_R / D_L (true diameters), E_s = mean true diameter / nominal.
    All three default to 1 (no error).
    """

    E_b: float = 1.0
    E_d: float = 1.0
    E_s: float = 1.0

    def __post_init__(self) -> None:
        check_positive("E_b", self.E_b)
        check_positive("E_d", self.E_d)
        check_positive("E_s", self.E_s)

    @classmethod
    def between(cls, true: WheelGeometry, nominal: WheelGeometry) -> SystematicError:
        """The errors that make ``nominal.with_systematic(...)`` equal ``true``: E_b = b / b_n,
        E_d = D_R / D_L, E_s = mean(D) / mean(D_n) (scalar geometries)."""
        return cls(
            E_b=float(true.wheelbase_m / nominal.wheelbase_m),
            E_d=float(true.diameter_ratio),
            E_s=float(true.mean_diameter_m / nominal.mean_diameter_m),
        )


@dataclass(frozen=True)
class NonSystematicError:
    """Random wheel-travel error in the paper's (Siegwart) form.

    Over an increment, each wheel's true travel gets independent zero-mean Gaussian noise of
    variance ``k_r_m * |ds_r|`` and ``k_l_m * |ds_l|``. k is in METRES (Chong & Kleeman's own k,
    in m^0.5, is the square root of this one).
    """

    k_r_m: float = 0.0
    k_l_m: float = 0.0

    def __post_init__(self) -> None:
        check_nonnegative("k_r_m", self.k_r_m)
        check_nonnegative("k_l_m", self.k_l_m)

    @property
    def is_zero(self) -> bool:
        """Whether both wheels are noise-free (k_r_m = k_l_m = 0)."""
        return self.k_r_m == 0.0 and self.k_l_m == 0.0

    @property
    def k_sum_m(self) -> float:
        """k_r_m + k_l_m (m): what the straight-line and turn variances grow with."""
        return self.k_r_m + self.k_l_m


@dataclass(frozen=True)
class MeasurementNoise:
    """Noise of the instrument that measures the final pose (ground truth).

    Attributes
    ----------
    sigma_xy_m : float
        Standard deviation of each measured position coordinate (m).
    sigma_theta_rad : float
        Standard deviation of the measured heading (rad).
    """

    sigma_xy_m: float = 0.0
    sigma_theta_rad: float = 0.0

    def __post_init__(self) -> None:
        check_nonnegative("sigma_xy_m", self.sigma_xy_m)
        check_nonnegative("sigma_theta_rad", self.sigma_theta_rad)

    @property
    def is_zero(self) -> bool:
        """Whether the measurement is exact (no position or heading noise)."""
        return self.sigma_xy_m == 0.0 and self.sigma_theta_rad == 0.0

    @classmethod
    def from_degrees(cls, sigma_xy_m: float, sigma_theta_deg: float) -> MeasurementNoise:
        """The noise from the heading's standard deviation in degrees (position in m)."""
        return cls(sigma_xy_m, math.radians(sigma_theta_deg))


#: The kinematics odocal models: a two-wheel differential drive, or a skid-steer or tracked
#: robot.
Kinematics = Literal["differential", "skid-steer"]
KINEMATICS: tuple[Kinematics, ...] = ("differential", "skid-steer")


@dataclass(frozen=True)
class Robot:
    """A differential-drive robot: nominal geometry, its errors, and what it believes.

    Attributes
    ----------
    nominal : WheelGeometry
        The nominal (datasheet) geometry. Systematic errors are defined relative to it.
    systematic, nonsystematic, measurement
        Error models (default: no error).
    believed : WheelGeometry or None
        The parameters the robot's controller and odometry use; ``None`` means the nominal ones.
        A calibration result is installed here to re-drive a calibrated robot.
    kinematics : {'differential', 'skid-steer'}
        A two-wheel differential drive, or a skid-steer or tracked robot (its effective track
        wider than the physical one: :mod:`odocal.core.skid_steer`).
    ran_with_stated : bool
        Whether the robot file says what the controller ran with (``believed``, or the
        diff_drive_controller multipliers): when it does not, the nominal geometry stands in,
        and a route that inverts the controller's odometry says so.
    """

    nominal: WheelGeometry
    systematic: SystematicError = field(default_factory=SystematicError)
    nonsystematic: NonSystematicError = field(default_factory=NonSystematicError)
    measurement: MeasurementNoise = field(default_factory=MeasurementNoise)
    believed: WheelGeometry | None = None
    kinematics: Kinematics = "differential"
    ran_with_stated: bool = False

    @property
    def true_geometry(self) -> WheelGeometry:
        """The geometry the robot really drives with: nominal with the systematic errors applied."""
        return self.nominal.with_systematic(self.systematic)

    @property
    def believed_geometry(self) -> WheelGeometry:
        """The geometry the robot's odometry uses: ``believed``, else the nominal one."""
        return self.nominal if self.believed is None else self.believed

    def with_believed(self, believed: WheelGeometry | None) -> Robot:
        """The same physical robot running with other parameters (e.g. a calibration result)."""
        return replace(self, believed=believed)
