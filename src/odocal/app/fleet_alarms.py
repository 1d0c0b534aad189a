"""``odocal fleet alarms`` and ``odocal fleet ack``: the change detector's alarms as the ingest
stored them (the ``alarms`` table), and an operator's acknowledgement of one.

An alarm is **active** while it is younger than :data:`~odocal.app.fleet_status.ACTIVE_S`
(30 days of bag time) before its robot's latest bag and nobody acknowledged it. An acknowledged
alarm stays in the table, in the list and in the robot's history figure; ``status`` and the
dashboard no longer count it as the robot's drift alarm (they list it as acknowledged). The
ingest keeps an acknowledgement as long as the detector still finds that alarm (the same
parameter, raised by the same bag); a new alarm is a new one to acknowledge.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..calibration.route_answer import KEYS
from ..errors import InputError, quote_path
from ..io.fleet_db import AlarmRow, open_db
from .fleet import now_utc
from .fleet_status import ACTIVE_S

__all__ = ["PARAMETER_NAMES", "AlarmsResult", "AckResult", "fleet_alarms", "fleet_ack"]

#: The names a parameter may be given by on the command line: its own, or its short symbol.
PARAMETER_NAMES = {
    **{k: k for k in KEYS},
    "D_R": "wheel_diameter_right_m",
    "D_L": "wheel_diameter_left_m",
    "b": "wheelbase_m",
}


def _active(a: AlarmRow, latest: dict[str, float]) -> bool:
    """Not acknowledged, and younger than ACTIVE_S before the robot's latest bag."""
    if a.acknowledged:
        return False
    last = latest.get(a.robot_id)
    return a.start_s is None or last is None or last - a.start_s <= ACTIVE_S


@dataclass(frozen=True)
class AlarmsResult:
    """Every stored alarm (by robot, bag start, parameter) and which of them are active."""

    db: Path
    alarms: tuple[AlarmRow, ...]
    active: tuple[bool, ...]

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet alarms --json``."""
        return {
            "db": str(self.db),
            "alarms": [
                {
                    "robot_id": a.robot_id,
                    "parameter": a.parameter,
                    "bag": a.bag,
                    "content_hash": a.content_hash,
                    "start_s": a.start_s,
                    "size_m": a.size,
                    "z": a.z,
                    "raised_at": a.raised_at,
                    "acknowledged": a.acknowledged,
                    "acknowledged_at": a.acknowledged_at,
                    "active": active,
                }
                for a, active in zip(self.alarms, self.active, strict=True)
            ],
        }


def fleet_alarms(db_path: str | Path) -> AlarmsResult:
    """Every alarm of the fleet database (module docstring)."""
    with open_db(db_path, write=False) as db:
        rows = tuple(db.alarms())
        latest = db.latest_starts()
    return AlarmsResult(Path(db_path), rows, tuple(_active(a, latest) for a in rows))


@dataclass(frozen=True)
class AckResult:
    """The alarm acknowledged (``already``: it had been, at ``alarm.acknowledged_at``)."""

    alarm: AlarmRow
    already: bool

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet ack --json``."""
        a = self.alarm
        return {
            "robot_id": a.robot_id,
            "parameter": a.parameter,
            "bag": a.bag,
            "content_hash": a.content_hash,
            "raised_at": a.raised_at,
            "acknowledged_at": a.acknowledged_at,
            "already_acknowledged": self.already,
        }


def _parameter(name: str) -> str:
    if name not in PARAMETER_NAMES:
        raise InputError(
            f"no parameter {name!r}: one of {', '.join(PARAMETER_NAMES)}", field="PARAMETER"
        )
    return PARAMETER_NAMES[name]


def _listed(alarms: list[AlarmRow]) -> str:
    return "; ".join(
        f"{quote_path(a.bag or a.content_hash)}"
        + (f" (acknowledged {a.acknowledged_at})" if a.acknowledged else "")
        for a in alarms
    )


def _choose(alarms: list[AlarmRow], bag: str | None, what: str) -> AlarmRow:
    """The alarm of ``bag`` (its path as listed, or the start of its sha256, 8 digits at
    least), or the one alarm not acknowledged yet."""
    if bag is not None:
        found = [
            a
            for a in alarms
            if a.bag == bag or (len(bag) >= 8 and a.content_hash.startswith(bag.lower()))
        ]
        if len(found) != 1:
            how = "no alarm" if not found else f"{len(found)} alarms"
            raise InputError(
                f"{how} of {what} raised by bag {quote_path(bag)} (its alarms: "
                f"{_listed(alarms) or 'none'})"
            )
        return found[0]
    open_ = [a for a in alarms if not a.acknowledged]
    if len(open_) == 1:
        return open_[0]
    if not open_:
        raise InputError(
            f"no alarm of {what} to acknowledge (its alarms: {_listed(alarms) or 'none'})"
        )
    raise InputError(
        f"{len(open_)} alarms of {what} not acknowledged: name the BAG that raised the one to "
        f"acknowledge ({_listed(open_)})"
    )


def fleet_ack(
    db_path: str | Path, robot_id: str, parameter: str, bag: str | None = None
) -> AckResult:
    """Acknowledge one alarm of ``robot_id``'s ``parameter`` (a name of
    :data:`PARAMETER_NAMES`): the one raised by ``bag`` (its path as ``fleet alarms`` lists
    it, or the start of its sha256), or without ``bag`` its one alarm not acknowledged yet.
    The alarm is kept; it no longer counts as active."""
    key = _parameter(parameter)
    with open_db(db_path, write=True, create=False) as db:
        robots = [r for r, _ in db.robots()]
        if robot_id not in robots:
            raise InputError(
                f"no robot {quote_path(robot_id)} in the fleet database (robots: "
                f"{', '.join(map(quote_path, robots)) or 'none'})",
                db_path,
            )
        what = f"{key} on robot {quote_path(robot_id)}"
        alarm = _choose([a for a in db.alarms(robot_id) if a.parameter == key], bag, what)
        if alarm.acknowledged:
            return AckResult(alarm, True)
        db.acknowledge(robot_id, key, alarm.content_hash, now_utc())
        (now,) = [a for a in db.alarms(robot_id) if (a.parameter, a.content_hash) ==
                  (key, alarm.content_hash)]  # fmt: skip
    return AckResult(now, False)
