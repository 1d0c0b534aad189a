"""``odocal reproduce``: regenerate the paper's figures and, with --realdata, its experiment on a
real robot."""

from __future__ import annotations

import argparse
import sys

from ..errors import InputError
from .common import ProgressBar, print_json, seed_int, trials_int


def add_parser(sub) -> None:
    """Add ``odocal reproduce``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "reproduce",
        description="Regenerate the paper's simulations from its stated conditions (Figs. 3, 4, "
        "5, 6, 8, 9) and predict its experiment (Tables 1-3); write PNG figures and REPORT.md "
        "(the paper's numbers beside odocal's) into DIR. With --realdata, also run the paper's "
        "procedure on the real OptiOdom robot: measure its errors, design its track, calibrate "
        "on its 0.75 m and 1.7 m squares and validate on its held-out runs "
        "(docs/real-experiment.md). Figures need matplotlib (the 'plot' extra).",
    )
    p.add_argument("--out", metavar="DIR", help="output folder (created if needed)")
    p.add_argument(
        "--realdata",
        metavar="DIR",
        help="an optiodom_diff folder (square/, ivanjko/, circular/, free/): the experiment on "
        "the real robot",
    )
    p.add_argument(
        "--trials",
        type=trials_int,
        default=800,
        metavar="M",
        help="Monte-Carlo trials per candidate (default 800, the paper's)",
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off with --json or when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``odocal reproduce`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.reproduce import reproduce

    if args.out is None and not args.json:
        raise InputError("give --out DIR (the report and figures) or --json", field="out")
    bar = ProgressBar("odocal reproduce", enabled=not (args.quiet or args.json))
    try:
        res = reproduce(
            args.out, trials=args.trials, seed=args.seed, progress=bar, realdata=args.realdata
        )
    finally:
        bar.close()
    print(f"odocal: simulation took {res.elapsed_s:.1f} s", file=sys.stderr)
    if args.json:
        print_json(res.as_dict())
        return 0
    rep = res.reproduction
    print(f"reproduced the paper's simulations with {args.trials} trials, seed {args.seed}")
    if rep is not None:
        for name, c in (("Fig. 5", rep.fig5), ("Fig. 6", rep.fig6), ("Fig. 9", rep.fig9)):
            r = c.recommended
            print(
                f"  {name}: recommended side {r.side_m:g} m ({r.travel_m:g} m travel), error "
                f"{r.post_error_mean_m:.4f} m (floor {c.floor.mean_m:.4f} m)"
            )
    if res.real is not None and res.verdict is not None:
        real, v = res.real, res.verdict
        print(f"real robot ({len(real.heldout_names)} held-out runs):")
        for s in real.sides_m:
            cal = real.calibration(s)
            p = real.prediction.real[s]
            print(
                f"  heading on the {s:g} m squares: E_b {cal.E_b:.5f}, E_d {cal.E_d:.6f}, "
                f"held-out error {cal.heldout_error_m * 1000:.1f} mm (design predicted "
                f"{p.post_error_mean_m * 1000:.1f} mm)"
            )
        t = real.ttests["heading"].paired
        print(
            f"  paired t = {t.t:.2f}, p = {t.p_two_sided:.2g}; design prefers "
            f"{v.preferred_side_m:g} m; ordering predicted: "
            f"{'yes' if v.ordering_predicted else 'no'}; difference within the prediction: "
            f"{'yes' if v.difference_within_prediction else 'no'}"
        )
    for path in res.figures.values():
        print(f"wrote {path}")
    if res.report is not None:
        print(f"wrote {res.report}")
    return 0
