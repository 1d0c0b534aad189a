"""The text of ``odocal design`` (``DesignRun.text()``, so ``str(result)``): the candidates,
the recommendation, its rule and its stability."""

from __future__ import annotations

import math
from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

from ..design.sweep import DesignResult
from .text import Text, written_lines

if TYPE_CHECKING:
    from ..design.recommend import Recommendation
    from ..design.result import Candidate
    from ..design.robust import RangeDesign
    from .measured import MeasuredRobot

__all__ = ["design_text", "design_report", "range_design_report"]


def _print_measured(out: Text, measured: MeasuredRobot) -> None:
    m = measured.robot
    out(
        f"Robot measured from {len(measured.fit.runs)} run(s): E_b {m.systematic.E_b:.6f}, "
        f"E_d {m.systematic.E_d:.6f} (relative to nominal), k_r + k_l "
        f"{m.nonsystematic.k_sum_m:.3g} m, instrument {m.measurement.sigma_xy_m * 1000:.3g} mm "
        f"/ {math.degrees(m.measurement.sigma_theta_rad):.3g} deg "
        f"({measured.measurement_source})"
    )


def _f(v: float | None, fmt: str) -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, fmt)


def design_text(
    result: DesignResult | RangeDesign,
    robot: str,
    *,
    seed: int | None = None,
    measured: MeasuredRobot | None = None,
    notes: Sequence[str] = (),
    written: Sequence[Path] = (),
) -> str:
    """The text of ``odocal design`` (``DesignRun.text()``): what was measured (``measured``)
    and assumed (``notes``), the report of the design (:func:`design_report` or
    :func:`range_design_report`) and the files ``written``."""
    out = Text()
    if measured is not None:
        _print_measured(out, measured)
    for note in notes:
        out(f"Note: {note}")
    if isinstance(result, DesignResult):
        design_report(out, result, robot, seed)
    else:
        range_design_report(out, result, robot)
    written_lines(out, written)
    return str(out)


def design_report(out: Text, result: DesignResult, robot: str, seed: int | None = None) -> None:
    """The human-readable design report."""
    _print_header(out, result, robot, seed)
    out()
    _print_candidates(out, result)
    out()
    _print_recommendation(out, result)
    _print_stability(out, result)
    _print_alternatives(out, result)
    if result.recommendation.neighbours:
        out()
        _print_neighbours(out, result)


def _print_header(out: Text, result: DesignResult, robot: str, seed: int | None) -> None:
    if result.trials is None:
        how = "first-order analytic (expected values, no trials)"
    else:
        crn = ", common random numbers" if result.paired else ""
        how = f"{result.trials} Monte-Carlo trials per candidate{crn}, seed {seed}"
    out(
        f"Test-track design for {robot}: {result.method} method, "
        f"{result.runs_per_direction} runs per direction, {how}"
    )
    mean_of = "means over the trials" if result.trials is not None else "expected values"
    out(
        f"Validation: {result.validation.label}; uncalibrated error "
        f"{_f(result.uncalibrated.mean_m, '.3f')} m, floor with the true parameters "
        f"{_f(result.floor.mean_m, '.3f')} m ({mean_of})"
    )


_CANDIDATE_COLUMNS = (
    "track",
    "side_m",
    "travel_m",
    "share_%",
    "|beta|_deg",
    "sigma_deg",
    "E_b mean",
    "E_b std",
    "E_d mean",
    "E_d std",
    "error_m",
    "std_m",
    "95%_range_m",
    "residual_m",
)


def _candidate_row(c: Candidate, recommended: bool) -> tuple[str, ...]:
    from ..design.result import shape_name

    lo, hi = c.post_error_ci95_m
    return (
        ("* " if recommended else "  ") + shape_name(c.sides),
        _f(c.side_m, "g"),
        _f(c.travel_m, "g"),
        _f(100 * c.systematic_share, ".1f"),
        _f(math.degrees(c.leg_heading_systematic_rad), ".3f"),
        _f(math.degrees(c.leg_heading_noise_rad), ".3f"),
        _f(c.E_b_mean, ".5f"),
        _f(c.E_b_std, ".5f"),
        _f(c.E_d_mean, ".6f"),
        _f(c.E_d_std, ".6f"),
        _f(c.post_error_mean_m, ".4f"),
        _f(c.post_error_std_m, ".4f"),
        f"{_f(lo, '.3f')}-{_f(hi, '.3f')}",
        _f(c.residual_error_mean_m, ".4f"),
    )


def _print_candidates(out: Text, result: DesignResult) -> None:
    index = result.recommendation.index
    rows: list[tuple[str, ...]] = [_CANDIDATE_COLUMNS]
    rows += [_candidate_row(c, i == index) for i, c in enumerate(result.candidates)]
    out.table(rows)
    out(
        "  share: systematic share of the n-run-mean leg heading error; |beta|, sigma: "
        "systematic and random heading error of one leg;\n"
        "  error: final position error on the validation track after calibration (mean, std, "
        "central 95 % of single calibrations); residual: the same without wheel noise"
    )
    if result.failed_trials:
        out(
            f"  {result.failed_trials} trial(s) gave no calibration (equations undefined) and "
            "are left out"
        )


def _judged(rec: Recommendation) -> str:
    return "error after calibration" if rec.criterion == "error" else "residual error"


def _print_recommendation(out: Text, result: DesignResult) -> None:
    from ..design.result import shape_name

    r, rec = result.recommended, result.recommendation
    out(
        f"Recommended: {shape_name(r.sides)}, side {r.side_m:g} m ({r.travel_m:g} m travel per "
        f"run): error {r.post_error_mean_m:.4f} m after calibration, residual "
        f"{_f(r.residual_error_mean_m, '.4f')} m "
        f"(uncalibrated {result.uncalibrated.mean_m:.4f} m, gain {result.gain_m:.4f} m; floor "
        f"{result.floor.mean_m:.4f} m)"
    )
    test = {
        "exact": "expected values compared directly",
        "paired": f"one-sided paired t-test on common random numbers, alpha {rec.alpha:g}",
        "welch": f"one-sided Welch t-test, alpha {rec.alpha:g}",
    }[rec.test]
    out(
        f"Rule: the smallest track that no larger track beats by more than "
        f"{100 * rec.tolerance:g} % in {_judged(rec)} ({test})."
    )


def _print_stability(out: Text, result: DesignResult) -> None:
    st = result.stability
    if st is not None:
        lo, hi = st.range_m
        picks = ", ".join(f"{p.side_m:g} m {100 * p.share:.0f} %" for p in st.picks[:4])
        if not st.indistinguishable:
            verdict = f"stable: {lo:g} m in at least 90 % of them"
        else:
            verdict = f"{lo:g}-{hi:g} m hold 90 % of them: these sizes are indistinguishable"
        out(
            f"Stability: the rule on {st.resamples} bootstrap resamples of the trials picks "
            f"{picks}; {verdict}."
        )
    elif result.trials is None:
        out(
            "Stability: expected values (no sampling error); the first-order approximation is "
            "checked by Monte Carlo ('odocal design' without --analytic)."
        )


def _print_alternatives(out: Text, result: DesignResult) -> None:
    from ..design.result import shape_name

    other, o = result.other, result.other_recommended
    if other is not None and o is not None:
        what = "residual alone" if other.criterion == "residual" else "error after calibration"
        out(
            f"  judged on the {what} (--criterion {other.criterion}): side {o.side_m:g} m "
            f"({o.travel_m:g} m travel)"
        )
    picks = result.shape_picks
    if len(picks) > 1:
        for c in picks:
            out(f"  best {shape_name(c.sides)}: side {c.side_m:g} m ({c.travel_m:g} m)")


def _print_neighbours(out: Text, result: DesignResult) -> None:
    r, rec, cands = result.recommended, result.recommendation, result.candidates
    tol = f"{100 * rec.tolerance:g} %"
    rows: list[tuple[str, ...]]
    if rec.test == "exact":
        out(f"The recommended {r.side_m:g} m track against its neighbours (expected values):")
        rows = [("track", "vs", "mean difference_m", "ratio", f"better by > {tol}")]
        for comp in rec.neighbours:
            rows.append(
                (
                    f"{cands[comp.other].side_m:g} m",
                    f"{r.side_m:g} m",
                    _f(comp.mean_difference, "+.4f"),
                    _f(result.error_ratio(comp), ".4f"),
                    "yes" if comp.significant else "no",
                )
            )
    else:
        kind = "paired" if rec.test == "paired" else "Welch"
        out(
            f"t-tests of the {_judged(rec)} against the recommended {r.side_m:g} m track ({kind}; "
            "as the paper's Tables 2 and 3): 'any difference' is the two-sided test, "
            f"'better by > {tol}' the rule's one-sided test (H1: the other track's mean < "
            f"{1 - rec.tolerance:g} x this one's)"
        )
        rows = [
            (
                "track",
                "vs",
                "mean difference_m",
                "t (any difference)",
                "df",
                "p (any difference)",
                f"t (better by > {tol})",
                f"p (better by > {tol})",
                f"better by > {tol}",
            )
        ]
        for comp in rec.neighbours:
            assert comp.test is not None and comp.rule is not None  # tests, not exact
            rows.append(
                (
                    f"{cands[comp.other].side_m:g} m",
                    f"{r.side_m:g} m",
                    _f(comp.mean_difference, "+.4f"),
                    _f(comp.test.t, ".3f"),
                    _f(comp.test.df, ".1f"),
                    _f(comp.test.p_two_sided, ".3f"),
                    _f(comp.rule.t, ".3f"),
                    _f(comp.rule.p_less, ".3f"),
                    "yes" if comp.significant else "no",
                )
            )
    out.table(rows)


def range_design_report(out: Text, design: RangeDesign, robot: str) -> None:
    """The report of a design over plausible errors."""
    from ..design.result import shape_name

    eb, ed, k = (design.level_range(key) for key in ("E_b", "E_d", "k_m"))
    unknown = " and ".join(design.unknown)
    out(
        f"Test-track design for {robot}: its {unknown} errors are not given, so the design runs "
        f"over {len(design.scenarios)} plausible robots (E_b {eb[0]:g}-{eb[1]:g}, "
        f"E_d {ed[0]:g}-{ed[1]:g}, k {k[0]:.2g}-{k[1]:.2g} m; "
        "typical ranges, docs/design.md), first-order analytic, "
        f"{design.method} method, {design.runs_per_direction} runs per direction"
    )
    uncal, floor = design.uncalibrated_range_m, design.floor_range_m
    out(
        f"Validation: {design.validation.label}; uncalibrated error "
        f"{uncal[0]:.3f}-{uncal[1]:.3f} m, floor "
        f"{floor[0]:.3f}-{floor[1]:.3f} m over the plausible robots"
    )
    out()
    rows = [("track", "side_m", "travel_m", "worst beaten by_%", "error range_m")]
    worst, lo, hi = design.worst_shortfall, design.error_min_m, design.error_max_m
    for i, c in enumerate(design.candidates):
        rows.append(
            (
                ("* " if i == design.index else "  ") + shape_name(c.sides),
                _f(c.side_m, "g"),
                _f(c.travel_m, "g"),
                _f(100 * worst[i], ".1f"),
                f"{_f(lo[i], '.4f')}-{_f(hi[i], '.4f')}",
            )
        )
    out.table(rows)
    out(
        "  worst beaten by: the most the best size beats this one by, as a share of this size's "
        "error after calibration (the rule's measure), over the plausible robots; error range: "
        "its smallest and largest error"
    )
    out()
    out(f"Recommended: {design.describe()}.")
    out(
        f"Rule: the smallest track that, for every plausible robot, no larger track beats by more "
        f"than {100 * design.tolerance:g} % (expected values). Give the robot's errors in "
        "ROBOT.yaml once calibrated (or --known-errors) for a design for them alone."
    )
