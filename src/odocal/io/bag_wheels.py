"""The wheels of a bag: joint states when it has them, else the controller's own odometry.

Every bag route needs the wheel rotations over time. Many robots publish no
``sensor_msgs/JointState`` (the Clearpath Husky, the CARMEN-era logs, most mobile bases behind
a vendor driver), only the controller's ``nav_msgs/Odometry`` or its ``odom -> base_link`` on
``/tf``. That pose was integrated from the wheel rotations through the geometry the controller
ran with, so they are recovered exactly by undoing it
(:func:`odocal.core.inverse_odometry.wheel_angles_from_poses`) — provided that geometry is known:
the robot file's ``believed`` geometry (what the robot runs with, multipliers included), else its
nominal one. The source is named in the result so that every output can say which it was.

Choice, in order: ``--joint-topic`` (or the only JointState topic); ``--odom-topic`` (or the
only Odometry topic); ``/tf``'s ``odom -> base_link``. Several Odometry topics and no
``--odom-topic`` is an error that lists them (one of them may be a ground truth).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..core.inverse_odometry import wheel_angles_from_poses
from ..core.model import WheelGeometry
from ..core.transforms import planar_pose
from ..errors import InputError
from .bag_options import BagOptions
from .bags import (
    JOINT_STATE,
    ODOMETRY,
    BagContents,
    TopicInfo,
    joint_series,
    pick_topic,
    pose_series,
    present,
    tf_messages,
)

__all__ = ["WheelSeries", "WheelSource", "choose_wheels", "wheel_series", "ODOM_FRAMES"]

WheelSource = Literal["joint_states", "odometry", "tf"]
#: The odometry edge looked for on /tf when the bag has neither joints nor an Odometry topic.
ODOM_FRAMES = ("odom", "base_link")
# More than this share of steps moving sideways: not a differential drive's own odometry.
_MAX_LATERAL_SHARE = 0.2


@dataclass(frozen=True)
class WheelSeries:
    """Cumulative wheel angles over time, and where they came from.

    Attributes
    ----------
    time_s : ndarray, shape (K,)
        Sample times (s, relative to the bag start).
    right, left : ndarray, shape (K,)
        Cumulative wheel rotations (rad).
    topic : str
        The topic read (``/tf`` for the odometry edge).
    source : {'joint_states', 'odometry', 'tf'}
    ran_with : WheelGeometry or None
        The geometry the odometry was inverted through (None for joint states).
    meta : dict
        The joint reader's facts (joint names, tick conversion) for joint states.
    warnings : tuple of str
    """

    time_s: np.ndarray
    right: np.ndarray
    left: np.ndarray
    topic: str
    source: WheelSource
    ran_with: WheelGeometry | None = None
    meta: dict = field(default_factory=dict)
    warnings: tuple[str, ...] = ()

    def describe(self) -> str:
        """Where the wheel rotations came from, in words."""
        if self.source == "joint_states":
            return f"joint states on {self.topic}"
        g = self.ran_with
        assert g is not None  # inverted through it
        what = f"odometry on {self.topic}" if self.source == "odometry" else "odom -> base_link"
        return (
            f"{what}, inverted through the geometry the controller ran with (D_R "
            f"{g.diameter_right_m:.6g} m, D_L {g.diameter_left_m:.6g} m, b {g.wheelbase_m:.6g} m)"
        )


def choose_wheels(info: list[TopicInfo], options: BagOptions, path: Path) -> dict[str, str | None]:
    """The topics to read for the wheels (for a reader's topic choice): ``joints``, else
    ``wheel_odom``, else ``/tf`` (``tf`` set)."""
    jt = pick_topic(
        info, options.joint_topic, (JOINT_STATE,), "wheel joints", path, "--joint-topic",
        required=False,
    )  # fmt: skip
    if jt is not None:
        return {"joints": jt, "wheel_odom": None}
    if options.joint_topic is None:
        candidates = info if options.odom_topic else [t for t in info if not t.world_pose]
        odom = pick_topic(
            candidates, options.odom_topic, (ODOMETRY,), "wheel odometry", path,
            "--odom-topic", required=False,
        )  # fmt: skip
        if odom is not None:
            return {"joints": None, "wheel_odom": odom}
        if present(info, "/tf") is not None:
            return {"joints": None, "wheel_odom": None, "tf": "/tf"}
    raise InputError(
        "no wheel data: the bag has no sensor_msgs/JointState, no nav_msgs/Odometry and no "
        "/tf; record the wheel joints or the controller's odometry",
        path,
    )


def _odom_edge(bag: BagContents, path: Path) -> tuple[np.ndarray, np.ndarray]:
    edges = tf_messages(bag)
    if ODOM_FRAMES not in edges:
        found = ", ".join(f"{a} -> {b}" for a, b in edges) or "none"
        raise InputError(
            "no wheel data: no joint states, no Odometry topic, and no odom -> base_link on /tf "
            f"(edges: {found})",
            path,
        )
    e = edges[ODOM_FRAMES]
    from ..core.transforms import RigidTransforms

    return e.time_s, planar_pose(RigidTransforms(e.translation_m, e.quaternion_xyzw))


def wheel_series(
    bag: BagContents,
    options: BagOptions,
    ticks_per_rev: float | None,
    ran_with: WheelGeometry | None,
) -> WheelSeries:
    """The wheels of a bag read with topics chosen by :func:`choose_wheels`. ``ran_with`` is
    needed when they come from the odometry (InputError that says so otherwise)."""
    picked: dict[str, Any] = bag.picked
    jt = picked.get("joints")
    if jt:
        j = joint_series(bag, jt, options.right_joint, options.left_joint, ticks_per_rev)
        return WheelSeries(j.time_s, j.values["right"], j.values["left"], jt, "joint_states",
                           meta=dict(j.meta))  # fmt: skip
    topic = picked.get("wheel_odom")
    if ran_with is None:
        raise InputError(
            f"the bag has no wheel joint states; its odometry ({topic or 'odom -> base_link'}) "
            "can stand in for them only through the geometry the controller ran with: give "
            "--robot ROBOT.yaml (its 'believed' geometry, else the nominal one)",
            bag.path,
        )
    if topic:
        s = pose_series(bag, topic)
        if s.frame_id and "odom" not in s.frame_id.lower() and options.odom_topic != topic:
            raise InputError(
                f"the Odometry on {topic} is a pose in the '{s.frame_id}' frame, not the wheel "
                "odometry (whose frame is 'odom'): it cannot be inverted into wheel rotations; "
                "record the joint states or name the wheel odometry with --odom-topic",
                bag.path,
            )
        t, poses = s.time_s, np.column_stack([s.values["x"], s.values["y"], s.values["yaw"]])
        source: WheelSource = "odometry"
    else:
        t, poses = _odom_edge(bag, bag.path)
        topic, source = "/tf", "tf"
    inv = wheel_angles_from_poses(poses, ran_with)
    warnings = []
    if inv.moving_steps == 0:
        raise InputError(
            f"the odometry on {topic} never moves: no wheel rotation to calibrate", bag.path
        )
    share = inv.lateral_steps / inv.moving_steps
    if share > _MAX_LATERAL_SHARE:
        raise InputError(
            f"the odometry on {topic} moves sideways in {100 * share:.0f} % of its steps: it is "
            "not a differential drive's wheel odometry (a fused or SLAM pose?); give the wheel "
            "odometry with --odom-topic or record the joint states",
            bag.path,
        )
    if inv.lateral_steps:
        warnings.append(
            f"{inv.lateral_steps} of {inv.moving_steps} odometry steps on {topic} move sideways "
            "(no wheel rotation explains them exactly)"
        )
    return WheelSeries(t, inv.angle_right_rad, inv.angle_left_rad, topic, source, ran_with,
                       warnings=tuple(warnings))  # fmt: skip
