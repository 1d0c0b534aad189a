"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags)."""

from __future__ import annotations

import math
import sys
from collections import Counter
from pathlib import Path

from ..errors import InputError
from .common import (
    length_m,
    nonnegative_float,
    positive_float,
    print_json,
    print_recording_warnings,
    print_table,
)

METHODS = ("trajectory", "linear", "umbmark", "heading", "gyro")


def add_bag_args(p) -> None:
    """Topic and joint options for ROS bags (shared with ``validate``)."""
    g = p.add_argument_group("ROS bags")
    g.add_argument("--joint-topic", metavar="T", help="sensor_msgs/JointState wheel positions")
    g.add_argument("--truth-topic", metavar="T", help="ground-truth pose (PoseStamped/Odometry)")
    g.add_argument("--imu-topic", metavar="T", help="sensor_msgs/Imu topic")
    g.add_argument("--right-joint", metavar="NAME", help="right wheel joint name")
    g.add_argument("--left-joint", metavar="NAME", help="left wheel joint name")


def add_parser(sub) -> None:
    p = sub.add_parser(
        "fit",
        help="calibrate wheel diameters and wheelbase from recorded runs",
        description="Calibrate D_R, D_L and b from recorded runs: generic run CSVs, OptiOdom "
        "folders (a data set such as square/230620202042, or a category folder such as square/) "
        "or ROS bags. Nominal values come from --robot or from the recordings' metadata.",
    )
    p.add_argument("paths", nargs="+", metavar="RUN_OR_DIR", help="run file, folder or bag")
    p.add_argument(
        "--robot",
        metavar="ROBOT.yaml",
        help="nominal geometry (and, for runs without metadata, the parameters they ran with: "
        "its 'believed', else nominal); default: the recordings' metadata",
    )
    p.add_argument(
        "--method",
        choices=METHODS,
        default="trajectory",
        help="trajectory (nonlinear least squares, default), linear (Antonelli et al. 2005), "
        "umbmark / heading (recorded CW and CCW squares), gyro (IMU vs wheel rotation, bags)",
    )
    p.add_argument("--out", metavar="PARAMS.yaml", help="write the calibrated parameters")
    p.add_argument(
        "--ros2", metavar="FILE.yaml", help="write a ros2_control diff_drive_controller file"
    )
    p.add_argument(
        "--controller-name",
        default="diff_drive_controller",
        metavar="NAME",
        help="controller name in the --ros2 file (default diff_drive_controller)",
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
        type=nonnegative_float,
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
    p.add_argument(
        "--ticks-per-rev",
        type=positive_float,
        metavar="N",
        help="encoder ticks per wheel revolution for tick inputs that do not give it",
    )
    add_bag_args(p)
    g = p.add_argument_group("gyro method (bags)")
    g.add_argument("--odom-topic", metavar="T", help="nav_msgs/Odometry wheel odometry")
    g.add_argument("--imu-axis", metavar="A", help="IMU axis carrying the yaw rate (e.g. y, -z)")
    p.add_argument(
        "--list-topics", action="store_true", help="print the topics of the given bag(s) and exit"
    )
    p.set_defaults(run=run)


def _bags():
    try:
        from ..io import bags
    except ImportError:
        raise InputError(
            "ROS bag support is not available in this build (odocal.io.bags is missing; "
            "install odocal with the 'bags' extra)"
        ) from None
    return bags


def bag_options(args) -> dict:
    return {
        "joint_topic": getattr(args, "joint_topic", None),
        "truth_topic": getattr(args, "truth_topic", None),
        "imu_topic": getattr(args, "imu_topic", None),
        "right_joint": getattr(args, "right_joint", None),
        "left_joint": getattr(args, "left_joint", None),
    }


def nominal_geometry(robot_spec, recordings):
    """Nominal geometry: ROBOT.yaml's if given, else the most common ``ran_with`` (or None)."""
    if robot_spec:
        from ..io.robot_file import load_robot

        return load_robot(robot_spec).nominal
    counts = Counter(r.ran_with for r in recordings if r.ran_with is not None)
    return counts.most_common(1)[0][0] if counts else None


def fit_recordings(
    recordings,
    method: str = "trajectory",
    *,
    nominal=None,
    ran_with=None,
    residual: str = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    exclude=(),
    drop_outliers: bool = False,
    run_weight: str = "travel",
    side_m: float | None = None,
    umbmark_form: str = "mean",
):
    """Calibrate from loaded recordings (with ground truth); returns a ``GeometryFit``."""
    from ..calibration.linear import fit_linear
    from ..calibration.squares import fit_recorded_squares
    from ..calibration.trajectory import fit_trajectory
    from ..io.recordings import require_ground_truth

    require_ground_truth(recordings, f"--method {method}")
    if method == "linear":
        return fit_linear(recordings, nominal)
    if method == "trajectory":
        return fit_trajectory(
            recordings,
            nominal=nominal,
            residual=residual,
            segment_m=segment_m,
            heading_weight_m=heading_weight_m,
            exclude=exclude,
            drop_outliers=drop_outliers,
            run_weight=run_weight,
        )
    if method in ("umbmark", "heading"):
        return fit_recorded_squares(
            recordings,
            method,
            side_m=side_m,
            ran_with=ran_with,
            nominal=nominal,
            umbmark_form=umbmark_form,
        )
    raise InputError(f"unknown method {method!r}", field="method")


def _run_gyro(args) -> int:
    bags = _bags()
    if len(args.paths) != 1:
        raise InputError("--method gyro takes exactly one bag", field="paths")
    nominal = None
    if args.robot:
        from ..io.robot_file import load_robot

        nominal = load_robot(args.robot).nominal
    opts = {
        "odom_topic": args.odom_topic,
        "imu_topic": args.imu_topic,
        "joint_topic": args.joint_topic,
        "imu_axis": args.imu_axis,
        "wheel_geometry": nominal,
    }
    result = bags.fit_gyro_from_bag(args.paths[0], **{k: v for k, v in opts.items() if v})
    out = result.as_dict()
    if (args.out or args.ros2) and nominal is None:
        raise InputError("--out/--ros2 with --method gyro need the nominal geometry: --robot")
    if nominal is not None:
        from ..core.model import WheelGeometry

        # effective wheelbase = nominal b x wheelbase_multiplier (diameters unchanged)
        geometry = WheelGeometry(
            nominal.diameter_right_m,
            nominal.diameter_left_m,
            nominal.wheelbase_m * out["wheelbase_multiplier"],
        )
        _write_outputs(args, geometry, nominal, "gyro")
        out.update({f"calibrated_{k}": v for k, v in geometry.as_dict().items()})
    for w in out.get("warnings", []):
        print(f"odocal: warning: {w}", file=sys.stderr)
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
    return 0


def _write_outputs(args, geometry, nominal, method) -> None:
    from ..io.robot_file import params_yaml
    from ..io.textfile import atomic_write

    if args.ros2:
        from ..io.ros2_export import ros2_params_yaml

        if nominal is None:
            raise InputError("--ros2 needs the nominal geometry: give --robot ROBOT.yaml")
        text = ros2_params_yaml(geometry, nominal, args.controller_name, method=method)
    if args.out:
        atomic_write(args.out, params_yaml(geometry, method=method))
    if args.ros2:
        atomic_write(args.ros2, text)


def run(args) -> int:
    from ..io.recordings import is_bag, load_recordings

    if args.list_topics:
        for path in args.paths:
            if not is_bag(path):
                raise InputError("--list-topics needs a ROS bag (.bag, .db3, .mcap)", path)
        bags = _bags()
        for path in args.paths:
            if len(args.paths) > 1:
                print(f"{path}:")
            print(bags.format_topics(bags.list_topics(path)))
        return 0
    if args.method == "gyro":
        return _run_gyro(args)
    recordings = load_recordings(args.paths, ticks_per_rev=args.ticks_per_rev, **bag_options(args))
    print_recording_warnings(recordings)
    nominal = nominal_geometry(args.robot, recordings)
    ran_with = None
    if args.robot:
        from ..io.robot_file import load_robot

        ran_with = load_robot(args.robot).believed_geometry
    result = fit_recordings(
        recordings,
        args.method,
        nominal=nominal,
        ran_with=ran_with,
        residual=args.residual,
        segment_m=args.segment_length,
        heading_weight_m=args.heading_weight,
        exclude=args.exclude,
        drop_outliers=args.drop_outliers,
        run_weight=args.run_weight,
        side_m=args.side_length,
        umbmark_form=args.umbmark_form,
    )
    _write_outputs(args, result.geometry, nominal, result.method)
    out = result.as_dict()
    out["nominal"] = None if nominal is None else nominal.as_dict()
    for w in result.warnings:
        print(f"odocal: warning: {w}", file=sys.stderr)
    if args.json:
        print_json(out)
        return 0
    print(f"{result.method} fit from {len(result.runs)} run(s)")
    g, se = result.geometry, result.stderr
    rows = [("", "nominal", "calibrated", "std. error")]
    for key, label in (
        ("wheel_diameter_right_m", "wheel_diameter_right_m"),
        ("wheel_diameter_left_m", "wheel_diameter_left_m"),
        ("wheelbase_m", "wheelbase_m"),
    ):
        nom = "-" if nominal is None else f"{nominal.as_dict()[key]:.6f}"
        err = "-" if se.get(key) is None else f"{se[key]:.2e}"
        rows.append((label, nom, f"{g.as_dict()[key]:.6f}", err))
    print_table(rows)
    if "data_sets" in result.extras:
        print(
            f"pooled from {len(result.extras['data_sets'])} data set(s): per data set, "
            "composed with its ran-with parameters; scale = nominal mean diameter"
        )
    if result.excluded:
        print("excluded: " + ", ".join(Path(n).name for n in result.excluded))
    if "residual_rms" in result.extras:
        print(f"residual RMS {result.extras['residual_rms']:.3g} ({result.extras['residual']})")
    for f in (args.out, args.ros2):
        if f:
            print(f"wrote {f}")
    return 0
