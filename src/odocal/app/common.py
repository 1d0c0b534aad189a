"""What several commands share: the robot they are given, and the paths they read."""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.heldout import HeldOut
from ..calibration.result import WHEELS_HINT, far_from_nominal
from ..core.covariance import OdometryCovariance
from ..core.model import Kinematics, Robot, WheelGeometry
from ..core.plausibility import calibrated_geometry_problem, wheel_size_problem
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from ..io.limits import ROBOT_LENGTH_M
from ..io.outputs import OutputPlan
from ..io.robot_file import load_params, load_robot, params_yaml
from ..io.ros2_export import DEFAULT_CONTROLLER, ros2_params_yaml
from ..presets import DEFAULT_ROBOT, PRESETS

__all__ = [
    "RobotSpec",
    "kinematics_of",
    "resolve_robot",
    "optional_robot",
    "robot_label",
    "input_paths",
    "nominal_geometry",
    "register_exports",
    "write_exports",
    "make_robot",
    "refuse_absurd",
    "implausible_geometry",
    "refuse_untrusted",
    "require_robot",
    "robot_nominal",
    "robot_ran_with",
    "load_warnings",
    "unused_offsets",
    "Exports",
    "NO_EXPORTS",
]

#: A robot as a command takes it: a Robot, a built-in name, a ROBOT.yaml path, or None (default).
RobotSpec = Robot | str | Path | None


def resolve_robot(
    robot: RobotSpec = None, params: str | Path | WheelGeometry | None = None
) -> Robot:
    """The Robot of ``robot`` (default :data:`odocal.presets.DEFAULT_ROBOT`), with ``params``
    (a PARAMS.yaml path or a geometry) installed as the parameters it runs with."""
    r = robot if isinstance(robot, Robot) else load_robot(robot)
    if params is not None:
        r = r.with_believed(params if isinstance(params, WheelGeometry) else load_params(params))
    return r


def require_robot(robot: RobotSpec, why: str) -> None:
    """A command whose answer depends on the robot's geometry has no default robot: InputError
    when ``robot`` is None (``why``: what the geometry sets)."""
    if robot is None:
        raise InputError(
            "which robot drove the runs? Give --robot ROBOT.yaml (its nominal geometry, and "
            "'believed' if it ran with other values) or a built-in robot by name "
            f"({', '.join(PRESETS)}): there is no default robot, {why}"
        )


def optional_robot(robot: RobotSpec) -> Robot | None:
    """The Robot of ``robot``, or None when none is given (no default robot: recorded runs carry
    their own parameters)."""
    if robot is None or isinstance(robot, Robot):
        return robot
    return load_robot(robot)


def make_robot(
    wheel_diameter_m: float,
    wheelbase_m: float,
    *,
    E_b: float = 1.0,
    E_d: float = 1.0,
    E_s: float = 1.0,
    k_r_m: float = 0.0,
    k_l_m: float | None = None,
    sigma_xy_m: float = 0.0,
    sigma_theta_deg: float = 0.0,
) -> Robot:
    """A Robot from the values of a ROBOT.yaml, in its units (m, deg; k in m): nominal wheel
    diameter and wheelbase, systematic errors E_b, E_d, E_s, wheel noise k_r_m, k_l_m (default
    k_r_m) and the instrument's sigma_xy_m and sigma_theta_deg. Each is one number (ModelError
    naming it otherwise: a string, None or an array is refused), then the same checks as the file
    (diameter against wheelbase: a unit slip cannot pass)."""
    from ..core.checks import check_nonnegative_float, check_number
    from ..core.model import MeasurementNoise, NonSystematicError, SystematicError
    from ..core.plausibility import proportions_problem, robot_scale_problem
    from ..io.limits import (
        ERROR_FACTOR,
        K_MAX_M,
        ROBOT_LENGTH_M,
        SIGMA_THETA_MAX_DEG,
        SIGMA_XY_MAX_M,
    )

    lo, hi = ROBOT_LENGTH_M
    diameter = check_number(
        "wheel_diameter_m", wheel_diameter_m, at_least=lo, at_most=hi, hint=" m"
    )
    b = check_number("wheelbase_m", wheelbase_m, at_least=lo, at_most=hi, hint=" m")
    problem = proportions_problem(diameter, diameter, b) or robot_scale_problem(diameter, b)
    if problem:
        raise InputError(problem, field="wheelbase_m")
    lo, hi = ERROR_FACTOR
    E = [
        check_number(n, v, at_least=lo, at_most=hi, hint=" (a real robot's is near 1)")
        for n, v in (("E_b", E_b), ("E_d", E_d), ("E_s", E_s))
    ]
    k_r = check_nonnegative_float("k_r_m", k_r_m, at_most=K_MAX_M, hint=" m")
    k_l = (
        k_r
        if k_l_m is None
        else check_nonnegative_float("k_l_m", k_l_m, at_most=K_MAX_M, hint=" m")
    )
    return Robot(
        WheelGeometry.symmetric(diameter, b),
        SystematicError(*E),
        NonSystematicError(k_r, k_l),
        MeasurementNoise.from_degrees(
            check_nonnegative_float("sigma_xy_m", sigma_xy_m, at_most=SIGMA_XY_MAX_M, hint=" m"),
            check_nonnegative_float(
                "sigma_theta_deg", sigma_theta_deg, at_most=SIGMA_THETA_MAX_DEG, hint=" deg"
            ),
        ),
    )


def robot_label(robot: RobotSpec, params: Any = None) -> str:
    """How a report names the robot."""
    if isinstance(robot, Robot):
        label = "given robot"
    elif robot is None:
        label = f"{DEFAULT_ROBOT} (built-in)"
    else:
        label = str(robot)
    if params is not None and not isinstance(params, WheelGeometry):
        label += f" running with {params}"
    return label


def input_paths(*specs: Any) -> list[Path]:
    """The file-system paths among ``specs`` (built-in robot names and objects are not paths)."""
    out = []
    for s in specs:
        if s is None or isinstance(s, (Robot, WheelGeometry)):
            continue
        if isinstance(s, (list, tuple)):
            out += input_paths(*s)
            continue
        if isinstance(s, str) and s in PRESETS:
            continue
        if isinstance(s, (str, Path)):
            out.append(Path(s))
    return out


def nominal_geometry(robot: Robot | None, recordings: Sequence[Recording]) -> WheelGeometry | None:
    """Nominal geometry: the robot's if given, else the most common ``ran_with`` (or None)."""
    if robot is not None:
        return robot.nominal
    counts = Counter(r.ran_with for r in recordings if r.ran_with is not None)
    return counts.most_common(1)[0][0] if counts else None


def load_warnings(recordings: Sequence[Recording]) -> tuple[str, ...]:
    """What the readers said about each run (its ``meta['warnings']``), named by run."""
    return tuple(
        f"{r.name}: {w}" for r in recordings for w in (r.meta.get("warnings", ()) if r.meta else ())
    )


def unused_offsets(given: Sequence[tuple[str, float]], used: Sequence[str]) -> tuple[str, ...]:
    """A warning for each clock offset fixed with ``--time-offset SOURCE=SECONDS`` (``given``)
    whose source no route that ran aligns (``used``): a given offset is never ignored in
    silence."""
    return tuple(
        f"--time-offset {source}={value:g} was given, but no route that ran aligns the "
        f"{source}'s clock: it was not used"
        for source, value in given
        if source not in used
    )


#: Below this rotation (rad, each wheel, over the whole run) a run's robot never moved.
STILL_WHEEL_ROTATION_RAD = 0.01


def refuse_still_runs(recordings: Sequence[Recording]) -> None:
    """A run in which the robot never moves (neither wheel turns by
    :data:`STILL_WHEEL_ROTATION_RAD`) holds nothing to calibrate or check: InputError naming
    it, before any work and any output."""
    for r in recordings:
        turned = max(
            float(np.ptp(a)) if len(a) else 0.0
            for a in (r.wheel_angle_right_rad, r.wheel_angle_left_rad)
        )
        if not turned >= STILL_WHEEL_ROTATION_RAD:
            raise InputError(
                f"the robot never moves in this run (its wheels turn {turned:.3g} rad at most); "
                "nothing to calibrate or check: remove the run",
                r.name,
            )


def implausible_geometry(geometry: WheelGeometry) -> str | None:
    """Why a calibrated ``geometry`` is not a robot the robot-file reader would accept (lengths
    out of range, diameters against the wheelbase), or None."""
    return calibrated_geometry_problem(geometry, ROBOT_LENGTH_M)


def refuse_absurd(
    geometry: WheelGeometry, nominal: WheelGeometry | None, force: bool, hint: str = WHEELS_HINT
) -> list[str]:
    """A calibration far (> 25 %) from ``nominal``, or not a plausible robot at all
    (:func:`implausible_geometry`, checked with or without a nominal; without one, wheels larger
    than any robot's too: :func:`~odocal.core.plausibility.wheel_size_problem`), is refused
    (CalibrationError, nothing written) unless ``force``; then its messages are returned as
    warnings (an implausible geometry is still never written: :func:`write_exports`). ``hint``:
    what the route's inputs can get wrong."""
    values = (geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m)
    problems = far_from_nominal(values, nominal, hint)
    implausible = implausible_geometry(geometry)
    if not implausible and nominal is None:
        implausible = wheel_size_problem(geometry)
    if implausible:
        problems.insert(0, f"not a plausible robot: {implausible}; {hint}")
    if problems and not force:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise CalibrationError(
            f"{problems[0]}{more}; nothing written (--force accepts the result anyway)"
        )
    return problems


def refuse_untrusted(heldout: HeldOut | None, force: bool) -> None:
    """A calibration that no model can make beat the nominal geometry on data it did not fit
    (the held-out check) is refused (CalibrationError, nothing written) unless ``force``."""
    if heldout is not None and heldout.preferred is None and not force:
        raise CalibrationError(
            f"{heldout.verdict()}; nothing written (--force exports the calibration anyway)"
        )


def robot_nominal(robot: RobotSpec) -> WheelGeometry | None:
    """The nominal geometry of ``robot``, or None when none is given."""
    return load_robot(robot).nominal if robot else None


def robot_ran_with(robot: RobotSpec) -> WheelGeometry | None:
    """The geometry the robot's controller ran with (its odometry is inverted through it when a
    bag has no joint states): ROBOT.yaml's ``believed``, else its nominal; None without a
    robot."""
    return load_robot(robot).believed_geometry if robot else None


def register_exports(
    plan: OutputPlan, out: str | Path | None = None, ros2: str | Path | None = None
) -> None:
    """Register the PARAMS.yaml (``out``) and ros2_control (``ros2``) files a calibration writes,
    before the work (checked against the inputs)."""
    if out is not None:
        plan.file(out, "--out")
    if ros2 is not None:
        plan.file(ros2, "--ros2")


def write_exports(
    plan: OutputPlan,
    geometry: WheelGeometry,
    nominal: WheelGeometry | None,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
    *,
    files: Mapping[Path, Any] | None = None,
    record: Mapping[str, str | float] | None = None,
    covariance: OdometryCovariance | None = None,
    doubts: Sequence[str] = (),
) -> tuple[Path, ...]:
    """The one export path of every calibration: PARAMS.yaml (``out``) and the ros2_control
    ``diff_drive_controller`` file (``ros2``; nominal base values, the calibration in the
    multipliers, the pose/twist ``covariance`` when known), written all or none with the
    command's other ``files`` (path -> content, e.g. figures). ``record`` (method, E_b, ...)
    goes beside the values; ``doubts`` (a calibration written with ``--force`` despite them)
    into both files' headers, and ``trusted: false`` into PARAMS.yaml: a week later a forced
    file does not look like a trustworthy one. A geometry the robot-file reader would refuse
    (:func:`implausible_geometry`) is never written: CalibrationError."""
    record = dict(record or {})
    implausible = implausible_geometry(geometry) if (out or ros2) else None
    if implausible:
        raise CalibrationError(
            f"not a plausible robot: {implausible}; nothing written (the file could not be read "
            "back)"
        )
    contents: dict[Path, Any] = dict(files or {})
    if ros2 is not None:
        if nominal is None:
            raise InputError("--ros2 needs the nominal geometry: give --robot ROBOT.yaml")
        text = {k: v for k, v in record.items() if isinstance(v, str)}
        contents[Path(ros2)] = ros2_params_yaml(
            geometry, nominal, controller_name, covariance, doubts, **text
        )
    if out is not None:
        contents[Path(out)] = params_yaml(geometry, doubts, **record)
    return tuple(plan.commit(contents)) if contents else ()


@dataclass(frozen=True)
class Exports:
    """Where a calibration goes: PARAMS.yaml (``out``) and the ros2_control
    ``diff_drive_controller`` file (``ros2``, its controller named ``controller_name``)."""

    out: str | Path | None = None
    ros2: str | Path | None = None
    controller_name: str = DEFAULT_CONTROLLER

    def register(self, plan: OutputPlan) -> None:
        """Register the files in ``plan`` before the work (:func:`register_exports`)."""
        register_exports(plan, self.out, self.ros2)

    def write(
        self,
        plan: OutputPlan,
        geometry: WheelGeometry,
        nominal: WheelGeometry | None,
        *,
        files: Mapping[Path, Any] | None = None,
        record: Mapping[str, str | float] | None = None,
        doubts: Sequence[str] = (),
    ) -> tuple[Path, ...]:
        """Write them, with the command's other ``files``, all or none (:func:`write_exports`;
        ``doubts``: accepted with ``--force``)."""
        return write_exports(
            plan,
            geometry,
            nominal,
            self.out,
            self.ros2,
            self.controller_name,
            files=files,
            record=record,
            doubts=doubts,
        )


#: No file to write.
NO_EXPORTS = Exports()


def kinematics_of(kinematics: Kinematics | None, robot: RobotSpec) -> Kinematics:
    """The kinematics asked for, else the robot's (its file's ``kinematics``), else
    differential. A robot file that is a pipe is read once, by the route (say
    ``--kinematics`` then)."""
    if kinematics is not None:
        return kinematics
    if isinstance(robot, Robot):
        return robot.kinematics
    if robot and (str(robot) in PRESETS or Path(robot).is_file()):
        return load_robot(robot).kinematics
    return "differential"
