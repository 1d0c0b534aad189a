"""``odocal fit BAG --method auto``: one bag, every route it allows, one answer a careful
engineer can trust (or a clear statement that there is none).

1. **Survey** (:func:`odocal.io.bag_survey.survey`): which routes the bag allows and why not.
2. **Run** every usable route (trajectory with an external truth topic, the SLAM pose on /tf,
   laser scan matching, the gyro), each with its clock offset, its cluster-robust standard
   errors and its held-out check.
3. **Cross-check** the routes against each other: every pair that estimates the same quantity
   (D_R, D_L, b; the gyro's wheelbase at the diameters it ran with) must agree within
   3 combined standard errors (:mod:`odocal.calibration.cross_check`).
4. **Answer**: the first route that ran, in the order trajectory, SLAM, scan, gyro (a truth
   topic is the best reference, the gyro sees only the wheelbase), with the covariances for
   ``diff_drive_controller`` from its residuals (:mod:`odocal.calibration.interval_noise`).
5. **Verdict**: trustworthy when the answer's route ran, its held-out check found a model that
   beats the nominal one, the routes agree, its timing and its parts are consistent and the log
   check (trajectory) saw every parameter. Otherwise the reasons, the exit status
   :data:`~odocal.cli.common.NOT_ENOUGH` and nothing written unless ``force``.

The results and their JSON contract are in :mod:`odocal.app.fit_auto_result`.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.cross_check import KEYS, MAX_Z, CrossCheck, cross_checks
from ..calibration.fit_settings import DEFAULT_SQUARES, DEFAULT_TRAJECTORY
from ..calibration.heldout import intervals_of_runs
from ..calibration.interval_noise import IntervalNoise, estimate_interval_noise
from ..core.covariance import OdometryCovariance, odometry_covariance
from ..errors import CalibrationError, InputError, OdocalError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bag_survey import BagSurvey, RouteOption, survey
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot
from ..io.ros2_export import DEFAULT_CONTROLLER
from .common import RobotSpec, input_paths, write_exports
from .fit_auto_result import AutoFitResult, RouteRun
from .fit_gyro import GyroFitResult, fit_gyro
from .fit_relative import RelativeFitResult
from .fit_runs import FitResult, fit_run_files
from .fit_scan import fit_scan_bags
from .fit_slam import fit_slam_bags

__all__ = ["AutoFitResult", "CrossCheck", "RouteRun", "fit_auto", "KEYS", "MAX_Z"]


def _run_route(
    option: RouteOption,
    bag: Path,
    plan: OutputPlan,
    robot: RobotSpec,
    options: BagOptions,
    found: BagSurvey,
    scan_interval_s: float,
) -> RouteRun:
    """Run one usable route (force: its own checks become reasons here, not errors)."""
    name = option.name
    try:
        if name == "trajectory":
            res: Any = fit_run_files([bag], "trajectory", plan, robot=robot,
                                     settings=DEFAULT_TRAJECTORY, squares=DEFAULT_SQUARES,
                                     bag=options, force=True)  # fmt: skip
            e = res.fit.stderr
            se = (e.get(KEYS[0]), e.get(KEYS[1]), e.get(KEYS[2]))
            return RouteRun(option, True, option.reason, res.fit.geometry, se, res)
        if name == "slam":
            assert found.slam_edge is not None
            res = fit_slam_bags([bag], plan, found.slam_edge, options, robot=robot, force=True)
            return RouteRun(option, True, option.reason, res.geometry, res.geometry_stderr, res)
        if name == "scan":
            res = fit_scan_bags([bag], plan, options, robot=robot, force=True,
                                scan_interval_s=scan_interval_s)  # fmt: skip
            return RouteRun(option, True, option.reason, res.geometry, res.geometry_stderr, res)
        res = fit_gyro(bag, robot=robot, options=options, force=True)
        return RouteRun(option, True, option.reason, res.geometry, _gyro_stderr(res), res)
    except OdocalError as exc:
        return RouteRun(option, False, f"it ran into: {exc}")


def _gyro_stderr(res: GyroFitResult) -> tuple[float | None, float | None, float | None]:
    """The gyro route's wheelbase error (it sees no diameter): b = b_ref / ratio."""
    g, se = res.geometry, res.gyro.rotation_ratio_stderr
    if g is None or se is None:
        return (None, None, None)
    return (None, None, float(g.wheelbase_m * se / res.gyro.rotation_ratio))


def _run_routes(
    found: BagSurvey, plan: OutputPlan, robot: RobotSpec, options: BagOptions, scan_s: float
) -> list[RouteRun]:
    """Every route of the survey: run where usable, else with the survey's reason."""
    return [
        _run_route(o, found.path, plan, robot, options, found, scan_s)
        if o.usable
        else RouteRun(o, False, o.reason)
        for o in found.routes
    ]


def _speed(answer: RouteRun) -> float | None:
    """The robot's cruise speed (m/s) in the answer route's intervals (SLAM): the median of
    distance over time among the intervals that move."""
    res = answer.result
    if not isinstance(res, RelativeFitResult) or not res.slam_bags:
        return None
    m = res.slam_bags[0].motions
    d = np.hypot(m.sensor_motion[:, 0], m.sensor_motion[:, 1])
    dt = np.asarray(m.end_s) - np.asarray(m.start_s)
    moving = (d > 0.05) & (dt > 0)
    return float(np.median(d[moving] / dt[moving])) if moving.any() else None


def _answer_noise(
    answer: RouteRun | None, bag: Path, options: BagOptions
) -> tuple[IntervalNoise | None, OdometryCovariance | None]:
    """The answer route's random error (from its residuals), and the pose and twist
    covariances for ``diff_drive_controller`` from it at the robot's cruise speed."""
    if answer is None:
        return None, None
    res = answer.result
    noise = res.noise if isinstance(res, RelativeFitResult) else None
    if noise is None and isinstance(res, FitResult):
        noise = _trajectory_noise(answer, bag, options)
    speed = _speed(answer)
    if noise is None or answer.geometry is None:
        return noise, None
    k = 0.5 * noise.k_sum_m
    b = float(answer.geometry.wheelbase_m)
    return noise, odometry_covariance(k, k, b, speed_m_s=speed or 0.5)


def _doubts(res: Any) -> list[str]:
    """What speaks against a route's own answer: no held-out check or one no model passed, a
    timing that is not a constant offset, parts of the log that disagree, a log check that says
    NOT enough."""
    out = []
    if isinstance(res, (FitResult, RelativeFitResult)):
        h = res.heldout
        if h is None:
            out.append(f"no held-out check ({'; '.join(res.notes) or 'none made'})")
        elif h.preferred is None:
            out.append(h.verdict())
    if isinstance(res, RelativeFitResult) and res.timing is not None and res.timing.warning:
        out.append(res.timing.warning)
    if isinstance(res, FitResult):
        c = res.fit.consistency
        if c is not None and not c.consistent:
            out.append("the log's parts disagree beyond their uncertainty")
        if res.log_check is not None and not res.log_check.check.ok:
            out.append("the log check says NOT enough")
    return out


def _reasons(
    answer: RouteRun | None, runs: Sequence[RouteRun], checks: Sequence[CrossCheck]
) -> list[str]:
    """Why the answer is not to be trusted."""
    if answer is None:
        return [
            "no route could calibrate this bag: " + "; ".join(f"{r.name}: {r.reason}" for r in runs)
        ]
    return [f"{answer.name}: {d}" for d in _doubts(answer.result)] + [
        f"the {x.routes[0]} and {x.routes[1]} routes disagree on {x.quantity} by "
        f"{x.z:+.1f} combined standard errors"
        for x in checks
        if not x.agree
    ]


def _warnings(runs: Sequence[RouteRun], answer: RouteRun | None) -> tuple[str, ...]:
    """The warnings of every route that ran, and what a gyro answer leaves out."""
    warnings = tuple(w for r in runs if r.used for w in getattr(r.result, "warnings", ()))
    if answer is not None and isinstance(answer.result, GyroFitResult):
        warnings += (
            "the gyro route calibrates the wheelbase only: the wheel diameters stay nominal "
            "(record a SLAM pose, a laser or a truth topic to calibrate them)",
        )
    return warnings


def _write(
    plan: OutputPlan,
    result: AutoFitResult,
    out: str | Path | None,
    ros2: str | Path | None,
    controller_name: str,
    force: bool,
) -> AutoFitResult:
    """Write the diff_drive_controller file ``ros2`` and the report into the folder ``out``
    (report.md, params.yaml and the figures) through the one export path
    (:func:`~odocal.app.common.write_exports`); nothing when none is asked for, there is no
    answer, or the answer is not to be trusted without ``force``."""
    a = result.answer
    if (out is None and ros2 is None) or a is None or a.geometry is None:
        return result
    if result.reasons and not force:
        return result
    files: dict[Path, Any] = {}
    if out is not None:
        from ..io.auto_report import auto_report_markdown
        from ..plot.bag import bag_figures

        files.update(bag_figures(result.time_offsets, result.heldout, Path(out)))
        files[Path(out) / "report.md"] = auto_report_markdown(result.as_dict())
    written = write_exports(
        plan,
        a.geometry,
        result.nominal,
        None if out is None else Path(out) / "params.yaml",
        ros2,
        controller_name,
        files=files,
        record={"method": f"auto ({a.name})"},
        covariance=result.covariance,
    )
    return replace(result, written=written)


def fit_auto(
    bag: str | Path,
    *,
    robot: RobotSpec,
    options: BagOptions = NO_BAG_OPTIONS,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
    scan_interval_s: float = 0.5,
    force: bool = False,
) -> AutoFitResult:
    """The one command for a bag (module docstring). ``out``: a folder for the report
    (report.md, params.yaml and the figures); ``ros2``: the diff_drive_controller file with the
    calibration and the covariances. They are written only for a trustworthy answer, or with
    ``force``."""
    if not robot:
        raise InputError(
            "--method auto needs the robot file (--robot ROBOT.yaml): the nominal geometry the "
            "calibration is held against, and the geometry the controller ran with"
        )
    nominal = load_robot(robot).nominal
    plan = OutputPlan(input_paths([bag], robot))
    if ros2 is not None:
        plan.file(ros2, "--ros2")
    if out is not None:
        from ..plot.bag import HELDOUT_FIGURE, OFFSET_FIGURE

        # the files of _write's report: no other output may name one of them
        names = ("report.md", "params.yaml", OFFSET_FIGURE, HELDOUT_FIGURE)
        plan.folder(out, "--out", files=names)
    found = survey(bag, options)
    runs = _run_routes(found, plan, robot, options, scan_interval_s)
    answer = next((r for r in runs if r.used), None)
    checks = cross_checks(
        [(r.name, r.geometry, r.stderr) for r in runs if r.used and r.geometry is not None]
    )
    noise, cov = _answer_noise(answer, found.path, options)
    reasons = tuple(_reasons(answer, runs, checks))
    result = AutoFitResult(found.path, tuple(runs), answer, nominal, checks, noise, cov, reasons,
                           (), _warnings(runs, answer))  # fmt: skip
    return _write(plan, result, out, ros2, controller_name, force)


def _trajectory_noise(answer: RouteRun, bag: Path, options: BagOptions) -> IntervalNoise | None:
    """The random error of a trajectory route: its runs cut into 1 s intervals against the
    truth (:func:`~odocal.calibration.heldout.intervals_of_runs`)."""
    from ..io.recordings import load_recordings

    if answer.geometry is None:
        return None
    try:
        recs = load_recordings([bag], bag=options)
        a, b, r, lft, m = intervals_of_runs(recs, 1.0)
        return estimate_interval_noise(r, lft, m, answer.geometry, a, end_s=b)
    except (OdocalError, CalibrationError):
        return None
