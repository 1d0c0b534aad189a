"""Test tracks: sequences of motion segments, in the robot's own belief.

A segment is a constant-curvature motion of the axle centre: a signed distance d (m, negative =
backwards) and a signed heading change psi (rad, CCW positive). Straight: psi = 0. Spot turn:
d = 0. Arc of radius rho through angle psi: d = rho |psi|. The believed wheel travel of a segment
is s_R = d + psi b_hat / 2 and s_L = d - psi b_hat / 2 (docs/conventions.md).

Segment values may be numpy arrays (one value per batch element, e.g. per candidate track size in
a design sweep); they broadcast against the batch in the simulator.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .model import ModelError, check_positive
from .pose import compose

__all__ = [
    "Segment",
    "Track",
    "straight",
    "spot_turn",
    "arc",
    "polygon",
    "straight_line",
    "out_and_back",
    "circle",
    "direction_sign",
    "DIRECTIONS",
]

DIRECTIONS = ("cw", "ccw")


def direction_sign(direction: str) -> int:
    """+1 for 'ccw' (left turns), -1 for 'cw' (right turns)."""
    d = direction.lower()
    if d == "ccw":
        return 1
    if d == "cw":
        return -1
    raise ModelError(f"direction must be 'cw' or 'ccw', got {direction!r}")


@dataclass(frozen=True)
class Segment:
    """One constant-curvature motion: signed distance ``distance_m`` (m), heading change
    ``angle_rad`` (rad, CCW +)."""

    distance_m: float | np.ndarray = 0.0
    angle_rad: float | np.ndarray = 0.0

    @property
    def kind(self) -> str:
        """'straight' (no heading change), 'turn' (on the spot) or 'arc'."""
        d0 = np.all(np.asarray(self.distance_m) == 0)
        a0 = np.all(np.asarray(self.angle_rad) == 0)
        if a0:
            return "straight"
        return "turn" if d0 else "arc"

    def wheel_travel(
        self, wheelbase_m: float | np.ndarray
    ) -> tuple[float | np.ndarray, float | np.ndarray]:
        """Believed wheel travel (s_R, s_L) in m for a robot believing ``wheelbase_m``."""
        half = 0.5 * self.angle_rad * wheelbase_m
        return self.distance_m + half, self.distance_m - half


def straight(distance_m: float | np.ndarray) -> Segment:
    """Drive straight for ``distance_m`` (m; negative = backwards)."""
    return Segment(distance_m, 0.0)


def spot_turn(angle_rad: float) -> Segment:
    """Turn on the spot by ``angle_rad`` (rad, CCW +)."""
    return Segment(0.0, angle_rad)


def arc(radius_m: float, angle_rad: float) -> Segment:
    """Drive forward on an arc of axle-centre radius ``radius_m`` (m) through ``angle_rad``
    (rad, CCW + = left)."""
    if not (math.isfinite(radius_m) and radius_m >= 0):
        raise ModelError(f"arc radius must be finite and >= 0, got {radius_m!r}")
    return Segment(radius_m * abs(angle_rad), angle_rad)


@dataclass(frozen=True)
class Track:
    """A named sequence of segments. ``closed`` tracks end where they start (in belief)."""

    name: str
    segments: tuple[Segment, ...]

    def __post_init__(self) -> None:
        if not self.segments:
            raise ModelError("a track needs at least one segment")

    @property
    def travel_m(self) -> float | np.ndarray:
        """Total believed axle-centre distance (m)."""
        return sum(np.abs(s.distance_m) for s in self.segments)

    @property
    def rotation_rad(self) -> float | np.ndarray:
        """Total signed believed heading change (rad)."""
        return sum(s.angle_rad for s in self.segments)

    @property
    def direction_label(self) -> str:
        """'ccw' or 'cw' by the sign of the total believed rotation; 'fwd' for none."""
        rot = (
            float(np.max(self.rotation_rad))
            if np.ndim(self.rotation_rad)
            else float(self.rotation_rad)
        )
        return "ccw" if rot > 1e-12 else "cw" if rot < -1e-12 else "fwd"

    def mean_wheel_travel_m(self, wheelbase_m: float) -> float:
        """Mean wheel travel (m) of one drive: the sum over segments of
        (|d + psi b/2| + |d - psi b/2|) / 2, so spot turns count (|psi| b / 2)."""
        total = 0.0
        for s in self.segments:
            half = 0.5 * abs(float(s.angle_rad)) * wheelbase_m
            d = abs(float(s.distance_m))
            total += 0.5 * (abs(d + half) + abs(d - half))
        return float(total)

    def footprint_m(self, samples_per_segment: int = 32) -> float:
        """Largest distance (m) of the commanded path from its start (floor space it needs)."""
        pose = np.zeros(3)
        far = 0.0
        f = np.linspace(0.0, 1.0, samples_per_segment + 1)[1:]
        for s in self.segments:
            p = compose(pose, s.distance_m * f, s.angle_rad * f)  # every sample at once
            far = max(far, float(np.hypot(p[:, 0], p[:, 1]).max()))
            pose = compose(pose, s.distance_m, s.angle_rad)
        return far


# Largest N of a regular N-gon: beyond it the track is a circle and the work grows without
# purpose (2 N segments per run).
MAX_POLYGON_SIDES = 1000


def polygon(sides: int, side_m: float | np.ndarray, direction: str) -> Track:
    """Regular N-gon: N times (straight ``side_m``, spot turn of 2 pi / N), left turns for 'ccw',
    right turns for 'cw'. UMBmark is ``polygon(4, 4.0, ...)``. ``side_m`` may be an array."""
    if not isinstance(sides, (int, np.integer)) or sides < 3:
        raise ModelError(f"a polygon needs an integer number of sides >= 3, got {sides!r}")
    if sides > MAX_POLYGON_SIDES:
        raise ModelError(
            f"a polygon of {sides} sides is too many (at most {MAX_POLYGON_SIDES}; "
            "for a circle use a circle track)"
        )
    check_positive("side length", side_m)
    turn = direction_sign(direction) * 2.0 * math.pi / sides
    segs: list[Segment] = []
    for _ in range(sides):
        segs += [straight(side_m), spot_turn(turn)]
    return Track(f"{sides}-gon {np.max(side_m):g} m {direction.lower()}", tuple(segs))


def straight_line(distance_m: float) -> Track:
    """A single straight run of ``distance_m`` (m)."""
    check_positive("distance", distance_m)
    return Track(f"straight {distance_m:g} m", (straight(distance_m),))


def out_and_back(distance_m: float) -> Track:
    """Forward ``distance_m`` then backward ``distance_m`` without turning (systematic curvature
    cancels: the robot retraces its arc)."""
    check_positive("distance", distance_m)
    return Track(f"out-and-back {distance_m:g} m", (straight(distance_m), straight(-distance_m)))


def circle(radius_m: float, direction: str, turns: float = 1.0) -> Track:
    """Forward circle(s) of axle-centre radius ``radius_m`` (m), ``turns`` full turns."""
    check_positive("circle radius", radius_m)
    check_positive("turns", turns)
    angle = direction_sign(direction) * 2.0 * math.pi * turns
    return Track(f"circle r={radius_m:g} m {direction.lower()}", (arc(radius_m, angle),))
