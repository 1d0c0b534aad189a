"""``odocal fit BAG --method gyro``: the gyro-only heading calibration, the IMU's rotation against
the wheel odometry's (:mod:`odocal.calibration.gyro`).

:func:`gyro_fit` is the route itself, I/O-free over a loaded bag (as evo's ``main_ape.ape()``);
:func:`fit_gyro_bag` reads the bag and calls it; :func:`fit_gyro` adds the nominal geometry, the
absurd-result check and the exports. The router :func:`odocal.app.fit.fit` chooses this route.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.gyro import GyroResult, gyro_calibration, integrate_rate
from ..calibration.result import ABSURD_FRACTION
from ..calibration.time_offset import TimeOffset, estimate_time_offset, resolve_offset
from ..core.model import Robot, WheelGeometry
from ..core.odometry import wheel_heading
from ..errors import CalibrationError, InputError
from ..io.bag_gyro import GyroBag, read_gyro_bag
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.outputs import OutputPlan
from ..io.robot_file import load_robot
from .common import NO_EXPORTS, Exports, RobotSpec
from .text import Presented, Text, written_lines

__all__ = [
    "GyroFitResult",
    "gyro_fit",
    "gyro_route_fit",
    "gyro_topics",
    "fit_gyro_bag",
    "fit_gyro",
]


@dataclass(frozen=True)
class GyroFitResult(Presented):
    """A gyro-only calibration from a bag, with the calibrated geometry when the nominal one is
    known (effective wheelbase = nominal b x wheelbase_multiplier; diameters unchanged)."""

    gyro: GyroResult
    nominal: WheelGeometry | None
    geometry: WheelGeometry | None
    written: tuple[Path, ...] = ()
    time_offset: TimeOffset | None = None
    base: str = ""
    forced: tuple[str, ...] = ()
    load_warnings: tuple[str, ...] = ()

    method = "gyro"

    @property
    def warnings(self) -> tuple[str, ...]:
        """The calibration's warnings, the clock offset's and the absurd-result message
        accepted with ``force``."""
        own = tuple(self.gyro.warnings)
        offset = () if self.time_offset is None else tuple(self.time_offset.warnings)
        return own + offset + self.forced

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """{'imu': seconds} when the IMU's clock offset was found."""
        return {} if self.time_offset is None else {"imu": self.time_offset.applied_s}

    def text(self) -> str:
        """The text ``odocal fit`` prints for a gyro calibration."""
        return gyro_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit BAG --method gyro --json``."""
        out = self.gyro.as_dict()
        if self.geometry is not None:
            out.update({f"calibrated_{k}": v for k, v in self.geometry.as_dict().items()})
            out["calibrated_from"] = self.base
        out["time_offsets_s"] = self.time_offsets_s
        out["time_offsets"] = [] if self.time_offset is None else [self.time_offset.as_dict()]
        return out


def _odometry_heading(
    loaded: GyroBag,
    wheel_geometry: WheelGeometry | None,
    invert_right: bool,
    invert_left: bool,
    meta: dict[str, Any],
) -> tuple[np.ndarray, np.ndarray, np.ndarray | None]:
    """Time (s), heading (rad) and speed (m/s, or None) of the wheel odometry; its source goes
    into ``meta``. JointState: the wheel-angle heading with ``wheel_geometry``; Odometry: the
    pose yaw (unwrapped), its twist's yaw rate integrated only if the pose never turns."""
    od = loaded.odometry
    if loaded.from_joints:
        assert wheel_geometry is not None  # read_gyro_bag refuses joints without it
        yaw, speed = wheel_heading(
            od.time_s,
            od.values["right"],
            od.values["left"],
            wheel_geometry,
            invert_right=invert_right,
            invert_left=invert_left,
        )
        meta.update(odometry_source="joint_states", **od.meta)
        return od.time_s, yaw, speed
    yaw = od.values["yaw"]
    meta["odometry_source"] = "pose_yaw"
    if np.ptp(yaw) < 1e-9 and np.any(np.abs(od.values["yaw_rate"]) > 1e-6):
        yaw = integrate_rate(od.time_s, od.values["yaw_rate"])
        meta["odometry_source"] = "twist_integrated"
    return od.time_s, yaw, od.values["speed"]


def _mounting(
    loaded: GyroBag, imu_rotation: np.ndarray | None, meta: dict[str, Any]
) -> tuple[np.ndarray | None, str | None]:
    """The IMU's mounting (R_base_imu) and where it came from: ``imu_rotation`` if given, else
    the bag's ``/tf_static`` chain (then ``meta['tf_chain']``), else none (detected later)."""
    if imu_rotation is not None:
        return imu_rotation, "rotation"
    if loaded.mounting is None:
        return None, None
    frame = loaded.imu.frame_id
    same = loaded.mounting_parent == frame.lstrip("/")
    meta["tf_chain"] = f"{loaded.mounting_parent} -> {frame}"
    return loaded.mounting, ("imu frame_id is the base frame" if same else "tf_static")


def gyro_fit(
    loaded: GyroBag,
    *,
    wheel_geometry: WheelGeometry | None = None,
    imu_axis: str | None = None,
    imu_rotation: np.ndarray | None = None,
    invert_right: bool = False,
    invert_left: bool = False,
    bias: Any = "auto",
    min_still_s: float = 1.0,
) -> GyroResult:
    """The gyro route, I/O-free: :func:`~odocal.calibration.gyro.gyro_calibration` of a loaded
    bag (:func:`fit_gyro_bag` says what is read and how)."""
    meta = _meta(loaded)
    heading = _odometry_heading(loaded, wheel_geometry, invert_right, invert_left, meta)
    return _calibrate(
        loaded, heading, meta, wheel_geometry, imu_axis, imu_rotation, bias, min_still_s
    )


def _meta(loaded: GyroBag) -> dict[str, Any]:
    return {
        "bag": str(loaded.path),
        "imu_topic": loaded.imu.topic,
        "odom_topic": loaded.odometry.topic,
    }


def _calibrate(
    loaded: GyroBag,
    heading: tuple[np.ndarray, np.ndarray, np.ndarray | None],
    meta: dict[str, Any],
    wheel_geometry: WheelGeometry | None,
    imu_axis: str | None,
    imu_rotation: np.ndarray | None,
    bias: Any = "auto",
    min_still_s: float = 1.0,
) -> GyroResult:
    """:func:`gyro_fit` on the odometry's ``heading`` (time, yaw, speed)."""
    t_o, yaw, speed = heading
    rotation, source = _mounting(loaded, imu_rotation, meta)
    try:
        result = gyro_calibration(
            loaded.imu.time_s,
            loaded.imu.values["angular_velocity"],
            t_o,
            odom_yaw_rad=yaw,
            odom_speed_m_s=speed,
            rotation=rotation,
            imu_axis=imu_axis,
            mounting_source=source,
            bias=bias,
            min_still_s=min_still_s,
            meta=meta,
        )
    except CalibrationError as exc:
        hint = ""
        if loaded.from_joints and "opposite directions" in str(exc):
            hint = "; or the wheel joints are swapped"
        raise InputError(
            f"{exc}{hint} (IMU '{loaded.imu.topic}', odometry '{loaded.odometry.topic}')",
            loaded.path,
        ) from None
    if wheel_geometry is not None:
        b = float(wheel_geometry.wheelbase_m)
        extra = {"wheelbase_used_m": b, "wheelbase_corrected_m": b * result.wheelbase_multiplier}
        result = replace(result, meta={**result.meta, **extra})
    return result


def imu_offset(
    loaded: GyroBag,
    result: GyroResult,
    t_o: np.ndarray,
    yaw: np.ndarray,
    given: float | None = None,
) -> TimeOffset:
    """The IMU's clock offset against the odometry (:func:`~odocal.calibration.time_offset.
    resolve_offset`): ``given`` (s), else the gyro's yaw (its yaw axis, the bias removed,
    integrated) registered on the odometry's heading
    (:func:`~odocal.calibration.time_offset.estimate_time_offset`, the heading standing in for
    the wheels). The rotation ratio compares whole turns between still periods, which an offset
    hardly moves: an estimate is reported, not applied; a given one is applied (the IMU's
    stamps moved onto the wheels' clock before the calibration)."""

    def estimate() -> TimeOffset:
        t_i = loaded.imu.time_s
        rate = loaded.imu.values["angular_velocity"] @ np.asarray(result.yaw_axis_in_imu)
        gyro_yaw = integrate_rate(t_i, rate - result.bias_rad_s)
        window = max(0.25, float(np.median(np.diff(t_i))))
        a = np.arange(t_i[0], t_i[-1] - window, window)
        heading = np.interp(a + window, t_i, gyro_yaw) - np.interp(a, t_i, gyro_yaw)
        est = estimate_time_offset(t_o, yaw, np.zeros_like(yaw), a, a + window, heading,
                                   source="imu")  # fmt: skip
        return replace(est, applied=False, how=f"{est.how.split(',')[0]}; reported, not applied")

    return resolve_offset("imu", given, estimate)


def _on_wheel_clock(loaded: GyroBag, offset_s: float | None) -> GyroBag:
    """``loaded`` with the IMU's stamps moved onto the wheels' clock by a given offset (its
    sample stamped t saw the robot at wheel time t - offset)."""
    if not offset_s:
        return loaded
    imu = replace(loaded.imu, time_s=loaded.imu.time_s - float(offset_s))
    return replace(loaded, imu=imu)


def fit_gyro_bag(
    path: str | Path,
    *,
    odom_topic: str | None = None,
    imu_topic: str | None = None,
    joint_topic: str | None = None,
    imu_axis: str | None = None,
    wheel_geometry: WheelGeometry | None = None,
    imu_rotation: np.ndarray | None = None,
    right_joint: str | None = None,
    left_joint: str | None = None,
    invert_right: bool = False,
    invert_left: bool = False,
    bias: Any = "auto",
    min_still_s: float = 1.0,
) -> GyroResult:
    """Gyro-only heading calibration from a bag (see :mod:`odocal.calibration.gyro`).

    The odometric rotation comes from a ``nav_msgs/Odometry`` topic (its POSE yaw, unwrapped:
    the controller's own integrated heading, which also covers dropped messages and is not
    smoothed like the twist; the twist's angular.z is integrated only if the pose never turns),
    or from JointState wheel angles with ``wheel_geometry`` (nominal diameters and wheelbase).
    Topic defaults: explicit topics win; else the only Odometry topic; else the JointState topic
    (needs ``wheel_geometry``). IMU mounting: ``imu_axis`` if given, else ``/tf_static`` (base
    frame = the odometry's child frame, or base_link / base_footprint), else detected.
    With ``wheel_geometry`` the result's meta also holds ``wheelbase_used_m`` and
    ``wheelbase_corrected_m`` (with an Odometry topic, pass the geometry the controller ran with).
    ``imu_rotation`` (shape (3, 3), R_base_imu, e.g. from
    :func:`~odocal.calibration.gyro.rotation_from_rpy`) overrides ``/tf_static``.
    Returns a :class:`~odocal.calibration.gyro.GyroResult`. Bags only: reads it with
    :func:`odocal.io.bag_gyro.read_gyro_bag`.
    """
    options = BagOptions(
        joint_topic=joint_topic,
        imu_topic=imu_topic,
        odom_topic=odom_topic,
        right_joint=right_joint,
        left_joint=left_joint,
    )
    loaded = read_gyro_bag(
        path,
        options,
        have_geometry=wheel_geometry is not None,
        mounting=imu_axis is None and imu_rotation is None,
    )
    return gyro_fit(
        loaded,
        wheel_geometry=wheel_geometry,
        imu_axis=imu_axis,
        imu_rotation=imu_rotation,
        invert_right=invert_right,
        invert_left=invert_left,
        bias=bias,
        min_still_s=min_still_s,
    )


def gyro_route_fit(
    loaded: GyroBag,
    robot: Robot | None,
    options: BagOptions = NO_BAG_OPTIONS,
    *,
    force: bool = False,
) -> GyroFitResult:
    """The gyro route, I/O-free, with what ``fit --method gyro`` adds: the IMU's clock offset
    (:func:`imu_offset`; a given one applied), the calibrated geometry when the nominal one is
    known (``robot``'s; the correction applies to what the odometry was computed with) and the
    25 % rule: a wheelbase multiplier more than 25 % from 1 is absurd for a calibration:
    CalibrationError (nothing written) unless ``force``, then its message is kept
    (``forced``)."""
    nominal = robot.nominal if robot is not None else None
    given = options.time_offset("imu")
    loaded = _on_wheel_clock(loaded, given)
    meta = _meta(loaded)
    heading = _odometry_heading(loaded, nominal, options.invert_right, options.invert_left, meta)
    result = _calibrate(loaded, heading, meta, nominal, options.imu_axis or None, None)
    offset = imu_offset(loaded, result, heading[0], heading[1], given)
    forced = _refuse_absurd(float(result.wheelbase_multiplier), force)
    if nominal is None or robot is None:
        return GyroFitResult(result, nominal, None, (), offset, "", forced)
    geometry, base = _corrected(loaded, result, nominal, robot)
    return GyroFitResult(result, nominal, geometry, (), offset, base, forced)


def fit_gyro(
    bag: str | Path,
    *,
    robot: RobotSpec = None,
    exports: Exports = NO_EXPORTS,
    options: BagOptions = NO_BAG_OPTIONS,
    force: bool = False,
) -> GyroFitResult:
    """``odocal fit BAG --method gyro``: the gyro's rotation against the wheel odometry's, with
    the topics, joints and IMU axis of ``options`` (:func:`gyro_route_fit`); the ``exports``
    need the nominal geometry (``robot``)."""
    plan = OutputPlan([Path(bag), *_robot_file(robot)])
    exports.register(plan)
    loaded_robot = load_robot(robot) if robot else None
    if (exports.out or exports.ros2) and loaded_robot is None:
        raise InputError("--out/--ros2 with --method gyro need the nominal geometry: --robot")
    loaded = read_gyro_bag(
        bag, gyro_topics(options), have_geometry=loaded_robot is not None,
        mounting=not options.imu_axis,
    )  # fmt: skip
    res = gyro_route_fit(loaded, loaded_robot, options, force=force)
    if res.geometry is None or res.nominal is None:
        return res
    written = exports.write(
        plan, res.geometry, res.nominal, record={"method": "gyro"}, doubts=res.forced
    )
    return replace(res, written=written)


def gyro_topics(options: BagOptions) -> BagOptions:
    """The topics and joints of ``options`` for the reader (an empty name: none given)."""
    return BagOptions(
        joint_topic=options.joint_topic or None,
        imu_topic=options.imu_topic or None,
        odom_topic=options.odom_topic or None,
        right_joint=options.right_joint or None,
        left_joint=options.left_joint or None,
    )


def _refuse_absurd(m: float, force: bool) -> tuple[str, ...]:
    """A wheelbase multiplier ``m`` more than 25 % from 1 is absurd for a calibration:
    CalibrationError (nothing written) unless ``force``; then its message."""
    if abs(m - 1) <= ABSURD_FRACTION:
        return ()
    message = (
        f"wheelbase_multiplier = {m:.6g} is {100 * (m - 1):+.0f} % from 1: absurd for a "
        "calibration; check the IMU's mounting (--imu-axis, /tf_static), the gyro's units "
        "(rad/s, not deg/s) and the wheel joints"
    )
    if not force:
        raise CalibrationError(f"{message}; nothing written (--force accepts the result anyway)")
    return (message,)


def _corrected(
    loaded: GyroBag, result: GyroResult, nominal: WheelGeometry, robot: Robot
) -> tuple[WheelGeometry, str]:
    """The calibrated geometry and what it corrects: the odometry's rotation was computed
    through the joints with the nominal geometry, or by the controller with the geometry it ran
    with (multipliers included): the correction applies to that one."""
    ran_with = robot.believed_geometry
    ref = nominal if loaded.from_joints else ran_with
    base = (
        "nominal (joint states)" if loaded.from_joints else "the geometry the controller ran with"
    )
    geometry = WheelGeometry(
        ref.diameter_right_m, ref.diameter_left_m, ref.wheelbase_m * result.wheelbase_multiplier
    )
    return geometry, base


def _robot_file(robot: RobotSpec) -> list[Path]:
    """``robot`` if it names an existing file (not a built-in robot or a Robot)."""
    if isinstance(robot, (str, Path)) and robot and Path(robot).exists():
        return [Path(robot)]
    return []


def gyro_text(res: GyroFitResult) -> str:
    """The text of ``odocal fit --method gyro``."""
    out = Text()
    g, meta = res.gyro, res.gyro.meta
    out(f"gyro calibration of {meta['bag']} ({meta['imu_topic']} vs {meta['odom_topic']})")
    out.table(
        [
            ("rotation_ratio (gyro / odometry)", f"{g.rotation_ratio:.5f}"),
            (
                "  its standard error (bias, noise, drift)",
                "- (too short to estimate)"
                if g.rotation_ratio_stderr is None
                else f"{g.rotation_ratio_stderr:.5f}",
            ),
            ("wheelbase_multiplier", f"{g.wheelbase_multiplier:.5f}"),
            ("gyro rotation (deg)", f"{math.degrees(g.gyro_rotation_rad):+.2f}"),
            ("odometry rotation (deg)", f"{math.degrees(g.odometry_rotation_rad):+.2f}"),
            ("IMU yaw axis", f"{g.axis} ({g.mounting_source})"),
            ("gyro bias removed (rad/s)", f"{g.bias_rad_s:.3g} ({g.bias_source})"),
        ]
    )
    if res.geometry is not None:
        out(
            f"  calibrated wheelbase_m: {float(res.geometry.wheelbase_m):.6f} (the correction "
            f"applied to {res.base})"
        )
    o = res.time_offset
    if o is not None:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"  clock offset of the imu: {o.offset_s:+.4f}{se} s ({o.how})")
    written_lines(out, res.written)
    return str(out)
