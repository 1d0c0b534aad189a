"""Which calibration routes a bag allows, from what it recorded.

A route needs the wheels (joint states, or the controller's odometry inverted through the
geometry it ran with) and a reference that did not come from the wheels: a SLAM pose on ``/tf``
(``map -> odom``), a 2D laser (scan matching), an IMU (the gyro: the wheelbase only), or an
external pose topic (motion capture, GPS: ``--truth-topic``). The robot's own odometry is never
a reference for itself. :func:`survey` says, for each route, whether the bag has what it needs
and why not; it reads the topic list and, when the bag has ``/tf``, its edges.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..calibration.route_answer import ROUTE_NAMES, RouteName
from ..errors import InputError
from .bag_options import BagOptions
from .bags import (
    IMU,
    JOINT_STATE,
    LASER_SCAN,
    ODOMETRY,
    POSE_TYPES,
    BagContents,
    TopicInfo,
    check_bag_path,
    list_topics,
    read_bag,
    tf_messages,
)

__all__ = ["RouteOption", "BagSurvey", "survey", "slam_frames", "ROUTES"]

#: The bag routes, in the order the one-command fit prefers them.
ROUTES = ROUTE_NAMES


@dataclass(frozen=True)
class RouteOption:
    """One route: its name, whether the bag allows it, and why (or why not)."""

    name: RouteName
    usable: bool
    reason: str

    def as_dict(self) -> dict[str, object]:
        """The JSON contract's route object (``name``, ``used``, ``reason``; ``used`` is set by
        the caller that runs it)."""
        return {"name": self.name, "usable": self.usable, "reason": self.reason}


@dataclass(frozen=True)
class BagSurvey:
    """What a bag recorded, and the routes it allows.

    Attributes
    ----------
    path : Path
    topics : tuple of TopicInfo
    wheels : str or None
        Where the wheel rotations would come from (None: nowhere).
    slam_edge : tuple of str or None
        The truth frames of a SLAM pose on ``/tf`` (e.g. ('map', 'base_link')), if any.
    routes : tuple of RouteOption
        One per entry of :data:`ROUTES`.
    """

    path: Path
    topics: tuple[TopicInfo, ...]
    wheels: str | None
    slam_edge: tuple[str, str] | None
    routes: tuple[RouteOption, ...]

    def route(self, name: RouteName) -> RouteOption:
        """The option of route ``name``."""
        return next(r for r in self.routes if r.name == name)

    def allowed(self) -> str:
        """The routes the bag allows, in words, for error messages."""
        ok = [f"{r.name} ({r.reason})" for r in self.routes if r.usable]
        return "; ".join(ok) if ok else "none (" + "; ".join(r.reason for r in self.routes) + ")"


def _of(topics: list[TopicInfo], types: tuple[str, ...]) -> list[str]:
    return [t.name for t in topics if t.msgtype in types]


def slam_frames(path: Path | BagContents) -> tuple[str, str] | None:
    """The truth frames of a SLAM pose on /tf: (the parent of the odometry frame ``odom``, the
    odometry's child, the base), if /tf has both edges."""
    bag = read_bag(path, ["/tf"])
    edges = list(tf_messages(bag))
    parent = next((a for a, b in edges if b == "odom" and a != "odom"), None)
    base = next((b for a, b in edges if a == "odom" and b != "odom"), None)
    return (parent, base) if parent and base else None


def _refuse_wheels_as_truth(topics: list[TopicInfo], opts: BagOptions, p: Path) -> None:
    """A truth topic named that is the wheel odometry itself (an Odometry in the odometry
    frame, or the topic named as the wheels) would calibrate the odometry against itself:
    InputError."""
    named = opts.truth_topic
    if named is None:
        return
    info = next((t for t in topics if t.name == named), None)
    if info is None:
        return
    if named == opts.odom_topic or (info.wheel_odometry_frame and info.frames is not None):
        frame = "" if info.frames is None else f" (frame '{info.frames[0]}')"
        raise InputError(
            f"--truth-topic {named} is the wheel odometry{frame}: the odometry cannot be its "
            "own reference (an exit-0 calibration of it against itself); name an external "
            "pose (motion capture, GPS, lidar ICP in the 'map' frame), or use the SLAM pose "
            "on /tf, the laser or the gyro (--method auto)",
            p,
        )


def survey(path: str | Path | BagContents, options: BagOptions | None = None) -> BagSurvey:
    """The routes ``path`` allows (module docstring); ``options`` name topics explicitly. A bag
    already read (:class:`~odocal.io.bags.BagContents`) is surveyed without opening it."""
    opts = options if options is not None else BagOptions()
    p = check_bag_path(path)
    topics = path.topics if isinstance(path, BagContents) else list_topics(p)
    names = {t.name for t in topics}
    joints = _of(topics, (JOINT_STATE,))
    # an Odometry in a world frame ('map': lidar ICP, SLAM, motion capture) is a truth, never
    # the wheels (its frames are known when the bag was read: read_bag_once)
    world = [t.name for t in topics if t.world_pose and t.name != opts.odom_topic]
    odoms = [n for n in _of(topics, (ODOMETRY,)) if n not in world]
    _refuse_wheels_as_truth(topics, opts, p)
    wheels: str | None = None
    if opts.joint_topic or joints:
        wheels = f"joint states on {opts.joint_topic or joints[0]}"
    elif opts.odom_topic or len(odoms) == 1:
        wheels = f"the odometry on {opts.odom_topic or odoms[0]} (inverted: needs --robot)"
    elif len(odoms) > 1:
        wheels = None
    elif "/tf" in names:
        wheels = "odom -> base_link on /tf (inverted: needs --robot)"
    edge = slam_frames(path if isinstance(path, BagContents) else p) if "/tf" in names else None
    no_wheels = (
        f"no wheel data (several Odometry topics: {', '.join(odoms)}; name the wheel odometry "
        "with --odom-topic)"
        if len(odoms) > 1 and not joints
        else "no wheel data (no JointState, no Odometry)"
    )
    truth = opts.truth_topic or next(iter(_of(topics, POSE_TYPES)), None) or next(
        iter(world), None
    )
    routes = []
    if truth and wheels:
        routes.append(RouteOption("trajectory", True, f"truth {truth}, wheels from {wheels}"))
    else:
        why = no_wheels if not wheels else (
            "no external pose topic (PoseStamped, PoseWithCovarianceStamped, TransformStamped; "
            "an Odometry that is not the wheel odometry: --truth-topic)"
        )  # fmt: skip
        routes.append(RouteOption("trajectory", False, why))
    if edge and wheels:
        routes.append(
            RouteOption(
                "slam", True, f"SLAM correction {edge[0]} -> {edge[1]} on /tf, wheels from {wheels}"
            )  # fmt: skip
        )
    else:
        routes.append(RouteOption("slam", False, no_wheels if not wheels else
                                  "no SLAM correction (a map -> odom edge) on /tf"))  # fmt: skip
    scans = [opts.scan_topic] if opts.scan_topic else _of(topics, (LASER_SCAN,))
    if scans and wheels:
        routes.append(RouteOption("scan", True, f"laser scans on {scans[0]}, wheels from {wheels}"))
    else:
        routes.append(RouteOption("scan", False, no_wheels if not wheels else
                                  "no sensor_msgs/LaserScan"))  # fmt: skip
    imus = [opts.imu_topic] if opts.imu_topic else _of(topics, (IMU,))
    if imus and (wheels or odoms):
        against = wheels or f"the odometry on {odoms[0]}"
        routes.append(
            RouteOption(
                "gyro", True,
                f"IMU on {imus[0]} against {against.split(' (')[0]} (the wheelbase only: no "
                "diameters)",
            )
        )  # fmt: skip
    else:
        routes.append(RouteOption("gyro", False, no_wheels if not (wheels or odoms) else
                                  "no sensor_msgs/Imu"))  # fmt: skip
    return BagSurvey(p, tuple(topics), wheels, edge, tuple(routes))
