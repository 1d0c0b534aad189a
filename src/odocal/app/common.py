"""What several commands share: the robot they are given, and the paths they read."""

from __future__ import annotations

from collections import Counter
from collections.abc import Sequence
from pathlib import Path
from typing import Any

from ..calibration.result import far_from_nominal
from ..core.model import Robot, WheelGeometry
from ..core.recording import Recording
from ..errors import CalibrationError
from ..io.robot_file import load_params, load_robot
from ..presets import DEFAULT_ROBOT, PRESETS

__all__ = [
    "RobotSpec",
    "resolve_robot",
    "optional_robot",
    "robot_label",
    "input_paths",
    "nominal_geometry",
    "refuse_absurd",
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


def optional_robot(robot: RobotSpec) -> Robot | None:
    """The Robot of ``robot``, or None when none is given (no default robot: recorded runs carry
    their own parameters)."""
    if robot is None or isinstance(robot, Robot):
        return robot
    return load_robot(robot)


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


def refuse_absurd(geometry: WheelGeometry, nominal: WheelGeometry | None, force: bool) -> list[str]:
    """A calibration far (> 25 %) from ``nominal`` is refused (CalibrationError, nothing
    written) unless ``force``; then its messages are returned as warnings."""
    values = (geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m)
    problems = far_from_nominal(values, nominal)
    if problems and not force:
        more = f" (and {len(problems) - 1} more)" if len(problems) > 1 else ""
        raise CalibrationError(
            f"{problems[0]}{more}; nothing written (--force accepts the result anyway)"
        )
    return problems
