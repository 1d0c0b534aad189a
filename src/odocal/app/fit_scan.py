"""``odocal fit BAG --method scan``: the relative-motion calibration against the laser's own
motion between scans, from scan matching (:mod:`odocal.calibration.scan_matching`), the laser's
mounting estimated too.

:func:`fit_scan_bags` reads the bags (:func:`odocal.io.bag_scan.read_scan_bag`), matches the
scans (:func:`scan_intervals`), calls the relative-motion route
:func:`odocal.app.fit_relative.fit_relative`, checks the answer
(:mod:`odocal.calibration.relative_checks`) and writes what was asked for.
"""

from __future__ import annotations

from collections.abc import Iterable, Sequence
from pathlib import Path

import numpy as np

from ..calibration.relative_motions import RelativeMotions, stack_motions
from ..calibration.scan_matching import ScanIntervals, scan_interval_motions
from ..core.model import WheelGeometry
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from ..io.bag_scan import ScanBag, read_scan_bag
from ..io.bags import is_bag
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot
from .common import NO_EXPORTS, Exports, RobotSpec
from .fit_relative import RelativeFitResult, fit_relative, relative_checks, write_bag_route
from .relative_inputs import ScanSummary

__all__ = ["fit_scan_bags", "scan_fit", "scan_intervals"]


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


def scan_fit(
    loaded: Iterable[ScanBag],
    nominal: WheelGeometry,
    *,
    names: Sequence[str | Path],
    scan_interval_s: float = 0.5,
    time_offset_s: float | None = None,
    force: bool = False,
    noise: bool = True,
) -> RelativeFitResult:
    """The scan route, I/O-free: the laser's motion between scans ``scan_interval_s`` apart
    from scan matching of the ``loaded`` bags (named ``names`` in messages), the relative-motion
    calibration (the laser's mounting too), the held-out check and the noise. ``loaded`` may be
    a generator: each bag's scans are matched and let go before the next is read."""
    motions, summaries, origins = [], [], []
    for one in loaded:
        m, s = scan_intervals(one, nominal, scan_interval_s, time_offset_s)
        motions.append(m)
        summaries.append(s)
        origins.append(one.start_ns * 1e-9)
    result, forced = fit_relative(
        motions, nominal, force=force, source="scan", names=names, origins_s=origins
    )
    stacked = stack_motions(motions)
    usable = np.ones(len(stacked.phi_right_rad), dtype=bool)
    usable[list(result.dropped_indices)] = False
    mount = np.array([result.sensor_x_m, result.sensor_y_m, result.sensor_yaw_rad])
    checks = relative_checks(
        stacked, usable, mount, result, nominal, source="laser", force=force, noise=noise,
        where=names[0] if len(names) == 1 else None,
    )  # fmt: skip
    return RelativeFitResult(
        result, nominal, len(summaries), "scan", scans=tuple(summaries), forced=forced,
        time_offsets=tuple(s.intervals.time_offset for s in summaries),
        heldout=checks.heldout, noise=checks.noise, timing=checks.timing, notes=checks.notes,
    )  # fmt: skip


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
    """``fit BAG --method scan``: the bags loaded and fitted (:func:`scan_fit`). Needs the
    nominal geometry (``robot``) for the matcher's start."""
    if not robot:
        raise InputError(
            "--method scan needs the nominal geometry (--robot ROBOT.yaml): the scan matcher "
            "starts from the odometry's motion"
        )
    loaded_robot = load_robot(robot)
    nominal, ran_with = loaded_robot.nominal, loaded_robot.believed_geometry
    for p in paths:
        if not is_bag(p):
            raise InputError("--method scan needs ROS bags with laser scans", p)
    loaded = (read_scan_bag(p, bag, ticks_per_rev, ran_with) for p in paths)
    res = scan_fit(
        loaded, nominal, names=paths, scan_interval_s=scan_interval_s,
        time_offset_s=bag.time_offset("laser"), force=force,
    )  # fmt: skip
    return write_bag_route(res, plan, exports, plot)
