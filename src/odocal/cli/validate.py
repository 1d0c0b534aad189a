"""``odocal validate``: how well given parameters dead-reckon recorded runs, against nominal."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
from typing import Any

from .common import (
    add_recording_args,
    add_slam_args,
    bag_options,
    print_json,
    print_table,
    print_warnings,
    truth_frames,
)


def add_parser(sub: Any) -> None:
    """Add ``odocal validate``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "validate",
        description="Dead-reckon recorded runs with the given parameters and with the nominal "
        "ones, and report the final and maximum position and heading errors per run.",
    )
    add_recording_args(p)
    p.add_argument(
        "--params", metavar="PARAMS.yaml", required=True, help="the parameters to validate"
    )
    p.add_argument(
        "--robot", metavar="ROBOT.yaml", help="nominal geometry (default: the runs' metadata)"
    )
    p.add_argument(
        "--nominal",
        choices=("robot", "firmware"),
        default=None,
        help="what the 'nominal' columns use: robot (ROBOT.yaml's nominal geometry; needs "
        "--robot) or firmware (each run's own ran-with parameters, e.g. an OptiOdom data set's "
        "firmware values); default robot with --robot, else firmware",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="DIR", help="write one PNG trajectory plot per run into DIR")
    add_slam_args(p)
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``odocal validate`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.validate import validate

    result = validate(
        args.paths,
        args.params,
        robot=args.robot,
        nominal=args.nominal,
        plot=args.plot,
        ticks_per_rev=args.ticks_per_rev,
        bag=bag_options(args),
        truth_frames=truth_frames(args),
        slam_stamp_offset_s=args.slam_stamp_offset,
    )
    print_warnings(result.load_warnings)
    d = result.as_dict()
    if args.json:
        print_json(d)
        return 0

    def mm(v: float | None) -> str:
        return "-" if v is None else f"{1000 * v:.1f}"

    def deg(v: float | None) -> str:
        return "-" if v is None else f"{math.degrees(v):.2f}"

    col = {"robot": "robot", "firmware": "firmware"}.get(result.nominal_source, "nominal")
    rows = [
        (
            "run",
            "final mm",
            "max mm",
            "final deg",
            f"{col} final mm",
            f"{col} max mm",
            f"{col} final deg",
        )
    ]
    for r in result.runs:
        rows.append(
            (
                Path(r["path"]).name,
                mm(r["final_error_m"]),
                mm(r["max_error_m"]),
                deg(r["final_heading_error_rad"]),
                mm(r["nominal_final_error_m"]),
                mm(r["nominal_max_error_m"]),
                deg(r["nominal_final_heading_error_rad"]),
            )
        )
    rows.append(
        (
            "mean",
            mm(d["mean_final_error_m"]),
            mm(d["mean_max_error_m"]),
            deg(d["mean_final_heading_error_rad"]),
            mm(d["mean_nominal_final_error_m"]),
            mm(d["mean_nominal_max_error_m"]),
            deg(d["mean_nominal_final_heading_error_rad"]),
        )
    )
    source = {
        "robot": f"ROBOT.yaml's nominal geometry ({args.robot}; --nominal robot)",
        "firmware": "each run's firmware values, the parameters it ran with (--nominal firmware)",
        "unknown": "unknown for some runs (they do not say what they ran with; give --robot)",
    }
    print(f"  {col} columns: {source[result.nominal_source]}")
    print_table(rows, title=f"{len(result.runs)} run(s), parameters from {args.params}")
    if result.written:
        print(f"wrote {len(result.written)} plot(s) to {args.plot}")
    return 0
