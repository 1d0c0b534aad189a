"""``odocal compare``: every calibration method on the same simulated robot (and real runs)."""

from __future__ import annotations

import math
import statistics

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


def add_parser(sub) -> None:
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


def _fmt(v, scale=1.0, f=".2f"):
    return "-" if v is None or (isinstance(v, float) and math.isnan(v)) else format(v * scale, f)


def run(args) -> int:
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
    real = comparison.real
    png = comparison.written[0] if comparison.written else None
    doc = comparison_document(
        comparison,
        robot=args.robot or DEFAULT_ROBOT,
        seed=args.seed,
        plot=None if png is None else str(png),
    )
    if args.json:
        print_json(doc)
        return 0
    s = doc["simulated"]
    nom = s["nominal"]
    print(
        f"Simulated robot {doc['robot']}: {s['trials']} trials, seed {s['seed']}; budget "
        f"{s['budget']['runs']} runs and {s['budget']['travel_m']:.1f} m wheel travel per "
        f"method; validation {s['validation_track']}"
    )
    rows = [
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
    for m in s["methods"]:
        size = ", ".join(
            f"{k.replace('_m', '')} {v:.2f} m" if k.endswith("_m") else f"{k} {v:g}"
            for k, v in m["sizes"].items()
            if k != "spin_deg"
        )
        eb, ed, fe = m["E_b_error"], m["E_d_error"], m["final_error_m"]
        rows.append(
            (
                m["name"] + (f" ({m['failed_trials']} failed)" if m["failed_trials"] else ""),
                m["drives"],
                size,
                f"{m['travel_m']:.0f}",
                f"{m['footprint_m']:.1f}",
                f"{_fmt(eb['bias'], 100, '+.3f')} +- {_fmt(eb['std'], 100, '.3f')}",
                f"{_fmt(ed['bias'], 100, '+.4f')} +- {_fmt(ed['std'], 100, '.4f')}",
                f"{_fmt(fe['mean'], 1e3, '.1f')} +- {_fmt(fe['std'], 1e3, '.1f')}",
                _fmt(fe["p95"], 1e3, ".1f"),
                _fmt(m["systematic_final_error_m"]["mean"], 1e3, ".1f"),
            )
        )
    fe = nom["final_error_m"]
    rows.append(
        (
            "nominal",
            "(no calibration)",
            "",
            "",
            "",
            "",
            "",
            f"{_fmt(fe['mean'], 1e3, '.1f')} +- {_fmt(fe['std'], 1e3, '.1f')}",
            _fmt(fe["p95"], 1e3, ".1f"),
            _fmt(nom["systematic_final_error_m"], 1e3, ".1f"),
        )
    )
    print_table(rows)
    if real is not None:
        r = doc["realdata"]
        print(
            f"\nReal OptiOdom runs ({args.realdata}): validated on {len(r['heldout_runs'])} "
            "held-out runs (free/ and the circle data sets BCPT does not calibrate on)"
        )
        rows = [("method", "calibrations", "held-out mean final err mm (mean, min-max)")]
        for m in r["methods"]:
            h = m["heldout_mean_final_error_m"]
            rows.append(
                (
                    m["name"],
                    m["calibrations"],
                    f"{_fmt(h['mean'], 1e3, '.1f')} ({_fmt(h['min'], 1e3, '.1f')}-"
                    f"{_fmt(h['max'], 1e3, '.1f')})",
                )
            )
        rows.append(("nominal", "", _fmt(r["nominal_mean_final_error_m"], 1e3, ".1f")))
        if r["published"] is not None:
            rows.append(
                (
                    "published OptiOdom (all data)",
                    "",
                    _fmt(r["published"]["heldout_mean_final_error_m"], 1e3, ".1f"),
                )
            )
        print_table(rows)
        for f in r["failures"]:
            print(f"  {f['method']}: not calibrated: {f['error']}")
        agree: dict = {}
        for a in r["published_same_method"]:
            agree.setdefault((a["method"], a["published_method"]), []).append(
                a["max_abs_difference_m"]
            )
        for (ours, theirs), diffs in agree.items():
            print(
                f"  {ours} vs published {theirs}: {len(diffs)} data sets, largest parameter "
                f"difference {1e6 * max(diffs):.1f} um "
                f"(median {1e6 * statistics.median(diffs):.1f})"
            )
    if png:
        print(f"wrote {png}")
    return 0
