"""``odocal check``: is this log enough? What the recorded motion lets a fit see."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..calibration.fit_settings import DEFAULT_TRAJECTORY, TrajectorySettings
from ..calibration.identifiability import (
    MAX_BLOCKS_PER_RUN,
    LogCheck,
    NoiseModel,
    check_recordings,
)
from ..core.model import Robot, WheelGeometry
from ..core.recording import Recording
from ..errors import InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bag_recording import without_gyro
from ..io.bag_slam import load_slam_bags
from ..io.recordings import load_recordings
from .common import RobotSpec, load_warnings, nominal_geometry, optional_robot

__all__ = ["CheckResult", "check", "check_loaded", "noise_model"]


@dataclass(frozen=True)
class CheckResult:
    """The check of a log, the noise it assumed and where that came from."""

    check: LogCheck
    noise_source: str
    recordings: int
    load_warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        return self.check.as_dict() | {
            "noise_source": self.noise_source,
            "load_warnings": list(self.load_warnings),
        }


def noise_model(r: Robot | None) -> tuple[NoiseModel, str]:
    """The stated noise: the robot's ``nonsystematic`` and ``measurement`` where given (a part
    left at zero keeps the default), else the defaults of :class:`NoiseModel`."""
    default = NoiseModel()
    if r is None:
        return default, "default (k 1e-6 m per wheel, tracker 1 mm and 0.2 deg): give --robot"
    wheel = r.nonsystematic if not r.nonsystematic.is_zero else default.wheel
    meas = r.measurement if not r.measurement.is_zero else default.measurement
    parts = [
        "ROBOT.yaml nonsystematic" if wheel is r.nonsystematic else "default k",
        "ROBOT.yaml measurement" if meas is r.measurement else "default tracker noise",
    ]
    return NoiseModel(wheel, meas), ", ".join(parts)


def check_loaded(
    recordings: Sequence[Recording],
    geometry: WheelGeometry,
    robot: Robot | None = None,
    *,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    mounting: bool = False,
    max_blocks_per_run: int = MAX_BLOCKS_PER_RUN,
) -> CheckResult:
    """The check of loaded recordings, linearised at ``geometry``, with ``robot``'s noise, for
    the trajectory fit of ``settings`` (its residual, segment length, heading weight, samples
    and run weight)."""
    noise, source = noise_model(robot)
    chk = check_recordings(
        list(recordings),
        geometry,
        noise=noise,
        residual=settings.residual,
        segment_m=settings.segment_m,
        heading_weight_m=settings.heading_weight_m,
        samples_per_run=settings.samples_per_run,
        run_weight=settings.run_weight,
        mounting=mounting,
        max_blocks_per_run=max_blocks_per_run,
    )
    return CheckResult(chk, source, len(recordings))


def check(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotSpec = None,
    ticks_per_rev: float | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
    mounting: bool = False,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
) -> CheckResult:
    """Load the runs in ``paths`` (ground truth optional) and check what they let a trajectory
    fit with ``settings`` see, at the nominal geometry (``robot``, else the recordings'
    metadata). ``truth_frames``: bags whose truth is a SLAM pose on /tf (its stamps
    ``slam_stamp_offset_s`` late)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    notes: list[str] = []
    if truth_frames is not None:
        slam = load_slam_bags(
            paths,
            truth_frames,
            bag,
            ticks_per_rev=ticks_per_rev,
            stamp_offset_s=slam_stamp_offset_s,
        )
        recordings = [b.recording for b in slam]
    else:
        with without_gyro():  # the check does not use the gyro heading
            recordings = load_recordings(
                paths, ticks_per_rev=ticks_per_rev, warnings=notes, bag=bag
            )
    r = optional_robot(robot)
    geometry = nominal_geometry(r, recordings)
    if geometry is None:
        raise InputError(
            "the check needs the robot's nominal geometry: give --robot ROBOT.yaml (the "
            "recordings carry no firmware parameters)"
        )
    res = check_loaded(recordings, geometry, r, settings=settings, mounting=mounting)
    return replace(res, load_warnings=tuple(notes) + load_warnings(recordings))
