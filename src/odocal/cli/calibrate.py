"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

from .common import (
    add_export_args,
    add_robot_args,
    length_m,
    print_json,
    print_warnings,
    sides_int,
)


def add_parser(sub) -> None:
    """Add ``odocal calibrate``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "calibrate",
        description="Calibrate the wheelbase and wheel-diameter ratio from the measured final "
        "pose errors of CW and CCW runs on a regular N-gon (heading, umbmark), or from the "
        "measured radii of CW and CCW circles of commanded radius R (bcpt). The track comes "
        "from the run sheet ('# sides:' and '# side_m:' lines, written by 'odocal plan') or "
        "from --sides/--side-length; there is no default side length.",
    )
    p.add_argument(
        "runs_csv",
        metavar="RUNS.csv",
        help="measured runs: direction,x_m,y_m,theta_deg (heading, umbmark) or "
        "direction,radius_m (bcpt)",
    )
    add_robot_args(
        p,
        "the parameters the robot RAN WITH during the runs (default: ROBOT.yaml's "
        "'believed', else nominal)",
        required=True,
    )
    p.add_argument(
        "--sides",
        type=sides_int,
        default=None,
        metavar="N",
        help="regular N-gon the runs drove (default: the run sheet's, else 4, a square)",
    )
    p.add_argument(
        "--side-length",
        type=length_m,
        default=None,
        metavar="L",
        help="its side length in m (default: the run sheet's 'side_m'; required otherwise)",
    )
    p.add_argument(
        "--method",
        choices=("heading", "umbmark", "bcpt"),
        default="heading",
        help="heading-error method (any N-gon, default), UMBmark (squares) or BCPT "
        "(CW/CCW circles; needs --radius)",
    )
    p.add_argument(
        "--radius",
        type=length_m,
        metavar="R",
        default=None,
        help="bcpt: commanded axle-centre circle radius in m",
    )
    p.add_argument(
        "--umbmark-form",
        choices=("x", "y", "mean"),
        default="mean",
        help="UMBmark equations from x, y or their mean (default mean)",
    )
    add_export_args(p, "write the corrected parameters")
    p.add_argument(
        "--force",
        action="store_true",
        help="accept a result more than 25 %% from what the robot ran with (absurd for a "
        "calibration: by default an error, and nothing is written)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args) -> int:
    """Run ``odocal calibrate`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.calibrate import calibrate

    res = calibrate(
        args.runs_csv,
        args.robot,
        params=args.params,
        method=args.method,
        sides=args.sides,
        side_m=args.side_length,
        umbmark_form=args.umbmark_form,
        radius_m=args.radius,
        out=args.out,
        ros2=args.ros2,
        controller_name=args.controller_name,
        force=args.force,
    )
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    print(res.text())
    return 0
