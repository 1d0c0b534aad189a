"""``odocal check``: is this log enough? What the recorded motion lets a fit see."""

from __future__ import annotations

import argparse
from typing import Any

from ..calibration.fit_methods import RESIDUALS
from .common import (
    NOT_ENOUGH,
    add_recording_args,
    add_slam_args,
    bag_options,
    print_json,
    print_warnings,
    truth_frames,
)

__all__ = ["add_parser", "run"]


def add_parser(sub: Any) -> None:
    """Register ``odocal check`` on the subcommand parser ``sub``."""
    p = sub.add_parser(
        "check",
        description="From the motion actually recorded (wheel angles; ground truth optional): "
        "the Fisher information of D_R, D_L and b for the trajectory fit, the predicted "
        "standard errors, the condition number, the degenerate motions present (only straight "
        "lines, only spot turns, one turning direction, constant curvature, too little travel; "
        "named after Lee et al. 2020: no motion, pure translation, pure rotation, constant "
        "angular and linear velocity, one-axis rotation) and what to drive to fix them: the "
        "shortest top-up (spins, straights, figure-eights at the log's own speeds) that makes "
        "the log enough, or that halves its weakest standard error. The noise is ROBOT.yaml's "
        "nonsystematic k and measurement; else, with a SLAM truth (--truth-frames), the log's "
        "own residuals; else stated defaults, named in the output (docs/check.md). Exit "
        "status: 0 when the log is enough, 3 when it is NOT enough, 2 on an error.",
    )
    add_recording_args(p)
    p.add_argument(
        "--robot",
        metavar="ROBOT.yaml",
        help="nominal geometry (the linearisation point) and the noise (nonsystematic, "
        "measurement); default: the recordings' metadata and stated defaults",
    )
    p.add_argument(
        "--residual",
        choices=RESIDUALS,
        default="pose",
        help="the trajectory fit's residual (default pose)",
    )
    p.add_argument(
        "--mounting",
        action="store_true",
        help="also the mounting (x, y, yaw) of the ground-truth sensor (relative-motion fits)",
    )
    p.add_argument(
        "--kinematics",
        choices=("differential", "skid-steer"),
        default=None,
        help="skid-steer: bags of a skid-steer or tracked robot read as fit --kinematics "
        "skid-steer reads them; the standard errors are the skid-steer fit's own (its slip), "
        "and the turn rates its multiplier's curve can be read at; default: the robot file's "
        "'kinematics', else differential",
    )
    add_slam_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def run(args: argparse.Namespace) -> int:
    """Run ``odocal check``: print the check; exit 0 when the log is enough, 3 when not."""
    from ..app.check import check
    from ..calibration.fit_settings import TrajectorySettings

    res = check(
        args.paths,
        robot=args.robot,
        ticks_per_rev=args.ticks_per_rev,
        bag=bag_options(args),
        truth_frames=truth_frames(args),
        slam_stamp_offset_s=args.slam_stamp_offset,
        mounting=args.mounting,
        settings=TrajectorySettings(residual=args.residual),
        kinematics=args.kinematics,
    )
    print_warnings(res.load_warnings)
    status = 0 if res.check.ok else NOT_ENOUGH
    if args.json:
        print_json(res.as_dict())
        return status
    print(res.text())
    return status
