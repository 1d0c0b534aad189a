"""``odocal fleet status`` and ``odocal fleet export``: each robot's history through the change
detector (:mod:`odocal.calibration.drift`), its current parameters and its alarms.

The history of a parameter is the robot's trustworthy bags (the bag route's verdict
``enough``) whose answer ESTIMATED it with a standard error, in the order of the bags' start
times, each read from the bag's calibration record
(:meth:`~odocal.io.fleet_record.CalibrationRecord.measurement`): a parameter the route held (at
nominal, or at the value the robot ran with) is no measurement, nor are diameters tied to one
common scale, nor the diameters of a ratio-only answer (the gyro).
The **current parameters** are the filtered levels after the last bag (since the last change:
a step restarts the filter), with their standard errors. An alarm is **active** while it is
younger than :data:`ACTIVE_S` (30 days) of bag time before the robot's latest bag: the
``drift_alarm`` of ``status``, unless an operator acknowledged it (``odocal fleet ack``: kept in
the alarms table and the history, no longer active). A robot without current parameters (no
trustworthy bag estimated any: all its bags failed, or were calibrated but not to be trusted,
or it has none yet) has **no trusted calibration**: a problem, listed after the drift alarms
and before the robots that are well.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.cross_check import KEYS
from ..calibration.drift import DriftTrack, track_parameter
from ..calibration.result import ABSURD_FRACTION, CalibrationError, far_from_nominal
from ..core.covariance import odometry_covariance
from ..core.model import WheelGeometry
from ..errors import InputError, quote_path
from ..io.fleet_db import BagRow, FleetDb, open_db
from ..io.outputs import OutputPlan
from ..io.ros2_export import DEFAULT_CONTROLLER, ros2_multipliers, ros2_params_yaml

__all__ = [
    "ParameterHistory",
    "RobotDrift",
    "RobotStatus",
    "FleetStatus",
    "robot_drift",
    "fleet_status",
    "fleet_export",
    "ExportResult",
    "ACTIVE_S",
    "robot_status",
]

#: how long an alarm stays active (s of bag time before the robot's latest bag): 30 days
ACTIVE_S = 30 * 86400.0


@dataclass(frozen=True)
class ParameterHistory:
    """One parameter of one robot: the bags (indices into the robot's history) that estimate
    it, their values and standard errors, and the detector's track."""

    key: str
    bags: tuple[int, ...]
    values: np.ndarray
    std_errors: np.ndarray
    track: DriftTrack | None


@dataclass(frozen=True)
class RobotDrift:
    """A robot's history through the detector."""

    history: tuple[BagRow, ...]
    parameters: tuple[ParameterHistory, ...]

    def alarm_rows(self) -> list[tuple[str, str, float | None, float, float]]:
        """(parameter, content_hash, start_s, size, z) of every alarm, for the database."""
        out = []
        for p in self.parameters:
            for a in () if p.track is None else p.track.alarms:
                bag = self.history[p.bags[a.index]]
                out.append((p.key, bag.content_hash, bag.start_s, a.size, a.z))
        return out

    def current(self) -> dict[str, dict[str, float]] | None:
        """Each estimated parameter's filtered level and its standard error after the last bag
        (a parameter no trustworthy bag estimated is absent: the gyro route, for one, holds the
        diameters at nominal), or None when none was estimated."""
        out = {}
        for p in self.parameters:
            if p.track is not None:
                out[p.key] = {
                    "value": float(p.track.level[-1]),
                    "std_error": float(p.track.level_se[-1]),
                }
        return out or None

    def active_alarms(self, acknowledged: Collection[tuple[str, str]] = ()) -> list[dict[str, Any]]:
        """The alarms younger than :data:`ACTIVE_S` before the latest bag, largest first, but
        those ``acknowledged`` ((parameter, content_hash of the bag that raised it) each)."""
        return [a for key, a in self._recent_alarms() if key not in acknowledged]

    def acknowledged_alarms(
        self, acknowledged: Collection[tuple[str, str]]
    ) -> list[dict[str, Any]]:
        """The alarms that would be active but are ``acknowledged``, largest first."""
        return [a for key, a in self._recent_alarms() if key in acknowledged]

    def _recent_alarms(self) -> list[tuple[tuple[str, str], dict[str, Any]]]:
        """((parameter, content_hash), alarm) of the alarms younger than :data:`ACTIVE_S`
        before the latest bag, largest first."""
        latest = max((b.start_s for b in self.history if b.start_s is not None), default=None)
        out: list[tuple[tuple[str, str], dict[str, Any]]] = []
        for p in self.parameters:
            if p.track is None:
                continue
            for a in p.track.alarms:
                bag = self.history[p.bags[a.index]]
                t = bag.start_s
                if latest is not None and t is not None and latest - t > ACTIVE_S:
                    continue
                before = float(p.track.level[a.index] - a.size)
                out.append(
                    (
                        (p.key, bag.content_hash),
                        {
                            "parameter": p.key,
                            "size_m": a.size,
                            "size_percent": 100.0 * a.size / before,
                            "z": a.z,
                            "bag": bag.path,
                            "change_bag": self.history[p.bags[a.start_index]].path,
                            "bags_since": len(self.history) - 1 - p.bags[a.index],
                        },
                    )
                )
        return sorted(out, key=lambda ka: -abs(ka[1]["z"]))


def robot_drift(history: Sequence[BagRow]) -> RobotDrift:
    """The detector on each parameter of a robot's history (module docstring)."""
    params = []
    for key in KEYS:
        idx, vals, ses = [], [], []
        for i, b in enumerate(history):
            m = None if b.status != "done" or b.record is None else b.record.measurement(key)
            if m is not None:
                idx.append(i)
                vals.append(m[0])
                ses.append(m[1])
        y, s = np.asarray(vals, float), np.asarray(ses, float)
        track = track_parameter(y, s) if len(y) else None
        params.append(ParameterHistory(key, tuple(idx), y, s, track))
    return RobotDrift(tuple(history), tuple(params))


@dataclass(frozen=True)
class RobotStatus:
    """One row of ``odocal fleet status``."""

    robot_id: str
    bags: int
    bags_done: int
    bags_failed: int
    last_calibrated: str | None
    parameters: dict[str, dict[str, float]] | None
    nominal: dict[str, float]
    alarms: tuple[dict[str, Any], ...]
    bags_untrusted: int = 0
    acknowledged: tuple[dict[str, Any], ...] = ()

    @property
    def trusted(self) -> bool:
        """Has a trusted calibration: current parameters (module docstring)."""
        return self.parameters is not None

    @property
    def drift_alarm(self) -> bool:
        """An active alarm (module docstring)."""
        return bool(self.alarms)

    @property
    def drift_z(self) -> float:
        """The largest active alarm's size in standard errors (0 without one)."""
        return max((abs(a["z"]) for a in self.alarms), default=0.0)

    @property
    def sort_key(self) -> tuple[float, bool, str]:
        """The rows' order: the largest drift first, then the robots without a trusted
        calibration, then the rest; by id within each."""
        return (-self.drift_z, self.trusted, self.robot_id)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of one robot in ``odocal fleet status --json``."""
        top = self.alarms[0] if self.alarms else None
        return {
            "robot_id": self.robot_id,
            "bags": self.bags,
            "bags_done": self.bags_done,
            "bags_failed": self.bags_failed,
            "bags_untrusted": self.bags_untrusted,
            "last_calibrated": self.last_calibrated,
            "parameters": self.parameters,
            "trusted_calibration": self.trusted,
            "nominal": self.nominal,
            "drift_alarm": self.drift_alarm,
            "drift": None if top is None else dict(top),
            "alarms": [dict(a) for a in self.alarms],
            "alarms_acknowledged": [dict(a) for a in self.acknowledged],
        }


@dataclass(frozen=True)
class FleetStatus:
    """``odocal fleet status``: one row per robot, the largest drift first, then the robots
    without a trusted calibration."""

    db: Path
    robots: tuple[RobotStatus, ...]

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet status --json``."""
        return {"db": str(self.db), "robots": [r.as_dict() for r in self.robots]}


def robot_status(
    robot_id: str,
    nominal: dict,
    history: Sequence[BagRow],
    acknowledged: Collection[tuple[str, str]] = (),
) -> RobotStatus:
    """One robot's row of the status (its history through the detector); ``acknowledged``:
    (parameter, content_hash) of its alarms an operator acknowledged (not active)."""
    drift = robot_drift(history)
    done = [b for b in history if b.status == "done"]
    return RobotStatus(
        robot_id,
        len(history),
        len(done),
        sum(b.status != "done" for b in history),
        max((b.ingested_at for b in done), default=None),
        drift.current(),
        nominal,
        tuple(drift.active_alarms(acknowledged)),
        sum(not b.enough for b in done),
        tuple(drift.acknowledged_alarms(acknowledged)),
    )


def acknowledged_alarms(db: FleetDb) -> dict[str, set[tuple[str, str]]]:
    """Robot id -> (parameter, content_hash) of each alarm an operator acknowledged."""
    out: dict[str, set[tuple[str, str]]] = {}
    for a in db.alarms():
        if a.acknowledged:
            out.setdefault(a.robot_id, set()).add((a.parameter, a.content_hash))
    return out


def fleet_status(db_path: str | Path) -> FleetStatus:
    """Every robot's row (module docstring), in :attr:`RobotStatus.sort_key` order: the
    largest drift first, then the robots without a trusted calibration, then by id."""
    with open_db(db_path, write=False) as db:
        acks = acknowledged_alarms(db)
        rows = [robot_status(r, nom, db.history(r), acks.get(r, ())) for r, nom in db.robots()]
    return FleetStatus(Path(db_path), tuple(sorted(rows, key=lambda r: r.sort_key)))


def _quoted(robot_id: str) -> str:
    """A robot id in a message: in quotes, with escapes when it holds an odd character."""
    shown = quote_path(robot_id)
    return shown if shown != robot_id else f"'{robot_id}'"


@dataclass(frozen=True)
class ExportResult:
    """``odocal fleet export``: the robot's current geometry, written for diff_drive_controller."""

    robot_id: str
    geometry: WheelGeometry
    bags: int
    written: tuple[Path, ...]

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet export --json``."""
        return {
            "robot_id": self.robot_id,
            "parameters": self.geometry.as_dict(),
            "bags": self.bags,
            "written": [str(p) for p in self.written],
        }


def fleet_export(
    db_path: str | Path,
    robot_id: str,
    ros2: str | Path,
    *,
    controller_name: str = DEFAULT_CONTROLLER,
) -> ExportResult:
    """Write the robot's current parameters (the filtered levels) as ``fit --ros2`` does, with
    the covariances of its latest trustworthy bag."""
    plan = OutputPlan([Path(db_path)])
    plan.file(ros2, "--ros2")
    with open_db(db_path, write=False) as db:
        robots = dict(db.robots())
        if robot_id not in robots:
            known = ", ".join(robots) or "none"
            raise InputError(
                f"no robot {_quoted(robot_id)} in the fleet database (robots: {known})", db_path
            )
        history = db.history(robot_id)
    drift = robot_drift(history)
    current = drift.current()
    if current is None:
        raise InputError(
            f"robot {_quoted(robot_id)} has no trustworthy calibration yet (bags: {len(history)})",
            db_path,
        )
    nominal = WheelGeometry(*(robots[robot_id][k] for k in KEYS))
    # a parameter no bag estimated stays at its nominal value (said in the file)
    g = WheelGeometry(
        *(float(current[k]["value"]) if k in current else robots[robot_id][k] for k in KEYS)
    )
    latest = [b.record for b in history if b.status == "done" and b.record and b.record.enough]
    skid = bool(latest) and latest[-1].model == "skid-steer"
    _refuse_absurd(robot_id, g, nominal, skid)
    kept = [k for k in KEYS if k not in current]
    cov = None
    c = latest[-1].covariance if latest else None
    if c is not None:
        cov = odometry_covariance(
            c.k_r_m,
            c.k_l_m,
            float(g.wheelbase_m),
            speed_m_s=c.speed_m_s,
            distance_m=c.distance_m,
            window_s=c.window_s,
        )
    n = max(len(p.bags) for p in drift.parameters)
    # the id quoted with escapes when it holds a line break (a YAML key of its own otherwise)
    method = f"odocal fleet: robot {quote_path(robot_id)}, filtered level of {n} bags" + (
        f"; nominal (never estimated): {', '.join(kept)}" if kept else ""
    )
    text = ros2_params_yaml(g, nominal, controller_name, cov, method=method)
    return ExportResult(robot_id, g, n, tuple(plan.commit({Path(ros2): text})))


#: What a filtered level far from the robot's nominal geometry usually means in a fleet.
FLEET_HINT = (
    "has its robot.yaml changed since these bags were calibrated, or were they stored before "
    "a result 25 % from nominal made a bag untrustworthy?"
)


def _refuse_absurd(robot_id: str, g: WheelGeometry, nominal: WheelGeometry, skid: bool) -> None:
    """The 25 % rule on what export writes: no parameter further than
    :data:`~odocal.calibration.result.ABSURD_FRACTION` from the robot's nominal geometry, and no
    multiplier of the file further than that from 1 (nothing written otherwise). A skid-steer
    robot's effective track is wider than its wheelbase by design: its
    ``wheel_separation_multiplier`` must lie in
    :data:`~odocal.app.fit_skid.TRACK_MULTIPLIER_RANGE` instead."""
    from .fit_skid import TRACK_MULTIPLIER_RANGE

    values = (g.diameter_right_m, g.diameter_left_m, g.wheelbase_m)
    problems = [
        x
        for x in far_from_nominal(values, nominal, FLEET_HINT)
        if not (skid and x.startswith("wheelbase_m"))
    ]
    lo, hi = TRACK_MULTIPLIER_RANGE
    for k, m in ros2_multipliers(g, nominal).items():
        if skid and k == "wheel_separation_multiplier":
            if not lo <= m <= hi:
                problems.append(f"{k} = {m:.6g} is no skid-steer robot's ({lo:g}-{hi:g})")
        elif abs(m - 1) > ABSURD_FRACTION:
            problems.append(
                f"{k} = {m:.6g} is {100 * (m - 1):+.0f} % from 1: absurd for a calibration"
            )
    if problems:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise CalibrationError(
            f"robot {_quoted(robot_id)}: the filtered level's {problems[0]}{more}; nothing written"
        )
