"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags)."""

from __future__ import annotations

import argparse
import math
from pathlib import Path
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
    format_topics,
    heading_weight,
    length_m,
    motion_mix,
    number,
    print_check,
    print_json,
    print_table,
    print_warnings,
    sides_int,
    truth_frames,
)

if TYPE_CHECKING:
    from ..app.fit import AutoFitResult, FitResult, GyroFitResult, RelativeFitResult
    from ..calibration.result import GeometryFit
    from ..calibration.time_offset import TimeOffset
    from ..calibration.turning import EffectiveWheelbase


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


def _print_gyro(res: GyroFitResult, as_json: bool) -> int:
    print_warnings(res.warnings)
    if as_json:
        print_json(res.as_dict())
        return 0
    g, meta = res.gyro, res.gyro.meta
    print(f"gyro calibration of {meta['bag']} ({meta['imu_topic']} vs {meta['odom_topic']})")
    print_table(
        [
            ("rotation_ratio (gyro / odometry)", f"{g.rotation_ratio:.5f}"),
            (
                "  its standard error from the bias",
                "- (no still period: bias unknown)"
                if g.rotation_ratio_stderr is None
                else f"{g.rotation_ratio_stderr:.5f}",
            ),
            ("wheelbase_multiplier", f"{g.wheelbase_multiplier:.5f}"),
            ("gyro rotation (deg)", f"{math.degrees(g.gyro_rotation_rad):+.2f}"),
            ("odometry rotation (deg)", f"{math.degrees(g.odometry_rotation_rad):+.2f}"),
            ("IMU yaw axis", f"{g.axis} ({g.mounting_source})"),
            ("gyro bias removed (rad/s)", f"{g.bias_rad_s:.3g} ({g.bias_source})"),
        ]
    )
    if res.geometry is not None:
        print(
            f"  calibrated wheelbase_m: {float(res.geometry.wheelbase_m):.6f} (the correction "
            f"applied to {res.base})"
        )
    o = res.time_offset
    if o is not None:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        print(f"  clock offset of the imu: {o.offset_s:+.4f}{se} s ({o.how})")
    _print_written(res.written)
    return 0


def _list_topics(paths: list[str]) -> int:
    from ..app.bag_info import bag_info
    from ..io.bags import is_bag

    for path in paths:
        if not is_bag(path):
            raise InputError("--list-topics needs a ROS bag (.bag, .db3, .mcap)", path)
    for path in paths:
        if len(paths) > 1:
            print(f"{path}:")
        print(format_topics(bag_info(path).topics))
    return 0


def run(args: argparse.Namespace) -> int:
    """Run ``odocal fit``: calibrate, print (text or JSON), return the exit status."""
    if args.list_topics:
        return _list_topics(args.paths)
    from ..app.fit import AutoFitResult, GyroFitResult, RelativeFitResult, fit
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
    )
    if isinstance(res, GyroFitResult):
        return _print_gyro(res, args.json)
    if isinstance(res, AutoFitResult):
        return _print_auto(res, args.json)
    print_warnings(res.load_warnings)
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
    elif isinstance(res, RelativeFitResult):
        _print_relative(res)
    else:
        _print_runs(res)
    return 0


def _print_written(written: tuple[Path, ...]) -> None:
    for f in written:
        print(f"wrote {f}")


def _print_runs(res: FitResult) -> None:
    """A fit of runs with ground truth: the geometry against nominal, then what the method adds
    and the log check."""
    result, nominal = res.fit, res.nominal
    print(f"{result.method} fit from {len(result.runs)} run(s)")
    g, se = result.geometry.as_dict(), result.stderr
    nom = None if nominal is None else nominal.as_dict()
    rows = [("", "nominal", "calibrated", "std. error")]
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        err = se.get(key)
        rows.append(
            (
                key,
                "-" if nom is None else f"{nom[key]:.6f}",
                f"{g[key]:.6f}",
                "-" if err is None else f"{err:.2e}",
            )
        )
    print_table(rows)
    if result.covariance_formal is not None:
        print(f"std. errors: {result.uncertainty} (formal ones in the JSON)")
    if result.squares is not None:
        print(
            f"pooled from {len(result.squares.data_sets)} data set(s): per data set, "
            "composed with its ran-with parameters; scale = nominal mean diameter"
        )
    if result.excluded:
        print("excluded: " + ", ".join(Path(n).name for n in result.excluded))
    rms = _residual_rms(result)
    if rms is not None:
        print(f"residual RMS {rms:.3g} ({_residual_kind(result)})")
    _print_bands(result)
    if res.log_check is not None:
        print("Is this log enough? (odocal check)")
        print_check(res.log_check, indent="  ")
    _print_offsets(res.time_offsets)
    if res.heldout is not None:
        print(res.heldout.verdict())
    for note in res.notes:
        print(note)
    _print_written(res.written)


def _print_offsets(offsets: tuple[TimeOffset, ...]) -> None:
    """The clock offsets: every applied one, and how many were found within their noise."""
    quiet = [o for o in offsets if not o.applied]
    for o in offsets:
        if o.applied:
            se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
            print(f"clock offset of the {o.source}: {o.offset_s:+.4f}{se} s ({o.how}; applied)")
    if quiet:
        worst = max(abs(o.offset_s) for o in quiet)
        print(
            f"clock offsets within their noise (not applied): {len(quiet)} of {len(offsets)} "
            f"source(s), at most {1e3 * worst:.1f} ms"
        )


def _residual_rms(fit: GeometryFit) -> float | None:
    if fit.trajectory is not None:
        return fit.trajectory.residual_rms
    return None if fit.banded is None else fit.banded.residual_rms


def _residual_kind(fit: GeometryFit) -> str:
    return "pose" if fit.trajectory is None else fit.trajectory.settings.residual


def _radius(lo: float, hi: float | None) -> str:
    if lo == 0:
        return f"< {hi:.3g}"
    return f"> {lo:.3g}" if hi is None else f"{lo:.3g}-{hi:.3g}"


def _print_band_table(table: EffectiveWheelbase) -> None:
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
    for b in table.bands:
        est, ci = "not excited", ""
        if b.excited and b.wheelbase_m is not None and b.ci95_m is not None:
            est = f"{b.wheelbase_m:.6f}"
            ci = f"{b.ci95_m[0]:.6f}-{b.ci95_m[1]:.6f}"
        rows.append(
            (
                b.band,
                _radius(*b.radius_range_m),
                est,
                ci,
                f"{b.segments} ({b.runs} runs)",
                f"{100 * b.rotation_share:.0f} %",
            )
        )
    print_table(rows, "effective wheelbase per band of motion (at the fitted diameters):")


def _print_bands(fit: GeometryFit) -> None:
    """The effective wheelbase per band of motion, the banded fit and the motion mix."""
    if fit.effective_wheelbase is not None:
        _print_band_table(fit.effective_wheelbase)
    if fit.banded is not None:
        fitted = ", ".join(f"{k} {v:.6f} m" for k, v in fit.banded.band_wheelbase_m.items())
        print(f"banded model: {fitted}")
    mix = fit.motion_mix
    if mix is not None:
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in mix.mix.items())
        errs = ", ".join(f"{k} {v:+.2f}" for k, v in mix.heading_error_deg_per_turn.items())
        se = "" if mix.wheelbase_stderr_m is None else f" +- {mix.wheelbase_stderr_m:.2e}"
        print(
            f"single wheelbase for the motion mix ({shares}): {mix.wheelbase_m:.6f}{se} m; "
            f"heading error per full turn (deg): {errs}; RMS "
            f"{mix.rms_heading_error_deg_per_turn:.2f} deg per turn"
        )


def _print_relative(res: RelativeFitResult) -> None:
    r, nominal = res.fit, res.nominal
    print(
        f"relative-motion fit (Censi et al. 2013) from {r.tuples_used} of {r.tuples_total} "
        f"intervals ({r.tuples_dropped} dropped as outliers)"
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
    if r.covariance_formal is not None:
        print(f"  std. errors: {r.uncertainty} (formal ones in the JSON)")
    for b in res.slam_bags:
        print(f"  {b.path}: {b.chain}: {b.motions.summary()}")
        print(f"    wheels: {b.wheels}")
    for s in res.scans:
        x, y, yaw = s.mount_guess
        print(
            f"  {s.bag}: {s.intervals.matched} of {s.intervals.intervals} scan intervals matched "
            f"({s.scans} scans on {s.scan_topic}, {s.intervals.interval_scans} apart); laser "
            f"mounting from {s.mount_source}: x {x:.4f} m, y {y:.4f} m, yaw {yaw:.4f} rad"
        )
    _print_checks(res)
    _print_written(res.written)


def _print_checks(res: RelativeFitResult) -> None:
    """Clock offsets, the held-out check, the answer's model and the one-log noise."""
    for o in res.time_offsets:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        print(f"  clock offset of the {o.source}: {o.offset_s:+.4f}{se} s ({o.how}; > 0: its "
              "stamps run late)")  # fmt: skip
    if res.heldout is not None:
        print(f"  {res.heldout.verdict()}")
    if res.model != "full":
        g, errs = res.geometry, res.geometry_stderr
        cells = [
            f"{name} {v:.6f}" + (" (nominal)" if not e else f" +- {e:.2e}")
            for name, v, e in zip(("D_R", "D_L", "b"), (g.diameter_right_m, g.diameter_left_m,
                                                        g.wheelbase_m), errs, strict=True)
        ]  # fmt: skip
        print(f"  the answer is the '{res.model}' model: {', '.join(cells)} m")
    if res.noise is not None:
        n = res.noise
        lo, hi = n.k_ci95_m
        print(
            f"  random error: wheels k_r + k_l {n.k_sum_m:.3g} m (95 %: {lo:.3g} to {hi:.3g}); "
            f"truth {1e3 * n.truth_sigma_xy_m:.3g} mm, {math.degrees(n.truth_sigma_theta_rad):.3g}"
            f" deg per interval ({n.intervals} intervals)"
        )
    for note in res.notes:
        print(f"  {note}")


def _print_auto(res: AutoFitResult, as_json: bool) -> int:
    """The one-command answer: the routes, the parameters, the checks, the verdict; exit 0
    when it can be trusted, :data:`NOT_ENOUGH` when not."""
    print_warnings(res.warnings)
    status = 0 if res.enough else NOT_ENOUGH
    if as_json:
        print_json(res.as_dict())
        return status
    print(f"one answer for {res.bag} (every route it allows, cross-checked)")
    for r in res.routes:
        print(f"  {r.name:10s} {'used' if r.used else 'not used'}: {r.reason}")
    a = res.answer
    if a is not None and a.geometry is not None:
        print(f"parameters (the {a.name} route's):")
        nom, g = res.nominal.as_dict(), a.geometry.as_dict()
        rows = [("", "nominal", "calibrated", "std. error")]
        for key, se in zip(("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"),
                           a.stderr, strict=True):  # fmt: skip
            rows.append(
                (key, f"{nom[key]:.6f}", f"{g[key]:.6f}", "-" if se is None else f"{se:.2e}")
            )
        print_table(rows)
    for o in res.time_offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        print(f"clock offset of the {o.source}: {o.offset_s:+.4f}{pm} s ({o.how})")
    if res.heldout is not None:
        print(res.heldout.verdict())
    for c in res.cross_checks:
        word = "agree" if c.agree else "DISAGREE"
        print(
            f"{c.routes[0]} vs {c.routes[1]} on {c.quantity}: {c.z:+.2f} standard errors ({word})"
        )
    if res.covariance is not None:
        cov = res.covariance
        print(f"covariances for diff_drive_controller: pose {list(cov.pose_diagonal)}, twist "
              f"{list(cov.twist_diagonal)} (k_r = k_l = {cov.k_r_m:.3g} m)")  # fmt: skip
    if res.enough:
        print("verdict: trustworthy")
    else:
        print("verdict: NOT to be trusted:")
        for reason in res.reasons:
            print(f"  - {reason}")
        if not res.written:
            print("nothing written (--force writes the files anyway)")
    _print_written(res.written)
    return status
