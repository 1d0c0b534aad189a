"""``odocal reproduce``: regenerate the paper's simulations (figures and a Markdown report)."""

from __future__ import annotations

import time
from pathlib import Path

from .common import seed_int
from .design import ProgressBar, trials_int


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
    p.add_argument("--quiet", action="store_true", help="no progress bar")
    p.set_defaults(run=run)


def run_reproduce(out_dir, trials: int = 800, seed: int = 0, progress=None) -> dict:
    """Compute, draw and write everything; returns {'report': path, 'figures': {...},
    'reproduction': Reproduction, 'elapsed_s': float}."""
    from ..design.reproduce import reproduce
    from ..io.plots import output_folder, reproduce_figures, require_matplotlib
    from ..io.report import reproduce_markdown
    from ..io.textfile import atomic_write

    # fail early, before the computation, when matplotlib is missing or DIR is unusable
    require_matplotlib()
    output_folder(out_dir)
    start = time.perf_counter()
    rep = reproduce(trials, seed, progress=progress)
    elapsed = time.perf_counter() - start
    figures = reproduce_figures(rep, out_dir)
    names = {k: Path(v).name for k, v in figures.items()}
    report = Path(out_dir) / "REPORT.md"
    atomic_write(report, reproduce_markdown(rep, names, elapsed))
    return {"report": report, "figures": figures, "reproduction": rep, "elapsed_s": elapsed}


def run(args) -> int:
    bar = ProgressBar("odocal reproduce", enabled=not args.quiet)
    try:
        res = run_reproduce(args.out, args.trials, args.seed, progress=bar)
    finally:
        bar.close()
    rep = res["reproduction"]
    print(
        f"reproduced the paper's simulations with {args.trials} trials, seed {args.seed} "
        f"(simulation {res['elapsed_s']:.1f} s)"
    )
    for name, c in (("Fig. 5", rep.fig5), ("Fig. 6", rep.fig6), ("Fig. 9", rep.fig9)):
        r = c.recommended
        print(
            f"  {name}: recommended side {r.side_m:g} m ({r.travel_m:g} m travel), error "
            f"{r.post_error_mean_m:.4f} m (floor {c.floor.mean_m:.4f} m)"
        )
    for path in res["figures"].values():
        print(f"wrote {path}")
    print(f"wrote {res['report']}")
    return 0
