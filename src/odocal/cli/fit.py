"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags)."""

from __future__ import annotations

import argparse
from typing import TYPE_CHECKING, Any

from ..calibration.fit_methods import (
    FIT_METHODS,
    HEADING_SOURCES,
    RESIDUALS,
    RUN_WEIGHTS,
    UMBMARK_FORMS,
    WHEELBASE_MODELS,
    methods_help,
)
from ..errors import InputError
from .common import (
    NOT_ENOUGH,
    add_export_args,
    add_recording_args,
    add_slam_args,
    bag_options,
    heading_weight,
    length_m,
    motion_mix,
    number,
    print_json,
    print_warnings,
    sides_int,
    truth_frames,
)

if TYPE_CHECKING:
    pass


def add_parser(sub: Any) -> None:
    """Register ``odocal fit`` on the subcommand parser ``sub``."""
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
    p.add_argument("--method", choices=FIT_METHODS, default=None, help=methods_help())
    p.add_argument(
        "--kinematics",
        choices=("differential", "skid-steer"),
        default=None,
        help="differential (a two-wheel differential drive) or skid-steer (a skid-steer or "
        "tracked robot: the effective track, the diff_drive_controller multipliers, the track "
        "against the turn rate; bags with a truth pose track, else with an IMU, or --method "
        "gyro / scan for the gyro's or the laser's heading alone); default: the robot file's "
        "'kinematics', else differential",
    )
    add_export_args(p, "write the calibrated parameters")
    p.add_argument(
        "--force",
        action="store_true",
        help="accept a result more than 25 %% from nominal (absurd for a calibration: by "
        "default an error, and nothing is written)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    _add_trajectory_args(p)
    _add_square_args(p)
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


def _add_trajectory_args(p: argparse.ArgumentParser) -> None:
    """The trajectory fit's settings (TrajectorySettings), the measured robot and the figure."""
    t = p.add_argument_group("trajectory method")
    t.add_argument(
        "--residual",
        choices=RESIDUALS,
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
        choices=RUN_WEIGHTS,
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
        choices=WHEELBASE_MODELS,
        default="constant",
        help="constant: one wheelbase (default); banded: one per band of motion (spot turns, "
        "tight arcs, wide arcs, near-straight) where the runs excite at least two bands "
        "(refused, with the reason, otherwise)",
    )
    t.add_argument(
        "--motion-mix",
        type=motion_mix,
        metavar="BAND=SHARE,...",
        help="fit the banded model and export the single wheelbase that is best for this mix "
        "of motions (shares of the robot's rotation per band: spot, tight, wide, straight), "
        "e.g. spot=0.2,wide=0.8, with its standard error and what one value costs per band; "
        "every band of the mix must be excited by the runs (default with --wheelbase-model "
        "banded: the runs' own mix)",
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


def _add_square_args(p: argparse.ArgumentParser) -> None:
    """UMBmark's and the heading method's settings (SquareSettings)."""
    s = p.add_argument_group("umbmark / heading methods")
    s.add_argument(
        "--side-length",
        type=length_m,
        metavar="L",
        help="square side, m (default: from the recordings' metadata)",
    )
    s.add_argument(
        "--umbmark-form",
        choices=UMBMARK_FORMS,
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
        choices=HEADING_SOURCES,
        default="truth",
        help="heading method: each run's final heading error from the ground truth (default) or "
        "from the integrated gyro (an IMU topic in the bag, or a gyro_yaw_rad column): no "
        "position ground truth needed",
    )


def _list_topics(paths: list[str]) -> int:
    from ..app.text import format_topics
    from ..io.bags import is_bag, list_topics

    for path in paths:
        if not is_bag(path):
            raise InputError("--list-topics needs a ROS bag (.bag, .db3, .mcap)", path)
    for path in paths:
        if len(paths) > 1:
            print(f"{path}:")
        print(format_topics(list_topics(path)))
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``odocal fit``: calibrate, print (text or JSON), return the exit status."""
    if args.list_topics:
        return _list_topics(args.paths)
    from ..app.fit import AutoFitResult, SkidFitResult, SkidGyroResult, fit
    from ..calibration.fit_settings import SquareSettings, TrajectorySettings

    res = fit(
        args.paths,
        args.method,
        robot=args.robot,
        settings=TrajectorySettings(
            residual=args.residual,
            segment_m=args.segment_length,
            heading_weight_m=args.heading_weight,
            run_weight=args.run_weight,
            exclude=tuple(args.exclude),
            drop_outliers=args.drop_outliers,
            wheelbase_model=args.wheelbase_model,
            motion_mix=args.motion_mix,
        ),
        squares=SquareSettings(
            side_m=args.side_length,
            umbmark_form=args.umbmark_form,
            heading_source=args.heading_source,
            sides=args.sides,
        ),
        bag=bag_options(args),
        ticks_per_rev=args.ticks_per_rev,
        truth_frames=truth_frames(args),
        slam_stamp_offset_s=args.slam_stamp_offset,
        scan_interval_s=args.scan_interval,
        out=args.out,
        ros2=args.ros2,
        controller_name=args.controller_name,
        plot=args.plot,
        robot_out=args.robot_out,
        force=args.force,
        kinematics=args.kinematics,
    )
    untrusted = (
        isinstance(res, (AutoFitResult, SkidFitResult, SkidGyroResult)) and not res.enough
    )
    status = NOT_ENOUGH if untrusted else 0
    print_warnings(getattr(res, "load_warnings", ()))
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
    else:
        print(res.text())
    return status
