"""``odocal fit BAG ... --truth-frames PARENT:CHILD``: the relative-motion calibration against a
SLAM pose on /tf, between the SLAM's updates (docs/slam-truth.md).

:func:`fit_slam_bags` loads the bags (:func:`load_slam_bags`), calls the
relative-motion route :func:`odocal.app.fit_relative.fit_relative`, checks the answer
(:mod:`odocal.calibration.relative_checks`) and writes what was asked for.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..calibration.censi import SensorOdometryFit
from ..calibration.relative_checks import slam_chains, with_offset_error
from ..calibration.slam_bag import SlamBag
from ..core.model import WheelGeometry
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from ..io.bags import is_bag
from ..io.outputs import OutputPlan
from .common import NO_EXPORTS, Exports, RobotSpec, robot_nominal, robot_ran_with
from .fit_relative import (
    RelativeFitResult,
    fit_relative,
    relative_checks,
    write_bag_route,
)
from .slam_bags import load_slam_bags

__all__ = ["fit_slam_bags", "slam_fit"]


def slam_fit(
    bags: Sequence[SlamBag],
    nominal: WheelGeometry | None,
    *,
    names: Sequence[str | Path],
    force: bool = False,
    noise: bool = True,
) -> RelativeFitResult:
    """The SLAM route, I/O-free: the relative-motion calibration of loaded ``bags`` (named
    ``names`` in messages), its offset's own uncertainty, the held-out check and the noise (the
    truth frame is the base itself: no mounting)."""
    try:
        result, forced = fit_relative(
            [b.relative_motions for b in bags],
            nominal,
            sensor_pose=(0.0, 0.0, 0.0),
            force=force,
            source="slam",
            names=names,
            origins_s=[b.meta.get("start_ns", 0) * 1e-9 for b in bags],
        )
    except CalibrationError as exc:
        raise _with_cause(bags, exc) from None
    result = _with_offset_error(bags, result)
    every, usable = slam_chains(
        [(b.every_motions, b.every_used) for b in bags],
        result.dropped_indices,
    )
    checks = relative_checks(
        every, usable, np.zeros(3), result, nominal, source="SLAM", force=force, noise=noise,
        where=names[0] if len(names) == 1 else None,
    )  # fmt: skip
    return RelativeFitResult(
        result, nominal, len(bags), "slam", slam_bags=tuple(bags), forced=forced,
        time_offsets=tuple(b.time_offset for b in bags),
        load_warnings=tuple(w for b in bags for w in b.wheel_warnings),
        heldout=checks.heldout, noise=checks.noise, timing=checks.timing, notes=checks.notes,
    )  # fmt: skip


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
    updates (docs/slam-truth.md), loaded and fitted (:func:`slam_fit`)."""
    nominal = robot_nominal(robot)
    for p in paths:
        if not is_bag(p):
            raise InputError("--truth-frames needs ROS bags", p)
    bags = load_slam_bags(
        paths,
        truth_frames,
        bag,
        ticks_per_rev=ticks_per_rev,
        stamp_offset_s=slam_stamp_offset_s,
        ran_with=robot_ran_with(robot),
        time_offset_s=bag.time_offset("slam"),
    )
    res = slam_fit(bags, nominal, names=paths, force=force)
    return write_bag_route(res, plan, exports, plot)


def _with_cause(bags: Sequence[SlamBag], exc: CalibrationError) -> CalibrationError:
    """The fit's failure ``exc`` with its real cause first when a bag's SLAM value changes
    faster than a SLAM updates (:meth:`~odocal.calibration.slam.SlamMotions.
    fast_changes_problem`: the intervals that pass the gates are then only the fastest turns,
    and the fit says 'only turns on the spot'); else ``exc``."""
    for b in bags:
        cause = b.motions.fast_changes_problem()
        if cause is not None:
            return CalibrationError(f"{b.path}: {cause} (what is left: {exc})")
    return exc


def _with_offset_error(bags: Sequence[SlamBag], result: SensorOdometryFit) -> SensorOdometryFit:
    """One bag with its wheel series: ``result`` with the clock offset's own uncertainty added
    (:func:`~odocal.calibration.relative_checks.with_offset_error`); else ``result``."""
    series = bags[0].wheel_series if len(bags) == 1 else None
    if series is None:
        return result
    t, right, left = series
    b0 = bags[0]
    m0 = b0.motions
    return with_offset_error(
        result, b0.time_offset, t, right, left, m0.start_s, m0.end_s, m0.sensor_motion
    )
