"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

import math

from ..calibration.bcpt import calibrate_bcpt
from ..calibration.heading import calibrate_heading
from ..calibration.umbmark import UMBMARK_FORMS, calibrate_umbmark
from ..errors import InputError
from .common import (
    add_robot_args,
    add_track_args,
    length_m,
    print_json,
    print_table,
    print_warnings,
    resolve_robot,
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
        choices=UMBMARK_FORMS,
        default="mean",
        help="UMBmark equations from x, y or their mean (default mean)",
    )
    p.add_argument("--out", metavar="PARAMS.yaml", help="write the corrected parameters")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def calibrate_file(
    path,
    robot,
    method: str,
    sides: int,
    side_m: float,
    form: str = "mean",
    radius_m: float | None = None,
):
    """Read RUNS.csv (or the BCPT runs file) and calibrate; returns a CalibrationResult."""
    from ..io.runs_csv import read_circle_runs, read_runs

    ran_with = robot.believed_geometry
    if radius_m is not None and method != "bcpt":
        raise InputError(f"--radius is only used with --method bcpt (got --method {method})")
    if method == "bcpt":
        if radius_m is None:
            raise InputError("--method bcpt needs --radius R (the commanded circle radius, m)")
        return calibrate_bcpt(read_circle_runs(path), radius_m, ran_with)
    # each method reads only what it uses: heading the final headings, UMBmark the positions
    runs = read_runs(path, required=("theta_deg",) if method == "heading" else ("x_m", "y_m"))
    if method == "umbmark":
        if sides != 4:
            raise InputError(
                f"UMBmark is defined for squares only (--sides 4), got --sides {sides}"
            )
        return calibrate_umbmark(runs, side_m, ran_with, form)
    return calibrate_heading(runs, sides, side_m, ran_with)


def run(args) -> int:
    from ..io.robot_file import params_yaml
    from ..io.textfile import atomic_write

    robot = resolve_robot(args)
    result = calibrate_file(
        args.runs_csv,
        robot,
        args.method,
        args.sides,
        args.side_length,
        args.umbmark_form,
        args.radius,
    )
    from ..calibration.result import check_physical

    c = result.corrected
    # an absurd calibration (e.g. the wrong --side-length or units) is reported, not hidden
    print_warnings(
        check_physical(
            (c.diameter_right_m, c.diameter_left_m, c.wheelbase_m), result.ran_with, result.method
        )
    )
    if args.out:
        atomic_write(
            args.out,
            params_yaml(result.corrected, method=result.method, E_b=result.E_b, E_d=result.E_d),
        )
    if args.json:
        print_json(result.as_dict())
        return 0
    ins = result.inputs
    label = result.method + (f" ({ins['form']}-form)" if "form" in ins else "")
    if result.method == "bcpt":
        track = f"circles of commanded radius {ins['commanded_radius_m']:g} m"
    else:
        track = f"{args.sides}-gon side {args.side_length:g} m"
    print(f"{label} from {ins['runs_cw']} CW and {ins['runs_ccw']} CCW runs, {track}")
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
    if args.out:
        print(f"wrote {args.out}")
    return 0
