"""``odocal reproduce``: regenerate the paper's simulations (figures and a Markdown report)."""

from __future__ import annotations

import sys

from .common import ProgressBar, seed_int, trials_int


def add_parser(sub) -> None:
    p = sub.add_parser(
        "reproduce",
        help="regenerate the paper's figures and compare with its numbers",
        description="Regenerate the paper's simulations from its stated conditions (Figs. 3, 4, "
        "5, 6, 8, 9) and predict its experiment (Tables 1-3); write PNG figures and REPORT.md "
        "(the paper's numbers beside odocal's) into DIR. Needs matplotlib (the 'plot' extra).",
    )
    p.add_argument("--out", metavar="DIR", required=True, help="output folder (created if needed)")
    p.add_argument(
        "--trials",
        type=trials_int,
        default=800,
        metavar="M",
        help="Monte-Carlo trials per candidate (default 800, the paper's)",
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


def run(args) -> int:
    from ..app.reproduce import reproduce

    bar = ProgressBar("odocal reproduce", enabled=not args.quiet)
    try:
        res = reproduce(args.out, trials=args.trials, seed=args.seed, progress=bar)
    finally:
        bar.close()
    rep = res.reproduction
    print(f"reproduced the paper's simulations with {args.trials} trials, seed {args.seed}")
    print(f"odocal: simulation took {res.elapsed_s:.1f} s", file=sys.stderr)
    for name, c in (("Fig. 5", rep.fig5), ("Fig. 6", rep.fig6), ("Fig. 9", rep.fig9)):
        r = c.recommended
        print(
            f"  {name}: recommended side {r.side_m:g} m ({r.travel_m:g} m travel), error "
            f"{r.post_error_mean_m:.4f} m (floor {c.floor.mean_m:.4f} m)"
        )
    for path in res.figures.values():
        print(f"wrote {path}")
    print(f"wrote {res.report}")
    return 0
