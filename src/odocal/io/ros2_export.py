"""ros2_control ``diff_drive_controller`` parameter files from a calibrated geometry.

Convention (chosen and fixed): the BASE values stay the nominal ones (what the URDF and the
robot's datasheet say) and the calibration goes into the multipliers::

    <controller>:
      ros__parameters:
        wheel_separation: b_n                     # nominal wheelbase (m)
        wheel_radius: D_n / 2                     # nominal mean wheel radius (m)
        wheel_separation_multiplier: b / b_n
        left_wheel_radius_multiplier: D_L / D_n
        right_wheel_radius_multiplier: D_R / D_n

The controller's effective values are wheel_radius x multiplier (per wheel) and
wheel_separation x wheel_separation_multiplier, which reproduce the calibrated D_R/2, D_L/2 and b
(to the last bit or so: numbers are written with 17 significant digits, which round-trip).
A calibration can thus be undone by setting the multipliers to 1.
"""

from __future__ import annotations

import re
from collections.abc import Sequence

from ..core.covariance import UNMEASURED_VARIANCE, OdometryCovariance
from ..core.model import WheelGeometry
from ..errors import InputError, one_line
from .robot_file import untrusted_lines

__all__ = ["ros2_params_yaml", "ros2_multipliers", "read_ros2_params", "DEFAULT_CONTROLLER"]

DEFAULT_CONTROLLER = "diff_drive_controller"
_NAME = re.compile(r"^[A-Za-z_][A-Za-z0-9_/]*$")


def _check_name(name: str) -> None:
    if not _NAME.match(name or ""):
        raise InputError(
            f"not a valid controller name: {name!r} (letters, digits, '_' and '/', "
            "not starting with a digit)",
            field="controller-name",
        )


def ros2_params_yaml(
    calibrated: WheelGeometry,
    nominal: WheelGeometry,
    controller: str = DEFAULT_CONTROLLER,
    covariance: OdometryCovariance | None = None,
    doubts: Sequence[str] = (),
    **record,
) -> str:
    """The YAML text (module docstring); ``record`` (method, ...) goes into header comments.
    With ``covariance`` (from the measured wheel noise) the file also sets
    ``pose_covariance_diagonal`` and ``twist_covariance_diagonal`` and ends with a commented
    process-noise suggestion for robot_localization (docs/ros.md). ``doubts``: why the
    calibration is not to be trusted (written with ``--force``), as header comments."""
    _check_name(controller)
    d_n = float(nominal.mean_diameter_m)
    b_n = float(nominal.wheelbase_m)
    values = {
        "wheel_separation": b_n,
        "wheel_radius": d_n / 2.0,
        **ros2_multipliers(calibrated, nominal),
    }
    lines = [
        "# ros2_control diff_drive_controller parameters written by odocal",
        "# base values = nominal geometry; calibration = the multipliers",
        f"# calibrated: right wheel diameter {float(calibrated.diameter_right_m):.9g} m, "
        f"left {float(calibrated.diameter_left_m):.9g} m, wheelbase "
        f"{float(calibrated.wheelbase_m):.9g} m",
    ]
    # one comment line each, whatever a value holds (a line break would start a YAML key)
    lines += [f"# {k}: {one_line(str(v))}" for k, v in record.items()]
    lines += untrusted_lines(doubts)
    if covariance is not None:
        c = covariance
        lines += [
            f"# covariances from the wheel noise k_r {c.k_r_m:.3g} m, k_l {c.k_l_m:.3g} m: pose "
            f"after {c.distance_m:g} m of straight travel, twist at {c.speed_m_s:g} m/s measured "
            f"over {c.window_s:g} s; z, roll, pitch unmeasured ({UNMEASURED_VARIANCE:g})",
        ]
    lines += [f"{controller}:", "  ros__parameters:"]
    lines += [f"    {k}: {v!r}" for k, v in values.items()]
    if covariance is not None:
        lines.append(f"    pose_covariance_diagonal: {_floats(covariance.pose_diagonal)}")
        lines.append(f"    twist_covariance_diagonal: {_floats(covariance.twist_diagonal)}")
        q = covariance.process_noise_per_s
        lines += [
            "# robot_localization (ekf_node) process_noise_covariance: the wheel odometry alone",
            f"# grows by x {q['x']:.3g} m^2/s, y {q['y']:.3g} m^2/s, yaw {q['yaw']:.3g} rad^2/s at "
            f"{covariance.speed_m_s:g} m/s;",
            "# use at least these for the diagonal entries of x, y and yaw (indices 0, 1, 5 of",
            "# the 15 x 15 matrix; the filter multiplies them by its time step). The velocity",
            "# entries describe how fast the robot can change speed, which k does not tell.",
        ]
    return "\n".join(lines) + "\n"


def ros2_multipliers(calibrated: WheelGeometry, nominal: WheelGeometry) -> dict[str, float]:
    """The calibration as diff_drive_controller's multipliers of the nominal base values (the
    wheelbase, the mean wheel radius): ``wheel_separation_multiplier``,
    ``left_wheel_radius_multiplier``, ``right_wheel_radius_multiplier``."""
    d_n = float(nominal.mean_diameter_m)
    return {
        "wheel_separation_multiplier": float(calibrated.wheelbase_m) / float(nominal.wheelbase_m),
        "left_wheel_radius_multiplier": float(calibrated.diameter_left_m) / d_n,
        "right_wheel_radius_multiplier": float(calibrated.diameter_right_m) / d_n,
    }


def _floats(values) -> str:
    return "[" + ", ".join(repr(float(v)) for v in values) + "]"


def read_ros2_params(path, controller: str = DEFAULT_CONTROLLER) -> WheelGeometry:
    """The EFFECTIVE geometry (D_R, D_L, b in m) a diff_drive_controller file configures."""
    from .yamlfile import load_yaml

    doc = load_yaml(path, "ros2_control parameter file")
    section = doc.data.get(controller)
    if not isinstance(section, dict) or not isinstance(section.get("ros__parameters"), dict):
        raise InputError(f"no '{controller}: ros__parameters:' mapping", doc.path)
    p = section["ros__parameters"]

    def get(key, default=None):
        if key not in p:
            if default is None:
                raise InputError(f"missing key '{key}'", doc.path, None, key)
            return default
        return doc.number(f"{controller}.ros__parameters.{key}", p[key], positive=True)

    r = get("wheel_radius")
    s = get("wheel_separation")
    return WheelGeometry(
        2.0 * r * get("right_wheel_radius_multiplier", 1.0),
        2.0 * r * get("left_wheel_radius_multiplier", 1.0),
        s * get("wheel_separation_multiplier", 1.0),
    )
