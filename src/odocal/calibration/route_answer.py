"""One route's answer for a bag, in one type for every route: each parameter with its value, its
standard error and whether the route estimated it or held it.

A route does not always estimate all three of (D_R, D_L, b):

- ``estimated``: measured by the route; its standard error is the route's.
- ``tied``: a wheel diameter of a model that fits one common scale of both wheels (the
  held-out check's 'equal-diameters' and 'scale' models): their ratio is held at the nominal
  one, their mean is measured. Only the mean may be compared with another route.
- ``held``: not measured at all: the nominal value (or the value the robot ran with) is
  carried through. It has no standard error (not an error of 0) and is never compared with
  another route (:mod:`odocal.calibration.cross_check`).

The gyro measures a heading ratio only: its wheelbase is the file's (or the controller's)
wheelbase times that ratio, so its diameters are held and its wheelbase is ``estimated``
relative to the file's scale (:attr:`RouteAnswer.relative`).
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any, Literal

import numpy as np

from ..core.model import WheelGeometry

__all__ = [
    "KEYS",
    "RouteName",
    "ROUTE_NAMES",
    "ParameterStatus",
    "ParameterEstimate",
    "RouteAnswer",
    "route_answer",
]

#: The parameters, in the JSON contract's names (and the order of every tuple below).
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")

#: The bag routes, in the order the one-command fit prefers them.
RouteName = Literal["trajectory", "slam", "scan", "gyro"]
ROUTE_NAMES: tuple[RouteName, ...] = ("trajectory", "slam", "scan", "gyro")

#: What a route did with a parameter (module docstring).
ParameterStatus = Literal["estimated", "tied", "held"]

#: The statuses of each model, for (D_R, D_L, b).
_MODEL_STATUS: dict[str, tuple[ParameterStatus, ParameterStatus, ParameterStatus]] = {
    "full": ("estimated", "estimated", "estimated"),
    "equal-diameters": ("tied", "tied", "estimated"),
    "scale": ("tied", "tied", "held"),
    "heading-ratio": ("held", "held", "estimated"),
    # a skid-steer robot's effective rolling diameters and effective track
    "skid-steer": ("estimated", "estimated", "estimated"),
}


@dataclass(frozen=True)
class ParameterEstimate:
    """One parameter of a route's answer.

    Attributes
    ----------
    name : str
        One of :data:`KEYS`.
    value : float
        (m).
    std_error : float or None
        (m); None when held, or when the route could not give one.
    status : {'estimated', 'tied', 'held'}
    """

    name: str
    value: float
    std_error: float | None
    status: ParameterStatus

    @property
    def measured(self) -> bool:
        """Estimated or tied: the route's data moved it."""
        return self.status != "held"

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract's parameter: ``value``, ``std_error`` (null when held) and
        ``status``."""
        return {"value": self.value, "std_error": self.std_error, "status": self.status}


@dataclass(frozen=True)
class RouteAnswer:
    """One route's calibrated geometry, parameter by parameter.

    Attributes
    ----------
    route : str
        One of :data:`ROUTE_NAMES`.
    model : str
        'full', 'equal-diameters', 'scale' (the held-out check's models), 'heading-ratio'
        (the gyro) or 'skid-steer' (the effective track and rolling diameters of a skid-steer
        robot, :mod:`odocal.calibration.skid_steer`).
    parameters : tuple of ParameterEstimate
        (D_R, D_L, b), in :data:`KEYS` order.
    covariance : ndarray, shape (3, 3), or None
        Of (D_R, D_L, b) (m^2) where the route gives one (zero rows for held parameters).
    ratio, ratio_std_error : float or None
        What a ratio-only route measured (the gyro: the heading ratio, gyro / odometry), and
        its standard error; None for the others.
    """

    route: RouteName
    model: str
    parameters: tuple[ParameterEstimate, ParameterEstimate, ParameterEstimate]
    covariance: np.ndarray | None = None
    ratio: float | None = None
    ratio_std_error: float | None = None

    @property
    def geometry(self) -> WheelGeometry:
        """The calibrated geometry."""
        d_r, d_l, b = (p.value for p in self.parameters)
        return WheelGeometry.unchecked(d_r, d_l, b)

    @property
    def stderr(self) -> tuple[float | None, float | None, float | None]:
        """Standard errors of (D_R, D_L, b) (m); None where held or unknown."""
        a, b, c = (p.std_error for p in self.parameters)
        return (a, b, c)

    @property
    def relative(self) -> bool:
        """The route measured a ratio only (the gyro): its answer scales with the file's."""
        return self.model == "heading-ratio"

    @property
    def held(self) -> tuple[str, ...]:
        """The names of the parameters the route held."""
        return tuple(p.name for p in self.parameters if p.status == "held")

    def mean_diameter(self) -> tuple[float, float | None] | None:
        """The mean wheel diameter (m) and its standard error, when the route measured it
        (estimated or tied diameters); None when it held them."""
        right, left = self.parameters[0], self.parameters[1]
        if not (right.measured and left.measured):
            return None
        value = 0.5 * (right.value + left.value)
        if self.covariance is not None:
            w = np.array([0.5, 0.5, 0.0])
            var = float(w @ self.covariance @ w)
            return value, (math.sqrt(var) if var >= 0 else None)
        if right.std_error is None or left.std_error is None:
            return value, None
        if right.status == "tied":  # one scale: the two errors move together
            return value, 0.5 * (right.std_error + left.std_error)
        return value, None  # the correlation of two free diameters is unknown: not compared

    def as_dict(self) -> dict[str, dict[str, Any]]:
        """The JSON contract's parameters: name -> value, standard error and status."""
        return {p.name: p.as_dict() for p in self.parameters}


def route_answer(
    route: RouteName,
    model: str,
    geometry: WheelGeometry,
    stderr: tuple[float | None, float | None, float | None],
    covariance: np.ndarray | None = None,
    ratio: tuple[float, float | None] | None = None,
) -> RouteAnswer:
    """The answer of ``route`` for ``model``: each parameter's status from the model, held
    parameters without a standard error (a restricted model reports them with an error of 0;
    that is no measurement); ``ratio``: what a ratio-only route measured, with its standard
    error."""
    status = _MODEL_STATUS[model]
    values = (geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m)
    params = tuple(
        ParameterEstimate(k, float(v), None if s == "held" or se is None else float(se), s)
        for k, v, se, s in zip(KEYS, values, stderr, status, strict=True)
    )
    assert len(params) == 3
    cov = None if covariance is None else np.asarray(covariance, dtype=float)
    r, r_se = (None, None) if ratio is None else ratio
    return RouteAnswer(route, model, (params[0], params[1], params[2]), cov, r, r_se)
