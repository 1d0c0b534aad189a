"""``odocal check``: is this log enough? What the recorded motion lets a fit see."""

from __future__ import annotations

from .common import (
    add_recording_args,
    add_slam_args,
    bag_options,
    print_json,
    print_table,
    print_warnings,
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "check",
        description="From the motion actually recorded (wheel angles; ground truth optional): "
        "the Fisher information of D_R, D_L and b for the trajectory fit, the predicted "
        "standard errors, the condition number, the degenerate motions present (only straight "
        "lines, only spot turns, one turning direction, constant curvature, too little travel) "
        "and what to drive to fix them. The noise is ROBOT.yaml's nonsystematic k and "
        "measurement, else stated defaults (docs/check.md).",
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
        choices=("pose", "segment"),
        default="pose",
        help="the trajectory fit's residual (default pose)",
    )
    p.add_argument(
        "--mounting",
        action="store_true",
        help="also the mounting (x, y, yaw) of the ground-truth sensor (relative-motion fits)",
    )
    add_slam_args(p)
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def print_check(res, indent: str = "") -> None:
    """The human-readable check (also the 'Is this log enough?' section of fit)."""
    c = res.check
    d = c.motion.as_dict()
    print(
        f"{indent}{'enough' if c.ok else 'NOT enough'} for "
        f"{', '.join(c.parameters)}: condition number {c.condition_number:.3g}; weakest: "
        f"{c.weakest_direction}"
    )
    rows = [("", "value", "predicted std. error")]
    for name, value in zip(c.parameters, c.values, strict=True):
        se = c.stderr[name]
        rows.append(
            (
                indent + name,
                f"{value:.6g}",
                "not identifiable" if se == float("inf") else f"{se:.2e}",
            )
        )
    print_table(rows)
    print(f"{indent}  motion: {_motion_line(d)}")
    for g in c.degeneracies:
        print(f"{indent}  {g.severity}: {g.message}")
    for s in c.suggestions:
        print(f"{indent}  suggestion: {s}")
    print(f"{indent}  noise: {res.noise_source}")


def _motion_line(d: dict) -> str:
    return (
        f"{d['travel_m']:.1f} m driven, {d['rotation_deg']:.0f} deg turned "
        f"({d['rotation_left_deg']:.0f} left, {d['rotation_right_deg']:.0f} right); wheel "
        f"travel {100 * d['share_straight']:.0f} % straight, {100 * d['share_spot']:.0f} % spot "
        f"turns, {100 * d['share_arc']:.0f} % arcs"
    )


def run(args) -> int:
    from ..app.check import check

    truth_frames = None
    if args.truth_frames:
        from ..io.bag_slam import parse_truth_frames

        truth_frames = parse_truth_frames(args.truth_frames)
    res = check(
        args.paths,
        robot=args.robot,
        ticks_per_rev=args.ticks_per_rev,
        bag_options=bag_options(args),
        truth_frames=truth_frames,
        mounting=args.mounting,
        residual=args.residual,
    )
    print_warnings(res.load_warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    print(f"Is this log enough? {res.recordings} run(s)")
    print_check(res)
    return 0
