"""Do several calibrations of one robot agree? Every pair of answers (e.g. the routes of one bag:
a truth topic, the SLAM pose, scan matching, the gyro) compared on every quantity both MEASURED,
in combined standard errors.

An answer is a :class:`~odocal.calibration.route_answer.RouteAnswer`: each of (D_R, D_L, b) with
its value, standard error and status. A held parameter (a restricted model's, the gyro's
diameters) is no measurement and is never compared; tied diameters (one common scale) are
compared through their mean only. The gyro sees only the rotation: its wheelbase holds at the
diameters it ran with (see :func:`cross_checks`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from .route_answer import KEYS, RouteAnswer

__all__ = ["KEYS", "MAX_Z", "MEAN_DIAMETER", "CrossCheck", "cross_checks"]

#: Two routes agree when no shared quantity differs by more than this many combined standard
#: errors.
MAX_Z = 3.0
#: The quantity compared when a route tied the diameters to one scale.
MEAN_DIAMETER = "wheel_diameter_mean_m"


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


def _wheelbases(a: RouteAnswer, b: RouteAnswer) -> tuple[float, float]:
    """The two answers' wheelbases; against the gyro's, turning is compared: the other's b at
    the gyro's diameters."""
    ga, gb = a.geometry, b.geometry
    va, vb = float(ga.wheelbase_m), float(gb.wheelbase_m)
    if "gyro" in (a.route, b.route):
        gy, other = (ga, gb) if a.route == "gyro" else (gb, ga)
        scaled = float(other.wheelbase_m * gy.mean_diameter_m / other.mean_diameter_m)
        own = float(gy.wheelbase_m)
        va, vb = (own, scaled) if a.route == "gyro" else (scaled, own)
    return va, vb


def _z(va: float, vb: float, sa: float | None, sb: float | None) -> float | None:
    """The difference in combined standard errors (None without an error on each side, one of
    them positive)."""
    if sa is None or sb is None or not (sa > 0 or sb > 0):
        return None
    return float((va - vb) / math.hypot(sa, sb))


def _pair(a: RouteAnswer, b: RouteAnswer) -> list[CrossCheck]:
    """Two answers compared on every quantity both measured."""
    names = (a.route, b.route)
    out = []
    pa, pb = a.parameters, b.parameters
    free = all(p.status == "estimated" for p in (pa[0], pa[1], pb[0], pb[1]))
    if free:
        for k in (0, 1):
            z = _z(pa[k].value, pb[k].value, pa[k].std_error, pb[k].std_error)
            if z is not None:
                out.append(CrossCheck(names, KEYS[k], z))
    else:
        ma, mb = a.mean_diameter(), b.mean_diameter()
        if ma is not None and mb is not None:
            z = _z(ma[0], mb[0], ma[1], mb[1])
            if z is not None:
                out.append(CrossCheck(names, MEAN_DIAMETER, z))
    if pa[2].status == "estimated" and pb[2].status == "estimated":
        va, vb = _wheelbases(a, b)
        z = _z(va, vb, pa[2].std_error, pb[2].std_error)
        if z is not None:
            out.append(CrossCheck(names, KEYS[2], z))
    return out


def cross_checks(answers: Sequence[RouteAnswer]) -> tuple[CrossCheck, ...]:
    """Every pair of ``answers`` (the routes that ran), on every quantity both measured. The
    gyro's wheelbase takes the diameters as nominal (it sees only the rotation): it is compared
    (at its own diameters, the other route's b scaled by the diameters' ratio) only when no
    other answer measured the diameters, since a left/right difference turns the robot as a
    wheelbase error does and the gyro cannot tell them apart."""
    used = list(answers)
    if any(a.route != "gyro" for a in used):
        used = [a for a in used if a.route != "gyro"]
    return tuple(x for i, a in enumerate(used) for b in used[i + 1 :] for x in _pair(a, b))
