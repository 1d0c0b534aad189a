"""``odocal fit BAG --method auto``: one bag, every route it allows, one answer a careful
engineer can trust (or a clear statement that there is none).

0. **Load once**: the robot file is read once (a typed :class:`~odocal.core.model.Robot`: the
   nominal geometry and the one the controller ran with), the bag once (every topic a route
   may need, :func:`odocal.io.bags.read_bag_once`).
1. **Survey** (:func:`odocal.io.bag_survey.survey`): which routes the bag allows and why not.
2. **Run** (:mod:`odocal.app.bag_routes`) every usable route (trajectory with an external
   truth topic, the SLAM pose on /tf, laser scan matching, the gyro), each with its clock
   offset, its cluster-robust standard errors and its held-out check, into one typed result
   (each parameter estimated, tied or held).
3. **Cross-check** the routes against each other: every pair that measured the same quantity
   (D_R, D_L, b; their mean where a route tied the diameters; the gyro's wheelbase at the
   diameters it ran with; never a parameter a route held) must agree within 3 combined
   standard errors (:mod:`odocal.calibration.cross_check`).
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

from ..calibration.cross_check import KEYS, MAX_Z, CrossCheck, cross_checks
from ..core.covariance import OdometryCovariance, odometry_covariance
from ..core.model import Robot
from ..errors import InputError, OdocalError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bag_survey import BagSurvey, survey
from ..io.bags import BagContents, read_bag_once
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot
from ..io.ros2_export import DEFAULT_CONTROLLER
from .bag_routes import BagInputs, run_route
from .check import CheckResult, check_bag
from .common import RobotSpec, input_paths, unused_offsets, write_exports
from .fit_auto_result import AutoFitResult, RouteRun

__all__ = ["AutoFitResult", "CrossCheck", "RouteRun", "fit_auto", "KEYS", "MAX_Z"]


def _covariance(answer: RouteRun | None) -> OdometryCovariance | None:
    """The pose and twist covariances for ``diff_drive_controller`` from the answer route's
    random error, at the robot's cruise speed."""
    if answer is None or answer.noise is None or answer.geometry is None:
        return None
    k = 0.5 * answer.noise.k_sum_m
    b = float(answer.geometry.wheelbase_m)
    return odometry_covariance(k, k, b, speed_m_s=answer.speed_m_s or 0.5)


def _reasons(
    answer: RouteRun | None, runs: Sequence[RouteRun], checks: Sequence[CrossCheck]
) -> list[str]:
    """Why the answer is not to be trusted."""
    if answer is None:
        return [
            "no route could calibrate this bag: " + "; ".join(f"{r.name}: {r.reason}" for r in runs)
        ]
    return (
        [f"{answer.name}: {d}" for d in answer.doubts]
        + _ratio_only(answer)
        + [
            f"the {x.routes[0]} and {x.routes[1]} routes disagree on {x.quantity} by "
            f"{x.z:+.1f} combined standard errors"
            for x in checks
            if not x.agree
        ]
    )


def _ratio_only(answer: RouteRun) -> list[str]:
    """A ratio is no calibration on its own: what the gyro measured, what it cannot see, and
    whether it has an uncertainty at all."""
    a = answer.answer
    if a is None or a.ratio is None:
        return []
    b = a.parameters[2]
    base = b.value * a.ratio
    se = "" if a.ratio_std_error is None else f" +- {a.ratio_std_error:.4f}"
    out = [
        f"{answer.name}: it measured a heading ratio only ({a.ratio:.4f}{se}, gyro over "
        f"odometry): the wheelbase {b.value:.6g} m is the robot file's {base:.6g} m divided by "
        "it, so "
        "nothing in this bag checks the file's scale or the wheel diameters (record a truth "
        "topic, a SLAM pose or a laser to measure them)"
    ]
    if a.ratio_std_error is None:
        out.append(f"{answer.name}: the heading ratio has no uncertainty")
    return out


def _warnings(
    runs: Sequence[RouteRun], answer: RouteRun | None, options: BagOptions
) -> tuple[str, ...]:
    """The warnings of every route that ran, a given clock offset no route used, and what a
    gyro answer leaves out."""
    used = [o.source for r in runs if r.used for o in r.time_offsets]
    warnings = tuple(w for r in runs if r.used for w in r.warnings)
    warnings += unused_offsets(options.time_offsets, used)
    if answer is not None and answer.name == "gyro":
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
        doubts=result.reasons,
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
    plan = OutputPlan(input_paths([bag], robot))
    if ros2 is not None:
        plan.file(ros2, "--ros2")
    if out is not None:
        from ..plot.bag import HELDOUT_FIGURE, OFFSET_FIGURE

        # the files of _write's report: no other output may name one of them
        names = ("report.md", "params.yaml", OFFSET_FIGURE, HELDOUT_FIGURE)
        plan.folder(out, "--out", files=names)
    loaded_robot: Robot = load_robot(robot)  # once: it may be a pipe
    named = (options.joint_topic, options.truth_topic, options.imu_topic, options.odom_topic,
             options.scan_topic)  # fmt: skip
    contents = read_bag_once(bag, named)
    found = survey(contents, options)
    if not any(o.usable for o in found.routes):
        why = "; ".join(f"{o.name}: {o.reason}" for o in found.routes)
        raise InputError(f"no route can read this bag: {why}", found.path)
    inputs = BagInputs(contents, found, loaded_robot, options, scan_interval_s)
    runs: list[RouteRun] = []
    for o in found.routes:  # the random error of the answer's route only (the first that ran)
        first = not any(r.used for r in runs)
        runs.append(run_route(o, replace(inputs, noise=first)))
    answer = next((r for r in runs if r.used), None)
    checks = cross_checks([r.answer for r in runs if r.used and r.answer is not None])
    log_check = _log_check(contents, loaded_robot, options, answer)
    reasons = tuple(
        _reasons(answer, runs, checks)
        + _check_reasons(answer, log_check)
        + _skid_steer(runs, loaded_robot)
        + _ran_with_unstated(found, loaded_robot)
    )
    noise = None if answer is None else answer.noise
    result = AutoFitResult(found.path, tuple(runs), answer, loaded_robot.nominal, checks, noise,
                           _covariance(answer), reasons, (), _warnings(runs, answer, options),
                           log_check)  # fmt: skip
    return _write(plan, result, out, ros2, controller_name, force)


def _log_check(
    bag: BagContents, robot: Robot, options: BagOptions, answer: RouteRun | None
) -> CheckResult | None:
    """Is this log enough? The trajectory route's own check; else the check of the bag's wheel
    motion (with the SLAM truth's noise and predicted errors when the answer is the SLAM
    route's); None when the wheels cannot be read."""
    from .fit_relative import RelativeFitResult
    from .fit_runs import FitResult

    detail = None if answer is None else answer.detail
    if isinstance(detail, FitResult):
        return detail.log_check
    slam = detail.slam_bags if isinstance(detail, RelativeFitResult) else ()
    try:
        return check_bag(bag, robot, options, slam)
    except OdocalError:
        return None


#: A differential drive whose measured wheelbase is this much wider than its file's turns like
#: a skid-steer or tracked robot (the Warthog: 1.6-1.9, a Husky: 1.8).
SKID_STEER_TRACK = 1.25


def _skid_steer(runs: Sequence[RouteRun], robot: Robot) -> list[str]:
    """A differential model that fits badly because the robot skids: a route that measured the
    wheelbase found it far wider than the file's. Says so, and what to run instead."""
    if robot.kinematics != "differential":
        return [
            "the robot file says skid-steer: a differential-drive calibration is not its answer "
            "(odocal fit BAG --kinematics skid-steer, or the library's fit(..., "
            "kinematics='skid-steer'), fits its effective track)"
        ]
    b = float(robot.nominal.wheelbase_m)
    wide = [
        (r.name, float(r.answer.parameters[2].value))
        for r in runs
        if r.used and r.answer is not None and r.answer.parameters[2].measured
    ]
    wide = [(n, v) for n, v in wide if v > SKID_STEER_TRACK * b]
    if not wide:
        return []
    name, v = wide[0]
    return [
        f"the {name} route's wheelbase is {v / b:.2f} times the robot file's ({v:.4g} m against "
        f"{b:.4g} m): the robot turns like a skid-steer or tracked robot, whose effective track "
        "is wider than its wheels are apart; a differential-drive calibration of it is wrong: "
        "fit it with --kinematics skid-steer (or kinematics: skid_steer in the robot file)"
    ]


def _ran_with_unstated(found: BagSurvey, robot: Robot) -> list[str]:
    """The wheels are the controller's odometry inverted through the geometry it ran with, and
    the robot file does not say what that was: for a skid-steer robot (whose controller runs
    with a wheel_separation_multiplier far from 1) that guess is a reason."""
    inverted = found.wheels is not None and "inverted" in found.wheels
    if not inverted or robot.ran_with_stated or robot.kinematics != "skid-steer":
        return []
    return [
        "the wheels are the controller's odometry, and the robot file does not say what the "
        "controller ran with (no 'believed', no wheel_separation_multiplier): the nominal "
        "geometry was taken, which a skid-steer controller rarely runs with"
    ]


def _check_reasons(answer: RouteRun | None, log_check: CheckResult | None) -> list[str]:
    """A log the check calls NOT enough (the trajectory route says so among its doubts)."""
    if answer is None or log_check is None or log_check.check.ok or answer.name == "trajectory":
        return []
    return [f"the log check says NOT enough ({log_check.check.weakest_direction} weakest)"]
