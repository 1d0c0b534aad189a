"""Do several calibrations of one robot agree? Every pair of answers (e.g. the routes of one bag:
a truth topic, the SLAM pose, scan matching, the gyro) compared on every quantity both estimate,
in combined standard errors.

An answer is ``(name, geometry, stderr)``: the route's name, its (D_R, D_L, b) and their standard
errors (m; None where it does not estimate one). An answer named ``'gyro'`` sees only the
rotation: its wheelbase holds at the diameters it ran with (see :func:`cross_checks`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from ..core.model import WheelGeometry

__all__ = ["KEYS", "MAX_Z", "RouteAnswer", "CrossCheck", "cross_checks"]

#: The parameters, in the JSON contract's names.
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
#: Two routes agree when no shared quantity differs by more than this many combined standard
#: errors.
MAX_Z = 3.0

#: A route's answer: its name, its geometry and the standard errors of (D_R, D_L, b) (m).
RouteAnswer = tuple[str, WheelGeometry, tuple[float | None, float | None, float | None]]


@dataclass(frozen=True)
class CrossCheck:
    """Two routes compared on one quantity: the difference in combined standard errors."""

    routes: tuple[str, str]
    quantity: str
    z: float

    @property
    def agree(self) -> bool:
        """Within :data:`MAX_Z` combined standard errors."""
        return abs(self.z) <= MAX_Z

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"routes": list(self.routes), "quantity": self.quantity, "z": self.z,
                "agree": self.agree}  # fmt: skip


def _values(a: RouteAnswer, b: RouteAnswer, key: str) -> tuple[float, float]:
    """The two answers' values of ``key``; the wheelbase against the gyro's compares turning:
    the other's b at the gyro's diameters."""
    (na, ga, _), (nb, gb, _) = a, b
    va, vb = ga.as_dict()[key], gb.as_dict()[key]
    if key == "wheelbase_m" and "gyro" in (na, nb):
        gy, other = (ga, gb) if na == "gyro" else (gb, ga)
        scaled = other.wheelbase_m * gy.mean_diameter_m / other.mean_diameter_m
        va, vb = (gy.wheelbase_m, scaled) if na == "gyro" else (scaled, gy.wheelbase_m)
    return va, vb


def _pair(a: RouteAnswer, b: RouteAnswer) -> list[CrossCheck]:
    """Two answers compared on every quantity both estimate (a standard error on each side, one
    of them positive)."""
    out = []
    for k, key in enumerate(KEYS):
        sa, sb = a[2][k], b[2][k]
        if sa is None or sb is None or not (sa > 0 or sb > 0):
            continue
        va, vb = _values(a, b, key)
        out.append(CrossCheck((a[0], b[0]), key, float((va - vb) / math.hypot(sa, sb))))
    return out


def cross_checks(answers: Sequence[RouteAnswer]) -> tuple[CrossCheck, ...]:
    """Every pair of ``answers`` (the routes that ran), on every quantity both estimate. The
    gyro's wheelbase takes the diameters as nominal (it sees only the rotation): it is compared
    (at its own diameters, the other route's b scaled by the diameters' ratio) only when no
    other answer measured the diameters, since a left/right difference turns the robot as a
    wheelbase error does and the gyro cannot tell them apart."""
    used = list(answers)
    if any(name != "gyro" for name, _, _ in used):
        used = [a for a in used if a[0] != "gyro"]
    return tuple(x for i, a in enumerate(used) for b in used[i + 1 :] for x in _pair(a, b))
