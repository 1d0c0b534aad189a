"""One run from a ROS bag: wheel angles, ground truth in the start frame, gyro heading.

Reads the series with :mod:`odocal.io.bags`; checks the wheel joints' signs against the ground
truth; integrates the gyro with :func:`odocal.calibration.gyro.gyro_heading`. Every problem is an
:class:`~odocal.errors.InputError` naming the bag and the topic.
"""

from __future__ import annotations

import math
from collections.abc import Iterator
from contextlib import contextmanager
from contextvars import ContextVar

import numpy as np

from ..calibration.gyro import gyro_heading
from ..core.model import WheelGeometry
from ..core.pose import start_frame
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from .bag_options import BagOptions
from .bag_wheels import choose_wheels, wheel_series
from .bags import (
    BASE_FRAMES,
    IMU,
    ODOMETRY,
    POSE_TYPES,
    TopicSeries,
    check_bag_path,
    imu_series,
    pick_topic,
    pose_series,
    present,
    read_bag,
    static_rotation,
)

__all__ = ["load_bag_recording", "load_bag_run", "without_gyro", "reads_gyro"]

# False within without_gyro(): the IMU topic is chosen (and checked) but not read
_READ_GYRO: ContextVar[bool] = ContextVar("odocal_read_gyro", default=True)


def reads_gyro() -> bool:
    """Whether :func:`load_bag_recording` reads the IMU now (False within
    :func:`without_gyro`)."""
    return _READ_GYRO.get()


@contextmanager
def without_gyro() -> Iterator[None]:
    """Within this block, :func:`load_bag_recording` does not read the bags' IMU (no
    ``gyro_yaw_rad``, no gyro facts or warnings): for a caller that does not use the gyro
    heading (``odocal check``): an IMU is often most of a bag's messages. The IMU topic is still
    chosen, so a wrong ``--imu-topic`` is the same error."""
    token = _READ_GYRO.set(False)
    try:
        yield
    finally:
        _READ_GYRO.reset(token)


def _check_wheel_signs(time_s, right, left, gt, path, topic, names) -> list[str]:
    """Detect a mirrored wheel joint or swapped left/right joints against the ground truth.

    Increments over about 0.5 s. On straight stretches (the ground truth moves but does not
    turn) both wheels must turn the same way; the one turning against the ground truth's heading
    is named when that is clear. Where the ground truth turns, right minus left must turn with
    it. Both checks do not depend on the ground truth's heading offset except the naming.
    Returns warnings (a ground-truth heading pointing backwards).
    """
    if len(time_s) < 3:
        return []
    step = max(1, int(round(0.5 / max(float(np.median(np.diff(time_s))), 1e-9))))
    idx = np.r_[np.arange(0, len(time_s) - 1, step), len(time_s) - 1]
    th = gt[idx, 2]
    dx, dy = np.diff(gt[idx, 0]), np.diff(gt[idx, 1])
    moved = np.hypot(dx, dy)
    fwd = dx * np.cos(th[:-1]) + dy * np.sin(th[:-1])
    dth = np.diff(th)
    dr, dl = np.diff(right[idx]), np.diff(left[idx])

    def corr(a, b):
        den = math.sqrt(float(np.dot(a, a) * np.dot(b, b)))
        return float(np.dot(a, b) / den) if den > 0 else 0.0

    rn, ln = names
    warnings = []
    # straight stretches: moving (> 1 mm per step) while turning less than 1 mrad per step
    straight = (moved > 1e-3) & (np.abs(dth) < 1e-3)
    if float(np.sum(moved[straight])) > 0.2:
        s_dr, s_dl, s_fwd = dr[straight], dl[straight], fwd[straight]
        if corr(s_dr, s_dl) < -0.5:
            cr, cl = corr(s_dr, s_fwd), corr(s_dl, s_fwd)
            which = None
            # which wheel is wrong only if the ground truth's body axis resolves forward (a body
            # frame turned 90 deg leaves |fwd| at rounding level, whose correlations mean nothing)
            resolved = float(np.sum(np.abs(s_fwd))) > 0.5 * float(np.sum(moved[straight]))
            if resolved and cl < -0.5 < 0.5 < cr:
                which = ("left", ln)
            elif resolved and cr < -0.5 < 0.5 < cl:
                which = ("right", rn)
            if which:
                side, joint = which
                what = (
                    f"the {side} wheel joint '{joint}' turns backwards while the robot drives "
                    f"straight forward: its axis is mirrored; invert it with the invert_{side} "
                    f"option (--invert-{side})"
                )
            else:
                what = (
                    "the wheel joints turn in opposite directions while the robot drives "
                    "straight: one joint's axis is mirrored; invert it with the invert_right or "
                    "invert_left option (--invert-right / --invert-left)"
                )
            raise InputError(what, path, None, topic)
        mean = 0.5 * (s_dr + s_dl)
        if corr(mean, s_fwd) < -0.5:
            warnings.append(
                "the ground truth's heading points backwards relative to the wheels' forward "
                "motion: its body frame may be rotated against the robot's"
            )
    if float(np.sum(np.abs(dth))) > math.radians(30):
        cd = corr(dr - dl, dth)
        if cd < -0.5:
            raise InputError(
                f"the wheels look swapped: right minus left wheel rotation turns opposite to the "
                f"ground truth (correlation {cd:.2f}); swap the joints (right joint now '{rn}', "
                f"left '{ln}')",
                path,
                None,
                topic,
            )
    return warnings


def _gyro_yaw(bag, imu: TopicSeries, t_ref, right, left, imu_axis, base_frames):
    """Integrated gyro heading (rad) at ``t_ref`` (starting at 0), its facts and warnings.

    Without a geometry, the wheel angles stand in for the odometry (right minus left for the
    heading, both for standing still)."""
    rot, parent = static_rotation(bag, imu.frame_id, base_frames) if imu.frame_id else (None, None)
    source = None
    if rot is not None and imu_axis is None:
        same = parent == imu.frame_id
        source = (
            "imu frame_id is the base frame" if same else f"tf_static ({parent} -> {imu.frame_id})"
        )
    try:
        h = gyro_heading(
            imu.time_s,
            imu.values["angular_velocity"],
            t_ref,
            right - left,
            0.5 * (right + left),
            rotation=None if imu_axis is not None else rot,
            imu_axis=imu_axis,
            mounting_source=source,
        )
    except CalibrationError as exc:
        raise InputError(f"{exc} (--imu-axis)", bag.path, None, imu.topic) from None
    meta = {
        "imu_topic": imu.topic,
        "imu_mounting": h.mounting_source,
        "imu_yaw_axis": list(h.yaw_axis_in_imu),
        "gyro_bias_rad_s": h.bias_rad_s,
        "gyro_bias_source": h.bias_source,
    }
    return h.yaw_rad, meta, list(h.warnings)


def load_bag_recording(
    path,
    *,
    joint_topic: str | None = None,
    truth_topic: str | None = None,
    imu_topic: str | None = None,
    right_joint: str | None = None,
    left_joint: str | None = None,
    ticks_per_rev: float | None = None,
    invert_right: bool = False,
    invert_left: bool = False,
    imu_axis: str | None = None,
    ran_with: WheelGeometry | None = None,
) -> Recording:
    """One run from a bag: wheel angles, ground truth and (optional) gyro heading.

    Topics default to the only topic of the right type (JointState; a pose type, else Odometry
    for the ground truth; Imu); with several candidates the error lists them. Ground truth and gyro
    are resampled (linear interpolation) at the wheel-sample times, and wheel samples outside the
    ground-truth time span are dropped. Ground truth is expressed in the start frame (first pose
    (0, 0, 0), heading unwrapped). ``ticks_per_rev``: the joint positions are encoder ticks.
    ``invert_right``/``invert_left`` negate a joint whose axis is mirrored. Times start at 0.
    """
    p = check_bag_path(path)
    unnamed: list[str] = []
    opts = BagOptions(joint_topic=joint_topic, right_joint=right_joint, left_joint=left_joint)

    def choose(info):
        wheels = choose_wheels(info, opts, p)
        gt = truth_topic
        if gt is None:
            gt = pick_topic(info, None, POSE_TYPES, "ground truth", p, "--truth-topic", False)
            world = [t.name for t in info if t.world_pose]
            if gt is None and len(world) == 1:
                # an Odometry in a world frame ('map': lidar ICP, SLAM) is not the wheels
                gt = world[0]
            odom = [
                t.name
                for t in info
                if t.msgtype == ODOMETRY and not t.world_pose and t.name != wheels.get("wheel_odom")
            ]
            if gt is None and odom:
                # an Odometry topic is the robot's own odometry unless the user says otherwise:
                # never a reference for itself (the run has no truth; a fit says why)
                from .bag_survey import survey

                unnamed.append(
                    f"no ground truth named: the Odometry topic(s) {', '.join(odom)} may be the "
                    "wheel odometry itself, which cannot be its own reference; name an external "
                    "one with --truth-topic (motion capture, GPS). This bag allows: "
                    f"{survey(path).allowed()}"
                )
        else:
            pick_topic(info, gt, (*POSE_TYPES, ODOMETRY), "ground truth", p, "--truth-topic")
        it = pick_topic(info, imu_topic, (IMU,), "gyro", p, "--imu-topic", required=False)
        if not _READ_GYRO.get():
            it = None
        tf_static = present(info, "/tf_static") if it else None  # the IMU's mounting only
        return {**wheels, "truth": gt, "imu": it, "tf_static": tf_static}

    bag = read_bag(path, choose)
    gt_topic, it = bag.picked.get("truth"), bag.picked.get("imu")
    wheels = wheel_series(bag, opts, ticks_per_rev, ran_with)
    jt = wheels.topic
    t = wheels.time_s
    right = wheels.right * (-1.0 if invert_right else 1.0)
    left = wheels.left * (-1.0 if invert_left else 1.0)
    meta = {
        "bag": str(p),
        "joint_topic": jt,
        **wheels.meta,
        "start_time_ns": bag.start_ns,
    }
    if wheels.source != "joint_states":
        meta["wheels"] = wheels.describe()
    if unnamed:
        meta["no_truth"] = unnamed[0]
    warnings: list[str] = []
    gt = None
    if gt_topic:
        ps = pose_series(bag, gt_topic)
        if bag.msgtype(gt_topic) == ODOMETRY and "odom" in ps.frame_id.lower():
            raise InputError(
                f"the ground truth {gt_topic} is the wheel odometry (frame '{ps.frame_id}'): "
                "the odometry cannot be its own reference; name an external pose (motion "
                "capture, GPS, lidar ICP in the 'map' frame) with --truth-topic",
                p,
                None,
                gt_topic,
            )
        keep = (t >= ps.time_s[0]) & (t <= ps.time_s[-1])
        if keep.sum() < 2:
            raise InputError(
                f"the ground truth ({ps.time_s[0]:.3f} to {ps.time_s[-1]:.3f} s) and the wheel "
                f"joints ({t[0]:.3f} to {t[-1]:.3f} s) hardly overlap in time",
                p,
                None,
                gt_topic,
            )
        if not keep.all():
            meta["wheel_samples_dropped"] = int((~keep).sum())
        t, right, left = t[keep], right[keep], left[keep]
        x = np.interp(t, ps.time_s, ps.values["x"])
        y = np.interp(t, ps.time_s, ps.values["y"])
        yaw = np.interp(t, ps.time_s, ps.values["yaw"])
        gt = start_frame(x, y, yaw)
        meta["truth_topic"] = gt_topic
        warnings += _check_wheel_signs(
            t,
            right - right[0],
            left - left[0],
            gt,
            p,
            jt,
            (meta.get("right_joint", "right wheel"), meta.get("left_joint", "left wheel")),
        )
    right, left = right - right[0], left - left[0]
    meta["start_s"] = bag.start_ns * 1e-9 + float(t[0])  # the first sample, s since the epoch
    gyro_yaw = None
    if it:
        imu = imu_series(bag, it)
        base = (ps.child_frame_id,) if gt is not None and ps.child_frame_id else ()
        gyro_yaw, gmeta, gw = _gyro_yaw(bag, imu, t, right, left, imu_axis, base + BASE_FRAMES)
        meta.update(gmeta)
        warnings += gw
    if warnings:
        meta["warnings"] = warnings
    return Recording(
        name=f"{p}:{jt}",
        time_s=t - t[0],
        wheel_angle_right_rad=right,
        wheel_angle_left_rad=left,
        ground_truth=gt,
        gyro_yaw_rad=gyro_yaw,
        ran_with=ran_with,
        meta=meta,
    )


def load_bag_run(
    path,
    options: BagOptions,
    *,
    ticks_per_rev: float | None = None,
    ran_with: WheelGeometry | None = None,
) -> Recording:
    """:func:`load_bag_recording` with the topics, joints and IMU axis of ``options``."""
    return load_bag_recording(
        path,
        joint_topic=options.joint_topic,
        truth_topic=options.truth_topic,
        imu_topic=options.imu_topic,
        right_joint=options.right_joint,
        left_joint=options.left_joint,
        ticks_per_rev=ticks_per_rev,
        invert_right=options.invert_right,
        invert_left=options.invert_left,
        imu_axis=options.imu_axis,
        ran_with=ran_with,
    )
