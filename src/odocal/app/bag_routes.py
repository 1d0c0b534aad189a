"""The routes of ``odocal fit BAG --method auto``, each a function from a bag already read (every
topic, once: :func:`odocal.io.bags.read_bag_once`) and a robot already loaded to one typed
:class:`~odocal.app.fit_auto_result.RouteRun`: the answer parameter by parameter (estimated,
tied or held), the clock offsets, the held-out check, what speaks against the answer.

No route opens a file: each picks its topics from the bag's contents (the readers of
:mod:`odocal.io`), then calls its I/O-free fit (:func:`~odocal.app.fit_runs.fit_runs`,
:func:`~odocal.app.fit_slam.slam_fit`, :func:`~odocal.app.fit_scan.scan_fit`,
:func:`~odocal.app.fit_gyro.gyro_route_fit`) with ``force``: a route's own refusals become its
doubts here, which the one answer's verdict weighs (:mod:`odocal.app.fit_auto`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from ..calibration.heldout import intervals_of_runs
from ..calibration.interval_noise import IntervalNoise, estimate_interval_noise
from ..calibration.route_answer import RouteName, route_answer
from ..core.model import Robot
from ..core.recording import Recording
from ..errors import BagDataError, CalibrationError, OdocalError
from ..io.bag_options import BagOptions
from ..io.bag_recording import load_bag_run
from ..io.bag_survey import BagSurvey, RouteOption
from ..io.bags import BagContents
from .fit_auto_result import RouteRun

if TYPE_CHECKING:  # each route's modules are imported when the bag allows that route
    from .fit_gyro import GyroFitResult
    from .fit_relative import RelativeFitResult
    from .fit_runs import FitResult

__all__ = ["BagInputs", "run_route", "ROUTE_FUNCTIONS"]


def _heldout_doubts(res: FitResult | RelativeFitResult) -> list[str]:
    """No held-out check, or one that no model passed."""
    h = res.heldout
    if h is None:
        return [f"no held-out check ({'; '.join(res.notes) or 'none made'})"]
    if h.preferred is None:
        return [h.verdict()]
    return []


def _own_warnings(warnings: tuple[str, ...], doubts: list[str]) -> tuple[str, ...]:
    """A route's warnings, without those that became its doubts."""
    return tuple(w for w in warnings if w not in doubts)


def trajectory_run(option: RouteOption, res: FitResult, noise: IntervalNoise | None) -> RouteRun:
    """A trajectory fit (a truth topic) as a route run."""
    fit = res.fit
    e = fit.stderr
    se = (e.get("wheel_diameter_right_m"), e.get("wheel_diameter_left_m"), e.get("wheelbase_m"))
    answer = route_answer("trajectory", "full", fit.geometry, se, fit.covariance)
    doubts = _heldout_doubts(res)
    c = fit.consistency
    if c is not None and not c.consistent:
        doubts.append("the log's parts disagree beyond their uncertainty")
    if res.log_check is not None and not res.log_check.check.ok:
        doubts.append("the log check says NOT enough")
    doubts += list(res.forced)
    return RouteRun(
        option, True, option.reason, answer, res, res.time_offsets, res.heldout,
        tuple(doubts), _own_warnings(res.warnings, doubts), noise,
    )  # fmt: skip


def relative_run(option: RouteOption, res: RelativeFitResult) -> RouteRun:
    """A relative-motion fit (SLAM, scan) as a route run."""
    a = res.answer
    name: RouteName = "slam" if res.source == "slam" else "scan"
    answer = route_answer(name, a.model, a.geometry, a.stderr, a.covariance)
    doubts = _heldout_doubts(res)
    if res.timing is not None and res.timing.warning:
        doubts.append(res.timing.warning)
    doubts += list(res.forced)
    return RouteRun(
        option, True, option.reason, answer, res, res.time_offsets, res.heldout,
        tuple(doubts), _own_warnings(res.warnings, doubts), res.noise, _speed(res),
    )  # fmt: skip


def gyro_run(option: RouteOption, res: GyroFitResult) -> RouteRun:
    """A gyro calibration as a route run: the heading ratio, the wheelbase as the file's times
    it (the diameters held)."""
    g = res.geometry
    if g is None:
        raise CalibrationError("the gyro route needs the nominal geometry (--robot)")
    ratio, se = res.gyro.rotation_ratio, res.gyro.rotation_ratio_stderr
    se_b = None if se is None else float(g.wheelbase_m * se / ratio)
    answer = route_answer("gyro", "heading-ratio", g, (None, None, se_b), ratio=(ratio, se))
    doubts = list(res.forced)
    offsets = () if res.time_offset is None else (res.time_offset,)
    return RouteRun(
        option, True, option.reason, answer, res, offsets, None, tuple(doubts),
        _own_warnings(res.warnings, doubts),
    )  # fmt: skip


def _speed(res: RelativeFitResult) -> float | None:
    """The robot's cruise speed (m/s) in a SLAM route's intervals: the median of distance over
    time among the intervals that move."""
    if not res.slam_bags:
        return None
    m = res.slam_bags[0].motions
    d = np.hypot(m.sensor_motion[:, 0], m.sensor_motion[:, 1])
    dt = np.asarray(m.end_s) - np.asarray(m.start_s)
    moving = (d > 0.05) & (dt > 0)
    return float(np.median(d[moving] / dt[moving])) if moving.any() else None


def _bag_recordings(bag: BagContents, options: BagOptions) -> list[Recording]:
    """The bag's run with its truth topic (:func:`~odocal.io.bag_recording.load_bag_run`)."""
    return [load_bag_run(bag, options)]


def _trajectory_noise(recordings: list[Recording], res: FitResult) -> IntervalNoise | None:
    """The random error of a trajectory route: its runs cut into 1 s intervals against the
    truth (:func:`~odocal.calibration.heldout.intervals_of_runs`)."""
    try:
        a, b, r, lft, m = intervals_of_runs(recordings, 1.0)
        return estimate_interval_noise(r, lft, m, res.fit.geometry, a, end_s=b)
    except (OdocalError, CalibrationError):
        return None


@dataclass(frozen=True)
class BagInputs:
    """What every route of one bag takes: the bag read once, its survey, the robot loaded once,
    the options, the scan interval (s) and whether to estimate the route's random error (only
    the answer's is used)."""

    bag: BagContents
    found: BagSurvey
    robot: Robot
    options: BagOptions
    scan_interval_s: float = 0.5
    noise: bool = True


def _trajectory(option: RouteOption, x: BagInputs) -> RouteRun:
    from .fit_runs import fit_runs

    recordings = _bag_recordings(x.bag, x.options)
    res = fit_runs(
        recordings, "trajectory", robot=x.robot, force=True,
        truth_offset_s=x.options.time_offset("truth"),
    )  # fmt: skip
    return trajectory_run(option, res, _trajectory_noise(recordings, res) if x.noise else None)


def _slam(option: RouteOption, x: BagInputs) -> RouteRun:
    from .fit_slam import slam_fit
    from .slam_bags import load_slam_bag

    assert x.found.slam_edge is not None  # the survey allows the route only with it
    loaded = load_slam_bag(
        x.bag, x.found.slam_edge, x.options, ran_with=x.robot.believed_geometry,
        time_offset_s=x.options.time_offset("slam"),
    )  # fmt: skip
    res = slam_fit([loaded], x.robot.nominal, names=[x.bag.path], force=True, noise=x.noise)
    return relative_run(option, res)


def _scan(option: RouteOption, x: BagInputs) -> RouteRun:
    from ..io.bag_scan import read_scan_bag
    from .fit_scan import scan_fit

    loaded = read_scan_bag(x.bag, x.options, None, x.robot.believed_geometry)
    res = scan_fit(
        [loaded], x.robot.nominal, names=[x.bag.path], scan_interval_s=x.scan_interval_s,
        time_offset_s=x.options.time_offset("laser"), force=True, noise=x.noise,
    )  # fmt: skip
    return relative_run(option, res)


def _gyro(option: RouteOption, x: BagInputs) -> RouteRun:
    from ..io.bag_gyro import read_gyro_bag
    from .fit_gyro import gyro_route_fit, gyro_topics

    loaded = read_gyro_bag(
        x.bag, gyro_topics(x.options), have_geometry=True, mounting=not x.options.imu_axis
    )
    return gyro_run(option, gyro_route_fit(loaded, x.robot, x.options, force=True))


#: Route name -> the route (its option, the bag's inputs) -> its run.
ROUTE_FUNCTIONS: dict[RouteName, Callable[[RouteOption, BagInputs], RouteRun]] = {
    "trajectory": _trajectory,
    "slam": _slam,
    "scan": _scan,
    "gyro": _gyro,
}


def run_route(option: RouteOption, inputs: BagInputs) -> RouteRun:
    """One route of the survey: run where usable (its own checks become doubts, an error its
    reason), else not used with the survey's reason. Broken data in the bag (time running
    backwards, every message twice, two joints named the same: :class:`BagDataError`) are the
    bag's error, not one route's reason: raised."""
    if not option.usable:
        return RouteRun(option, False, option.reason)
    try:
        return ROUTE_FUNCTIONS[option.name](option, inputs)
    except BagDataError:
        raise
    except OdocalError as exc:
        return RouteRun(option, False, f"it ran into: {exc}")
