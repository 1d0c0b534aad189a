"""Relative plausibility: values checked against each other, so that a unit slip cannot pass.

Absolute ranges (a length between 0.1 mm and 1 km, ...) catch typos, but not a file written in
another unit: a ROBOT.yaml in millimetres (wheel diameter 66, wheelbase 160) holds plausible
numbers in plausible proportions. What gives it away is the robot's size against the track it
drove (a 160 m wheelbase on a 1 m square), a diameter in one unit beside a wheelbase in another
(0.066 m beside 160 mm), or an end error that no run of that robot on that track can have (12 m
after 4 m of travel: centimetres typed into a metre column). The end-error bounds come from the
model itself: the end errors of robots far worse than any real one (wheelbase 10 %, diameters
1 % off) on the same track, with a margin.

Each function returns a message (what is wrong and the likely slip) or None; the caller raises it
with the file and line it knows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from .covariance import mean_final_pose
from .model import Robot, SystematicError, WheelGeometry
from .simulate import odometric_pose
from .tracks import polygon

__all__ = [
    "DIAMETER_PER_WHEELBASE",
    "EXTREME_E_B",
    "EXTREME_E_D",
    "END_ERROR_MARGIN",
    "EndErrorBounds",
    "end_error_bounds",
    "proportions_problem",
    "calibrated_geometry_problem",
    "WHEEL_DIAMETER_MAX_M",
    "wheel_size_problem",
    "track_size_problem",
    "wrap_heading_error",
    "heading_error_problem",
    "end_distance_problem",
    "circle_radius_problem",
]

#: Plausible wheel diameter / wheelbase of a two-wheel differential drive (from about 0.3 for a
#: Kobuki or a Roomba, 0.4 for a TurtleBot3 or the TETRA-DS II, 0.6 for a Husky, to about 1.1 for
#: a wheelchair). The bounds are wide: they only catch one value in metres beside the other in
#: centimetres or millimetres (a factor of 100 or 1000).
DIAMETER_PER_WHEELBASE = (0.05, 2.0)

#: The extreme robots that bound what a real run can end like: wheelbase off by 10 % and
#: diameters off by 1 % (typical robots are within 3 % and 0.5 %; docs/design.md, "A new robot").
EXTREME_E_B = (0.9, 1.1)
EXTREME_E_D = (0.99, 1.01)
#: Margin on the extreme robots' end errors.
END_ERROR_MARGIN = 1.5


@dataclass(frozen=True)
class EndErrorBounds:
    """The largest final errors a closed polygon run of one robot can plausibly have.

    Attributes
    ----------
    heading_rad : float
        Largest |heading error| (rad): the extreme robots' (EXTREME_E_B, EXTREME_E_D) on this
        track, times END_ERROR_MARGIN, plus 5 sigma of the heading instrument.
    distance_m : float
        Largest distance between start and end (m), likewise.
    travel_m : float
        The run's travel (m).
    """

    heading_rad: float
    distance_m: float
    travel_m: float

    @property
    def unambiguous(self) -> bool:
        """Heading errors stay within +-180 deg, so a value a full turn away is a typing slip."""
        return self.heading_rad < math.pi


def end_error_bounds(
    sides: int, side_m: float, geometry: WheelGeometry, sigma_theta_rad: float = 0.0,
    sigma_xy_m: float = 0.0,
) -> EndErrorBounds:  # fmt: skip
    """The :class:`EndErrorBounds` of an N-gon of side ``side_m`` (m) for a robot of nominal
    ``geometry`` (m), measured with an instrument of ``sigma_theta_rad`` and ``sigma_xy_m``."""
    theta, dist = 0.0, 0.0
    for direction in ("cw", "ccw"):
        track = polygon(sides, side_m, direction)
        home = odometric_pose(track)
        for E_b in EXTREME_E_B:
            for E_d in EXTREME_E_D:
                true = Robot(geometry, SystematicError(E_b, E_d)).true_geometry
                e = mean_final_pose(track, true, geometry) - home
                theta = max(theta, abs(float(e[2])))
                dist = max(dist, math.hypot(float(e[0]), float(e[1])))
    return EndErrorBounds(
        END_ERROR_MARGIN * theta + 5.0 * sigma_theta_rad,
        END_ERROR_MARGIN * dist + 5.0 * sigma_xy_m,
        sides * side_m,
    )


def proportions_problem(
    diameter_right_m: float | np.ndarray,
    diameter_left_m: float | np.ndarray,
    wheelbase_m: float | np.ndarray,
) -> str | None:
    """Wheel diameters (m) against the wheelbase (m): None if plausible, else why not."""
    lo, hi = DIAMETER_PER_WHEELBASE
    b = float(np.mean(wheelbase_m))
    for name, d in (("right", diameter_right_m), ("left", diameter_left_m)):
        ratio = float(np.mean(d)) / b
        if not lo <= ratio <= hi:
            return (
                f"the {name} wheel diameter {float(np.mean(d)):g} is {ratio:.3g} times the "
                f"wheelbase {b:g}: a differential drive has {lo:g} .. {hi:g}; are the two in "
                "different units (metres beside millimetres or centimetres)?"
            )
    return None


def calibrated_geometry_problem(
    geometry: WheelGeometry, length_range_m: tuple[float, float]
) -> str | None:
    """A CALIBRATED geometry (m) checked as a robot file's is (every length finite and within
    ``length_range_m``, diameters against the wheelbase): None if plausible, else what is wrong,
    without a guess at the cause (the caller knows what its inputs can get wrong)."""
    lo, hi = length_range_m
    values = {
        "D_R": float(geometry.diameter_right_m),
        "D_L": float(geometry.diameter_left_m),
        "b": float(geometry.wheelbase_m),
    }
    shown = ", ".join(f"{k} = {v:.4g} m" for k, v in values.items())
    for name, v in values.items():
        if not (math.isfinite(v) and lo <= v <= hi):
            return f"{shown}: {name} is outside {lo:g} .. {hi:g} m, not a robot"
    r_lo, r_hi = DIAMETER_PER_WHEELBASE
    for name in ("D_R", "D_L"):
        ratio = values[name] / values["b"]
        if not r_lo <= ratio <= r_hi:
            return (
                f"{shown}: {name} is {ratio:.3g} times the wheelbase, where a differential drive "
                f"has {r_lo:g} .. {r_hi:g}"
            )
    return None


#: The largest wheel diameter (m) of a calibration judged without a nominal geometry: the
#: largest wheels of any robot are below it (a wheelchair's 0.6 m, an agricultural robot's
#: 1.5 m, an autonomous haul truck's 4 m tyres), and the small ones far below: a robot's lengths
#: in millimetres read as metres give a 0.066 m wheel 66 m.
WHEEL_DIAMETER_MAX_M = 5.0


def wheel_size_problem(geometry: WheelGeometry) -> str | None:
    """A CALIBRATED geometry (m) judged without a nominal one (when a nominal is known, a
    calibration more than 25 % from it is absurd: :data:`~odocal.calibration.result.
    ABSURD_FRACTION`): None if its wheels are no larger than :data:`WHEEL_DIAMETER_MAX_M`, else
    what is wrong and the likely slip (lengths in millimetres or centimetres)."""
    largest = max(float(geometry.diameter_right_m), float(geometry.diameter_left_m))
    if largest <= WHEEL_DIAMETER_MAX_M:
        return None
    return (
        f"D_R = {float(geometry.diameter_right_m):.4g} m, D_L = "
        f"{float(geometry.diameter_left_m):.4g} m, b = {float(geometry.wheelbase_m):.4g} m: wheels "
        f"larger than {WHEEL_DIAMETER_MAX_M:g} m are no robot's; lengths in millimetres or "
        "centimetres where the units are metres?"
    )


#: The largest wheelbase (m) of a wheeled robot: a haul truck's track is about 8 m.
WHEELBASE_MAX_M = 20.0


def robot_scale_problem(diameter_m: float, wheelbase_m: float) -> str | None:
    """A robot file's nominal wheel diameter and wheelbase (m) against the size of any wheeled
    robot (:data:`WHEEL_DIAMETER_MAX_M`, :data:`WHEELBASE_MAX_M`): None when plausible, else
    what is wrong and the unit slip it suggests. A file in millimetres or centimetres would
    pass every route that measures a ratio (the gyro): refused where the file is read."""
    for name, v, hi in (
        ("wheel_diameter_m", diameter_m, WHEEL_DIAMETER_MAX_M),
        ("wheelbase_m", wheelbase_m, WHEELBASE_MAX_M),
    ):
        if v > hi:
            guess = next(
                (f"{v * f:g} m if it is in {unit}" for f, unit in ((1e-3, "millimetres"),
                 (1e-2, "centimetres")) if v * f <= hi),
                "a length in other units",
            )  # fmt: skip
            return (
                f"{name}: {v:g} m is no wheeled robot's (at most {hi:g} m); the file's lengths "
                f"must be in metres: is it in millimetres? ({guess})"
            )
    return None


def track_size_problem(wheelbase_m: float, side_m: float, what: str = "track") -> str | None:
    """A polygon of side ``side_m`` (m) for a robot of wheelbase ``wheelbase_m`` (m): the side
    must be longer than the robot is wide."""
    if side_m <= wheelbase_m:
        return (
            f"the {what}'s side {side_m:g} m is not longer than the robot's wheelbase "
            f"{wheelbase_m:g} m: is the robot file in millimetres or centimetres (all lengths "
            "are in metres)?"
        )
    return None


def wrap_heading_error(theta_rad: ArrayLike) -> np.ndarray:
    """Heading errors wrapped into [-pi, pi) (rad; arrays keep their shape).

    The final heading error of a closed run is the small deviation from the commanded total turn.
    Where the run cannot deviate by half a turn (:attr:`EndErrorBounds.unambiguous`), a value a
    full turn away (-356.5 deg typed for +3.5 deg: the total turn instead of the deviation) means
    the same heading and is brought back, the same way in every row.
    """
    t = np.asarray(theta_rad, dtype=float)
    return np.mod(t + math.pi, 2.0 * math.pi) - math.pi


def heading_error_problem(theta_rad: float, bounds: EndErrorBounds) -> str | None:
    """A final heading error (rad) of a closed polygon run against its bounds: None if
    plausible."""
    if abs(theta_rad) > bounds.heading_rad:
        return (
            f"a final heading error of {math.degrees(theta_rad):+.4g} deg is not the deviation "
            f"from the commanded turn that this robot can have on this track (at most "
            f"{math.degrees(bounds.heading_rad):.3g} deg, even with its wheelbase 10 % and its "
            "diameters 1 % off): radians in the theta_deg column, a heading measured from "
            "another line than the start line, or a run that was not the polygon?"
        )
    return None


def end_distance_problem(x_m: float, y_m: float, bounds: EndErrorBounds) -> str | None:
    """The end of a closed run (x, y in m from its start) against its bounds."""
    dist = math.hypot(x_m, y_m)
    if dist > bounds.distance_m:
        return (
            f"the run ends {dist:.4g} m from its start after {bounds.travel_m:g} m of travel, "
            f"where this robot ends within {bounds.distance_m:.3g} m even with its wheelbase 10 % "
            "and its diameters 1 % off: centimetres or millimetres in a metre column, or the "
            "wrong --side-length?"
        )
    return None


#: A measured circle radius within this factor of the commanded one (BCPT runs).
MAX_RADIUS_FACTOR = 2.0


def circle_radius_problem(radius_m: float, commanded_m: float) -> str | None:
    """A measured circle radius (m) against the commanded one (m)."""
    ratio = radius_m / commanded_m
    if not 1.0 / MAX_RADIUS_FACTOR <= ratio <= MAX_RADIUS_FACTOR:
        return (
            f"a measured radius of {radius_m:g} m for a commanded {commanded_m:g} m circle "
            f"({ratio:.3g} times; a real run is within a factor {MAX_RADIUS_FACTOR:g}): "
            "centimetres or millimetres in a metre column, a diameter for a radius, or the "
            "wrong --radius?"
        )
    return None
