"""The text of ``odocal fit`` for each route's result (their ``text()``, so ``str(result)``):
the geometry against nominal, what the route adds, the checks and the files written."""

from __future__ import annotations

import math
from pathlib import Path
from typing import TYPE_CHECKING

from ..calibration.censi import PARAMETERS
from .text import Text, check_text, written_lines

if TYPE_CHECKING:
    from ..calibration.result import GeometryFit
    from ..calibration.route_answer import RouteAnswer
    from ..calibration.time_offset import TimeOffset
    from ..calibration.turning import EffectiveWheelbase
    from .fit_auto_result import AutoFitResult
    from .fit_gyro import GyroFitResult
    from .fit_relative import RelativeFitResult
    from .fit_runs import FitResult

__all__ = ["runs_text", "relative_text", "auto_text", "gyro_text"]


def gyro_text(res: GyroFitResult) -> str:
    """The text of ``odocal fit --method gyro``."""
    out = Text()
    g, meta = res.gyro, res.gyro.meta
    out(f"gyro calibration of {meta['bag']} ({meta['imu_topic']} vs {meta['odom_topic']})")
    out.table(
        [
            ("rotation_ratio (gyro / odometry)", f"{g.rotation_ratio:.5f}"),
            (
                "  its standard error (bias, noise, drift)",
                "- (too short to estimate)"
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
        out(
            f"  calibrated wheelbase_m: {float(res.geometry.wheelbase_m):.6f} (the correction "
            f"applied to {res.base})"
        )
    o = res.time_offset
    if o is not None:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"  clock offset of the imu: {o.offset_s:+.4f}{se} s ({o.how})")
    written_lines(out, res.written)
    return str(out)


def runs_text(res: FitResult) -> str:
    """The text of a fit of runs with ground truth: the geometry against nominal, then what the
    method adds and the log check."""
    out = Text()
    result, nominal = res.fit, res.nominal
    out(f"{result.method} fit from {len(result.runs)} run(s)")
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
    out.table(rows)
    if result.covariance_formal is not None:
        out(f"std. errors: {result.uncertainty} (formal ones in the JSON)")
    if result.squares is not None:
        out(
            f"pooled from {len(result.squares.data_sets)} data set(s): per data set, "
            "composed with its ran-with parameters; scale = nominal mean diameter"
        )
    if result.excluded:
        out("excluded: " + ", ".join(Path(n).name for n in result.excluded))
    rms = _residual_rms(result)
    if rms is not None:
        out(f"residual RMS {rms:.3g} ({_residual_kind(result)})")
    _print_bands(out, result)
    if res.log_check is not None:
        out("Is this log enough? (odocal check)")
        check_text(out, res.log_check, indent="  ")
    _print_offsets(out, res.time_offsets)
    if res.heldout is not None:
        out(res.heldout.verdict())
    for note in res.notes:
        out(note)
    written_lines(out, res.written)
    return str(out)


def _print_offsets(out: Text, offsets: tuple[TimeOffset, ...]) -> None:
    """The clock offsets: every applied one, and how many were found within their noise."""
    quiet = [o for o in offsets if not o.applied]
    for o in offsets:
        if o.applied:
            se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
            out(f"clock offset of the {o.source}: {o.offset_s:+.4f}{se} s ({o.how}; applied)")
    if quiet:
        worst = max(abs(o.offset_s) for o in quiet)
        out(
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


def _print_band_table(out: Text, table: EffectiveWheelbase) -> None:
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
    out.table(rows, "effective wheelbase per band of motion (at the fitted diameters):")


def _print_bands(out: Text, fit: GeometryFit) -> None:
    """The effective wheelbase per band of motion, the banded fit and the motion mix."""
    if fit.effective_wheelbase is not None:
        _print_band_table(out, fit.effective_wheelbase)
    if fit.banded is not None:
        fitted = ", ".join(f"{k} {v:.6f} m" for k, v in fit.banded.band_wheelbase_m.items())
        out(f"banded model: {fitted}")
    mix = fit.motion_mix
    if mix is not None:
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in mix.mix.items())
        errs = ", ".join(f"{k} {v:+.2f}" for k, v in mix.heading_error_deg_per_turn.items())
        se = "" if mix.wheelbase_stderr_m is None else f" +- {mix.wheelbase_stderr_m:.2e}"
        out(
            f"single wheelbase for the motion mix ({shares}): {mix.wheelbase_m:.6f}{se} m; "
            f"heading error per full turn (deg): {errs}; RMS "
            f"{mix.rms_heading_error_deg_per_turn:.2f} deg per turn"
        )


def relative_text(res: RelativeFitResult) -> str:
    """The text of a relative-motion fit (``.tuple`` files, SLAM bags, laser scans)."""
    out = Text()
    r, nominal = res.fit, res.nominal
    out(
        f"relative-motion fit (Censi et al. 2013) from {r.tuples_used} of {r.tuples_total} "
        f"intervals ({r.tuples_dropped} dropped as outliers)"
    )
    d = r.as_dict()
    rows = [("", "nominal", "calibrated", "std. error")]
    nom = {} if nominal is None else nominal.as_dict()
    for key in PARAMETERS:
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
    out.table(rows)
    if r.covariance_formal is not None:
        out(f"  std. errors: {r.uncertainty} (formal ones in the JSON)")
    for b in res.slam_bags:
        out(f"  {b.path}: {b.chain}: {b.motions.summary()}")
        out(f"    wheels: {b.wheels}")
    for s in res.scans:
        x, y, yaw = s.mount_guess
        out(
            f"  {s.bag}: {s.intervals.matched} of {s.intervals.intervals} scan intervals matched "
            f"({s.scans} scans on {s.scan_topic}, {s.intervals.interval_scans} apart); laser "
            f"mounting from {s.mount_source}: x {x:.4f} m, y {y:.4f} m, yaw {yaw:.4f} rad"
        )
    _print_checks(out, res)
    written_lines(out, res.written)
    return str(out)


def _print_checks(out: Text, res: RelativeFitResult) -> None:
    """Clock offsets, the held-out check, the answer's model and the one-log noise."""
    for o in res.time_offsets:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"  clock offset of the {o.source}: {o.offset_s:+.4f}{se} s ({o.how}; > 0: its "
              "stamps run late)")  # fmt: skip
    if res.heldout is not None:
        out(f"  {res.heldout.verdict()}")
    if res.model != "full":
        g, errs = res.geometry, res.geometry_stderr
        cells = [
            f"{name} {v:.6f}" + (" (nominal)" if not e else f" +- {e:.2e}")
            for name, v, e in zip(("D_R", "D_L", "b"), (g.diameter_right_m, g.diameter_left_m,
                                                        g.wheelbase_m), errs, strict=True)
        ]  # fmt: skip
        out(f"  the answer is the '{res.model}' model: {', '.join(cells)} m")
    if res.noise is not None:
        n = res.noise
        lo, hi = n.k_ci95_m
        out(
            f"  random error: wheels k_r + k_l {n.k_sum_m:.3g} m (95 %: {lo:.3g} to {hi:.3g}); "
            f"truth {1e3 * n.truth_sigma_xy_m:.3g} mm, {math.degrees(n.truth_sigma_theta_rad):.3g}"
            f" deg per interval ({n.intervals} intervals)"
        )
    for note in res.notes:
        out(f"  {note}")


def _model_words(answer: RouteAnswer) -> str:
    """The model a route settled on, and what it held."""
    if answer.model == "heading-ratio":
        return "heading ratio: the diameters held"
    if answer.model == "full":
        return "full model"
    held = ", ".join(answer.held)
    tied = "the diameters tied to one scale" if answer.model != "full" else ""
    what = "; ".join(x for x in (tied, f"{held} held" if held else "") if x)
    return f"'{answer.model}' model: {what}"


def auto_text(res: AutoFitResult) -> str:
    """The text of the one-command answer: the routes, the parameters, the checks, the
    verdict."""
    out = Text()
    out(f"one answer for {res.bag} (every route it allows, cross-checked)")
    for r in res.routes:
        model = "" if r.answer is None else f" ({_model_words(r.answer)})"
        out(f"  {r.name:10s} {'used' if r.used else 'not used'}{model}: {r.reason}")
    a = res.answer
    if a is not None and a.answer is not None:
        out(f"parameters (the {a.name} route's, {_model_words(a.answer)}):")
        nom = res.nominal.as_dict()
        rows = [("", "nominal", "calibrated", "std. error")]
        for p in a.answer.parameters:
            se = p.std_error
            err = "held" if p.status == "held" else ("-" if se is None else f"{se:.2e}")
            rows.append((p.name, f"{nom[p.name]:.6f}", f"{p.value:.6f}", err))
        out.table(rows)
    for o in res.time_offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"clock offset of the {o.source}: {o.offset_s:+.4f}{pm} s ({o.how})")
    if res.heldout is not None:
        out(res.heldout.verdict())
    for c in res.cross_checks:
        word = "agree" if c.agree else "DISAGREE"
        out(f"{c.routes[0]} vs {c.routes[1]} on {c.quantity}: {c.z:+.2f} standard errors ({word})")
    if res.log_check is not None:
        out("Is this log enough? (odocal check)")
        check_text(out, res.log_check, indent="  ")
    if res.covariance is not None:
        cov = res.covariance
        out(f"covariances for diff_drive_controller: pose {list(cov.pose_diagonal)}, twist "
              f"{list(cov.twist_diagonal)} (k_r = k_l = {cov.k_r_m:.3g} m)")  # fmt: skip
    if res.enough:
        out("verdict: trustworthy")
    else:
        out("verdict: NOT to be trusted:")
        for reason in res.reasons:
            out(f"  - {reason}")
        if not res.written:
            out("nothing written (--force writes the files anyway)")
        else:
            out("written anyway (--force): the files say NOT TO BE TRUSTED, with these reasons")
    written_lines(out, res.written)
    return str(out)
