"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

import math

from .common import (
    add_export_args,
    add_robot_args,
    length_m,
    print_json,
    print_table,
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
    result = res.calibration
    ins = result.inputs
    label = result.method + (f" ({ins['form']}-form)" if "form" in ins else "")
    where = "" if res.track_source == "arguments" else f" (track from the {res.track_source})"
    if res.track_source == "both":
        where = " (track from the run sheet and the arguments)"
    print(f"{label} from {ins['runs_cw']} CW and {ins['runs_ccw']} CCW runs, {res.track}{where}")
    r, c, unc = result.ran_with, result.corrected, result.uncertainty
    print(
        f"robot {res.robot}: ran with wheel diameters {r.diameter_right_m:.6g} / "
        f"{r.diameter_left_m:.6g} m (right / left), wheelbase {r.wheelbase_m:.6g} m"
    )
    ci = unc.ci95() if unc is not None else {}

    def cell(name: str, value: float, digits: int) -> tuple[str, str, str]:
        if unc is None:
            return f"{value:.{digits}f}", "-", "-"
        k = ("E_b", "E_d", *_GEOMETRY).index(name)
        lo, hi = ci[name]
        return (
            f"{value:.{digits}f}",
            f"{unc.stderr[k]:.{digits}f}",
            f"{lo:.{digits}f} .. {hi:.{digits}f}",
        )

    rows = [("", "ran with", "calibrated", "std error", "95 % interval")]
    rows.append(("E_b", "", *cell("E_b", result.E_b, 6)))
    rows.append(("E_d", "", *cell("E_d", result.E_d, 6)))
    for name, ran, cal in zip(
        _GEOMETRY,
        (r.diameter_right_m, r.diameter_left_m, r.wheelbase_m),
        (c.diameter_right_m, c.diameter_left_m, c.wheelbase_m),
        strict=True,
    ):
        rows.append((name, f"{ran:.6f}", *cell(name, float(cal), 6)))
    print_table(rows)
    if unc is not None:
        print(
            "  std error and 95 % interval from the run-to-run spread (delta method; Student t "
            f"with {min(unc.dof):.1f} or more degrees of freedom)"
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


_GEOMETRY = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
