"""What the fleet keeps of one bag's calibration: a typed, versioned record
(:class:`CalibrationRecord`), written by the ingest and read back into the same type by every
reader (drift, status, export, dashboard), as evo's result files and rosbags' metadata are.

A record is stored as the JSON of :meth:`CalibrationRecord.as_dict`, which carries
``record_version`` (:data:`RECORD_VERSION`). :meth:`CalibrationRecord.from_dict` reads that
version and only it; an older one goes through the upgrades of :data:`UPGRADES` first (one
function per version), a newer one is one clear error (:class:`RecordError`), and so is a key
that is missing or of the wrong type: a record reads whole or not at all, never with a part
silently left out.

Version 0 is what the fleet stored up to schema 2 (``calibrations.result_json``): the whole
``odocal fit BAG --method auto --json`` of the time, wrapped as ``{"record_version": 0,
"odocal_version": ..., "fit": {...}}``. Its upgrade (:func:`upgrade_fit_json`) reads the keys
every such row has had since the fleet began, and infers what older rows did not say: a
parameter without a ``status`` (stored before the route answers had one) is 'estimated' when
it has a positive finite standard error and 'held' otherwise (what the drift detector took from
it then); a result without ``answer_model`` has no model (``None``); a gyro answer without
``heading_ratio`` has no ratio.

The record lives in ``io``: it is the row format of the fleet database (versioned, read back,
migrated), read by ``io.fleet_db`` and ``io.fleet_html`` and by the app above; nothing below io
needs it (the detector, :mod:`odocal.calibration.drift`, takes arrays).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass
from typing import Any

from ..calibration.route_answer import KEYS, ROUTE_NAMES, ParameterEstimate, RouteName
from ..core.model import WheelGeometry
from ..errors import InputError, ModelError

__all__ = [
    "RECORD_VERSION",
    "RecordError",
    "StoredOffset",
    "StoredCovariance",
    "CalibrationRecord",
    "UPGRADES",
    "upgrade_fit_json",
    "COVARIANCE_KEYS",
]

#: The version of :meth:`CalibrationRecord.as_dict` this odocal writes and reads.
RECORD_VERSION = 1

#: What export needs to rebuild the covariances for diff_drive_controller (the wheel noise and
#: the motion they are stated for), in :class:`~odocal.core.covariance.OdometryCovariance`'s names.
COVARIANCE_KEYS = ("k_r_m", "k_l_m", "speed_m_s", "distance_m", "window_s")

_STATUSES = ("estimated", "tied", "held")


class RecordError(InputError):
    """A stored calibration record that cannot be read (a newer version, a key missing or of
    the wrong type)."""


@dataclass(frozen=True)
class StoredOffset:
    """One clock offset a route used.

    Attributes
    ----------
    source : str
        The clock's source (and the part of the log it belongs to): 'slam', 'truth (DATASET)'.
    offset_s : float
        The offset found (s).
    std_error_s : float or None
    applied : bool
        Whether the routes used it (an offset within 2 standard errors of 0 is not applied).
    """

    source: str
    offset_s: float
    std_error_s: float | None
    applied: bool

    @property
    def applied_s(self) -> float:
        """The offset the routes used (s): :attr:`offset_s` when applied, else 0."""
        return self.offset_s if self.applied else 0.0


@dataclass(frozen=True)
class StoredCovariance:
    """The wheel noise of the answer route and the motion the covariances are stated for: what
    ``odocal fleet export`` needs to write the pose and twist covariances
    (:func:`~odocal.core.covariance.odometry_covariance`)."""

    k_r_m: float
    k_l_m: float
    speed_m_s: float
    distance_m: float
    window_s: float


@dataclass(frozen=True)
class CalibrationRecord:
    """One bag's calibration as the fleet keeps it (module docstring).

    Attributes
    ----------
    odocal_version : str
        The odocal that calibrated the bag.
    route : {'trajectory', 'slam', 'scan', 'gyro'} or None
        The route whose answer this is; None when no route could calibrate the bag.
    model : str or None
        'full', 'equal-diameters', 'scale' or 'heading-ratio'; None without an answer, or for a
        row stored before odocal recorded it.
    parameters : tuple of 3 ParameterEstimate, or None
        (D_R, D_L, b) in :data:`~odocal.calibration.route_answer.KEYS` order, each with its
        value, standard error (None when held) and status ('estimated', 'tied', 'held').
    heading_ratio, heading_ratio_std_error : float or None
        What a ratio-only route (the gyro) measured: gyro over odometry heading; its diameters
        are then held and its wheelbase is the robot file's divided by it.
    enough : bool
        The verdict: trustworthy.
    reasons : tuple of str
        Why not (empty when trustworthy).
    time_offsets : tuple of StoredOffset
    covariance : StoredCovariance or None
    nominal : WheelGeometry
        The nominal geometry the bag was calibrated against.
    """

    odocal_version: str
    route: RouteName | None
    model: str | None
    parameters: tuple[ParameterEstimate, ParameterEstimate, ParameterEstimate] | None
    heading_ratio: float | None
    heading_ratio_std_error: float | None
    enough: bool
    reasons: tuple[str, ...]
    time_offsets: tuple[StoredOffset, ...]
    covariance: StoredCovariance | None
    nominal: WheelGeometry

    def __post_init__(self) -> None:
        if self.route is not None and self.route not in ROUTE_NAMES:
            raise RecordError(f"route {self.route!r} is none of {', '.join(ROUTE_NAMES)}")
        if self.parameters is not None:
            names = tuple(p.name for p in self.parameters)
            if names != KEYS:
                raise RecordError(f"parameters {names} are not {KEYS}")
            for p in self.parameters:
                if p.status not in _STATUSES:
                    raise RecordError(f"{p.name}: status {p.status!r} is none of {_STATUSES}")
                if p.status == "held" and p.std_error is not None:
                    raise RecordError(f"{p.name} is held: it has no standard error")
            if self.heading_ratio is not None and any(
                p.status != "held" for p in self.parameters[:2]
            ):
                raise RecordError("a ratio-only answer holds the wheel diameters")
        if self.enough and self.parameters is None:
            raise RecordError("a trustworthy verdict without parameters")

    @property
    def ratio_only(self) -> bool:
        """The answer is a heading ratio (the gyro): it sees no diameter and not the scale."""
        return self.heading_ratio is not None or self.model == "heading-ratio"

    def parameter(self, key: str) -> ParameterEstimate | None:
        """The answer's parameter ``key`` (one of KEYS), or None without an answer."""
        if self.parameters is None:
            return None
        return self.parameters[KEYS.index(key)]

    def measurement(self, key: str) -> tuple[float, float] | None:
        """(value, standard error) of parameter ``key`` as the drift detector may use it: from a
        trustworthy answer that ESTIMATED it (not tied to the other wheel, not held) with a
        positive finite standard error; never a diameter of a ratio-only answer. None
        otherwise."""
        p = self.parameter(key)
        if not self.enough or p is None or p.status != "estimated":
            return None
        if self.ratio_only and key != "wheelbase_m":
            return None
        se = p.std_error
        if se is None or not (math.isfinite(se) and se > 0) or not math.isfinite(p.value):
            return None
        return p.value, se

    def as_dict(self) -> dict[str, Any]:
        """The stored form, with ``record_version`` (:data:`RECORD_VERSION`)."""
        return {
            "record_version": RECORD_VERSION,
            "odocal_version": self.odocal_version,
            "route": self.route,
            "model": self.model,
            "parameters": None
            if self.parameters is None
            else [
                {"name": p.name, "value": p.value, "std_error": p.std_error, "status": p.status}
                for p in self.parameters
            ],
            "heading_ratio": self.heading_ratio,
            "heading_ratio_std_error": self.heading_ratio_std_error,
            "enough": self.enough,
            "reasons": list(self.reasons),
            "time_offsets": [
                {
                    "source": o.source,
                    "offset_s": o.offset_s,
                    "std_error_s": o.std_error_s,
                    "applied": o.applied,
                }
                for o in self.time_offsets
            ],
            "covariance": None
            if self.covariance is None
            else {k: getattr(self.covariance, k) for k in COVARIANCE_KEYS},
            "nominal": self.nominal.as_dict(),
        }

    @classmethod
    def from_dict(cls, d: Mapping[str, Any]) -> CalibrationRecord:
        """The record of a stored dict (:meth:`as_dict`), through :data:`UPGRADES` when it is of
        an older version; :class:`RecordError` for a newer version or a dict that is not one."""
        r = _Reader(d, "record")
        version = r.integer("record_version")
        if version > RECORD_VERSION:
            raise RecordError(
                f"record version {version} was written by a newer odocal (this one reads up to "
                f"{RECORD_VERSION}): upgrade odocal to read it"
            )
        if version < 0:
            raise RecordError(f"record version {version} is no version")
        data: Mapping[str, Any] = d
        for v in range(version, RECORD_VERSION):
            data = UPGRADES[v](data)
        return _read_current(_Reader(data, "record"))


class _Reader:
    """Typed access to one level of a stored dict: every key required, every type checked;
    an error names the path of the key ('record.parameters[2].std_error')."""

    def __init__(self, d: Any, where: str) -> None:
        if not isinstance(d, Mapping):
            raise RecordError(f"{where} is {type(d).__name__}, not an object")
        self.d, self.where = d, where

    def _get(self, key: str) -> Any:
        if key not in self.d:
            raise RecordError(f"{self.where} has no '{key}'")
        return self.d[key]

    def _bad(self, key: str, what: str) -> RecordError:
        return RecordError(f"{self.where}.{key} is {self.d[key]!r}, not {what}")

    def has(self, key: str) -> bool:
        return key in self.d

    def raw(self, key: str) -> Any:
        return self._get(key)

    def integer(self, key: str) -> int:
        v = self._get(key)
        if isinstance(v, bool) or not isinstance(v, int):
            raise self._bad(key, "an integer")
        return v

    def number(self, key: str) -> float:
        v = self._get(key)
        if isinstance(v, bool) or not isinstance(v, int | float):
            raise self._bad(key, "a number")
        return float(v)

    def number_or_none(self, key: str) -> float | None:
        return None if self._get(key) is None else self.number(key)

    def boolean(self, key: str) -> bool:
        v = self._get(key)
        if not isinstance(v, bool):
            raise self._bad(key, "true or false")
        return v

    def text(self, key: str) -> str:
        v = self._get(key)
        if not isinstance(v, str):
            raise self._bad(key, "a string")
        return v

    def text_or_none(self, key: str) -> str | None:
        return None if self._get(key) is None else self.text(key)

    def texts(self, key: str) -> tuple[str, ...]:
        v = self._get(key)
        if not isinstance(v, list) or not all(isinstance(x, str) for x in v):
            raise self._bad(key, "a list of strings")
        return tuple(v)

    def items(self, key: str) -> list[_Reader]:
        v = self._get(key)
        if not isinstance(v, list):
            raise self._bad(key, "a list")
        return [_Reader(x, f"{self.where}.{key}[{i}]") for i, x in enumerate(v)]

    def child(self, key: str) -> _Reader:
        return _Reader(self._get(key), f"{self.where}.{key}")

    def child_or_none(self, key: str) -> _Reader | None:
        return None if self._get(key) is None else self.child(key)


def _nominal(r: _Reader) -> WheelGeometry:
    try:
        return WheelGeometry(*(r.number(k) for k in KEYS))
    except ModelError as exc:
        raise RecordError(f"{r.where}: {exc}") from None


def _route(r: _Reader, key: str) -> RouteName | None:
    name = r.text_or_none(key)
    if name is not None and name not in ROUTE_NAMES:
        raise RecordError(f"{r.where}.{key} {name!r} is none of {', '.join(ROUTE_NAMES)}")
    return name


def _status(r: _Reader, key: str) -> Any:
    s = r.text(key)
    if s not in _STATUSES:
        raise RecordError(f"{r.where}.{key} {s!r} is none of {', '.join(_STATUSES)}")
    return s


def _read_current(r: _Reader) -> CalibrationRecord:
    """A record of version :data:`RECORD_VERSION` (every key required)."""
    if r.integer("record_version") != RECORD_VERSION:
        raise RecordError(f"{r.where} is not of version {RECORD_VERSION}")
    params = None
    if r.raw("parameters") is not None:
        items = r.items("parameters")
        if len(items) != 3:
            raise RecordError(f"{r.where}.parameters has {len(items)} entries, not 3")
        p0, p1, p2 = (
            ParameterEstimate(
                p.text("name"),
                p.number("value"),
                p.number_or_none("std_error"),
                _status(p, "status"),
            )
            for p in items
        )
        params = (p0, p1, p2)
    cov = r.child_or_none("covariance")
    return CalibrationRecord(
        odocal_version=r.text("odocal_version"),
        route=_route(r, "route"),
        model=r.text_or_none("model"),
        parameters=params,
        heading_ratio=r.number_or_none("heading_ratio"),
        heading_ratio_std_error=r.number_or_none("heading_ratio_std_error"),
        enough=r.boolean("enough"),
        reasons=r.texts("reasons"),
        time_offsets=tuple(
            StoredOffset(
                o.text("source"),
                o.number("offset_s"),
                o.number_or_none("std_error_s"),
                o.boolean("applied"),
            )
            for o in r.items("time_offsets")
        ),
        covariance=None
        if cov is None
        else StoredCovariance(*(cov.number(k) for k in COVARIANCE_KEYS)),
        nominal=_nominal(r.child("nominal")),
    )


def _legacy_status(p: _Reader) -> str:
    """A stored parameter's status; rows stored before odocal recorded one: 'estimated' with a
    positive finite standard error, else 'held' (a restricted model reported a held parameter
    with an error of 0, the gyro its diameters with none)."""
    if p.has("status"):
        return str(_status(p, "status"))
    se = p.number_or_none("std_error")
    return "estimated" if se is not None and math.isfinite(se) and se > 0 else "held"


def upgrade_fit_json(d: Mapping[str, Any]) -> dict[str, Any]:
    """Version 0 -> 1: ``{"record_version": 0, "odocal_version": V, "fit": FIT}``, FIT being
    the ``fit --method auto --json`` the fleet stored up to schema 2 (module docstring), as a
    record of version 1. Every key the fleet's readers took from FIT must be there (a renamed
    one is an error naming it, not a bag left out of the drift history)."""
    top = _Reader(d, "record")
    fit = top.child("fit")
    route = _route(fit, "answer_route")
    params = None
    ratio: tuple[float | None, float | None] = (None, None)
    if fit.raw("parameters") is not None:
        ps = fit.child("parameters")
        params = []
        for key in KEYS:
            p = ps.child(key)
            status = _legacy_status(p)
            se = p.number_or_none("std_error")
            if status == "held":
                se = None
            params.append(
                {"name": key, "value": p.number("value"), "std_error": se, "status": status}
            )
        for run in fit.items("routes"):
            if run.text("name") == route and run.has("heading_ratio"):
                h = run.child("heading_ratio")
                ratio = (h.number("value"), h.number_or_none("std_error"))
    verdict = fit.child("verdict")
    cov = fit.child_or_none("covariance")
    return {
        "record_version": 1,
        "odocal_version": top.text("odocal_version"),
        "route": route,
        "model": fit.text_or_none("answer_model") if fit.has("answer_model") else None,
        "parameters": params,
        "heading_ratio": ratio[0],
        "heading_ratio_std_error": ratio[1],
        "enough": verdict.boolean("enough"),
        "reasons": list(verdict.texts("reasons")),
        "time_offsets": [
            {
                "source": o.text("source"),
                "offset_s": o.number("offset_s"),
                "std_error_s": o.number_or_none("stderr_s"),
                "applied": o.boolean("applied"),
            }
            for o in fit.items("time_offsets")
        ],
        "covariance": None if cov is None else {k: cov.number(k) for k in COVARIANCE_KEYS},
        "nominal": _nominal(fit.child("nominal")).as_dict(),
    }


#: The upgrades of older records: ``UPGRADES[v]`` turns a record of version v into one of
#: version v + 1.
UPGRADES: tuple[Callable[[Mapping[str, Any]], dict[str, Any]], ...] = (upgrade_fit_json,)
assert len(UPGRADES) == RECORD_VERSION
