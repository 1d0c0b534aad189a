"""The results of ``odocal fit BAG --method auto`` (:mod:`odocal.app.fit_auto`): each route of
the bag, run or not (:class:`RouteRun`), and the one answer (:class:`AutoFitResult`), with the
JSON contract of ``--json``.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

from ..calibration.cross_check import CrossCheck
from ..calibration.heldout import HeldOut
from ..calibration.interval_noise import IntervalNoise
from ..calibration.route_answer import RouteAnswer, RouteName
from ..calibration.time_offset import TimeOffset
from ..core.covariance import OdometryCovariance
from ..core.model import WheelGeometry
from ..io.bag_survey import RouteOption
from .check import CheckResult
from .text import Presented, Text, check_text, verdict_lines, written_lines

__all__ = ["RouteRun", "AutoFitResult"]


if TYPE_CHECKING:  # (a route's module is imported when the bag allows the route)
    from .fit_gyro import GyroFitResult
    from .fit_relative import RelativeFitResult
    from .fit_runs import FitResult

    #: A route's own result, as the route's module gives it.
    RouteDetail = FitResult | RelativeFitResult | GyroFitResult


@dataclass(frozen=True)
class RouteRun:
    """One route of the bag, run or not, in the one type every route gives.

    Attributes
    ----------
    option : RouteOption
        Whether the bag allows it, and why.
    used : bool
        It ran and gave an answer.
    reason : str
        Why it was used, or why not (the survey's reason, or the error it ended in).
    answer : RouteAnswer or None
        Each parameter with its value, standard error and status (estimated, tied, held).
    detail : FitResult, RelativeFitResult, GyroFitResult or None
        The route's own result.
    time_offsets : tuple of TimeOffset
        The clock offsets the route used, one per source (and data set).
    heldout : HeldOut or None
        Its held-out check.
    doubts : tuple of str
        What speaks against its answer (no held-out check, a check no model passed, a timing
        that is not a constant offset, parts that disagree, a result 25 % from nominal, a
        ratio with no scale).
    warnings : tuple of str
    noise : IntervalNoise or None
        The route's random error (wheels and truth), from its residuals.
    speed_m_s : float or None
        The robot's cruise speed in the route's intervals (SLAM).
    """

    option: RouteOption
    used: bool
    reason: str
    answer: RouteAnswer | None = None
    detail: RouteDetail | None = None
    time_offsets: tuple[TimeOffset, ...] = ()
    heldout: HeldOut | None = None
    doubts: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()
    noise: IntervalNoise | None = None
    speed_m_s: float | None = None

    @property
    def name(self) -> RouteName:
        """The route's name."""
        return self.option.name

    @property
    def geometry(self) -> WheelGeometry | None:
        """The calibrated geometry (None when the route did not run)."""
        return None if self.answer is None else self.answer.geometry

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract's route object, with the route's model and parameters when it
        ran."""
        out: dict[str, Any] = {"name": self.name, "used": self.used, "reason": self.reason}
        a = self.answer
        if a is not None:
            out["model"] = a.model
            out["parameters"] = a.as_dict()
            if a.ratio is not None:
                out["heading_ratio"] = {"value": a.ratio, "std_error": a.ratio_std_error}
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
    log_check : CheckResult or None
        Is this log enough? (:func:`~odocal.app.check.check_bag`: what its motion lets a
        calibration see, not whether the answer is right.)
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
    log_check: CheckResult | None = None

    method = "auto"

    @property
    def enough(self) -> bool:
        """A trustworthy answer: a route ran and nothing below speaks against it."""
        return self.answer is not None and not self.reasons

    @property
    def time_offsets(self) -> tuple[TimeOffset, ...]:
        """Every clock offset the routes used (each source and part once, the first route's)."""
        seen: dict[str, TimeOffset] = {}
        for r in self.routes:
            for o in r.time_offsets:
                seen.setdefault(o.label, o)
        return tuple(seen.values())

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> the clock offset applied (s), the first of each source."""
        out: dict[str, float] = {}
        for o in self.time_offsets:
            out.setdefault(o.source, o.applied_s)
        return out

    @property
    def heldout(self) -> HeldOut | None:
        """The answer route's held-out check."""
        return None if self.answer is None else self.answer.heldout

    def text(self) -> str:
        """The text ``odocal fit`` prints for the one answer for a bag."""
        return auto_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract of ``odocal fit BAG --method auto --json``."""
        a = self.answer
        h = self.heldout
        params = None if a is None or a.answer is None else a.answer.as_dict()
        return {
            "method": "auto",
            "bag": str(self.bag),
            "routes": [r.as_dict() for r in self.routes],
            "answer_route": None if a is None else a.name,
            "answer_model": None if a is None or a.answer is None else a.answer.model,
            "parameters": params,
            "nominal": self.nominal.as_dict(),
            "time_offsets_s": self.time_offsets_s,
            "time_offsets": [o.as_dict() for o in self.time_offsets],
            "heldout": None if h is None else h.as_dict(),
            "cross_checks": [c.as_dict() for c in self.cross_checks],
            "noise": None if self.noise is None else self.noise.as_dict(),
            "covariance": None if self.covariance is None else self.covariance.as_dict(),
            "log_check": None if self.log_check is None else self.log_check.as_dict(),
            "verdict": {
                "enough": self.enough,
                "reasons": list(self.reasons),
                "written_despite_reasons": bool(self.written and self.reasons),
            },
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }


def _model_words(answer: RouteAnswer) -> str:
    """The model a route settled on, and what it held."""
    if answer.model == "heading-ratio":
        return "heading ratio: the diameters held"
    if answer.model == "full":
        return "full model"
    held = ", ".join(answer.held)
    tied = "the diameters tied to one scale" if answer.model != "full" else ""
    what = "; ".join(x for x in (tied, f"{held} held" if held else "") if x)
    return f"'{answer.model}' model: {what}"


def auto_text(res: AutoFitResult) -> str:
    """The text of the one-command answer: the routes, the parameters, the checks, the
    verdict."""
    out = Text()
    out(f"one answer for {res.bag} (every route it allows, cross-checked)")
    for r in res.routes:
        model = "" if r.answer is None else f" ({_model_words(r.answer)})"
        out(f"  {r.name:10s} {'used' if r.used else 'not used'}{model}: {r.reason}")
    a = res.answer
    if a is not None and a.answer is not None:
        out(f"parameters (the {a.name} route's, {_model_words(a.answer)}):")
        nom = res.nominal.as_dict()
        rows = [("", "nominal", "calibrated", "std. error")]
        for p in a.answer.parameters:
            se = p.std_error
            err = "held" if p.status == "held" else ("-" if se is None else f"{se:.2e}")
            rows.append((p.name, f"{nom[p.name]:.6f}", f"{p.value:.6f}", err))
        out.table(rows)
    for o in res.time_offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.how})")
    if res.heldout is not None:
        out(res.heldout.verdict())
    for c in res.cross_checks:
        word = "agree" if c.agree else "DISAGREE"
        out(f"{c.routes[0]} vs {c.routes[1]} on {c.quantity}: {c.z:+.2f} standard errors ({word})")
    if res.log_check is not None:
        out("Is this log enough? (odocal check)")
        check_text(out, res.log_check, indent="  ")
    if res.covariance is not None:
        cov = res.covariance
        out(f"covariances for diff_drive_controller: pose {list(cov.pose_diagonal)}, twist "
              f"{list(cov.twist_diagonal)} (k_r = k_l = {cov.k_r_m:.3g} m)")  # fmt: skip
    verdict_lines(out, res.enough, res.reasons)
    if not res.enough:
        if not res.written:
            out("nothing written (--force writes the files anyway)")
        else:
            out("written anyway (--force): the files say NOT TO BE TRUSTED, with these reasons")
    written_lines(out, res.written)
    return str(out)
