"""``odocal validate``: how well given parameters dead-reckon recorded runs, against nominal."""

from __future__ import annotations

import argparse
from typing import Any

from .common import (
    add_recording_args,
    add_slam_args,
    bag_options,
    print_json,
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
    p.add_argument(
        "--kinematics",
        choices=("differential", "skid-steer"),
        default=None,
        help="skid-steer: read the bags as fit --kinematics skid-steer does (a world-frame "
        "odometry such as a lidar ICP, or a SLAM /tf, as the truth), estimate each truth's "
        "clock offset and apply it; the parameters' wheelbase is the effective track; default: "
        "the robot file's 'kinematics', else differential",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="DIR", help="write one PNG trajectory plot per run into DIR")
    p.add_argument(
        "--tum",
        metavar="DIR",
        help="write each run's truth and its dead reckoning with the parameters and with the "
        "nominal geometry as TUM trajectories into DIR (evo_rpe reproduces the drift: "
        "docs/skid-steer.md)",
    )
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
        tum=args.tum,
        kinematics=args.kinematics,
        ticks_per_rev=args.ticks_per_rev,
        bag=bag_options(args),
        truth_frames=truth_frames(args),
        slam_stamp_offset_s=args.slam_stamp_offset,
    )
    print_warnings(result.load_warnings)
    if args.json:
        print_json(result.as_dict())
        return 0
    print(result.text())
    return 0
