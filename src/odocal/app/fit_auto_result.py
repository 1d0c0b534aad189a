"""The results of ``odocal fit BAG --method auto`` (:mod:`odocal.app.fit_auto`): each route of
the bag, run or not (:class:`RouteRun`), and the one answer (:class:`AutoFitResult`), with the
JSON contract of ``--json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from ..calibration.cross_check import KEYS, CrossCheck
from ..calibration.heldout import HeldOut
from ..calibration.interval_noise import IntervalNoise
from ..calibration.time_offset import TimeOffset
from ..core.covariance import OdometryCovariance
from ..core.model import WheelGeometry
from ..io.bag_survey import RouteOption
from .fit_gyro import GyroFitResult
from .fit_relative import RelativeFitResult
from .fit_runs import FitResult
from .text import Presented

__all__ = ["RouteRun", "AutoFitResult"]


def _parameters(
    g: WheelGeometry, stderr: tuple[float | None, float | None, float | None]
) -> dict[str, dict[str, float | None]]:
    """The JSON contract's parameters: each with its value and standard error."""
    values = g.as_dict()
    return {k: {"value": values[k], "std_error": se} for k, se in zip(KEYS, stderr, strict=True)}


@dataclass(frozen=True)
class RouteRun:
    """One route of the bag, run or not.

    Attributes
    ----------
    option : RouteOption
        Whether the bag allows it, and why.
    used : bool
        It ran and gave an answer.
    reason : str
        Why it was used, or why not (the survey's reason, or the error it ended in).
    geometry : WheelGeometry or None
    stderr : tuple of (float or None)
        Standard errors of (D_R, D_L, b) (m); None where the route does not estimate one.
    result : object or None
        The route's own result (FitResult, RelativeFitResult, GyroFitResult).
    """

    option: RouteOption
    used: bool
    reason: str
    geometry: WheelGeometry | None = None
    stderr: tuple[float | None, float | None, float | None] = (None, None, None)
    result: Any = None

    @property
    def name(self) -> str:
        """The route's name."""
        return self.option.name

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract's route object, with the route's parameters when it ran."""
        out: dict[str, Any] = {"name": self.name, "used": self.used, "reason": self.reason}
        if self.geometry is not None:
            out["parameters"] = _parameters(self.geometry, self.stderr)
        return out


@dataclass(frozen=True)
class AutoFitResult(Presented):
    """The one answer for a bag (module docstring).

    Attributes
    ----------
    bag : Path
    routes : tuple of RouteRun
    answer : RouteRun or None
        The route whose parameters are the answer.
    nominal : WheelGeometry
    cross_checks : tuple of CrossCheck
    noise : IntervalNoise or None
        The answer route's random error (wheels and truth).
    covariance : OdometryCovariance or None
        The pose and twist covariances for ``diff_drive_controller`` from it.
    reasons : tuple of str
        Why the answer is not to be trusted (empty: it is).
    written : tuple of Path
    warnings : tuple of str
    """

    bag: Path
    routes: tuple[RouteRun, ...]
    answer: RouteRun | None
    nominal: WheelGeometry
    cross_checks: tuple[CrossCheck, ...] = ()
    noise: IntervalNoise | None = None
    covariance: OdometryCovariance | None = None
    reasons: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)

    method = "auto"

    @property
    def enough(self) -> bool:
        """A trustworthy answer: a route ran and nothing below speaks against it."""
        return self.answer is not None and not self.reasons

    @property
    def time_offsets(self) -> tuple[TimeOffset, ...]:
        """Every clock offset the routes found (each source once, the first route's)."""
        seen: dict[str, TimeOffset] = {}
        for r in self.routes:
            res = r.result
            offsets: tuple[TimeOffset, ...] = ()
            if isinstance(res, (FitResult, RelativeFitResult)):
                offsets = res.time_offsets
            elif isinstance(res, GyroFitResult) and res.time_offset is not None:
                offsets = (res.time_offset,)
            for o in offsets:
                key = o.source.split(" ")[0]
                seen.setdefault(key, o)
        return tuple(seen.values())

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> the clock offset applied (s)."""
        return {o.source.split(" ")[0]: o.applied_s for o in self.time_offsets}

    @property
    def heldout(self) -> HeldOut | None:
        """The answer route's held-out check."""
        res = None if self.answer is None else self.answer.result
        return res.heldout if isinstance(res, (FitResult, RelativeFitResult)) else None

    def text(self) -> str:
        """The text ``odocal fit`` prints for the one answer for a bag."""
        from .fit_text import auto_text

        return auto_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract of ``odocal fit BAG --method auto --json``."""
        a = self.answer
        h = self.heldout
        params = None if a is None or a.geometry is None else _parameters(a.geometry, a.stderr)
        return {
            "method": "auto",
            "bag": str(self.bag),
            "routes": [r.as_dict() for r in self.routes],
            "answer_route": None if a is None else a.name,
            "parameters": params,
            "nominal": self.nominal.as_dict(),
            "time_offsets_s": self.time_offsets_s,
            "time_offsets": [o.as_dict() for o in self.time_offsets],
            "heldout": None if h is None else h.as_dict(),
            "cross_checks": [c.as_dict() for c in self.cross_checks],
            "noise": None if self.noise is None else self.noise.as_dict(),
            "covariance": None if self.covariance is None else self.covariance.as_dict(),
            "verdict": {"enough": self.enough, "reasons": list(self.reasons)},
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }
