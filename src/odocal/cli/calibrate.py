"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

import math

from .common import (
    add_robot_args,
    add_track_args,
    length_m,
    print_json,
    print_table,
    print_warnings,
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "calibrate",
        help="calibrate E_b, E_d from RUNS.csv",
        description="Calibrate the wheelbase and wheel-diameter ratio from the measured final "
        "pose errors of CW and CCW runs on a regular N-gon (heading, umbmark), or from the "
        "measured radii of CW and CCW circles of commanded radius R (bcpt).",
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
    )
    add_track_args(p)
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
    p.add_argument("--out", metavar="PARAMS.yaml", help="write the corrected parameters")
    p.add_argument(
        "--force",
        action="store_true",
        help="accept a result more than 25 %% from what the robot ran with (absurd for a "
        "calibration: by default an error, and nothing is written)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args) -> int:
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
        force=args.force,
    )
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    result = res.calibration
    ins = result.inputs
    label = result.method + (f" ({ins['form']}-form)" if "form" in ins else "")
    print(f"{label} from {ins['runs_cw']} CW and {ins['runs_ccw']} CCW runs, {res.track}")
    r, c = result.ran_with, result.corrected
    print_table(
        [
            ("", "ran with", "calibrated"),
            ("E_b", "", f"{result.E_b:.6f}"),
            ("E_d", "", f"{result.E_d:.6f}"),
            ("wheel_diameter_right_m", f"{r.diameter_right_m:.6f}", f"{c.diameter_right_m:.6f}"),
            ("wheel_diameter_left_m", f"{r.diameter_left_m:.6f}", f"{c.diameter_left_m:.6f}"),
            ("wheelbase_m", f"{r.wheelbase_m:.6f}", f"{c.wheelbase_m:.6f}"),
        ]
    )
    if "mean_theta_cw_rad" in ins:
        print(
            f"  mean heading error: CW {math.degrees(ins['mean_theta_cw_rad']):+.4f} deg, "
            f"CCW {math.degrees(ins['mean_theta_ccw_rad']):+.4f} deg"
        )
    if "mean_radius_cw_m" in ins:
        print(
            f"  mean radius: CW {ins['mean_radius_cw_m']:.6f} m, "
            f"CCW {ins['mean_radius_ccw_m']:.6f} m"
            f" (first order: E_b {ins['first_order_E_b']:.6f}, E_d {ins['first_order_E_d']:.6f})"
        )
    for f in res.written:
        print(f"wrote {f}")
    return 0
