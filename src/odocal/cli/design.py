"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING

from .common import (
    MAX_LENGTH_M,
    ProgressBar,
    add_robot_args,
    fraction,
    nonnegative_float,
    positive_int,
    print_json,
    print_table,
    print_warnings,
    seed_int,
    sides_int,
    trials_int,
)

if TYPE_CHECKING:
    import numpy as np

    from ..app.measured import MeasuredRobot
    from ..core.model import MeasurementNoise
    from ..design.recommend import Recommendation
    from ..design.result import Candidate, ValidationTrack
    from ..design.robust import RangeDesign
    from ..design.sweep import DesignResult


def parse_side_lengths(text: str) -> np.ndarray:
    """'START:STOP:STEP' (m, STOP inclusive within float tolerance) or one length 'L'."""
    parts = text.split(":")
    try:
        nums = [float(p) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP in metres (e.g. 0.5:10:0.5), got {text!r}"
        ) from None
    if len(nums) == 1:
        nums = [nums[0], nums[0], 1.0]
    if len(nums) != 3:
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP in metres (e.g. 0.5:10:0.5), got {text!r}"
        )
    start, stop, step = nums
    if not all(math.isfinite(v) and v > 0 for v in nums):
        raise argparse.ArgumentTypeError(
            f"START, STOP and STEP must be finite numbers > 0, got {text!r}"
        )
    if stop < start:
        raise argparse.ArgumentTypeError(f"STOP must be >= START, got {text!r}")
    if stop > MAX_LENGTH_M:
        raise argparse.ArgumentTypeError(
            f"side lengths must be at most {MAX_LENGTH_M:g} m (check the units), got {text!r}"
        )
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > 1000:
        raise argparse.ArgumentTypeError(f"{count} side lengths is too many (at most 1000)")
    import numpy as np

    lengths = np.round(start + step * np.arange(count), 12)
    if lengths[0] <= 0:  # below the 1e-12 m rounding
        raise argparse.ArgumentTypeError(f"side lengths must be at least 1e-12 m, got {text!r}")
    return lengths


def parse_validation(text: str) -> ValidationTrack:
    """'SIDES:LENGTH:DIRECTION', e.g. '4:4:ccw' (the paper's 4 m x 4 m square CCW)."""
    from ..core.tracks import MAX_POLYGON_SIDES
    from ..design.result import ValidationTrack

    parts = text.split(":")
    hint = f"expected SIDES:LENGTH:DIRECTION (e.g. 4:4:ccw), got {text!r}"
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(hint)
    try:
        sides = int(parts[0])
        length = float(parts[1])
    except ValueError:
        raise argparse.ArgumentTypeError(hint) from None
    direction = parts[2].strip().lower()
    if sides < 3:
        raise argparse.ArgumentTypeError(f"a polygon needs at least 3 sides, got {text!r}")
    if sides > MAX_POLYGON_SIDES:
        raise argparse.ArgumentTypeError(
            f"a polygon has at most {MAX_POLYGON_SIDES} sides, got {text!r}"
        )
    if not (math.isfinite(length) and 0 < length <= MAX_LENGTH_M):
        raise argparse.ArgumentTypeError(
            f"LENGTH must be a number > 0 and at most {MAX_LENGTH_M:g} m, got {text!r}"
        )
    if direction not in ("cw", "ccw"):
        raise argparse.ArgumentTypeError(f"DIRECTION must be cw or ccw, got {text!r}")
    return ValidationTrack(sides, length, direction)


def add_parser(sub) -> None:
    """Add ``odocal design``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "design",
        description="For each candidate polygon test track, simulate the calibration many times "
        "(n CW + n CCW runs, calibrate, drive a validation track with the result) and recommend "
        "the smallest track that no larger one beats significantly by more than the tolerance. "
        "With no arguments: the paper's Fig. 5 conditions on the built-in robot.",
    )
    add_robot_args(
        p,
        "parameters the robot runs with during the test (default: ROBOT.yaml's 'believed', "
        "else nominal)",
    )
    p.add_argument(
        "--sides",
        type=sides_int,
        action="append",
        metavar="N",
        help="polygon shape (default 4, a square); repeat to compare shapes at equal travel",
    )
    p.add_argument(
        "--side-lengths",
        type=parse_side_lengths,
        default=None,
        metavar="START:STOP:STEP",
        help="candidate side lengths in m, STOP inclusive (default: 20 steps of about 1.3 "
        "wheelbases, 0.5:10:0.5 for the paper's robot)",
    )
    p.add_argument(
        "--runs-per-direction",
        type=positive_int,
        default=5,
        metavar="n",
        help="test runs per direction in each calibration (default 5)",
    )
    p.add_argument(
        "--trials",
        type=trials_int,
        default=2000,
        metavar="M",
        help="Monte-Carlo trials per candidate (default 2000; the paper used 800)",
    )
    p.add_argument(
        "--method",
        choices=("heading", "umbmark"),
        default="heading",
        help="calibration method (default heading, the paper's; umbmark: squares only)",
    )
    p.add_argument(
        "--validate",
        type=parse_validation,
        default=None,
        metavar="SIDES:LENGTH:DIRECTION",
        help="validation track driven with each calibration (default: a CCW square of about 10 "
        "wheelbases, 4:4:ccw for the paper's robot)",
    )
    p.add_argument(
        "--alpha",
        type=fraction(lo_open=True),
        default=0.05,
        help="significance level of the rule's one-sided tests (default 0.05)",
    )
    p.add_argument(
        "--tolerance",
        type=fraction(lo_open=False),
        default=0.05,
        help="a larger track must be better by more than this fraction (default 0.05)",
    )
    p.add_argument(
        "--criterion",
        choices=("error", "residual"),
        default="error",
        help="what the rule compares: the error after calibration on the validation track "
        "(default) or the residual, the same drive without wheel noise",
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--reference-sim",
        action="store_true",
        help="simulate with 1 cm midpoint increments everywhere (slow; to check the fast mode)",
    )
    p.add_argument(
        "--analytic",
        action="store_true",
        help="first-order propagation instead of Monte Carlo: expected values, the same "
        "report in milliseconds (docs/nonsystematic-errors.md says when first order holds)",
    )
    p.add_argument(
        "--known-errors",
        action="store_true",
        help="design for the robot's errors as given even when ROBOT.yaml gives no "
        "'systematic' or 'nonsystematic' section (default: design over their typical ranges)",
    )
    p.add_argument(
        "--robot-from",
        nargs="+",
        metavar="RUN_OR_DIR",
        help="measure the robot from tracked runs instead (systematic errors from a trajectory "
        "fit, k from the spread of repeated runs, the instrument from the tracker's jitter "
        "unless given); --robot then only gives the nominal geometry",
    )
    p.add_argument(
        "--sigma-xy-m",
        type=nonnegative_float,
        metavar="S",
        help="the instrument's position noise per measured final pose, m (replaces the robot's)",
    )
    p.add_argument(
        "--sigma-theta-deg",
        type=nonnegative_float,
        metavar="S",
        help="the instrument's heading noise per measured final pose, deg (replaces the robot's)",
    )
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off with --json or when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``odocal design`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.design import design
    from ..design.robust import RangeDesign
    from ..design.spec import DesignSpec

    spec = DesignSpec(
        sides=tuple(args.sides or [4]),
        side_lengths_m=None
        if args.side_lengths is None
        else tuple(float(v) for v in args.side_lengths),
        runs_per_direction=args.runs_per_direction,
        trials=args.trials,
        method=args.method,
        validation=args.validate,
        alpha=args.alpha,
        tolerance=args.tolerance,
        criterion=args.criterion,
    )
    bar = ProgressBar("odocal design", enabled=not (args.quiet or args.json))
    try:
        res = design(
            args.robot,
            spec,
            params=args.params,
            engine="analytic" if args.analytic else "monte-carlo",
            seed=args.seed,
            reference_sim=args.reference_sim,
            plot=args.plot,
            progress=bar,
            error_range=False if args.known_errors else None,
            robot_from=args.robot_from,
            measurement=_instrument(args),
        )
    finally:
        bar.close()
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    if res.measured is not None:
        _print_measured(res.measured)
    for note in res.notes:
        print(f"Note: {note}")
    if isinstance(res.result, RangeDesign):
        print_range_design(res.result, res.robot)
    else:
        print_design(res.result, res.robot, res.seed)
    for path in res.written:
        print(f"wrote {path}")
    return 0


def _print_measured(measured: MeasuredRobot) -> None:
    m = measured.robot
    print(
        f"Robot measured from {len(measured.fit.runs)} run(s): E_b {m.systematic.E_b:.6f}, "
        f"E_d {m.systematic.E_d:.6f} (relative to nominal), k_r + k_l "
        f"{m.nonsystematic.k_sum_m:.3g} m, instrument {m.measurement.sigma_xy_m * 1000:.3g} mm "
        f"/ {math.degrees(m.measurement.sigma_theta_rad):.3g} deg "
        f"({measured.measurement_source})"
    )


def _instrument(args: argparse.Namespace) -> MeasurementNoise | None:
    if args.sigma_xy_m is None and args.sigma_theta_deg is None:
        return None
    from ..core.model import MeasurementNoise

    return MeasurementNoise.from_degrees(args.sigma_xy_m or 0.0, args.sigma_theta_deg or 0.0)


def _f(v: float | None, fmt: str) -> str:
    return "-" if v is None or not math.isfinite(v) else format(v, fmt)


def print_design(result: DesignResult, robot: str, seed: int | None = None) -> None:
    """The human-readable design report."""
    _print_header(result, robot, seed)
    print()
    _print_candidates(result)
    print()
    _print_recommendation(result)
    _print_stability(result)
    _print_alternatives(result)
    if result.recommendation.neighbours:
        print()
        _print_neighbours(result)


def _print_header(result: DesignResult, robot: str, seed: int | None) -> None:
    if result.trials is None:
        how = "first-order analytic (expected values, no trials)"
    else:
        crn = ", common random numbers" if result.paired else ""
        how = f"{result.trials} Monte-Carlo trials per candidate{crn}, seed {seed}"
    print(
        f"Test-track design for {robot}: {result.method} method, "
        f"{result.runs_per_direction} runs per direction, {how}"
    )
    mean_of = "means over the trials" if result.trials is not None else "expected values"
    print(
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


def _print_candidates(result: DesignResult) -> None:
    index = result.recommendation.index
    rows: list[tuple[str, ...]] = [_CANDIDATE_COLUMNS]
    rows += [_candidate_row(c, i == index) for i, c in enumerate(result.candidates)]
    print_table(rows)
    print(
        "  share: systematic share of the n-run-mean leg heading error; |beta|, sigma: "
        "systematic and random heading error of one leg;\n"
        "  error: final position error on the validation track after calibration (mean, std, "
        "central 95 % of single calibrations); residual: the same without wheel noise"
    )
    if result.failed_trials:
        print(
            f"  {result.failed_trials} trial(s) gave no calibration (equations undefined) and "
            "are left out"
        )


def _judged(rec: Recommendation) -> str:
    return "error after calibration" if rec.criterion == "error" else "residual error"


def _print_recommendation(result: DesignResult) -> None:
    from ..design.result import shape_name

    r, rec = result.recommended, result.recommendation
    print(
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
    print(
        f"Rule: the smallest track that no larger track beats by more than "
        f"{100 * rec.tolerance:g} % in {_judged(rec)} ({test})."
    )


def _print_stability(result: DesignResult) -> None:
    st = result.stability
    if st is not None:
        lo, hi = st.range_m
        picks = ", ".join(f"{p.side_m:g} m {100 * p.share:.0f} %" for p in st.picks[:4])
        if not st.indistinguishable:
            verdict = f"stable: {lo:g} m in at least 90 % of them"
        else:
            verdict = f"{lo:g}-{hi:g} m hold 90 % of them: these sizes are indistinguishable"
        print(
            f"Stability: the rule on {st.resamples} bootstrap resamples of the trials picks "
            f"{picks}; {verdict}."
        )
    elif result.trials is None:
        print(
            "Stability: expected values (no sampling error); the first-order approximation is "
            "checked by Monte Carlo ('odocal design' without --analytic)."
        )


def _print_alternatives(result: DesignResult) -> None:
    from ..design.result import shape_name

    other, o = result.other, result.other_recommended
    if other is not None and o is not None:
        what = "residual alone" if other.criterion == "residual" else "error after calibration"
        print(
            f"  judged on the {what} (--criterion {other.criterion}): side {o.side_m:g} m "
            f"({o.travel_m:g} m travel)"
        )
    picks = result.shape_picks
    if len(picks) > 1:
        for c in picks:
            print(f"  best {shape_name(c.sides)}: side {c.side_m:g} m ({c.travel_m:g} m)")


def _print_neighbours(result: DesignResult) -> None:
    r, rec, cands = result.recommended, result.recommendation, result.candidates
    tol = f"{100 * rec.tolerance:g} %"
    rows: list[tuple[str, ...]]
    if rec.test == "exact":
        print(f"The recommended {r.side_m:g} m track against its neighbours (expected values):")
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
        print(
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
    print_table(rows)


def print_range_design(design: RangeDesign, robot: str) -> None:
    """The report of a design over plausible errors."""
    from ..design.result import shape_name

    eb, ed, k = (design.level_range(key) for key in ("E_b", "E_d", "k_m"))
    unknown = " and ".join(design.unknown)
    print(
        f"Test-track design for {robot}: its {unknown} errors are not given, so the design runs "
        f"over {len(design.scenarios)} plausible robots (E_b {eb[0]:g}-{eb[1]:g}, "
        f"E_d {ed[0]:g}-{ed[1]:g}, k {k[0]:.2g}-{k[1]:.2g} m; "
        "typical ranges, docs/design.md), first-order analytic, "
        f"{design.method} method, {design.runs_per_direction} runs per direction"
    )
    uncal, floor = design.uncalibrated_range_m, design.floor_range_m
    print(
        f"Validation: {design.validation.label}; uncalibrated error "
        f"{uncal[0]:.3f}-{uncal[1]:.3f} m, floor "
        f"{floor[0]:.3f}-{floor[1]:.3f} m over the plausible robots"
    )
    print()
    rows = [("track", "side_m", "travel_m", "worst above best_%", "error range_m")]
    worst, lo, hi = design.worst_regret, design.error_min_m, design.error_max_m
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
    print_table(rows)
    print(
        "  worst above best: the largest excess of this size's error after calibration over the "
        "best size's, over the plausible robots; error range: its smallest and largest error"
    )
    print()
    print(f"Recommended: {design.describe()}.")
    print(
        f"Rule: the smallest track that, for every plausible robot, no larger track beats by more "
        f"than {100 * design.tolerance:g} % (expected values). Give the robot's errors in "
        "ROBOT.yaml once calibrated (or --known-errors) for a design for them alone."
    )
