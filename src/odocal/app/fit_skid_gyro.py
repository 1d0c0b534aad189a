"""``odocal fit BAG... --kinematics skid-steer --method gyro`` (and the skid-steer fit of bags
without a truth pose track but with an IMU): the effective track from the gyro's yaw rate against
the wheels' over 1 s intervals (:mod:`odocal.calibration.skid_gyro`).

Per bag: the IMU's yaw axis (/tf_static, ``--imu-axis``, else detected) and bias (still periods)
as the differential gyro route finds them (:func:`~odocal.calibration.gyro.gyro_heading`), its
clock offset against the wheels estimated and applied when it is clear of zero, the intervals
cut. Pooled over the bags: the gain (one effective track), the turn-rate table, and the held-out
heading error of each (leave one bag out; one bag: its halves). A gyro sees heading only: the
wheels' rolling scale is held at the nominal, which the answer says.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..calibration.gyro import gyro_heading, integrate_rate
from ..calibration.route_answer import RouteAnswer, route_answer
from ..calibration.scan_matching import scan_interval_motions
from ..calibration.skid_gyro import (
    GyroGainFit,
    HeadingIntervals,
    HeldOutHeading,
    fit_gyro_gain,
    heading_intervals,
    held_out_heading,
    rate_knots,
)
from ..calibration.skid_steer import TurnRateRow, z_score
from ..calibration.time_offset import TimeOffset, estimate_time_offset, resolve_offset
from ..core.model import Robot, WheelGeometry
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from ..io.bag_scan import ScanBag
from ..io.bag_skid import SkidGyroLog
from ..io.bags import BagContents
from ..io.outputs import OutputPlan
from .common import NO_EXPORTS, Exports
from .fit_skid import (
    MAX_Z,
    TRACK_MULTIPLIER_RANGE,
    RecordingMultiplier,
    _refuse_no_turning,
    refuse_unstated_ran_with,
    write_skid,
)
from .text import Presented, Text, verdict_lines, written_lines

__all__ = [
    "SkidGyroResult",
    "skid_gyro_fit",
    "skid_scan_fit",
    "heading_fit",
    "fit_skid_gyro_bags",
    "fit_skid_scan_bags",
    "NOT_ESTIMATED",
]

#: What the gyro route does not estimate, in the verdict's words.
NOT_ESTIMATED = (
    "a gyro measures heading only: the wheels' rolling scale is NOT estimated (held at the "
    "nominal: radius multipliers 1.0), and the gyro's own scale-factor error (0.1-1 % for a "
    "MEMS gyro, measured 1-5 % from the lidar ICP on the Warthog) is in the multiplier, not in "
    "its error"
)
#: The same for the scan route (the laser's heading changes only).
NOT_ESTIMATED_SCAN = (
    "the laser's heading changes only are used: the wheels' rolling scale is NOT estimated "
    "(held at the nominal: radius multipliers 1.0), and a scan matcher's rotation bias is in "
    "the multiplier, not in its error"
)


@dataclass(frozen=True)
class SkidGyroResult(Presented):
    """The gyro route's answer for a skid-steer robot (module docstring)."""

    names: tuple[str, ...]
    nominal: WheelGeometry
    fit: GyroGainFit
    table: GyroGainFit | None
    offsets: tuple[TimeOffset, ...]
    mountings: tuple[str, ...]
    heldout: HeldOutHeading | None
    per_bag: tuple[RecordingMultiplier, ...]
    reasons: tuple[str, ...]
    notes: tuple[str, ...]
    written: tuple[Path, ...] = ()
    load_warnings: tuple[str, ...] = ()
    sensor: Literal["gyro", "scan"] = "gyro"

    @property
    def not_estimated(self) -> str:
        """What this route does not estimate, in words."""
        return NOT_ESTIMATED if self.sensor == "gyro" else NOT_ESTIMATED_SCAN

    @property
    def enough(self) -> bool:
        """No reason to doubt the multiplier (the scale is never estimated: NOT_ESTIMATED)."""
        return not self.reasons

    @property
    def track_multiplier(self) -> tuple[float, float]:
        """The effective track over the nominal wheelbase (1 / gain) and its standard error."""
        g, se = float(self.fit.gain[0]), float(self.fit.gain_stderr[0])
        return 1.0 / g, se / g**2

    def answer(self) -> RouteAnswer:
        """The route's answer (route 'gyro', model 'heading-ratio'): the diameters held at the
        nominal, the effective track estimated, the gain as the measured ratio."""
        m, se = self.track_multiplier
        b_se = float(self.nominal.wheelbase_m * se)
        ratio = (float(self.fit.gain[0]), float(self.fit.gain_stderr[0]))
        return route_answer(self.sensor, "heading-ratio", self.geometry, (None, None, b_se),
                            ratio=ratio)  # fmt: skip

    @property
    def geometry(self) -> WheelGeometry:
        """The nominal diameters and the effective track."""
        n = self.nominal
        return WheelGeometry(
            n.diameter_right_m, n.diameter_left_m, n.wheelbase_m * self.track_multiplier[0]
        )

    @property
    def curve(self) -> tuple[TurnRateRow, ...]:
        """The multiplier at each knot of the turn-rate table (empty without one)."""
        if self.table is None:
            return ()
        se = self.table.gain_stderr
        return tuple(
            TurnRateRow(k, k * float(g), 1.0 / float(g), float(s) / float(g) ** 2)
            for k, g, s in zip(self.table.knots, self.table.gain, se, strict=True)
        )

    @property
    def warnings(self) -> tuple[str, ...]:
        """The clock offsets' warnings."""
        return tuple(w for o in self.offsets for w in o.warnings)

    def text(self) -> str:
        """The text ``odocal fit --kinematics skid-steer --method gyro`` prints."""
        out = Text()
        m, se = self.track_multiplier
        n = self.nominal
        what = "gyro" if self.sensor == "gyro" else "scan-matched laser"
        out(f"skid-steer {self.sensor} fit of {len(self.names)} recording(s) (the {what}'s "
            f"heading change against the wheels' over short intervals, {self.fit.used} used, "
            f"{self.fit.rejected} rejected)")  # fmt: skip
        out(f"  effective track {n.wheelbase_m * m:.4f} m = wheel_separation {n.wheelbase_m:g} m "
            f"x wheel_separation_multiplier {m:.4f} +- {se:.4f}")  # fmt: skip
        out("  right_wheel_radius_multiplier 1.0, left_wheel_radius_multiplier 1.0 (held)")
        for o, mount in zip(self.offsets, self.mountings, strict=True):
            pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
            use = "applied" if o.applied else "not applied"
            out(f"clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.how}; {use}); "
                f"heading from: {mount}")  # fmt: skip
        if self.per_bag:
            out("per recording (its own multiplier; z against the others'):")
            rows: list[tuple[str, ...]] = [("", "multiplier", "std. error", "z")]
            for r in self.per_bag:
                z = "-" if r.z is None else f"{r.z:+.2f}"
                rows.append((Path(r.name).name, f"{r.multiplier:.4f}", f"{r.stderr:.4f}", z))
            out.table(rows)
        if self.curve:
            out("the multiplier against the turn rate (for a controller turning at other rates):")
            rows = [("  |yaw rate| rad/s", "multiplier", "std. error")]
            rows += [(f"  {r.true_rate_rad_s:.3g}", f"{r.multiplier:.4f}", f"{r.stderr:.4f}")
                     for r in self.curve]  # fmt: skip
            out.table(rows)
        for note in self.notes:
            out(f"  {note}")
        if self.heldout is not None:
            h = self.heldout
            out(f"held out, rms heading error over {h.window_s:g} s windows ({h.windows} "
                "windows), deg:")  # fmt: skip
            for label, v in h.rms_deg.items():
                tag = " (exported)" if label == "effective track" else ""
                best = " (best)" if label == h.best else ""
                out(f"  {label:<30} {v:7.3f}{tag}{best}")
        out(f"not estimated: {self.not_estimated}")
        verdict_lines(out, self.enough, self.reasons)
        written_lines(out, self.written)
        return str(out)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit --kinematics skid-steer --method gyro --json``."""
        m, se = self.track_multiplier
        return {
            "kinematics": "skid-steer",
            "route": self.sensor,
            "recordings": list(self.names),
            "nominal": self.nominal.as_dict(),
            "effective_track_m": self.nominal.wheelbase_m * m,
            "ros2": {
                "wheel_separation_multiplier": m,
                "wheel_separation_multiplier_stderr": se,
                "left_wheel_radius_multiplier": 1.0,
                "right_wheel_radius_multiplier": 1.0,
            },
            "held": ["left_wheel_radius_multiplier", "right_wheel_radius_multiplier"],
            "not_estimated": self.not_estimated,
            "gain": float(self.fit.gain[0]),
            "gain_stderr": float(self.fit.gain_stderr[0]),
            "residual_bias_rad_s": self.fit.bias_rad_s,
            "intervals": {"used": self.fit.used, "rejected": self.fit.rejected},
            "time_offsets": [o.as_dict() for o in self.offsets],
            "heading_from": list(self.mountings),
            "turn_rate": [
                {
                    "true_rate_rad_s": r.true_rate_rad_s,
                    "wheel_rate_rad_s": r.wheel_rate_rad_s,
                    "multiplier": r.multiplier,
                    "stderr": r.stderr,
                }
                for r in self.curve
            ],  # fmt: skip
            "per_recording": [r.as_dict() for r in self.per_bag],
            "heldout": None
            if self.heldout is None
            else {
                "window_s": self.heldout.window_s,
                "windows": self.heldout.windows,
                "rms_heading_error_deg": self.heldout.rms_deg,
                "best": self.heldout.best,
            },
            "notes": list(self.notes),
            "verdict": {"enough": self.enough, "reasons": list(self.reasons)},
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }


def _wheel_yaw(right_rad: Any, left_rad: Any, nominal: WheelGeometry) -> np.ndarray:
    """The wheels' heading (or its change, from rotations) through the nominal geometry
    (rad)."""
    r = 0.5 * np.asarray(right_rad, dtype=float) * nominal.diameter_right_m
    left = 0.5 * np.asarray(left_rad, dtype=float) * nominal.diameter_left_m
    return (r - left) / nominal.wheelbase_m


def _intervals(
    log: SkidGyroLog, part: int, nominal: WheelGeometry, options: BagOptions
) -> tuple[HeadingIntervals, TimeOffset, str]:
    """One bag's intervals, the IMU's clock offset and where its yaw axis came from."""
    yaw_w = _wheel_yaw(log.angle_right_rad, log.angle_left_rad, nominal)
    travel = 0.5 * (np.asarray(log.angle_right_rad) + np.asarray(log.angle_left_rad))
    try:
        head = gyro_heading(
            log.imu_time_s, log.angular_velocity, log.time_s, yaw_w, travel,
            rotation=log.mounting, imu_axis=options.imu_axis or None,
            mounting_source=log.mounting_source,
        )  # fmt: skip
    except CalibrationError as exc:
        raise CalibrationError(f"{log.name}: {exc}") from None
    rate = log.angular_velocity @ np.asarray(head.yaw_axis_in_imu) - head.bias_rad_s
    gyro_yaw = integrate_rate(log.imu_time_s, rate)

    def estimate() -> TimeOffset:
        t = log.imu_time_s
        a = np.arange(t[0], t[-1] - 0.25, 0.25)
        change = np.interp(a + 0.25, t, gyro_yaw) - np.interp(a, t, gyro_yaw)
        return estimate_time_offset(
            log.time_s, yaw_w, np.zeros_like(yaw_w), a, a + 0.25, change, source="imu"
        )

    offset = replace(resolve_offset("imu", options.time_offset("imu"), estimate),
                     part=Path(log.name).name)  # fmt: skip
    found = heading_intervals(
        log.time_s, yaw_w, log.imu_time_s - offset.applied_s, gyro_yaw, part=part
    )
    how = log.mounting_source or ("--imu-axis" if options.imu_axis else "detected")
    axis = ", ".join(f"{v:+.3f}" for v in head.yaw_axis_in_imu)
    return found, offset, f"({axis}) in the IMU frame, {how}"


def _ran_with(robot: Robot) -> dict[str, float]:
    """The gain of the geometry the controller ran with, when the robot file states it: its
    heading over the nominal wheels' (mean radius ratio times nominal over its track)."""
    if not robot.ran_with_stated:
        return {}
    n, r = robot.nominal, robot.believed_geometry
    radius = (r.diameter_right_m + r.diameter_left_m) / (n.diameter_right_m + n.diameter_left_m)
    label = f"ran with (multiplier {r.wheelbase_m / n.wheelbase_m:.4g})"
    return {label: float(radius * n.wheelbase_m / r.wheelbase_m)}


def _halves(iv: HeadingIntervals) -> list[HeadingIntervals]:
    mid = 0.5 * (float(iv.start_s.min()) + float(iv.start_s.max()))
    first = iv.start_s < mid
    return [iv.subset(first), iv.subset(~first)]


def _folds(parts: Sequence[HeadingIntervals]) -> list[tuple[HeadingIntervals, HeadingIntervals]]:
    """Leave one bag out (one bag: each half left out in turn)."""
    units = list(parts) if len(parts) > 1 else _halves(parts[0])
    return [
        (HeadingIntervals.concatenate([u for j, u in enumerate(units) if j != i]), units[i])
        for i in range(len(units))
    ]


def _per_bag(parts: Sequence[HeadingIntervals]) -> tuple[RecordingMultiplier, ...]:
    """Each bag's multiplier and its z against the others' pooled fit."""
    out = []
    for i, p in enumerate(parts):
        rest = HeadingIntervals.concatenate([q for j, q in enumerate(parts) if j != i])
        try:
            own, other = fit_gyro_gain(p), fit_gyro_gain(rest)
        except CalibrationError:
            continue
        g, se = float(own.gain[0]), float(own.gain_stderr[0])
        go, so = float(other.gain[0]), float(other.gain_stderr[0])
        m, m_se = 1 / g, se / g**2
        z = z_score(m, m_se, 1 / go, so / go**2)
        out.append(RecordingMultiplier(str(i), m, m_se, z))
    return tuple(out)


def skid_gyro_fit(
    logs: Sequence[SkidGyroLog],
    robot: Robot,
    options: BagOptions,
    *,
    force: bool = False,
) -> SkidGyroResult:
    """The skid-steer gyro route, I/O-free (module docstring). A multiplier no skid-steer robot
    has is a CalibrationError unless ``force`` (then a reason)."""
    if not logs:
        raise InputError("no recording to fit")
    _refuse_no_turning(logs, robot.nominal)
    parts, offsets, mounts = [], [], []
    for i, log in enumerate(logs):
        iv, off, mount = _intervals(log, i, robot.nominal, options)
        parts.append(iv)
        offsets.append(off)
        mounts.append(mount)
    names = tuple(log.name for log in logs)
    return heading_fit(parts, names, tuple(offsets), tuple(mounts), robot, force=force)


def skid_scan_fit(
    loaded: Sequence[ScanBag],
    robot: Robot,
    options: BagOptions,
    *,
    interval_s: float = 0.5,
    force: bool = False,
) -> SkidGyroResult:
    """The skid-steer scan route: each bag's scans matched over intervals (the differential
    scan route's :func:`~odocal.calibration.scan_matching.scan_interval_motions`, the laser's
    clock offset estimated), their heading changes taken as a gyro's (a laser's rotation is the
    base's whatever its mounting), fitted by :func:`heading_fit`."""
    if not loaded:
        raise InputError("no recording to fit")
    nominal = robot.nominal
    parts, offsets, mounts = [], [], []
    for i, one in enumerate(loaded):
        joints, scans = one.joints, one.scans
        try:
            found = scan_interval_motions(
                scans.time_s, scans.points_m, joints.time_s, joints.values["right"],
                joints.values["left"], nominal, np.asarray(one.mount, dtype=float), interval_s,
                options.time_offset("laser"),
            )  # fmt: skip
        except CalibrationError as exc:
            raise InputError(str(exc), one.path, None, scans.topic) from None
        m = found.motions
        assert m.start_s is not None and m.end_s is not None
        u = _wheel_yaw(m.phi_right_rad, m.phi_left_rad, nominal)
        start = np.asarray(m.start_s, dtype=float)
        parts.append(HeadingIntervals(
            u, np.asarray(m.sensor_motion, dtype=float)[:, 2], np.asarray(m.end_s) - start,
            start, np.floor((start - start[0]) / 15.0).astype(int), np.full(len(u), i),
        ))  # fmt: skip
        offsets.append(replace(found.time_offset, part=Path(one.path).name))
        mounts.append(f"scans on {scans.topic} ({found.matched} of {found.intervals} matched)")
    names = tuple(str(one.path) for one in loaded)
    return heading_fit(parts, names, tuple(offsets), tuple(mounts), robot, force=force,
                       sensor="scan")  # fmt: skip


def heading_fit(
    parts: Sequence[HeadingIntervals],
    names: tuple[str, ...],
    offsets: tuple[TimeOffset, ...],
    mounts: tuple[str, ...],
    robot: Robot,
    *,
    force: bool = False,
    sensor: Literal["gyro", "scan"] = "gyro",
) -> SkidGyroResult:
    """The gain, the table, the per-recording multipliers and the held-out check of heading
    intervals (one part per recording), and the verdict (module docstring)."""
    nominal = robot.nominal
    pooled = HeadingIntervals.concatenate(parts)
    fit = fit_gyro_gain(pooled)
    reasons: list[str] = []
    m = 1.0 / float(fit.gain[0])
    lo, hi = TRACK_MULTIPLIER_RANGE
    if not lo <= m <= hi:
        problem = (
            f"the effective track is {m:.3g} times the wheelbase: no skid-steer robot's "
            f"({lo:g}-{hi:g}); check the wheelbase and the units of the robot file, or the IMU "
            "axis"
        )
        if not force:
            raise CalibrationError(f"{problem}; nothing written (--force accepts it anyway)")
        reasons.append(problem)
    notes: list[str] = []
    table = None
    try:
        table = fit_gyro_gain(pooled, rate_knots(pooled))
    except CalibrationError as exc:
        notes.append(f"no turn-rate table: {exc}")
    per: tuple[RecordingMultiplier, ...] = ()
    if len(parts) > 1:
        per = tuple(replace(r, name=names[int(r.name)]) for r in _per_bag(parts))
        for r in per:
            if r.z is not None and abs(r.z) > MAX_Z:
                reasons.append(
                    f"{Path(r.name).name}: its multiplier {r.multiplier:.4f} +- {r.stderr:.4f} "
                    f"differs from the other recordings' by {r.z:+.1f} combined standard "
                    "errors: the robot, its load or the ground changed (fit them apart)"
                )
    heldout = None
    try:
        heldout = held_out_heading(_folds(parts), fixed=_ran_with(robot))
    except CalibrationError as exc:
        notes.append(f"no held-out check: {exc}")
        reasons.append("no held-out check: the recordings cannot show that the calibration helps")
    if heldout is not None:
        cal, nom = heldout.rms_deg["effective track"], heldout.rms_deg["nominal"]
        if not cal < nom:
            reasons.append(
                f"held out, the calibrated heading errs {cal:.3g} deg per {heldout.window_s:g} s "
                f"against {nom:.3g} deg with the nominal track: the calibration does not help"
            )
    return SkidGyroResult(
        names, nominal, fit, table, offsets, mounts, heldout, per, tuple(reasons), tuple(notes),
        sensor=sensor,
    )  # fmt: skip


def fit_skid_gyro_bags(
    contents: Sequence[BagContents],
    plan: OutputPlan,
    bag: BagOptions,
    *,
    robot: Robot,
    ticks_per_rev: float | None = None,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
    plot: str | Path | None = None,
) -> SkidGyroResult:
    """The bags (read once: :func:`~odocal.app.fit_skid.read_skid_bags`) read for the gyro route
    (:func:`~odocal.io.bag_skid.read_skid_gyro_log`), fitted (:func:`skid_gyro_fit`) and the
    ``exports`` written (not when the verdict has reasons, unless ``force``)."""
    from ..io.bag_skid import read_skid_gyro_log

    logs = [
        read_skid_gyro_log(c, bag, robot.believed_geometry, ticks_per_rev=ticks_per_rev)
        for c in contents
    ]
    refuse_unstated_ran_with([(log.name, log.wheels) for log in logs], robot)
    res = skid_gyro_fit(logs, robot, bag, force=force)
    return write_skid(res, plan, exports, force, plot, "skid-steer gyro", "gyro")


def fit_skid_scan_bags(
    contents: Sequence[BagContents],
    plan: OutputPlan,
    bag: BagOptions,
    *,
    robot: Robot,
    ticks_per_rev: float | None = None,
    scan_interval_s: float = 0.5,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
    plot: str | Path | None = None,
) -> SkidGyroResult:
    """``fit BAG... --kinematics skid-steer --method scan``: the bags' scans
    (:func:`~odocal.io.bag_scan.read_scan_bag`) fitted (:func:`skid_scan_fit`) and the
    ``exports`` written (not when the verdict has reasons, unless ``force``)."""
    from ..io.bag_scan import read_scan_bag

    loaded = [read_scan_bag(c, bag, ticks_per_rev, robot.believed_geometry) for c in contents]
    sources = [(str(one.path), "odometry" if "inverted" in str(one.joints.meta.get("wheels"))
                else "joint_states") for one in loaded]  # fmt: skip
    refuse_unstated_ran_with(sources, robot)
    res = skid_scan_fit(loaded, robot, bag, interval_s=scan_interval_s, force=force)
    return write_skid(res, plan, exports, force, plot, "skid-steer scan", "scan")
