"""``odocal simulate``: drive a test track n times with a simulated robot."""

from __future__ import annotations

from .common import (
    add_robot_args,
    add_track_args,
    length_m,
    positive_int,
    print_json,
    seed_int,
)


def add_parser(sub) -> None:
    """Add ``odocal simulate``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "simulate",
        description="Drive a regular N-gon (or a track file) open loop with a simulated robot "
        "and report the final pose errors (actual - odometric). With --out, write them as "
        "RUNS.csv for 'odocal calibrate'.",
    )
    add_robot_args(p, "believed parameters the robot runs with (e.g. a calibration result)")
    add_track_args(p)
    p.add_argument("--track", metavar="TRACK.yaml", help="a custom track file instead of --sides")
    p.add_argument(
        "--direction",
        type=str.lower,  # CW, as the files accept any case
        choices=("cw", "ccw", "both"),
        default="both",
        help="driving direction (default both: n CW runs, then n CCW runs)",
    )
    p.add_argument(
        "--runs", type=positive_int, default=5, metavar="n", help="runs per direction (default 5)"
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--max-step",
        type=length_m,
        default=0.01,
        metavar="M",
        help="largest wheel travel of one integration increment, m (default 0.01)",
    )
    p.add_argument(
        "--predict",
        action="store_true",
        help="also print the final-pose covariance predicted by first-order propagation "
        "(eqs. (8)-(10), plus the instrument noise) beside the Monte-Carlo one",
    )
    p.add_argument(
        "--out",
        metavar="RUNS.csv",
        help="write the runs in RUNS.csv format (an existing file is replaced only if an "
        "earlier simulate wrote it)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace --out even if it may hold measured runs (any file simulate did not write)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``odocal simulate`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.simulate import simulate

    res = simulate(
        args.robot,
        params=args.params,
        sides=args.sides,
        side_m=args.side_length,
        track=args.track,
        directions=("cw", "ccw") if args.direction == "both" else (args.direction,),
        runs=args.runs,
        seed=args.seed,
        max_step_m=args.max_step,
        predict_covariance=args.predict,
        out=args.out,
        force=args.force,
    )
    if args.json:
        print_json(res.as_dict())
        return 0
    print(res.text())
    return 0
