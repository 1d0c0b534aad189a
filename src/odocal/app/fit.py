"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags).

This module only chooses the route; each route is its own module, an I/O-free function over
loaded objects plus a thin loader (as evo's ``main_ape.ape()``):

=====================================================  ======================================
inputs and method                                      route
=====================================================  ======================================
runs with ground truth: trajectory (default), linear,  :mod:`odocal.app.fit_runs`
umbmark, heading
``.tuple`` files, ``--method relative``                :mod:`odocal.app.fit_relative`
``--truth-frames`` (a SLAM pose)                       :mod:`odocal.app.fit_slam`
``--method scan``                                      :mod:`odocal.app.fit_scan`
``--method gyro`` (one bag)                            :mod:`odocal.app.fit_gyro`
``--method auto``: one bag                             :mod:`odocal.app.fit_auto`
``--method auto``: runs with ground truth (folders)    :mod:`odocal.app.fit_runs_auto`
=====================================================  ======================================

The settings arrive typed and validated (:class:`~odocal.calibration.fit_settings.
TrajectorySettings`, :class:`~odocal.calibration.fit_settings.SquareSettings`,
:class:`~odocal.io.bag_options.BagOptions`) and travel to the route unchanged.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from ..calibration.fit_methods import FIT_METHODS, FitMethod
from ..calibration.fit_settings import (
    DEFAULT_SQUARES,
    DEFAULT_TRAJECTORY,
    SquareSettings,
    TrajectorySettings,
    check_heading_source,
)
from ..core.model import Kinematics, Robot
from ..errors import InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bags import BagContents, is_bag
from ..io.outputs import OutputPlan
from ..io.recordings import expand_folders, refuse_repeated
from ..io.ros2_export import DEFAULT_CONTROLLER
from .common import Exports, RobotSpec, input_paths, kinematics_of, unused_offsets
from .text import emits_warnings

if TYPE_CHECKING:  # each route's module is imported when a fit takes that route
    from .fit_auto import AutoFitResult
    from .fit_gyro import GyroFitResult, fit_gyro, fit_gyro_bag, gyro_fit
    from .fit_relative import RelativeFitResult
    from .fit_runs import FitResult, fit_recordings, fit_runs
    from .fit_runs_auto import RunsAutoResult
    from .fit_skid import SkidFitResult
    from .fit_skid_gyro import SkidGyroResult

#: The names this module re-exports, and the route module each comes from (imported on first
#: use: a bag that needs one route does not pay for the others' imports).
_LAZY = {
    "AutoFitResult": "fit_auto",
    "fit_auto": "fit_auto",
    "GyroFitResult": "fit_gyro",
    "fit_gyro": "fit_gyro",
    "fit_gyro_bag": "fit_gyro",
    "gyro_fit": "fit_gyro",
    "RelativeFitResult": "fit_relative",
    "FitResult": "fit_runs",
    "fit_recordings": "fit_runs",
    "fit_runs": "fit_runs",
    "SkidFitResult": "fit_skid",
    "SkidGyroResult": "fit_skid_gyro",
    "RunsAutoResult": "fit_runs_auto",
}


def __getattr__(name: str) -> object:
    """The re-exported names of :data:`_LAZY`, from their route's module."""
    if name in _LAZY:
        from importlib import import_module

        return getattr(import_module(f".{_LAZY[name]}", __package__), name)
    raise AttributeError(f"module {__name__!r} has no attribute {name!r}")


__all__ = [
    "METHODS",
    "Route",
    "FitResult",
    "RelativeFitResult",
    "GyroFitResult",
    "AutoFitResult",
    "SkidFitResult",
    "SkidGyroResult",
    "RunsAutoResult",
    "choose_route",
    "fit",
    "fit_recordings",
    "fit_runs",
    "fit_gyro",
    "fit_gyro_bag",
    "gyro_fit",
]

#: The fit methods (:data:`odocal.calibration.fit_methods.FIT_METHODS`).
METHODS = FIT_METHODS

#: The routes of ``odocal fit``: runs with ground truth, ``.tuple`` files, SLAM bags, laser
#: scans, the gyro.
Route = Literal["runs", "tuples", "slam", "scan", "gyro"]


def _tuple_inputs(paths: Sequence[str | Path], relative: bool) -> list[str | Path]:
    """The paths that hold tuples: ``.tuple`` files, and with ``relative`` whatever is no bag (a
    pipe or ``<(...)`` has no name to tell a tuple file by)."""
    from .fit_relative import is_tuple_file

    return [p for p in paths if is_tuple_file(p) or (relative and not is_bag(p))]


def choose_route(
    paths: Sequence[str | Path], method: FitMethod | None, truth_frames: tuple[str, str] | None
) -> Route:
    """The route for ``paths`` and ``method`` (None: from the inputs). Relative motions come
    from ``.tuple`` files (a pipe or ``<(...)`` has no name to tell one by: ``method='relative'``
    says it is one) or from bags with ``truth_frames``; they cannot be mixed with runs."""
    if method in ("gyro", "scan"):
        return method
    tuples = _tuple_inputs(paths, method == "relative" and truth_frames is None)
    if not (tuples or truth_frames is not None or method == "relative"):
        return "runs"
    if method not in (None, "relative"):
        what = "--truth-frames (a SLAM pose)" if truth_frames else ".tuple files"
        raise InputError(
            f"{what} give relative motions only: use --method relative, not --method {method}"
        )
    if not tuples:
        if truth_frames is None:
            raise InputError("--method relative needs .tuple files or bags with --truth-frames")
        return "slam"
    if len(tuples) != len(paths):
        raise InputError(".tuple files cannot be mixed with other run files in one fit")
    if truth_frames is not None:
        raise InputError("--truth-frames is for bags; .tuple files hold relative motions")
    return "tuples"


def _is_auto(
    paths: Sequence[str | Path],
    method: FitMethod | None,
    truth_frames: tuple[str, str] | None,
    bag: BagOptions,
    settings: TrajectorySettings | None,
    squares: SquareSettings | None,
) -> bool:
    """The one-command route: asked for, or bags with no method, no truth and no fit settings
    named."""
    if method == "auto":
        return True
    named = truth_frames is not None or bag.truth_topic is not None
    if method is not None or named or not paths or not all(is_bag(p) for p in paths):
        return False
    return settings in (None, DEFAULT_TRAJECTORY) and squares in (None, DEFAULT_SQUARES)


def _refuse_for_auto(
    paths: Sequence[str | Path], plot: str | Path | None, robot_out: str | Path | None
) -> None:
    """The one-command route takes one bag and writes its figures into its report."""
    if len(paths) != 1:
        raise InputError(
            "--method auto (the default for bags when no method and no truth are named) "
            "takes one bag; name the method or the truth for several",
            field="paths",
        )
    if robot_out is not None:
        raise InputError(
            "--robot-out needs runs with ground truth: --method auto (the default for one bag) "
            "writes no measured robot, only its report into --out DIR; name the bag's truth "
            "topic (--truth-topic) for a trajectory fit"
        )
    if plot is not None:
        raise InputError("--plot: --method auto writes its figures into --out DIR (a report)")


def _refuse_other_routes_outputs(
    method: FitMethod | None, plot: str | Path | None, robot_out: str | Path | None
) -> None:
    """The figure is a trajectory fit's; the measured robot needs runs with ground truth."""
    if plot is not None and method not in (None, "trajectory", "relative", "scan"):
        raise InputError(
            "--plot draws the effective wheelbase of a trajectory fit, or the clock offsets and "
            "the held-out check of a bag route",
            field="plot",
        )
    if robot_out is not None and method == "gyro":
        raise InputError("--robot-out needs runs with ground truth (not --method gyro)")


def _figure_names(route: Route) -> tuple[str, ...]:
    """The files a route may write into ``--plot DIR``."""
    if route == "runs":
        from ..plot.fit import FIT_FIGURE

        return (FIT_FIGURE,)
    if route in ("slam", "scan"):
        from ..plot.bag import HELDOUT_FIGURE, OFFSET_FIGURE

        return (OFFSET_FIGURE, HELDOUT_FIGURE)
    return ()


def _output_plan(
    paths: Sequence[str | Path],
    robot: RobotSpec,
    exports: Exports,
    plot: str | Path | None,
    robot_out: str | Path | None,
    route: Route,
) -> OutputPlan:
    """Every file the fit may write, registered against its inputs before the work (the
    figures of ``route`` too: no other output may name one of them)."""
    plan = OutputPlan(input_paths(list(paths), robot))
    exports.register(plan)
    if robot_out is not None:
        plan.file(robot_out, "--robot-out")
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot", files=_figure_names(route))
    return plan


@emits_warnings
def fit(
    paths: str | Path | Sequence[str | Path],
    method: FitMethod | None = None,
    *,
    robot: RobotSpec = None,
    settings: TrajectorySettings | None = None,
    squares: SquareSettings | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
    ticks_per_rev: float | None = None,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
    scan_interval_s: float = 0.5,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
    plot: str | Path | None = None,
    robot_out: str | Path | None = None,
    force: bool = False,
    kinematics: Kinematics | None = None,
) -> (
    FitResult
    | RelativeFitResult
    | GyroFitResult
    | AutoFitResult
    | SkidFitResult
    | SkidGyroResult
    | RunsAutoResult
):
    """Load the runs in ``paths`` and calibrate with ``method`` (None: the trajectory fit, or
    the relative-motion fit for ``.tuple`` files and ``truth_frames``); write PARAMS.yaml to
    ``out``, a ros2_control file to ``ros2``, the effective-wheelbase figure (trajectory fits)
    into the folder ``plot`` and the measured robot (this calibration's systematic errors, k
    from the repeated runs among ``paths``, the tracker's jitter) to ``robot_out`` (a ROBOT.yaml
    for ``odocal design --robot``).

    ``robot``: ROBOT.yaml (nominal geometry; for runs without metadata, the parameters they ran
    with: its 'believed', else nominal). A result more than 25 % from nominal is absurd for a
    calibration: CalibrationError (nothing written) unless ``force``. ``settings``: the
    trajectory fit's (:class:`~odocal.calibration.fit_settings.TrajectorySettings`);
    ``squares``: UMBmark's and the heading method's; ``bag``: the topics and joints of bags.

    Relative motions (``method='relative'``, the default for them): ``.tuple`` files (wheel
    rotations and sensor displacements per interval; the sensor's mounting is estimated too), or
    bags whose ground truth is a SLAM pose on /tf between ``truth_frames`` (e.g. ('map',
    'base_link'); only the relative motions between the SLAM's update instants are used, see
    docs/slam-truth.md).

    Laser scans (``method='scan'``): bags with wheel joints and ``sensor_msgs/LaserScan``; the
    laser's own motion between scans ``scan_interval_s`` apart comes from scan matching
    (:mod:`odocal.calibration.scan_matching`), then the same relative-motion calibration, the
    laser's mounting included. Needs the nominal geometry (``robot``) for the matcher's start.

    The gyro (``method='gyro'``): one bag, :func:`odocal.app.fit_gyro.fit_gyro`.

    One bag with no method and no truth named (or ``method='auto'``): every route the bag
    allows, cross-checked, one answer (:func:`odocal.app.fit_auto.fit_auto`; ``out`` is then a
    folder for its report). ``method='auto'`` on runs with ground truth (not bags): the
    procedure (method and runs) with the lowest leave-one-data-set-out error, fitted
    (:func:`odocal.app.fit_runs_auto.fit_runs_auto`)."""
    paths = expand_folders([paths] if isinstance(paths, (str, Path)) else list(paths))
    if kinematics_of(kinematics, robot) == "skid-steer":
        if settings not in (None, DEFAULT_TRAJECTORY) or squares not in (None, DEFAULT_SQUARES):
            # --residual, --exclude, --drop-outliers ... were ignored without a word
            raise InputError(
                "--kinematics skid-steer fits its own models: the differential fits' settings "
                "(--residual, --exclude, --drop-outliers, --side-length ...) are not used by it"
            )
        if truth_frames is not None:
            raise InputError("--truth-frames is not used by the skid-steer fit (a truth topic is)")
        return _fit_skid(paths, method, robot, bag, ticks_per_rev,
                         Exports(out, ros2, controller_name), plot, robot_out, force,
                         scan_interval_s)  # fmt: skip
    if method == "auto" and paths and not all(is_bag(p) for p in paths):
        return _fit_runs_auto(paths, robot, settings, squares, bag, ticks_per_rev, out, ros2,
                              controller_name, plot, robot_out, force)  # fmt: skip
    if _is_auto(paths, method, truth_frames, bag, settings, squares):
        from .fit_auto import fit_auto

        _refuse_for_auto(paths, plot, robot_out)
        return fit_auto(paths[0], robot=robot, options=bag, out=out, ros2=ros2,
                        controller_name=controller_name, scan_interval_s=scan_interval_s,
                        force=force)  # fmt: skip
    exports = Exports(out, ros2, controller_name)
    _refuse_other_routes_outputs(method, plot, robot_out)
    if method == "gyro":
        if len(paths) != 1:
            raise InputError("--method gyro takes exactly one bag", field="paths")
        from .fit_gyro import fit_gyro

        gyro = fit_gyro(paths[0], robot=robot, exports=exports, options=bag, force=force)
        return replace(gyro, load_warnings=unused_offsets(bag.time_offsets, ["imu"]))
    res = _fit_route(
        paths, method, robot, settings, squares, bag, ticks_per_rev, truth_frames,
        slam_stamp_offset_s, scan_interval_s, exports, plot, robot_out, force,
    )  # fmt: skip
    unused = unused_offsets(bag.time_offsets, _offset_sources(res))
    return replace(res, load_warnings=unused + res.load_warnings)


def _fit_skid(
    paths: list[str | Path],
    method: FitMethod | None,
    robot: RobotSpec,
    bag: BagOptions,
    ticks_per_rev: float | None,
    exports: Exports,
    plot: str | Path | None,
    robot_out: str | Path | None,
    force: bool,
    scan_interval_s: float = 0.5,
) -> SkidFitResult | SkidGyroResult:
    """The skid-steer routes: bags with a truth pose track (:mod:`odocal.app.fit_skid`), else,
    or with ``--method gyro``, bags with an IMU; with ``--method scan``, bags with laser scans
    (:mod:`odocal.app.fit_skid_gyro`)."""
    from ..io.robot_file import load_robot
    from .fit_skid import read_skid_bags

    if method not in (None, "auto", "gyro", "scan"):
        raise InputError(
            f"--kinematics skid-steer fits the effective track of bags with a truth pose track, "
            f"an IMU (--method gyro) or laser scans (--method scan); --method {method} is a "
            "differential-drive method",
            field="method",
        )
    if robot_out is not None:
        raise InputError("--robot-out is not made by the skid-steer fit", field="robot-out")
    if not robot:
        raise InputError(
            "--kinematics skid-steer needs the robot file (--robot ROBOT.yaml): the nominal "
            "wheel diameter and wheelbase the multipliers are relative to"
        )
    loaded_robot = load_robot(robot)
    plan = OutputPlan(input_paths(list(paths), robot))
    exports.register(plan)
    if plot is not None:
        from ..plot._figure import require_matplotlib
        from ..plot.skid import SKID_FIGURE

        require_matplotlib()
        plan.folder(plot, "--plot", files=(SKID_FIGURE,))
    contents = read_skid_bags(paths, bag)
    res = _skid_route(contents, method, loaded_robot, bag, ticks_per_rev, plan, exports, plot,
                      force, scan_interval_s)  # fmt: skip
    used = {"scan": "laser", "gyro": "imu"}.get(getattr(res, "sensor", ""), "truth")
    return replace(res, load_warnings=unused_offsets(bag.time_offsets, [used]))


def _skid_route(
    contents: list[BagContents],
    method: FitMethod | None,
    robot: Robot,
    bag: BagOptions,
    ticks_per_rev: float | None,
    plan: OutputPlan,
    exports: Exports,
    plot: str | Path | None,
    force: bool,
    scan_interval_s: float,
) -> SkidFitResult | SkidGyroResult:
    """The bags' skid-steer route: the scan route with ``--method scan``, the gyro route with
    ``--method gyro`` or when no bag has a truth pose track, else the truth route."""
    from ..io.bag_skid import has_truth
    from ..io.bags import IMU
    from .fit_skid import fit_skid_bags
    from .fit_skid_gyro import fit_skid_gyro_bags, fit_skid_scan_bags

    if method == "scan":
        return fit_skid_scan_bags(contents, plan, bag, robot=robot,
                                  ticks_per_rev=ticks_per_rev, scan_interval_s=scan_interval_s,
                                  exports=exports, force=force, plot=plot)  # fmt: skip
    truth = [has_truth(c, bag) for c in contents]
    if method == "gyro" or not any(truth):
        for c in contents:
            if not any(t.msgtype == IMU for t in c.topics):
                raise InputError(
                    "--method gyro needs an IMU (sensor_msgs/Imu); this bag has none"
                    if method == "gyro"
                    else "the skid-steer fit needs a truth pose track (a PoseStamped, or an "
                    "Odometry in a world frame such as a lidar-ICP odometry in 'map'; "
                    "--truth-topic) or an IMU (sensor_msgs/Imu: the gyro route); this bag has "
                    "neither",
                    c.path,
                )
        res = fit_skid_gyro_bags(contents, plan, bag, robot=robot,
                                 ticks_per_rev=ticks_per_rev, exports=exports, force=force,
                                 plot=plot)  # fmt: skip
        if method == "gyro":
            return res
        why = "no truth pose track in the bags: the gyro route (--method gyro)"
        return replace(res, notes=(why, *res.notes))
    if not all(truth):
        lacking = next(c.path for c, t in zip(contents, truth, strict=True) if not t)
        raise InputError(
            "this bag has no truth pose track while the others have one: fit them apart, or "
            "all with --method gyro",
            lacking,
        )
    return fit_skid_bags(contents, plan, bag, robot=robot, ticks_per_rev=ticks_per_rev,
                         exports=exports, force=force, plot=plot)  # fmt: skip


def _fit_runs_auto(
    paths: list[str | Path],
    robot: RobotSpec,
    settings: TrajectorySettings | None,
    squares: SquareSettings | None,
    bag: BagOptions,
    ticks_per_rev: float | None,
    out: str | Path | None,
    ros2: str | Path | None,
    controller_name: str,
    plot: str | Path | None,
    robot_out: str | Path | None,
    force: bool,
) -> RunsAutoResult:
    """``--method auto`` on runs with ground truth (:mod:`odocal.app.fit_runs_auto`): the
    procedures compare with their default settings; it writes the chosen geometry only."""
    if settings not in (None, DEFAULT_TRAJECTORY) or squares not in (None, DEFAULT_SQUARES):
        raise InputError(
            "--method auto on runs compares the procedures with their default settings: name "
            "the method to fit with other settings"
        )
    if plot is not None or robot_out is not None:
        raise InputError(
            "--method auto on runs writes the chosen geometry only (--out, --ros2): name the "
            "method for --plot or --robot-out"
        )
    refuse_repeated(paths)
    exports = Exports(out, ros2, controller_name)
    plan = _output_plan(paths, robot, exports, None, None, "runs")
    from .fit_runs_auto import fit_runs_auto_files

    return fit_runs_auto_files(paths, plan, robot=robot, exports=exports, bag=bag,
                               ticks_per_rev=ticks_per_rev, force=force)  # fmt: skip


def _offset_sources(res: FitResult | RelativeFitResult) -> list[str]:
    """The clocks a route aligns: the truth's (a trajectory fit), the SLAM's, the laser's."""
    from .fit_relative import RelativeFitResult

    if isinstance(res, RelativeFitResult):
        return {"slam": ["slam"], "scan": ["laser"]}.get(res.source, [])
    return ["truth"] if res.fit.method == "trajectory" else []


def _fit_route(
    paths: list[str | Path],
    method: FitMethod | None,
    robot: RobotSpec,
    settings: TrajectorySettings | None,
    squares: SquareSettings | None,
    bag: BagOptions,
    ticks_per_rev: float | None,
    truth_frames: tuple[str, str] | None,
    slam_stamp_offset_s: float,
    scan_interval_s: float,
    exports: Exports,
    plot: str | Path | None,
    robot_out: str | Path | None,
    force: bool,
) -> FitResult | RelativeFitResult:
    """:func:`fit` of every route but the gyro and the one-command route."""
    refuse_repeated(paths)  # the same file twice would count twice, whatever it holds
    route = choose_route(paths, method, truth_frames)
    if robot_out is not None and route != "runs":
        raise InputError(
            "--robot-out needs runs with ground truth (not .tuple files, a SLAM pose or laser "
            "scans: their relative motions measure no repeated runs)"
        )
    plan = _output_plan(paths, robot, exports, plot, robot_out, route)
    if route == "scan":
        from .fit_scan import fit_scan_bags

        return fit_scan_bags(
            paths,
            plan,
            bag,
            robot=robot,
            ticks_per_rev=ticks_per_rev,
            scan_interval_s=scan_interval_s,
            exports=exports,
            force=force,
            plot=plot,
        )
    if route == "tuples":
        if plot is not None:
            raise InputError(
                "--plot: .tuple files have no clock and no stretches to hold out; nothing to draw",
                field="plot",
            )
        from .fit_relative import fit_tuple_files

        return fit_tuple_files(paths, plan, robot=robot, exports=exports, force=force)
    if route == "slam":
        assert truth_frames is not None  # the route needs them
        from .fit_slam import fit_slam_bags

        return fit_slam_bags(
            paths,
            plan,
            truth_frames,
            bag,
            robot=robot,
            ticks_per_rev=ticks_per_rev,
            slam_stamp_offset_s=slam_stamp_offset_s,
            exports=exports,
            force=force,
            plot=plot,
        )
    squares = squares if squares is not None else DEFAULT_SQUARES
    run_method: FitMethod = method or "trajectory"
    # before the runs are loaded (many bags take a while), as fit_recordings checks it
    check_heading_source(run_method, squares.heading_source)
    from .fit_runs import fit_run_files

    return fit_run_files(
        paths,
        run_method,
        plan,
        robot=robot,
        settings=settings if settings is not None else DEFAULT_TRAJECTORY,
        squares=squares,
        bag=bag,
        ticks_per_rev=ticks_per_rev,
        exports=exports,
        plot=plot,
        robot_out=robot_out,
        force=force,
    )
