"""Relative plausibility: values checked against each other, so that a unit slip cannot pass.

Absolute ranges (a length between 0.1 mm and 1 km, ...) catch typos, but not a file written in
another unit: a ROBOT.yaml in millimetres (wheel diameter 66, wheelbase 160) holds plausible
numbers in plausible proportions. What gives it away is the robot's size against the track it
drove (a 160 m wheelbase on a 1 m square), a diameter in one unit beside a wheelbase in another
(0.066 m beside 160 mm), or an end error that no run of that track can have (12 m after 4 m of
travel: centimetres typed into a metre column).

Each function returns a message (what is wrong and the likely slip) or None; the caller raises it
with the file and line it knows.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = [
    "DIAMETER_PER_WHEELBASE",
    "MAX_HEADING_ERROR_DEG",
    "MAX_END_DISTANCE_PER_TRAVEL",
    "proportions_problem",
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

#: Largest final heading error of a closed polygon run (deg). A real run deviates from its
#: commanded +-360 deg by a few degrees; beyond 45 deg the value is the total turn, radians
#: multiplied out, or a run that was not the polygon (the recorded-square methods of ``fit`` use
#: the same bound).
MAX_HEADING_ERROR_DEG = 45.0

#: Largest distance between the start and the end of a closed polygon run, per metre of travel.
#: With heading errors within MAX_HEADING_ERROR_DEG a square run ends within about 0.3 of its
#: travel from its start; half the travel leaves room and still catches centimetres or
#: millimetres typed into a metre column.
MAX_END_DISTANCE_PER_TRAVEL = 0.5


def proportions_problem(diameter_right_m, diameter_left_m, wheelbase_m) -> str | None:
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


def wrap_heading_error(theta_rad):
    """Heading errors wrapped into [-pi, pi) (rad; arrays keep their shape).

    The final heading error of a closed run is the small deviation from the commanded total turn.
    A value a full turn away (-356.5 deg typed for +3.5 deg: the total turn instead of the
    deviation) means the same heading and is brought back, the same way in every row.
    """
    t = np.asarray(theta_rad, dtype=float)
    return np.mod(t + math.pi, 2.0 * math.pi) - math.pi


def heading_error_problem(theta_rad: float, sides: int) -> str | None:
    """A (wrapped) final heading error of a closed N-gon run: None if plausible."""
    deg = math.degrees(theta_rad)
    if abs(deg) > MAX_HEADING_ERROR_DEG:
        return (
            f"a final heading error of {deg:+.4g} deg is not the small deviation from the "
            f"commanded +-360 deg of a {sides}-gon run (at most {MAX_HEADING_ERROR_DEG:g} deg): "
            "radians in the theta_deg column, a heading measured from another line than the "
            "start line, or a run that was not the polygon?"
        )
    return None


def end_distance_problem(x_m: float, y_m: float, travel_m: float) -> str | None:
    """The end of a closed run (x, y in m from its start) against its travel (m)."""
    dist = math.hypot(x_m, y_m)
    if dist > MAX_END_DISTANCE_PER_TRAVEL * travel_m:
        return (
            f"the run ends {dist:.4g} m from its start after {travel_m:g} m of travel (a closed "
            f"run ends within {MAX_END_DISTANCE_PER_TRAVEL:g} of its travel): centimetres or "
            "millimetres in a metre column, or the wrong --side-length?"
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
