"""``odocal noise``: the non-systematic error parameters k_r, k_l, from RUNS.csv of repeated
straight runs (with --track) or from recorded runs of repeated tracks."""

from __future__ import annotations

import math

from ..errors import InputError
from .common import (
    add_bag_args,
    add_robot_args,
    bag_options,
    driven_length_m,
    noise_track,
    print_json,
    print_table,
    print_warnings,
    sigma_theta_deg,
    sigma_xy_m,
    speed_m_s,
    ticks_per_rev,
    twist_window_s,
)


def add_parser(sub) -> None:
    """Add ``odocal noise``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "noise",
        description="Estimate the non-systematic wheel-noise parameters (k in METRES; Chong & "
        "Kleeman's m^0.5 value is the square root). Two inputs: RUNS.csv of repeated "
        "out-and-back or one-way straight runs with --track (direction 'fwd'; see 'odocal plan "
        "--track'), or recorded runs (OptiOdom folders, run CSVs, bags) of repeated tracks, "
        "e.g. CW and CCW squares: their run-to-run spread around each group's mean.",
    )
    p.add_argument(
        "paths",
        nargs="+",
        metavar="RUNS.csv|RUN_OR_DIR",
        help="RUNS.csv (with --track), or recorded runs: files, folders, bags",
    )
    add_robot_args(
        p,
        "RUNS.csv: parameters the robot ran with (default: ROBOT.yaml's 'believed', else "
        "nominal); the wheelbase b of the estimators is ROBOT.yaml's true one, nominal x E_b",
        required=True,
    )
    p.add_argument(
        "--track",
        type=noise_track,
        metavar="out-and-back:D|straight:D",
        help="RUNS.csv: what was driven: out-and-back:D (forward D m, then backward D m "
        "without turning; systematic errors cancel) or straight:D (forward D m)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="estimate k even when the runs look dominated by a systematic part (a warning "
        "instead of an error)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    r = p.add_argument_group("recorded runs")
    r.add_argument(
        "--sigma-xy-m",
        type=sigma_xy_m,
        metavar="S",
        help="the instrument's position noise per measured final pose, m (default: ROBOT.yaml's "
        "measurement, else the tracker's jitter in the recordings)",
    )
    r.add_argument(
        "--sigma-theta-deg",
        type=sigma_theta_deg,
        metavar="S",
        help="the instrument's heading noise per measured final pose, deg (as --sigma-xy-m)",
    )
    r.add_argument(
        "--robot-out",
        metavar="ROBOT.yaml",
        help="write the measured robot (nominal, systematic errors, k, instrument) for "
        "'odocal design --robot'",
    )
    r.add_argument(
        "--ros2",
        metavar="FILE.yaml",
        help="write a ros2_control diff_drive_controller file with the calibrated geometry and "
        "the pose/twist covariances from k (docs/ros.md)",
    )
    r.add_argument(
        "--controller-name",
        default="diff_drive_controller",
        metavar="NAME",
        help="controller name in the --ros2 file (default diff_drive_controller)",
    )
    r.add_argument(
        "--speed",
        type=speed_m_s,
        metavar="M_PER_S",
        help="speed the covariances are for, m/s (default: the runs' cruise speed)",
    )
    r.add_argument(
        "--pose-distance",
        type=driven_length_m,
        default=1.0,
        metavar="M",
        help="travel after which the pose covariance is given, m (default 1)",
    )
    r.add_argument(
        "--twist-window",
        type=twist_window_s,
        default=0.2,
        metavar="S",
        help="time over which the controller measures its velocity, s (default 0.2: "
        "diff_drive_controller's rolling window of 10 samples at 50 Hz)",
    )
    r.add_argument(
        "--ticks-per-rev",
        type=ticks_per_rev,
        metavar="N",
        help="encoder ticks per wheel revolution for tick inputs that do not give it",
    )
    add_bag_args(p)
    p.set_defaults(run=run)


def _fmt(v, f=".4g"):
    return "-" if v is None else format(v, f)


def _k_rows(k_sum, ci, k_r, k_l):
    lo, hi = ci
    return [
        ("", "k (m)", "95 % interval (m)", "Chong & Kleeman k (m^0.5)"),
        ("k_r + k_l", _fmt(k_sum), f"{lo:.4g} .. {hi:.4g}", ""),
        (
            "k each, if k_r = k_l",
            _fmt(k_sum / 2),
            f"{lo / 2:.4g} .. {hi / 2:.4g}",
            _fmt(math.sqrt(max(k_sum, 0.0) / 2)),
        ),
        ("k_r", _fmt(k_r), "", "-" if k_r is None else _fmt(math.sqrt(k_r))),
        ("k_l", _fmt(k_l), "", "-" if k_l is None else _fmt(math.sqrt(k_l))),
    ]


_UNITS = (
    "  units: k here is in metres (variance k |ds| per wheel travel ds); Chong & Kleeman's "
    "k in m^0.5 is its square root"
)


def run(args) -> int:
    """Run ``odocal noise`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    if args.track is not None:
        return _run_sheet(args)
    if args.params is not None:
        raise InputError("--params is for RUNS.csv (with --track); recorded runs are fitted")
    from ..app.noise import noise_recordings

    res = noise_recordings(
        args.paths,
        robot=args.robot,
        sigma_xy_m=args.sigma_xy_m,
        sigma_theta_deg=args.sigma_theta_deg,
        force=args.force,
        robot_out=args.robot_out,
        ros2=args.ros2,
        controller_name=args.controller_name,
        speed_m_s=args.speed,
        distance_m=args.pose_distance,
        window_s=args.twist_window,
        ticks_per_rev=args.ticks_per_rev,
        bag=bag_options(args),
    )
    print_warnings(res.load_warnings)
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    m = res.measured
    est = m.noise
    print(
        f"{est.runs} repeated runs in {len(est.groups)} groups ({est.dof} degrees of freedom), "
        f"wheelbase b = {est.wheelbase_m:.6g} m (trajectory fit of the runs)"
    )
    print_table(_k_rows(est.k_sum_m, est.k_sum_ci95_m, est.k_r_m, est.k_l_m))
    print(f"  {est.split_note}")
    rows = [("group", "runs", "travel (m)", "heading std (deg)", "its k_r + k_l (m)")]
    for g in est.groups:
        rows.append(
            (
                g["group"],
                str(g["runs"]),
                f"{g['travel_m']:.3g}",
                f"{g['theta_std_deg']:.3f}",
                f"{g['k_sum_m']:.3g} ({g['k_sum_ci95'][0]:.2g}-{g['k_sum_ci95'][1]:.2g})",
            )
        )
    print_table(rows, "per group (a check of the model: k should not depend on the track):")
    if est.skipped:
        print(f"  left out: {'; '.join(est.skipped)}")
    r = m.robot
    print(
        f"robot: E_b {r.systematic.E_b:.6f}, E_d {r.systematic.E_d:.6f}, E_s "
        f"{r.systematic.E_s:.6f} relative to nominal; instrument sigma_xy "
        f"{r.measurement.sigma_xy_m * 1000:.3g} mm, sigma_theta "
        f"{math.degrees(r.measurement.sigma_theta_rad):.3g} deg ({m.measurement_source})"
    )
    if res.covariance is not None:
        c = res.covariance
        print(
            f"ros2 covariances at {c.speed_m_s:.3g} m/s: pose (after {c.distance_m:g} m) x "
            f"{c.pose_diagonal[0]:.3g} m^2, y {c.pose_diagonal[1]:.3g} m^2, yaw "
            f"{c.pose_diagonal[5]:.3g} rad^2; twist (over {c.window_s:g} s) vx "
            f"{c.twist_diagonal[0]:.3g} (m/s)^2, wz {c.twist_diagonal[5]:.3g} (rad/s)^2"
        )
    print(_UNITS)
    for f in res.written:
        print(f"wrote {f}")
    return 0


def _run_sheet(args) -> int:
    from ..app.noise import noise

    if len(args.paths) != 1:
        raise InputError("--track takes exactly one RUNS.csv", field="paths")
    for flag in ("robot_out", "ros2", "sigma_xy_m", "sigma_theta_deg", "speed"):
        if getattr(args, flag) is not None:
            raise InputError(
                f"--{flag.replace('_', '-')} is for recorded runs (without --track); for RUNS.csv "
                "put the instrument in ROBOT.yaml's measurement"
            )
    kind, dist = args.track
    est = noise(
        args.paths[0], args.robot, params=args.params, track=kind, distance_m=dist, force=args.force
    )
    print_warnings(est.warnings)
    if args.json:
        print_json(est.as_dict())
        return 0
    print(
        f"{kind} {dist:g} m: {est.runs} runs, wheelbase b = {est.wheelbase_m:g} m, "
        f"final heading error {math.degrees(est.theta_mean_rad):+.4f} deg mean, "
        f"{math.degrees(est.theta_std_rad):.4f} deg std"
    )
    print_table(_k_rows(est.k_sum_m, est.k_sum_ci95_m, est.k_r_m, est.k_l_m))
    print(f"  {est.split_note}")
    if est.measurement_var_theta_rad2 > 0:
        print(
            "  the instrument's heading noise "
            f"({math.degrees(math.sqrt(est.measurement_var_theta_rad2)):.4g} deg, ROBOT.yaml "
            "measurement) was subtracted from the heading spread"
        )
    print(_UNITS)
    return 0
