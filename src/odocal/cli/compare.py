"""``odocal compare``: every calibration method on the same simulated robot (and real runs)."""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from typing import TYPE_CHECKING

from ..presets import DEFAULT_ROBOT
from .common import (
    ProgressBar,
    add_robot_args,
    length_m,
    positive_int,
    print_json,
    print_table,
    seed_int,
)

if TYPE_CHECKING:
    from ..comparison.real import AgreementSummary, RealComparison
    from ..comparison.simulated import MethodStats, SimulatedComparison


def add_parser(sub) -> None:
    """Add ``odocal compare``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "compare",
        description="Run every calibration method (heading, UMBmark x/y/mean, BCPT, Ivanjko, "
        "...) on the same simulated robot with the same budget of runs and driven distance, "
        "over M seeded Monte-Carlo trials; report the bias and spread of the calibrated E_b, "
        "E_d relative to the truth and the final position error on a common validation track "
        "(the 4 m square CCW). With --realdata, also calibrate from real OptiOdom runs and "
        "validate on held-out runs.",
    )
    add_robot_args(p, "parameters the robot runs with during the tests (default nominal)")
    p.add_argument(
        "--trials",
        type=positive_int,
        default=200,
        metavar="M",
        help="Monte-Carlo trials (default 200)",
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--runs",
        type=positive_int,
        default=10,
        metavar="N",
        help="budget: runs per method (default 10)",
    )
    p.add_argument(
        "--travel",
        type=length_m,
        default=None,
        metavar="METRES",
        help="budget: total mean wheel travel per method in m (default: what 5 CW + 5 CCW runs "
        "on the 4 m square cost, scaled to --runs)",
    )
    p.add_argument(
        "--ivanjko-straight",
        type=length_m,
        default=None,
        metavar="METRES",
        help="cap Ivanjko's straight runs at this length in m (default: they take the budget "
        "the spins leave, about 42 m for the paper's robot)",
    )
    p.add_argument(
        "--realdata",
        metavar="DIR",
        default=None,
        help="an optiodom_diff folder: also compare on real runs (held-out validation)",
    )
    p.add_argument(
        "--circle-set",
        metavar="ID",
        default=None,
        help="with --realdata: the circular/ data set BCPT calibrates on (default "
        "231220200121); the other circle data sets are held out with free/",
    )
    p.add_argument("--plot", metavar="DIR", default=None, help="write compare.png into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off with --json or when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


def _fmt(v: float | None, scale: float = 1.0, f: str = ".2f") -> str:
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v * scale, f)


def _pm(centre: float | None, std: float | None, scale: float, f: str) -> str:
    """'mean +- std' (or bias +- std), scaled; ``f`` formats the centre (the std unsigned)."""
    return f"{_fmt(centre, scale, f)} +- {_fmt(std, scale, f.lstrip('+'))}"


def run(args: argparse.Namespace) -> int:
    """Run ``odocal compare`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.compare import compare, comparison_document

    bar = ProgressBar("odocal compare", enabled=not (args.quiet or args.json))
    try:
        comparison = compare(
            args.robot,
            params=args.params,
            trials=args.trials,
            seed=args.seed,
            runs=args.runs,
            travel_m=args.travel,
            ivanjko_straight_m=args.ivanjko_straight,
            realdata=args.realdata,
            circle_set=args.circle_set,
            plot=args.plot,
            progress=bar,
        )
    finally:
        bar.close()
    png = comparison.written[0] if comparison.written else None
    robot = args.robot or DEFAULT_ROBOT
    if args.json:
        doc = comparison_document(
            comparison, robot=robot, seed=args.seed, plot=None if png is None else str(png)
        )
        print_json(doc)
        return 0
    print_simulated(comparison.simulated, robot)
    if comparison.real is not None:
        print_real(comparison.real, comparison.agreement, args.realdata)
    if png:
        print(f"wrote {png}")
    return 0


def _sizes(m: MethodStats) -> str:
    return ", ".join(
        f"{k.replace('_m', '')} {float(v):.2f} m" if k.endswith("_m") else f"{k} {float(v):g}"
        for k, v in m.sizes.items()
        if k != "spin_deg"
    )


def print_simulated(sim: SimulatedComparison, robot: str) -> None:
    """The table of the simulated comparison."""
    print(
        f"Simulated robot {robot}: {sim.trials} trials, seed {sim.seed}; budget "
        f"{sim.budget_runs} runs and {sim.budget_travel_m:.1f} m wheel travel per "
        f"method; validation {sim.validation}"
    )
    rows: list[tuple[str, ...]] = [
        (
            "method",
            "drives",
            "size",
            "travel m",
            "extent m",
            "E_b err %",
            "E_d err %",
            "final err mm",
            "p95 mm",
            "noise-free mm",
        )
    ]
    for m in sim.methods:
        fe = m.final_error
        rows.append(
            (
                m.name + (f" ({m.failed} failed)" if m.failed else ""),
                m.drives,
                _sizes(m),
                f"{m.travel_m:.0f}",
                f"{m.footprint_m:.1f}",
                _pm(m.E_b_stats.bias, m.E_b_stats.std, 100, "+.3f"),
                _pm(m.E_d_stats.bias, m.E_d_stats.std, 100, "+.4f"),
                _pm(fe.mean, fe.std, 1e3, ".1f"),
                _fmt(fe.p95, 1e3, ".1f"),
                _fmt(m.systematic_error.mean, 1e3, ".1f"),
            )
        )
    fe = sim.nominal_final_error
    rows.append(
        (
            "nominal",
            "(no calibration)",
            "",
            "",
            "",
            "",
            "",
            _pm(fe.mean, fe.std, 1e3, ".1f"),
            _fmt(fe.p95, 1e3, ".1f"),
            _fmt(sim.nominal_systematic_error_m, 1e3, ".1f"),
        )
    )
    print_table(rows)


def print_real(
    real: RealComparison, agreement: Sequence[AgreementSummary], realdata: str | None
) -> None:
    """The table of the real-data comparison and the agreement with the published methods."""
    print(
        f"\nReal OptiOdom runs ({realdata}): validated on {len(real.heldout)} "
        "held-out runs (free/ and the circle data sets BCPT does not calibrate on)"
    )
    rows = [("method", "calibrations", "held-out mean final err mm (mean, min-max)")]
    for m in real.methods:
        h = m.heldout
        rows.append(
            (
                m.name,
                str(len(m.per_dataset)),
                f"{_fmt(h.mean, 1e3, '.1f')} ({_fmt(h.min, 1e3, '.1f')}-{_fmt(h.max, 1e3, '.1f')})",
            )
        )
    rows.append(("nominal", "", _fmt(real.nominal_mean_final_error_m, 1e3, ".1f")))
    if real.published is not None:
        rows.append(
            (
                "published OptiOdom (all data)",
                "",
                _fmt(real.published.heldout_mean_final_error_m, 1e3, ".1f"),
            )
        )
    print_table(rows)
    for f in real.failures:
        print(f"  {f.method}: not calibrated: {f.error}")
    for a in agreement:
        print(
            f"  {a.method} vs published {a.published_method}: {a.datasets} data sets, largest "
            f"parameter difference {1e6 * a.largest_m:.1f} um (median {1e6 * a.median_m:.1f})"
        )
