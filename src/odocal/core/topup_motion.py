"""Simple timed maneuvers (straight, spin, arc) as a synthetic recording: the motion a top-up of
``odocal check`` proposes (docs/check.md, "What to add").

A :class:`Maneuver` is one constant-curvature motion at a constant speed and turn rate for a
duration; :func:`maneuver_track` turns a sequence of them into a :class:`~odocal.core.tracks.Track`
(what :func:`odocal.core.simulate.drive` drives open loop) and :func:`maneuver_recording` into the
noise-free :class:`~odocal.core.recording.Recording` of that drive: the commanded wheel angles
(:func:`~odocal.core.simulate.commanded_wheel_angles`, so the increments are those ``drive``
pairs with true poses), their times at the maneuvers' speeds, and the dead-reckoned poses as
ground truth.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import ModelError
from .model import WheelGeometry
from .odometry import dead_reckon
from .recording import Recording
from .simulate import commanded_wheel_angles
from .tracks import Segment, Track, arc, spot_turn, straight

__all__ = ["Maneuver", "maneuver_track", "maneuver_recording", "MANEUVER_KINDS"]

MANEUVER_KINDS = ("straight", "spin", "arc")


@dataclass(frozen=True)
class Maneuver:
    """One timed motion: ``kind`` 'straight' (at ``speed_m_s``), 'spin' (on the spot at
    ``rate_rad_s``) or 'arc' (forward at ``speed_m_s`` turning at ``rate_rad_s``: radius
    speed / |rate|), for ``duration_s``. ``rate_rad_s`` is signed, CCW (left) positive;
    ``speed_m_s`` is the axle centre's speed (negative: backwards, straight only)."""

    kind: str
    duration_s: float
    speed_m_s: float = 0.0
    rate_rad_s: float = 0.0

    def __post_init__(self) -> None:
        if self.kind not in MANEUVER_KINDS:
            raise ModelError(f"maneuver kind must be one of {', '.join(MANEUVER_KINDS)}")
        if not (math.isfinite(self.duration_s) and self.duration_s > 0):
            raise ModelError(f"maneuver duration must be finite and > 0, got {self.duration_s!r}")
        moving = {"straight": self.speed_m_s, "spin": self.rate_rad_s}.get(
            self.kind, min(abs(self.speed_m_s), abs(self.rate_rad_s))
        )
        if not (math.isfinite(self.speed_m_s) and math.isfinite(self.rate_rad_s) and moving):
            raise ModelError(f"a {self.kind} needs a finite, non-zero speed / turn rate")
        if self.kind == "arc" and self.speed_m_s < 0:
            raise ModelError("an arc is driven forward (speed > 0)")

    @property
    def distance_m(self) -> float:
        """Axle-centre path length (m)."""
        return 0.0 if self.kind == "spin" else abs(self.speed_m_s) * self.duration_s

    @property
    def angle_rad(self) -> float:
        """Signed heading change (rad)."""
        return 0.0 if self.kind == "straight" else self.rate_rad_s * self.duration_s

    @property
    def radius_m(self) -> float | None:
        """Axle-centre radius of an arc (m), else None."""
        return abs(self.speed_m_s / self.rate_rad_s) if self.kind == "arc" else None

    def segment(self) -> Segment:
        """The track segment of this maneuver."""
        if self.kind == "straight":
            return straight(self.speed_m_s * self.duration_s)
        if self.kind == "spin":
            return spot_turn(self.angle_rad)
        return arc(float(self.radius_m or 0.0), self.angle_rad)

    def as_dict(self) -> dict:
        """JSON-ready: kind, direction, duration, speed, turn rate, radius, distance, angle."""
        direction = (
            ("forward" if self.speed_m_s > 0 else "backward")
            if self.kind == "straight"
            else ("ccw" if self.rate_rad_s > 0 else "cw")
        )
        return {
            "kind": self.kind,
            "direction": direction,
            "duration_s": float(self.duration_s),
            "speed_m_s": float(abs(self.speed_m_s)),
            "rate_rad_s": float(abs(self.rate_rad_s)),
            "radius_m": self.radius_m,
            "distance_m": float(self.distance_m),
            "angle_deg": float(math.degrees(abs(self.angle_rad))),
        }


def maneuver_track(maneuvers: Sequence[Maneuver], name: str = "top-up") -> Track:
    """The maneuvers, in order, as one track (one run)."""
    return Track(name, tuple(m.segment() for m in maneuvers))


def maneuver_recording(
    maneuvers: Sequence[Maneuver],
    geometry: WheelGeometry,
    *,
    max_step_m: float = 0.01,
    name: str = "top-up",
) -> tuple[Recording, int]:
    """The noise-free recording of driving ``maneuvers`` as one run with ``geometry``: wheel
    angles commanded in increments of at most ``max_step_m`` of wheel travel, sample times at the
    maneuvers' speeds, ground truth the dead-reckoned path. Also returns the increments per
    segment (``drive(..., steps_per_segment=n)`` pairs true poses with these samples)."""
    if not maneuvers:
        raise ModelError("a top-up needs at least one maneuver")
    track = maneuver_track(maneuvers, name)
    n, angles = commanded_wheel_angles(track, geometry, max_step_m)
    dt = np.repeat([m.duration_s / n for m in maneuvers], n)
    time = np.concatenate([[0.0], np.cumsum(dt)])
    poses = dead_reckon(angles[:, 0], angles[:, 1], geometry)
    rec = Recording(
        name=name,
        time_s=time,
        wheel_angle_right_rad=angles[:, 0],
        wheel_angle_left_rad=angles[:, 1],
        ground_truth=poses,
        ran_with=geometry,
        label=name,
    )
    return rec, n
