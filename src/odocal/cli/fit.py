"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags)."""

from __future__ import annotations

import math
from pathlib import Path

from ..errors import InputError
from .common import (
    add_export_args,
    add_recording_args,
    add_slam_args,
    bag_options,
    format_topics,
    heading_weight,
    length_m,
    motion_mix,
    number,
    print_json,
    print_table,
    print_warnings,
    sides_int,
)

METHODS = ("trajectory", "linear", "umbmark", "heading", "gyro", "relative", "scan")  # as app.fit


def add_parser(sub) -> None:
    p = sub.add_parser(
        "fit",
        description="Calibrate D_R, D_L and b from recorded runs: generic run CSVs, OptiOdom "
        "folders (a data set such as square/230620202042, or a category folder such as square/), "
        "ROS bags, or relative-motion .tuple files. Nominal values come from --robot or from the "
        "recordings' metadata.",
    )
    add_recording_args(p)
    p.add_argument(
        "--robot",
        metavar="ROBOT.yaml",
        help="nominal geometry (and, for runs without metadata, the parameters they ran with: "
        "its 'believed', else nominal); default: the recordings' metadata",
    )
    p.add_argument(
        "--method",
        choices=METHODS,
        default=None,
        help="trajectory (nonlinear least squares, default), linear (Antonelli et al. 2005), "
        "umbmark / heading (recorded CW and CCW squares), gyro (IMU vs wheel rotation, bags), "
        "relative (Censi et al. 2013: relative motions with the sensor's mounting; the default "
        "for .tuple files and --truth-frames), scan (bags with a 2D laser: scan matching, then "
        "relative; the laser's mounting too)",
    )
    add_export_args(p, "write the calibrated parameters")
    p.add_argument(
        "--force",
        action="store_true",
        help="accept a result more than 25 %% from nominal (absurd for a calibration: by "
        "default an error, and nothing is written)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    t = p.add_argument_group("trajectory method")
    t.add_argument(
        "--residual",
        choices=("pose", "segment"),
        default="pose",
        help="pose: sampled pose errors, each run weighted equally (default); segment: relative "
        "displacement over path segments (OptiOdom)",
    )
    t.add_argument(
        "--segment-length",
        type=length_m,
        default=1.0,
        metavar="M",
        help="segment travel for --residual segment, m (default 1)",
    )
    t.add_argument(
        "--heading-weight",
        type=heading_weight,
        default=0.1,
        metavar="M_PER_RAD",
        help="metres of residual per radian of heading error (default 0.1)",
    )
    t.add_argument(
        "--run-weight",
        choices=("travel", "equal"),
        default="travel",
        help="weight of each run: its travel in m (default) or equal",
    )
    t.add_argument(
        "--exclude",
        action="append",
        default=[],
        metavar="RUN",
        help="leave a run out (file name, path or substring); repeatable",
    )
    t.add_argument(
        "--drop-outliers", action="store_true", help="refit without the runs flagged as outliers"
    )
    t.add_argument(
        "--wheelbase-model",
        choices=("constant", "banded"),
        default="constant",
        help="constant: one wheelbase (default); banded: one per band of motion (spot turns, "
        "tight arcs, wide arcs, near-straight) where the runs excite at least two bands "
        "(refused, with the reason, otherwise)",
    )
    t.add_argument(
        "--motion-mix",
        type=motion_mix,
        metavar="BAND=SHARE,...",
        help="export the single wheelbase that is best for this mix of motions (shares of the "
        "robot's rotation per band: spot, tight, wide, straight), e.g. spot=0.2,wide=0.8; "
        "reports what one value costs per band (default with --wheelbase-model banded: the "
        "runs' own mix)",
    )
    p.add_argument(
        "--robot-out",
        metavar="ROBOT.yaml",
        help="write the measured robot (this fit's systematic errors, k from the repeated runs "
        "among the inputs, the tracker's jitter) for 'odocal design --robot'",
    )
    t.add_argument(
        "--plot",
        metavar="DIR",
        help="write the effective wheelbase per band of motion (effective_wheelbase.png)",
    )
    s = p.add_argument_group("umbmark / heading methods")
    s.add_argument(
        "--side-length",
        type=length_m,
        metavar="L",
        help="square side, m (default: from the recordings' metadata)",
    )
    s.add_argument(
        "--umbmark-form",
        choices=("x", "y", "mean"),
        default="mean",
        help="UMBmark equations from x, y or their mean (default mean)",
    )
    s.add_argument(
        "--sides",
        type=sides_int,
        default=4,
        metavar="N",
        help="heading method: the runs are regular N-gons (default 4, squares)",
    )
    s.add_argument(
        "--heading-source",
        choices=("truth", "gyro"),
        default="truth",
        help="heading method: each run's final heading error from the ground truth (default) or "
        "from the integrated gyro (an IMU topic in the bag, or a gyro_yaw_rad column): no "
        "position ground truth needed",
    )
    add_slam_args(p)
    sc = p.add_argument_group("scan method (bags with a 2D laser)")
    sc.add_argument(
        "--scan-interval",
        type=number(float, above=0, at_most=60, hint=" s"),
        default=0.5,
        metavar="S",
        help="time between the two scans matched for one interval (default 0.5 s)",
    )
    g = p.add_argument_group("gyro method (bags)")
    g.add_argument("--odom-topic", metavar="T", help="nav_msgs/Odometry wheel odometry")
    g.add_argument("--imu-axis", metavar="A", help="IMU axis carrying the yaw rate (e.g. y, -z)")
    p.add_argument(
        "--list-topics", action="store_true", help="print the topics of the given bag(s) and exit"
    )
    p.set_defaults(run=run)


def _run_gyro(args) -> int:
    from ..app.fit import fit_gyro

    if len(args.paths) != 1:
        raise InputError("--method gyro takes exactly one bag", field="paths")
    res = fit_gyro(
        args.paths[0],
        robot=args.robot,
        out=args.out,
        ros2=args.ros2,
        controller_name=args.controller_name,
        odom_topic=args.odom_topic,
        imu_topic=args.imu_topic,
        joint_topic=args.joint_topic,
        imu_axis=args.imu_axis,
        force=args.force,
    )
    out = res.as_dict()
    print_warnings(res.warnings)
    if args.json:
        print_json(out)
        return 0
    print(f"gyro calibration of {out['bag']} ({out['imu_topic']} vs {out['odom_topic']})")
    print_table(
        [
            ("rotation_ratio (gyro / odometry)", f"{out['rotation_ratio']:.5f}"),
            ("  its standard error from the bias", f"{out['rotation_ratio_stderr']:.5f}"),
            ("wheelbase_multiplier", f"{out['wheelbase_multiplier']:.5f}"),
            ("gyro rotation (deg)", f"{math.degrees(out['gyro_rotation_rad']):+.2f}"),
            ("odometry rotation (deg)", f"{math.degrees(out['odometry_rotation_rad']):+.2f}"),
            ("IMU yaw axis", f"{out['axis']} ({out['mounting_source']})"),
            ("gyro bias removed (rad/s)", f"{out['bias_rad_s']:.3g} ({out['bias_source']})"),
        ]
    )
    if "calibrated_wheelbase_m" in out:
        print(f"  calibrated wheelbase_m: {out['calibrated_wheelbase_m']:.6f}")
    for f in res.written:
        print(f"wrote {f}")
    return 0


def run(args) -> int:
    if args.list_topics:
        from ..app.bag_info import bag_info
        from ..io.bags import is_bag

        for path in args.paths:
            if not is_bag(path):
                raise InputError("--list-topics needs a ROS bag (.bag, .db3, .mcap)", path)
        for path in args.paths:
            if len(args.paths) > 1:
                print(f"{path}:")
            print(format_topics(bag_info(path).topics))
        return 0
    if args.method == "gyro":
        return _run_gyro(args)
    from ..app.fit import fit

    truth_frames = None
    if args.truth_frames:
        from ..io.bag_slam import parse_truth_frames

        truth_frames = parse_truth_frames(args.truth_frames)
    res = fit(
        args.paths,
        args.method,
        truth_frames=truth_frames,
        slam_stamp_offset_s=args.slam_stamp_offset,
        scan_interval_s=args.scan_interval,
        robot=args.robot,
        out=args.out,
        ros2=args.ros2,
        controller_name=args.controller_name,
        ticks_per_rev=args.ticks_per_rev,
        bag_options={**bag_options(args), "scan_topic": args.scan_topic},
        residual=args.residual,
        segment_m=args.segment_length,
        heading_weight_m=args.heading_weight,
        exclude=args.exclude,
        drop_outliers=args.drop_outliers,
        run_weight=args.run_weight,
        side_m=args.side_length,
        umbmark_form=args.umbmark_form,
        heading_source=args.heading_source,
        sides=args.sides,
        force=args.force,
        wheelbase_model=args.wheelbase_model,
        motion_mix=args.motion_mix,
        plot=args.plot,
        robot_out=args.robot_out,
    )
    print_warnings(res.load_warnings)
    result, nominal = res.fit, res.nominal
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    if result.method == "relative":
        _print_relative(res)
        return 0
    print(f"{result.method} fit from {len(result.runs)} run(s)")
    g, se = result.geometry, result.stderr
    rows = [("", "nominal", "calibrated", "std. error")]
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        nom = "-" if nominal is None else f"{nominal.as_dict()[key]:.6f}"
        err = "-" if se.get(key) is None else f"{se[key]:.2e}"
        rows.append((key, nom, f"{g.as_dict()[key]:.6f}", err))
    print_table(rows)
    if "data_sets" in result.extras:
        print(
            f"pooled from {len(result.extras['data_sets'])} data set(s): per data set, "
            "composed with its ran-with parameters; scale = nominal mean diameter"
        )
    if result.excluded:
        print("excluded: " + ", ".join(Path(n).name for n in result.excluded))
    if "residual_rms" in result.extras:
        print(
            f"residual RMS {result.extras['residual_rms']:.3g} "
            f"({result.extras.get('residual', 'pose')})"
        )
    _print_bands(result.extras)
    if res.log_check is not None:
        from .check import print_check

        print("Is this log enough? (odocal check)")
        print_check(res.log_check, indent="  ")
    for f in res.written:
        print(f"wrote {f}")
    return 0


def _print_bands(extras: dict) -> None:
    """The effective wheelbase per band of motion, the banded fit and the motion mix."""
    table = extras.get("effective_wheelbase")
    if table:
        rows = [
            (
                "band",
                "turn radius (m)",
                "eff. wheelbase (m)",
                "95 % interval",
                "segments",
                "share of rotation",
            )
        ]
        for b in table["bands"]:
            lo, hi = b["radius_range_m"]
            radius = (
                f"< {hi:.3g}"
                if lo == 0
                else (f"> {lo:.3g}" if hi is None else f"{lo:.3g}-{hi:.3g}")
            )
            est = "not excited"
            ci = ""
            if b["excited"]:
                est = f"{b['wheelbase_m']:.6f}"
                ci = f"{b['ci95_m'][0]:.6f}-{b['ci95_m'][1]:.6f}"
            rows.append(
                (
                    b["band"],
                    radius,
                    est,
                    ci,
                    f"{b['segments']} ({b['runs']} runs)",
                    f"{100 * b['rotation_share']:.0f} %",
                )
            )
        print_table(rows, "effective wheelbase per band of motion (at the fitted diameters):")
    if extras.get("wheelbase_model") == "banded":
        fitted = ", ".join(f"{k} {v:.6f} m" for k, v in extras["band_wheelbase_m"].items())
        print(f"banded model: {fitted}")
    mix = extras.get("motion_mix")
    if mix:
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in mix["mix"].items())
        errs = ", ".join(f"{k} {v:+.2f}" for k, v in mix["heading_error_deg_per_turn"].items())
        print(
            f"single wheelbase for the motion mix ({shares}): {mix['wheelbase_m']:.6f} m; "
            f"heading error per full turn (deg): {errs}; RMS "
            f"{mix['rms_heading_error_deg_per_turn']:.2f} deg per turn"
        )


def _print_relative(res) -> None:
    r, nominal = res.fit, res.nominal
    print(
        f"relative-motion fit (Censi et al. 2013) from {r.tuples_used} of {r.tuples_total} "
        f"intervals ({r.tuples_total - r.tuples_used} dropped as outliers)"
    )
    d = r.as_dict()
    rows = [("", "nominal", "calibrated", "std. error")]
    nom = {} if nominal is None else nominal.as_dict()
    for key in (
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
        "sensor_x_m",
        "sensor_y_m",
        "sensor_yaw_rad",
    ):
        if key.startswith("sensor") and r.sensor_pose_fixed:
            continue
        v, se = d[key], d["stderr"].get(key)
        rows.append(
            (
                key,
                f"{nom[key]:.6f}" if key in nom else "-",
                "-" if v is None else f"{v:.6f}",
                "-" if se is None else f"{se:.2e}",
            )
        )
    print_table(rows)
    for s in res.extra.get("slam", ()):
        print(f"  {s['bag']}: {s['chain']}: {s['summary']}")
    for s in res.extra.get("scan", ()):
        g = s["mount_guess"]
        print(
            f"  {s['bag']}: {s['matched']} of {s['intervals']} scan intervals matched "
            f"({s['scans']} scans on {s['scan_topic']}, {s['interval_scans']} apart); laser "
            f"mounting from {s['mount_source']}: x {g['x_m']:.4f} m, y {g['y_m']:.4f} m, "
            f"yaw {g['yaw_rad']:.4f} rad"
        )
    for f in res.written:
        print(f"wrote {f}")
