"""``odocal check``: is this log enough? What the recorded motion lets a fit see."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

from ..calibration.identifiability import LogCheck, NoiseModel, check_recordings
from ..core.model import Robot
from ..core.recording import Recording
from ..errors import InputError
from ..io.bag_slam import load_slam_bag
from ..io.recordings import load_recordings, refuse_repeated
from .common import nominal_geometry, optional_robot

__all__ = ["CheckResult", "check", "check_loaded", "noise_model"]


@dataclass(frozen=True)
class CheckResult:
    """The check of a log, the noise it assumed and where that came from."""

    check: LogCheck
    noise_source: str
    recordings: int
    load_warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict:
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
    geometry,
    robot: Robot | None = None,
    *,
    mounting: bool = False,
    **settings,
) -> CheckResult:
    """The check of loaded recordings, linearised at ``geometry``, with ``robot``'s noise."""
    noise, source = noise_model(robot)
    chk = check_recordings(list(recordings), geometry, noise=noise, mounting=mounting, **settings)
    return CheckResult(chk, source, len(recordings))


def check(
    paths: Sequence[str | Path],
    *,
    robot=None,
    ticks_per_rev: float | None = None,
    bag_options: dict | None = None,
    truth_frames: tuple[str, str] | None = None,
    mounting: bool = False,
    **settings,
) -> CheckResult:
    """Load the runs in ``paths`` (ground truth optional) and check what they let a trajectory
    fit see (``settings``: its residual, segment length, heading weight, run weight), at the
    nominal geometry (``robot``, else the recordings' metadata)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    opts = {k: v for k, v in (bag_options or {}).items() if k != "scan_topic"}
    notes: list[str] = []
    if truth_frames is not None:
        recordings = [
            load_slam_bag(
                p,
                truth_frames,
                joint_topic=opts.get("joint_topic"),
                right_joint=opts.get("right_joint"),
                left_joint=opts.get("left_joint"),
                ticks_per_rev=ticks_per_rev,
            ).recording
            for p in refuse_repeated(paths)
        ]
    else:
        recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, warnings=notes, **opts)
    r = optional_robot(robot)
    geometry = nominal_geometry(r, recordings)
    if geometry is None:
        raise InputError(
            "the check needs the robot's nominal geometry: give --robot ROBOT.yaml (the "
            "recordings carry no firmware parameters)"
        )
    res = check_loaded(recordings, geometry, r, mounting=mounting, **settings)
    loaded = tuple(
        f"{x.name}: {w}" for x in recordings for w in (x.meta.get("warnings", ()) if x.meta else ())
    )
    return replace(res, load_warnings=tuple(notes) + loaded)
