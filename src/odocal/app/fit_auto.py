"""``odocal fit BAG --method auto``: one bag, every route it allows, one answer a careful
engineer can trust (or a clear statement that there is none).

1. **Survey** (:func:`odocal.io.bag_survey.survey`): which routes the bag allows and why not.
2. **Run** every usable route (trajectory with an external truth topic, the SLAM pose on /tf,
   laser scan matching, the gyro), each with its clock offset, its cluster-robust standard
   errors and its held-out check.
3. **Cross-check** the routes against each other: every pair that estimates the same quantity
   (D_R, D_L, b; the gyro's wheelbase at the diameters it ran with) must agree within
   3 combined standard errors.
4. **Answer**: the first route that ran, in the order trajectory, SLAM, scan, gyro (a truth
   topic is the best reference, the gyro sees only the wheelbase), with the covariances for
   ``diff_drive_controller`` from its residuals (:mod:`odocal.calibration.interval_noise`).
5. **Verdict**: trustworthy when the answer's route ran, its held-out check found a model that
   beats the nominal one, the routes agree, its timing and its parts are consistent and the log
   check (trajectory) saw every parameter. Otherwise the reasons, the exit status
   :data:`~odocal.cli.common.NOT_ENOUGH` and nothing written unless ``force``.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.fit_settings import DEFAULT_SQUARES, DEFAULT_TRAJECTORY
from ..calibration.heldout import HeldOut, intervals_of_runs
from ..calibration.interval_noise import IntervalNoise, estimate_interval_noise
from ..calibration.time_offset import TimeOffset
from ..core.covariance import OdometryCovariance, odometry_covariance
from ..core.model import WheelGeometry
from ..errors import CalibrationError, InputError, OdocalError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bag_survey import BagSurvey, RouteOption, survey
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot, params_yaml
from ..io.ros2_export import DEFAULT_CONTROLLER, ros2_params_yaml
from .common import RobotSpec, input_paths
from .fit_gyro import GyroFitResult, fit_gyro
from .fit_relative import RelativeFitResult
from .fit_runs import FitResult, fit_run_files
from .fit_scan import fit_scan_bags
from .fit_slam import fit_slam_bags

__all__ = ["AutoFitResult", "RouteRun", "fit_auto", "KEYS", "MAX_Z"]

#: The parameters, in the JSON contract's names.
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
#: Two routes agree when no shared quantity differs by more than this many combined standard
#: errors.
MAX_Z = 3.0


@dataclass(frozen=True)
class RouteRun:
    """One route of the bag, run or not.

    Attributes
    ----------
    option : RouteOption
        Whether the bag allows it, and why.
    used : bool
        It ran and gave an answer.
    reason : str
        Why it was used, or why not (the survey's reason, or the error it ended in).
    geometry : WheelGeometry or None
    stderr : tuple of (float or None)
        Standard errors of (D_R, D_L, b) (m); None where the route does not estimate one.
    result : object or None
        The route's own result (FitResult, RelativeFitResult, GyroFitResult).
    """

    option: RouteOption
    used: bool
    reason: str
    geometry: WheelGeometry | None = None
    stderr: tuple[float | None, float | None, float | None] = (None, None, None)
    result: Any = None

    @property
    def name(self) -> str:
        """The route's name."""
        return self.option.name

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract's route object, with the route's parameters when it ran."""
        out: dict[str, Any] = {"name": self.name, "used": self.used, "reason": self.reason}
        if self.geometry is not None:
            g = self.geometry.as_dict()
            out["parameters"] = {
                k: {"value": g[k], "std_error": se} for k, se in zip(KEYS, self.stderr, strict=True)
            }
        return out


@dataclass(frozen=True)
class CrossCheck:
    """Two routes compared on one quantity: the difference in combined standard errors."""

    routes: tuple[str, str]
    quantity: str
    z: float

    @property
    def agree(self) -> bool:
        """Within :data:`MAX_Z` combined standard errors."""
        return abs(self.z) <= MAX_Z

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"routes": list(self.routes), "quantity": self.quantity, "z": self.z,
                "agree": self.agree}  # fmt: skip


@dataclass(frozen=True)
class AutoFitResult:
    """The one answer for a bag (module docstring).

    Attributes
    ----------
    bag : Path
    routes : tuple of RouteRun
    answer : RouteRun or None
        The route whose parameters are the answer.
    nominal : WheelGeometry
    cross_checks : tuple of CrossCheck
    noise : IntervalNoise or None
        The answer route's random error (wheels and truth).
    covariance : OdometryCovariance or None
        The pose and twist covariances for ``diff_drive_controller`` from it.
    reasons : tuple of str
        Why the answer is not to be trusted (empty: it is).
    written : tuple of Path
    warnings : tuple of str
    """

    bag: Path
    routes: tuple[RouteRun, ...]
    answer: RouteRun | None
    nominal: WheelGeometry
    cross_checks: tuple[CrossCheck, ...] = ()
    noise: IntervalNoise | None = None
    covariance: OdometryCovariance | None = None
    reasons: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)

    method = "auto"

    @property
    def enough(self) -> bool:
        """A trustworthy answer: a route ran and nothing below speaks against it."""
        return self.answer is not None and not self.reasons

    @property
    def time_offsets(self) -> tuple[TimeOffset, ...]:
        """Every clock offset the routes found (each source once, the first route's)."""
        seen: dict[str, TimeOffset] = {}
        for r in self.routes:
            res = r.result
            offsets: tuple[TimeOffset, ...] = ()
            if isinstance(res, (FitResult, RelativeFitResult)):
                offsets = res.time_offsets
            elif isinstance(res, GyroFitResult) and res.time_offset is not None:
                offsets = (res.time_offset,)
            for o in offsets:
                key = o.source.split(" ")[0]
                seen.setdefault(key, o)
        return tuple(seen.values())

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> the clock offset applied (s)."""
        return {o.source.split(" ")[0]: o.applied_s for o in self.time_offsets}

    @property
    def heldout(self) -> HeldOut | None:
        """The answer route's held-out check."""
        res = None if self.answer is None else self.answer.result
        return res.heldout if isinstance(res, (FitResult, RelativeFitResult)) else None

    def as_dict(self) -> dict[str, Any]:
        """The JSON contract of ``odocal fit BAG --method auto --json``."""
        a = self.answer
        h = self.heldout
        params = None
        if a is not None and a.geometry is not None:
            g = a.geometry.as_dict()
            params = {
                k: {"value": g[k], "std_error": se} for k, se in zip(KEYS, a.stderr, strict=True)
            }
        return {
            "method": "auto",
            "bag": str(self.bag),
            "routes": [r.as_dict() for r in self.routes],
            "answer_route": None if a is None else a.name,
            "parameters": params,
            "nominal": self.nominal.as_dict(),
            "time_offsets_s": self.time_offsets_s,
            "time_offsets": [o.as_dict() for o in self.time_offsets],
            "heldout": None if h is None else h.as_dict(),
            "cross_checks": [c.as_dict() for c in self.cross_checks],
            "noise": None if self.noise is None else self.noise.as_dict(),
            "covariance": None if self.covariance is None else self.covariance.as_dict(),
            "verdict": {"enough": self.enough, "reasons": list(self.reasons)},
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }


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


def cross_checks(runs: Sequence[RouteRun]) -> tuple[CrossCheck, ...]:
    """Every pair of routes that ran, on every quantity both estimate. The gyro's wheelbase
    takes the diameters as nominal (it sees only the rotation): it is compared (at its own
    diameters, the other route's b scaled by the diameters' ratio) only when no route that ran
    measured the diameters, since a left/right difference turns the robot as a wheelbase error
    does and the gyro cannot tell them apart."""
    out = []
    used = [r for r in runs if r.used and r.geometry is not None]
    if any(r.name != "gyro" for r in used):
        used = [r for r in used if r.name != "gyro"]
    for i, a in enumerate(used):
        for b in used[i + 1 :]:
            ga, gb = a.geometry, b.geometry
            assert ga is not None and gb is not None
            for k, key in enumerate(KEYS):
                sa, sb = a.stderr[k], b.stderr[k]
                if sa is None or sb is None or not (sa > 0 or sb > 0):
                    continue
                va, vb = ga.as_dict()[key], gb.as_dict()[key]
                if key == "wheelbase_m" and "gyro" in (a.name, b.name):
                    # compare turning: the other's b at the gyro's diameters
                    gy, other = (ga, gb) if a.name == "gyro" else (gb, ga)
                    scaled = other.wheelbase_m * gy.mean_diameter_m / other.mean_diameter_m
                    va, vb = (
                        (gy.wheelbase_m, scaled) if a.name == "gyro" else (scaled, gy.wheelbase_m)
                    )
                out.append(CrossCheck((a.name, b.name), key, float((va - vb) / math.hypot(sa, sb))))
    return tuple(out)


def _speed(answer: RouteRun) -> float | None:
    """The robot's cruise speed (m/s) in the answer route's intervals: the median of distance
    over time among the intervals that move."""
    res = answer.result
    if not isinstance(res, RelativeFitResult):
        return None
    bags = res.slam_bags
    if bags:
        m = bags[0].motions
        d = np.hypot(m.sensor_motion[:, 0], m.sensor_motion[:, 1])
        dt = np.asarray(m.end_s) - np.asarray(m.start_s)
    else:
        return None
    moving = (d > 0.05) & (dt > 0)
    return float(np.median(d[moving] / dt[moving])) if moving.any() else None


def _reasons(
    answer: RouteRun | None, runs: Sequence[RouteRun], checks: Sequence[CrossCheck]
) -> list[str]:
    """Why the answer is not to be trusted."""
    if answer is None:
        return [
            "no route could calibrate this bag: " + "; ".join(f"{r.name}: {r.reason}" for r in runs)
        ]
    out = []
    res = answer.result
    h = getattr(res, "heldout", None)
    if isinstance(res, (FitResult, RelativeFitResult)):
        if h is None:
            out.append(f"{answer.name}: no held-out check ({'; '.join(res.notes) or 'none made'})")
        elif h.preferred is None:
            out.append(f"{answer.name}: {h.verdict()}")
    if isinstance(res, RelativeFitResult) and res.timing is not None and res.timing.warning:
        out.append(f"{answer.name}: {res.timing.warning}")
    if isinstance(res, FitResult):
        c = res.fit.consistency
        if c is not None and not c.consistent:
            out.append(f"{answer.name}: the log's parts disagree beyond their uncertainty")
        if res.log_check is not None and not res.log_check.check.ok:
            out.append(f"{answer.name}: the log check says NOT enough")
    for x in checks:
        if not x.agree:
            out.append(
                f"the {x.routes[0]} and {x.routes[1]} routes disagree on {x.quantity} by "
                f"{x.z:+.1f} combined standard errors"
            )
    return out


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
        plan.folder(out, "--out")
    found = survey(bag, options)
    runs = []
    for option in found.routes:
        if not option.usable:
            runs.append(RouteRun(option, False, option.reason))
            continue
        runs.append(_run_route(option, found.path, plan, robot, options, found, scan_interval_s))
    answer = next((r for r in runs if r.used), None)
    checks = cross_checks(runs)
    noise = None
    cov = None
    if answer is not None and isinstance(answer.result, RelativeFitResult):
        noise = answer.result.noise
    if noise is None and answer is not None and isinstance(answer.result, FitResult):
        noise = _trajectory_noise(answer, found.path, options)
    speed = _speed(answer) if answer is not None else None
    if noise is not None and answer is not None and answer.geometry is not None:
        k = 0.5 * noise.k_sum_m
        b = float(answer.geometry.wheelbase_m)
        cov = odometry_covariance(k, k, b, speed_m_s=speed or 0.5)
    reasons = _reasons(answer, runs, checks)
    warnings = tuple(w for r in runs if r.used for w in getattr(r.result, "warnings", ()))
    if answer is not None and isinstance(answer.result, GyroFitResult):
        warnings += (
            "the gyro route calibrates the wheelbase only: the wheel diameters stay nominal "
            "(record a SLAM pose, a laser or a truth topic to calibrate them)",
        )
    result = AutoFitResult(found.path, tuple(runs), answer, nominal, checks, noise, cov,
                           tuple(reasons), (), warnings)  # fmt: skip
    if (out is None and ros2 is None) or answer is None or answer.geometry is None:
        return result
    if reasons and not force:
        return result
    contents: dict[Path, Any] = {}
    if ros2 is not None:
        contents[Path(ros2)] = ros2_params_yaml(answer.geometry, nominal, controller_name, cov,
                                               method=f"auto ({answer.name})")  # fmt: skip
    if out is not None:
        from ..io.auto_report import auto_report_markdown
        from ..plot.bag import bag_figures

        folder = Path(out)
        contents[folder / "params.yaml"] = params_yaml(
            answer.geometry, method=f"auto ({answer.name})"
        )
        h = result.heldout
        contents.update(bag_figures(result.time_offsets, h, folder))
        contents[folder / "report.md"] = auto_report_markdown(result.as_dict())
    written = tuple(plan.commit(contents))
    return AutoFitResult(found.path, tuple(runs), answer, nominal, checks, noise, cov,
                         tuple(reasons), written, warnings)  # fmt: skip


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
