"""``odocal fit`` on relative motions: the relative-motion calibration (Censi et al. 2013) of the
wheel geometry and the sensor's mounting, from ``.tuple`` files, from bags whose truth is a SLAM
pose on /tf (``--truth-frames``) or from bags with a 2D laser (``--method scan``).

:func:`fit_relative` is the route itself, I/O-free over loaded relative motions (as evo's
``main_ape.ape()``); :func:`fit_tuple_files`, :func:`fit_slam_bags` and :func:`fit_scan_bags`
load each kind of input, call it and write what was asked for. The router
:func:`odocal.app.fit.fit` chooses among them.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..calibration.censi import PARAMETERS, SensorOdometryFit, fit_censi
from ..calibration.heldout import HeldOut, heldout_check
from ..calibration.interval_noise import IntervalNoise, estimate_interval_noise
from ..calibration.relative_motions import RelativeMotions, stack_motions, wheel_increments
from ..calibration.scan_matching import ScanIntervals, scan_interval_motions
from ..calibration.time_offset import (
    TimeOffset,
    TimingCheck,
    offset_covariance,
    time_blocks,
    timing_consistency,
)
from ..core.model import WheelGeometry
from ..core.transforms import se2_compose, se2_inverse
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from ..io.bag_scan import ScanBag, read_scan_bag
from ..io.bag_slam import SlamBag, load_slam_bags
from ..io.bags import is_bag
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot
from ..io.tuples import read_tuples
from .common import NO_EXPORTS, Exports, RobotSpec, refuse_absurd

__all__ = [
    "RelativeSource",
    "TupleInput",
    "ScanSummary",
    "RelativeFitResult",
    "fit_relative",
    "is_tuple_file",
    "fit_tuple_files",
    "fit_slam_bags",
    "fit_scan_bags",
]

#: Where the relative motions came from.
RelativeSource = Literal["tuples", "slam", "scan"]


@dataclass(frozen=True)
class TupleInput:
    """One ``.tuple`` file of a fit: its path and how many tuples it holds."""

    path: str
    tuples: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the file and its tuple count."""
        return {"path": self.path, "tuples": self.tuples}


@dataclass(frozen=True)
class ScanSummary:
    """One bag of a scan-matching fit: the topics, the scans and intervals matched, and the
    laser's mounting the matcher started from (x_m, y_m, yaw_rad on the base)."""

    bag: str
    scan_topic: str
    joint_topic: str
    scans: int
    intervals: ScanIntervals
    mount_guess: tuple[float, float, float]
    mount_source: str
    warnings: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: this bag's entry of ``scan`` in ``fit --method scan --json``."""
        iv = self.intervals
        x, y, yaw = self.mount_guess
        return {
            "bag": self.bag,
            "scan_topic": self.scan_topic,
            "joint_topic": self.joint_topic,
            "scans": self.scans,
            "interval_scans": iv.interval_scans,
            "intervals": iv.intervals,
            "matched": iv.matched,
            "not_converged": iv.not_converged,
            "degenerate": iv.degenerate,
            "mount_guess": {"x_m": x, "y_m": y, "yaw_rad": yaw},
            "mount_source": self.mount_source,
            "warnings": list(self.warnings),
        }


@dataclass(frozen=True)
class RelativeFitResult:
    """A relative-motion fit, the nominal geometry it is compared with, its inputs and the files
    written.

    Attributes
    ----------
    fit : SensorOdometryFit
        The geometry and the sensor's mounting.
    nominal : WheelGeometry or None
    recordings : int
        Files or bags given.
    source : {'tuples', 'slam', 'scan'}
    tuple_files, slam_bags, scans : tuple
        The inputs of each source (the others empty).
    written : tuple of Path
    forced : tuple of str
        The absurd-result messages accepted with ``force``.
    time_offsets : tuple of TimeOffset
        Each bag's clock offset of its truth source against the wheels (SLAM, laser).
    heldout : HeldOut or None
        The blocked cross-validation against the nominal geometry (bags with a nominal).
    noise : IntervalNoise or None
        The wheels' random error and the truth's, from the residuals (bags).
    timing : TimingCheck or None
        Whether the wheels' turning against the source's depends on the interval length.
    notes : tuple of str
        What was not checked, and why.
    """

    fit: SensorOdometryFit
    nominal: WheelGeometry | None
    recordings: int
    source: RelativeSource
    tuple_files: tuple[TupleInput, ...] = ()
    slam_bags: tuple[SlamBag, ...] = ()
    scans: tuple[ScanSummary, ...] = ()
    written: tuple[Path, ...] = ()
    forced: tuple[str, ...] = ()
    load_warnings: tuple[str, ...] = ()
    time_offsets: tuple[TimeOffset, ...] = ()
    heldout: HeldOut | None = None
    noise: IntervalNoise | None = None
    timing: TimingCheck | None = None
    notes: tuple[str, ...] = ()

    @property
    def model(self) -> str:
        """The model of the answer: 'full', or the restricted model the held-out check
        preferred when the full one did not beat the nominal geometry."""
        h = self.heldout
        if h is None or h.preferred in (None, "full"):
            return "full"
        return h.preferred

    @property
    def geometry(self) -> WheelGeometry:
        """The answer: the full fit's geometry, or the preferred restricted model's."""
        if self.model == "full":
            return self.fit.geometry
        assert self.heldout is not None
        return next(m.geometry for m in self.heldout.models if m.model == self.model)

    @property
    def geometry_stderr(self) -> tuple[float | None, float | None, float | None]:
        """Standard errors of the answer's (D_R, D_L, b) (m)."""
        if self.model == "full":
            se = self.fit.stderr
            return (se.get("wheel_diameter_right_m"), se.get("wheel_diameter_left_m"),
                    se.get("wheelbase_m"))  # fmt: skip
        assert self.heldout is not None
        score = next(m for m in self.heldout.models if m.model == self.model)
        err = None if score.fit is None else score.fit.stderr
        if err is None:
            return (None, None, None)
        return (float(err[0]), float(err[1]), float(err[2]))

    @property
    def method(self) -> Literal["relative", "scan"]:
        """The method, as ``odocal fit --method`` names it."""
        return "scan" if self.source == "scan" else "relative"

    @property
    def warnings(self) -> tuple[str, ...]:
        """The fit's warnings, and the absurd-result messages accepted with ``force``."""
        own = tuple(self.fit.warnings)
        offsets = tuple(w for o in self.time_offsets for w in o.warnings)
        timing = () if self.timing is None or self.timing.warning is None else (
            self.timing.warning,
        )  # fmt: skip
        return own + offsets + timing + tuple(w for w in self.forced if w not in own)

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> clock offset (s) applied; with several bags, the first bag's (each bag's
        own is in ``time_offsets``)."""
        out: dict[str, float] = {}
        for o in self.time_offsets:
            out.setdefault(o.source, o.applied_s)
        return out

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit --json`` for relative motions."""
        out = self.fit.as_dict()
        out["warnings"] = list(self.load_warnings) + list(self.warnings)
        out["nominal"] = None if self.nominal is None else self.nominal.as_dict()
        if self.source == "tuples":
            out["inputs"] = [t.as_dict() for t in self.tuple_files]
        elif self.source == "slam":
            out["slam"] = [b.as_dict() for b in self.slam_bags]
        else:
            out["method"] = "scan"
            out["scan"] = [s.as_dict() for s in self.scans]
        if self.source != "tuples":
            out["time_offsets_s"] = self.time_offsets_s
            out["time_offsets"] = [o.as_dict() for o in self.time_offsets]
            out["heldout"] = None if self.heldout is None else self.heldout.as_dict()
            out["model"] = self.model
            if self.model != "full":
                g = self.geometry
                out["answer"] = g.as_dict() | {
                    "stderr": dict(zip(("wheel_diameter_right_m", "wheel_diameter_left_m",
                                        "wheelbase_m"), self.geometry_stderr, strict=True)),
                }  # fmt: skip
            out["noise"] = None if self.noise is None else self.noise.as_dict()
            out["timing"] = None if self.timing is None else self.timing.as_dict()
            out["notes"] = list(self.notes)
        return out


def fit_relative(
    motions: Sequence[RelativeMotions],
    nominal: WheelGeometry | None,
    *,
    sensor_pose: tuple[float, float, float] | None = None,
    force: bool = False,
) -> tuple[SensorOdometryFit, tuple[str, ...]]:
    """The relative-motion route, I/O-free: the calibration of the intervals of every source in
    ``motions`` together (``sensor_pose`` fixed, else estimated), and the absurd-result
    messages accepted with ``force`` (without it a result more than 25 % from ``nominal`` is
    a CalibrationError)."""
    m = stack_motions(motions)
    result = fit_censi(
        m.phi_right_rad,
        m.phi_left_rad,
        m.sensor_motion,
        sensor_pose=sensor_pose,
        nominal=nominal,
        wheel_increments=m.increments,
        clusters=_blocks(m),
    )
    return result, tuple(refuse_absurd(result.geometry, nominal, force))


def _blocks(m: RelativeMotions) -> np.ndarray:
    """The independent groups of the intervals for the cluster-robust standard errors:
    contiguous time blocks (:func:`~odocal.calibration.time_offset.time_blocks`); intervals
    without times (tuple files, in the order recorded) in blocks of consecutive intervals."""
    if m.start_s is not None:
        return time_blocks(np.asarray(m.start_s, dtype=float))
    return time_blocks(np.arange(len(m.phi_right_rad), dtype=float), min_block_s=0.0)


def is_tuple_file(path: str | Path) -> bool:
    """A ``.tuple`` file of relative motions, by its name."""
    return Path(path).suffix.lower() == ".tuple"


def _export(
    plan: OutputPlan,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
    method: str,
    exports: Exports,
    geometry: WheelGeometry | None = None,
    model: str = "full",
    files: dict[Path, Any] | None = None,
) -> tuple[Path, ...]:
    """PARAMS.yaml and the ros2_control file of a relative-motion fit (the sensor's mounting
    beside the values): ``geometry`` (default the fit's) of ``model``."""
    record: dict[str, str | float] = {
        "method": method,
        "sensor_x_m": result.sensor_x_m,
        "sensor_y_m": result.sensor_y_m,
        "sensor_yaw_rad": result.sensor_yaw_rad,
    }
    if model != "full":
        record["model"] = f"{model} (preferred by the held-out check)"
    chosen = result.geometry if geometry is None else geometry
    return exports.write(plan, chosen, nominal, files=files, record=record)


def _figures(res: RelativeFitResult, plot: str | Path | None) -> dict[Path, Any] | None:
    """The bag route's figures for ``--plot`` (:mod:`odocal.plot.bag`); InputError when there
    is nothing to draw."""
    if plot is None:
        return None
    from ..plot.bag import bag_figures

    figures = bag_figures(res.time_offsets, res.heldout, plot)
    if not figures:
        raise InputError(
            "--plot: no clock offset was estimated and no held-out check was made (give "
            "--robot for the check); nothing to draw",
            field="plot",
        )
    return figures


def _nominal(robot: RobotSpec) -> WheelGeometry | None:
    return load_robot(robot).nominal if robot else None


def _ran_with(robot: RobotSpec) -> WheelGeometry | None:
    """The geometry the robot's controller ran with (its odometry is inverted through it when a
    bag has no joint states): ROBOT.yaml's ``believed``, else its nominal."""
    return load_robot(robot).believed_geometry if robot else None


def _slam_chains(
    bags: Sequence[SlamBag], result: SensorOdometryFit
) -> tuple[RelativeMotions, np.ndarray]:
    """Every interval between SLAM updates of every bag (dropped ones included: they carry the
    held-out chains) and which of them the fit used (not a jump, not an outlier)."""
    parts, usable, k = [], [], 0
    dropped = set(result.dropped_indices)
    for b in bags:
        m = b.motions
        used = np.array(m.every_used, dtype=bool)
        keep = used.copy()
        pos = np.flatnonzero(used)
        for j, i in enumerate(pos):
            if k + j in dropped:
                keep[i] = False
        k += len(pos)
        inc = b.every_increments
        assert inc is not None  # the loader sets them
        d = b.time_offset.applied_s
        parts.append(RelativeMotions(
            inc[0].sum(axis=1), inc[1].sum(axis=1), np.asarray(m.every_motion), inc,
            np.asarray(m.every_start_s) - d, np.asarray(m.every_end_s) - d,
        ))  # fmt: skip
        usable.append(keep)
    return stack_motions(parts), np.concatenate(usable)


def _refit(motions: RelativeMotions, result: SensorOdometryFit) -> Any:
    """The route's own estimator on some of the intervals (for the held-out folds): the
    relative-motion fit, the sensor's mounting fixed if it was."""
    assert motions.increments is not None
    inc_r, inc_l = motions.increments
    sm = np.asarray(motions.sensor_motion, dtype=float)
    pose = result.sensor_pose if result.sensor_pose_fixed else None

    def fit(idx: np.ndarray) -> WheelGeometry:
        return fit_censi(
            inc_r[idx].sum(axis=1), inc_l[idx].sum(axis=1), sm[idx], sensor_pose=pose,
            wheel_increments=(inc_r[idx], inc_l[idx]),
        ).geometry  # fmt: skip

    return fit


def with_offset_error(
    result: SensorOdometryFit,
    offset: TimeOffset,
    t: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
    motion: np.ndarray,
) -> SensorOdometryFit:
    """``result`` with the clock offset's uncertainty added to its covariance
    (:func:`~odocal.calibration.time_offset.offset_covariance`): the same intervals (their
    stamps, before the offset) refitted with the wheels taken one standard error earlier and
    later, the outliers the fit dropped left out."""
    keep = np.setdiff1d(np.arange(len(start_s)), result.dropped_indices)
    pose = result.sensor_pose if result.sensor_pose_fixed else None

    def fit_at(d: float) -> np.ndarray:
        inc_r, inc_l = wheel_increments(t, right, left, start_s[keep] - d, end_s[keep] - d)
        f = fit_censi(inc_r.sum(axis=1), inc_l.sum(axis=1), motion[keep], sensor_pose=pose,
                      wheel_increments=(inc_r, inc_l), outlier_iterations=0)  # fmt: skip
        return f.parameters

    try:
        added = offset_covariance(fit_at, offset)
    except CalibrationError:
        return result
    if added is None:
        return result
    cov = np.array(result.covariance, dtype=float)
    free = np.isfinite(np.diag(cov))
    cov[np.ix_(free, free)] += added[np.ix_(free, free)]
    se = {k: (float(np.sqrt(cov[i, i])) if free[i] else None) for i, k in enumerate(PARAMETERS)}
    return replace(
        result, covariance=cov, stderr=se,
        uncertainty=f"{result.uncertainty}, and the clock offset's own uncertainty",
    )  # fmt: skip


def relative_checks(
    motions: RelativeMotions,
    usable: np.ndarray,
    mount: np.ndarray,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
    *,
    source: str,
    force: bool = False,
) -> dict[str, Any]:
    """The held-out check and the one-log noise estimate of a bag route: ``motions`` every
    interval in time order (the sensor's motion, seen from a sensor mounted at ``mount`` on
    the base), ``usable`` those the fit used. Without a nominal geometry there is nothing to
    hold the calibration against (a note says so). A log too short for the check is an
    InputError unless ``force``; a calibration that no model can make beat the nominal one on
    the held-out blocks is a CalibrationError unless ``force`` (nothing written)."""
    notes: list[str] = []
    if motions.increments is None or motions.start_s is None or motions.end_s is None:
        return {"notes": ("no held-out check: the intervals carry no times",)}
    inc_r, inc_l = motions.increments
    sm = np.asarray(motions.sensor_motion, dtype=float)
    base = sm
    if np.any(mount != 0):
        mnt = np.broadcast_to(mount, sm.shape)
        base = se2_compose(se2_compose(mnt, sm), se2_inverse(mnt))
    heldout = noise = None
    if nominal is None:
        notes.append("no held-out check: it needs the nominal geometry (--robot)")
    else:
        try:
            heldout = heldout_check(
                motions.start_s, motions.end_s, inc_r, inc_l, base, nominal, result.geometry,
                fit_mask=usable, fit_full=_refit(motions, result),
            )  # fmt: skip
        except CalibrationError as exc:
            if not force:
                raise InputError(f"{exc} (--force fits without it)") from None
            notes.append(f"no held-out check: {exc}")
        if heldout is not None and heldout.preferred is None and not force:
            raise CalibrationError(
                f"{heldout.verdict()}; nothing written (--force exports the calibration anyway)"
            )
    timing = timing_consistency(
        motions.phi_right_rad, motions.phi_left_rad, sm[:, 2], motions.start_s, motions.end_s,
        source=source,
    )  # fmt: skip
    try:
        noise = estimate_interval_noise(
            inc_r[usable],
            inc_l[usable],
            base[usable],
            result.geometry,
            motions.start_s[usable],
            end_s=motions.end_s[usable],
        )
    except CalibrationError as exc:
        notes.append(f"no noise estimate: {exc}")
    return {"heldout": heldout, "noise": noise, "timing": timing, "notes": tuple(notes)}


def fit_tuple_files(
    paths: Sequence[str | Path],
    plan: OutputPlan,
    *,
    robot: RobotSpec = None,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
) -> RelativeFitResult:
    """``fit FILE.tuple ...``: the relative motions of ``.tuple`` files (the sensor's mounting
    estimated too)."""
    nominal = _nominal(robot)
    data = [read_tuples(p) for p in paths]
    motions = [RelativeMotions(d.phi_right_rad, d.phi_left_rad, d.sensor_motion) for d in data]
    result, forced = fit_relative(motions, nominal, force=force)
    written = _export(plan, result, nominal, "relative", exports)
    inputs = tuple(TupleInput(str(d.path), len(d.phi_right_rad)) for d in data)
    return RelativeFitResult(
        result, nominal, len(paths), "tuples", tuple_files=inputs, written=written, forced=forced
    )


def fit_slam_bags(
    paths: Sequence[str | Path],
    plan: OutputPlan,
    truth_frames: tuple[str, str],
    bag: BagOptions,
    *,
    robot: RobotSpec = None,
    ticks_per_rev: float | None = None,
    slam_stamp_offset_s: float = 0.0,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
    plot: str | Path | None = None,
) -> RelativeFitResult:
    """``fit BAG ... --truth-frames PARENT:CHILD``: the relative motions between the SLAM's
    updates (docs/slam-truth.md); the truth frame is the base itself (no mounting)."""
    nominal = _nominal(robot)
    for p in paths:
        if not is_bag(p):
            raise InputError("--truth-frames needs ROS bags", p)
    bags = load_slam_bags(
        paths,
        truth_frames,
        bag,
        ticks_per_rev=ticks_per_rev,
        stamp_offset_s=slam_stamp_offset_s,
        ran_with=_ran_with(robot),
        time_offset_s=bag.time_offset("slam"),
    )
    result, forced = fit_relative(
        [b.relative_motions for b in bags], nominal, sensor_pose=(0.0, 0.0, 0.0), force=force
    )
    if len(bags) == 1 and bags[0].wheel_series is not None:
        b0 = bags[0]
        t, right, left = b0.wheel_series
        m0 = b0.motions
        result = with_offset_error(
            result, b0.time_offset, t, right, left, m0.start_s, m0.end_s, m0.sensor_motion
        )
    every, usable = _slam_chains(bags, result)
    checks = relative_checks(
        every, usable, np.zeros(3), result, nominal, source="SLAM", force=force
    )
    res = RelativeFitResult(
        result, nominal, len(paths), "slam", slam_bags=tuple(bags), forced=forced,
        time_offsets=tuple(b.time_offset for b in bags),
        load_warnings=tuple(w for b in bags for w in b.wheel_warnings), **checks,
    )  # fmt: skip
    written = _export(
        plan, result, nominal, "relative", exports, res.geometry, res.model, _figures(res, plot)
    )
    return replace(res, written=written)


def _scan_summary(loaded: ScanBag, intervals: ScanIntervals) -> ScanSummary:
    mount = loaded.mount
    return ScanSummary(
        str(loaded.path),
        loaded.scans.topic,
        loaded.joints.topic,
        int(len(loaded.scans.time_s)),
        intervals,
        (float(mount[0]), float(mount[1]), float(mount[2])),
        loaded.mount_source,
        loaded.warnings,
    )


def scan_intervals(
    loaded: ScanBag,
    nominal: WheelGeometry,
    interval_s: float,
    time_offset_s: float | None = None,
) -> tuple[RelativeMotions, ScanSummary]:
    """The scan-matched intervals of one loaded bag
    (:func:`~odocal.calibration.scan_matching.scan_interval_motions`) and its summary;
    InputError naming the bag and the scan topic when they cannot be matched."""
    joints, scans = loaded.joints, loaded.scans
    try:
        intervals = scan_interval_motions(
            scans.time_s,
            scans.points_m,
            joints.time_s,
            joints.values["right"],
            joints.values["left"],
            nominal,
            np.asarray(loaded.mount, dtype=float),
            interval_s,
            time_offset_s,
        )
    except CalibrationError as exc:
        raise InputError(str(exc), loaded.path, None, scans.topic) from None
    return intervals.motions, _scan_summary(loaded, intervals)


def fit_scan_bags(
    paths: Sequence[str | Path],
    plan: OutputPlan,
    bag: BagOptions,
    *,
    robot: RobotSpec = None,
    ticks_per_rev: float | None = None,
    scan_interval_s: float = 0.5,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
    plot: str | Path | None = None,
) -> RelativeFitResult:
    """``fit BAG --method scan``: the laser's motion between scans ``scan_interval_s`` apart
    from scan matching, then the relative-motion calibration (the laser's mounting too). Needs
    the nominal geometry (``robot``) for the matcher's start."""
    if not robot:
        raise InputError(
            "--method scan needs the nominal geometry (--robot ROBOT.yaml): the scan matcher "
            "starts from the odometry's motion"
        )
    nominal = load_robot(robot).nominal
    motions, summaries = [], []
    for p in paths:
        if not is_bag(p):
            raise InputError("--method scan needs ROS bags with laser scans", p)
        m, s = scan_intervals(
            read_scan_bag(p, bag, ticks_per_rev), nominal, scan_interval_s,
            bag.time_offset("laser"),
        )  # fmt: skip
        motions.append(m)
        summaries.append(s)
    result, forced = fit_relative(motions, nominal, force=force)
    stacked = stack_motions(motions)
    usable = np.ones(len(stacked.phi_right_rad), dtype=bool)
    usable[list(result.dropped_indices)] = False
    mount = np.array([result.sensor_x_m, result.sensor_y_m, result.sensor_yaw_rad])
    checks = relative_checks(stacked, usable, mount, result, nominal, source="laser", force=force)
    res = RelativeFitResult(
        result, nominal, len(paths), "scan", scans=tuple(summaries), forced=forced,
        time_offsets=tuple(s.intervals.time_offset for s in summaries), **checks,
    )  # fmt: skip
    written = _export(
        plan, result, nominal, "scan", exports, res.geometry, res.model, _figures(res, plot)
    )
    return replace(res, written=written)
