"""ROS 1 ``.bag`` and ROS 2 (``.mcap``, ``.db3`` or a rosbag2 folder) recordings via ``rosbags``.

No ROS installation is needed; ``rosbags`` (the ``bags`` extra) is imported only when a bag is
read. Timestamps are integer nanoseconds inside rosbags; they are turned into seconds here, at the
edge, relative to the bag's start time. A message's time is its ``header.stamp`` (when the
measurement was made); a topic whose stamps are zero falls back to the time it was recorded.

What is read (docs/ros.md):

- wheel angles from ``sensor_msgs/JointState`` (positions in rad, or ticks with
  ``ticks_per_rev``); wrapped positions (a driver reporting angles in (-pi, pi]) are unwrapped;
- ground truth from ``geometry_msgs/PoseStamped``, ``PoseWithCovarianceStamped``,
  ``TransformStamped`` or ``nav_msgs/Odometry``, expressed in the start frame;
- gyro angular velocity from ``sensor_msgs/Imu``, the IMU mounting from ``/tf_static``;
- wheel odometry from ``nav_msgs/Odometry`` (for the gyro calibration).

Every problem is an :class:`~odocal.errors.InputError` naming the bag and the topic.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..errors import InputError, OdocalError

__all__ = [
    "TopicInfo",
    "BagContents",
    "TopicSeries",
    "is_bag",
    "list_topics",
    "format_topics",
    "read_bag",
    "load_bag_recording",
    "fit_gyro_from_bag",
    "JOINT_STATE",
    "IMU",
    "ODOMETRY",
    "POSE_TYPES",
]

JOINT_STATE = "sensor_msgs/msg/JointState"
IMU = "sensor_msgs/msg/Imu"
ODOMETRY = "nav_msgs/msg/Odometry"
TF = "tf2_msgs/msg/TFMessage"
POSE_TYPES = (
    "geometry_msgs/msg/PoseStamped",
    "geometry_msgs/msg/PoseWithCovarianceStamped",
    "geometry_msgs/msg/TransformStamped",
)
_BASE_FRAMES = ("base_link", "base_footprint")
_INSTALL_HINT = "reading ROS bags needs the 'rosbags' package: pip install 'odocal[bags]'"


# --------------------------------------------------------------------------- opening bags


@dataclass(frozen=True)
class TopicInfo:
    """One topic of a bag: name, message type ('sensor_msgs/msg/Imu') and message count."""

    name: str
    msgtype: str
    count: int


@dataclass(frozen=True)
class BagContents:
    """Deserialised messages of some topics of one bag.

    Attributes
    ----------
    path : Path
    topics : list of TopicInfo
        Every topic of the bag (not only the ones read).
    messages : dict
        topic -> list of (log_time_ns, message), in recording order.
    start_ns : int
        The bag's start time (ns since the epoch); times in seconds are relative to it.
    """

    path: Path
    topics: list[TopicInfo]
    messages: dict
    start_ns: int

    def msgtype(self, topic: str) -> str | None:
        return next((t.msgtype for t in self.topics if t.name == topic), None)


def is_bag(path) -> bool:
    """True for a ``.bag``, ``.mcap`` or ``.db3`` file or a folder holding ``metadata.yaml``."""
    p = Path(path)
    if p.is_dir():
        return (p / "metadata.yaml").is_file()
    return p.suffix.lower() in (".bag", ".mcap", ".db3")


def _rosbags():
    try:
        from rosbags.highlevel import AnyReader
        from rosbags.typesys import Stores, get_typestore
    except ImportError:  # pragma: no cover - depends on the installation
        raise InputError(_INSTALL_HINT) from None
    return AnyReader, Stores, get_typestore


def _why(exc: BaseException) -> str:
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    return f"{type(exc).__name__}: {text}" if text else type(exc).__name__


def _check_path(path) -> Path:
    p = Path(path)
    if not p.exists():
        raise InputError("no such file or folder", p)
    if p.is_dir():
        if not (p / "metadata.yaml").is_file():
            raise InputError("not a ROS 2 bag folder (no metadata.yaml)", p)
    elif p.suffix.lower() not in (".bag", ".mcap", ".db3"):
        raise InputError(
            "not a ROS bag: expected a .bag, .mcap or .db3 file or a rosbag2 folder", p
        )
    return p


class _Bag:
    """An open AnyReader whose every failure becomes an InputError naming the bag."""

    def __init__(self, path) -> None:
        self.path = _check_path(path)
        any_reader, stores, get_typestore = _rosbags()
        ros1 = self.path.suffix.lower() == ".bag"
        default = get_typestore(stores.ROS1_NOETIC if ros1 else stores.ROS2_HUMBLE)
        try:
            self.reader = any_reader([self.path], default_typestore=default)
            self.reader.open()
        except OdocalError:
            raise
        except Exception as exc:  # corrupt or truncated data can raise anything
            raise InputError(
                f"cannot read the bag; is it truncated or corrupt? ({_why(exc)})", self.path
            ) from None

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        try:
            self.reader.close()
        except Exception:  # noqa: BLE001 - closing a broken bag must not mask the real error
            pass

    def topics(self) -> list[TopicInfo]:
        counts: dict[str, list] = {}
        for c in self.reader.connections:
            entry = counts.setdefault(c.topic, [c.msgtype, 0])
            entry[1] += int(c.msgcount)
        return [TopicInfo(name, t, n) for name, (t, n) in sorted(counts.items())]

    def read(self, topics: Iterable[str]) -> dict:
        wanted = set(topics)
        out: dict[str, list] = {t: [] for t in wanted}
        conns = [c for c in self.reader.connections if c.topic in wanted]
        topic, count = None, 0
        try:
            for conn, t_ns, raw in self.reader.messages(connections=conns):
                topic = conn.topic
                out[topic].append((int(t_ns), self.reader.deserialize(raw, conn.msgtype)))
                count += 1
        except OdocalError:
            raise
        except Exception as exc:
            last = f", the last on '{topic}'" if topic else ""
            raise InputError(
                f"cannot read the bag after {count} good messages{last} ({_why(exc)}); is it "
                "truncated or corrupt?",
                self.path,
            ) from None
        return out


def list_topics(path) -> list[TopicInfo]:
    """The topics of a bag, sorted by name."""
    with _Bag(path) as bag:
        return bag.topics()


def format_topics(topics: Sequence[TopicInfo]) -> str:
    """A readable table of topics (name, type, count)."""
    rows = [("topic", "type", "messages")] + [(t.name, t.msgtype, str(t.count)) for t in topics]
    w0 = max(len(r[0]) for r in rows)
    w1 = max(len(r[1]) for r in rows)
    w2 = max(len(r[2]) for r in rows)
    return "\n".join(f"{a.ljust(w0)}  {b.ljust(w1)}  {c.rjust(w2)}" for a, b, c in rows)


def read_bag(path, topics: Iterable[str] = ()) -> BagContents:
    """Read the messages of ``topics`` (names; each must exist) from a bag."""
    with _Bag(path) as bag:
        info = bag.topics()
        names = {t.name for t in info}
        for t in topics:
            if t not in names:
                raise InputError(f"no topic '{t}' in the bag; {_available(info)}", bag.path)
        messages = bag.read(topics)
        start = int(bag.reader.start_time) if info else 0
    return BagContents(bag.path, info, messages, start)


def _available(topics: Sequence[TopicInfo]) -> str:
    if not topics:
        return "the bag holds no topics"
    return "topics: " + ", ".join(f"{t.name} ({_short(t.msgtype)})" for t in topics)


def _short(msgtype: str) -> str:
    return msgtype.replace("/msg/", "/")


# --------------------------------------------------------------------------- topic choice


def _pick_topic(
    topics: Sequence[TopicInfo],
    requested: str | None,
    types: Sequence[str],
    role: str,
    path: Path,
    flag: str,
    required: bool = True,
) -> str | None:
    """The topic for ``role``: the requested one (checked) or the only one of ``types``."""
    by_name = {t.name: t for t in topics}
    wanted = " or ".join(_short(t) for t in types)
    if requested:
        if requested not in by_name:
            raise InputError(f"no topic '{requested}' in the bag; {_available(topics)}", path)
        got = by_name[requested].msgtype
        if got not in types:
            raise InputError(
                f"topic '{requested}' has type {_short(got)}, expected {wanted} for the {role}",
                path,
            )
        return requested
    found = [t.name for t in topics if t.msgtype in types]
    if len(found) == 1:
        return found[0]
    if not found:
        if not required:
            return None
        raise InputError(f"no {wanted} topic for the {role}; {_available(topics)}", path)
    raise InputError(
        f"several {wanted} topics could be the {role}: {', '.join(found)}; choose one with {flag}",
        path,
    )


# --------------------------------------------------------------------------- series


@dataclass(frozen=True)
class TopicSeries:
    """Numeric arrays of one topic. ``time_s`` shape (K,), relative to the bag start (s)."""

    topic: str
    time_s: np.ndarray
    values: dict
    frame_id: str = ""
    child_frame_id: str = ""
    meta: dict = field(default_factory=dict)


def _stamp_ns(header) -> int:
    return int(header.stamp.sec) * 1_000_000_000 + int(header.stamp.nanosec)


def _times(msgs: list, path: Path, topic: str, start_ns: int, has_header=True) -> np.ndarray:
    """Header stamps (or log times when the stamps are zero) in s relative to ``start_ns``;
    InputError unless strictly increasing."""
    if has_header:
        stamps = [_stamp_ns(m.header) for _, m in msgs]
        if any(s == 0 for s in stamps):
            stamps = [t for t, _ in msgs]
    else:
        stamps = [t for t, _ in msgs]
    t = (np.array(stamps, dtype=np.int64) - np.int64(start_ns)).astype(float) * 1e-9
    d = np.diff(t)
    bad = np.nonzero(d <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        what = "repeats" if d[bad[0]] == 0 else "goes backwards"
        raise InputError(
            f"time {what} at message {i} ({t[i]:.6f} s after {t[i - 1]:.6f} s); the header "
            "stamps must be strictly increasing",
            path,
            None,
            topic,
        )
    return t


def _finite(arr: np.ndarray, path: Path, topic: str, what: str) -> None:
    ok = np.all(np.isfinite(arr.reshape(len(arr), -1)), axis=1)
    if not np.all(ok):
        i = int(np.nonzero(~ok)[0][0])
        raise InputError(f"message {i}: {what} is not finite (NaN or inf)", path, None, topic)


def _need(msgs: list, path: Path, topic: str, n: int = 2) -> None:
    if len(msgs) < n:
        raise InputError(f"needs at least {n} messages, got {len(msgs)}", path, None, topic)


def _yaw(q) -> float:
    return math.atan2(2.0 * (q.w * q.z + q.x * q.y), 1.0 - 2.0 * (q.y * q.y + q.z * q.z))


def _pose_of(msg, msgtype: str):
    if msgtype == ODOMETRY or msgtype.endswith("PoseWithCovarianceStamped"):
        return msg.pose.pose.position, msg.pose.pose.orientation
    if msgtype.endswith("TransformStamped"):
        return msg.transform.translation, msg.transform.rotation
    return msg.pose.position, msg.pose.orientation


def pose_series(bag: BagContents, topic: str) -> TopicSeries:
    """x_m, y_m, yaw_rad (unwrapped) of a pose or odometry topic."""
    msgs, mt = bag.messages[topic], bag.msgtype(topic)
    _need(msgs, bag.path, topic)
    rows = []
    for _, m in msgs:
        p, q = _pose_of(m, mt)
        rows.append((p.x, p.y, _yaw(q)))
    xy = np.array(rows, dtype=float)
    _finite(xy, bag.path, topic, "the pose")
    t = _times(msgs, bag.path, topic, bag.start_ns)
    values = {"x": xy[:, 0], "y": xy[:, 1], "yaw": np.unwrap(xy[:, 2])}
    if mt == ODOMETRY:
        tw = np.array(
            [(m.twist.twist.linear.x, m.twist.twist.angular.z) for _, m in msgs], dtype=float
        )
        _finite(tw, bag.path, topic, "the twist")
        values["speed"], values["yaw_rate"] = tw[:, 0], tw[:, 1]
    last = msgs[0][1]
    return TopicSeries(
        topic,
        t,
        values,
        last.header.frame_id.lstrip("/"),
        getattr(last, "child_frame_id", "").lstrip("/"),
    )


def imu_series(bag: BagContents, topic: str) -> TopicSeries:
    """Angular velocity (rad/s, IMU frame), ``values['angular_velocity']`` shape (K, 3)."""
    msgs = bag.messages[topic]
    _need(msgs, bag.path, topic)
    w = np.array(
        [(m.angular_velocity.x, m.angular_velocity.y, m.angular_velocity.z) for _, m in msgs],
        dtype=float,
    )
    _finite(w, bag.path, topic, "angular_velocity")
    t = _times(msgs, bag.path, topic, bag.start_ns)
    return TopicSeries(topic, t, {"angular_velocity": w}, msgs[0][1].header.frame_id.lstrip("/"))


def _side_joint(names: set[str], side: str, path: Path, topic: str) -> str:
    cands = sorted(n for n in names if side in n.lower())
    if len(cands) > 1:
        wheels = [n for n in cands if "wheel" in n.lower()]
        cands = wheels or cands
    if len(cands) == 1:
        return cands[0]
    what = "no" if not cands else "several"
    raise InputError(
        f"{what} {side}-wheel joint among {', '.join(sorted(names)) or 'no joints'}"
        f"{': ' + ', '.join(cands) if cands else ''}; name it with the {side}_joint option "
        f"(--{side}-joint)",
        path,
        None,
        topic,
    )


def _unwrap_wheel(phi: np.ndarray, period: float, path: Path, topic: str, joint: str):
    """Unwrap a wheel angle reported modulo ``period``; reject other jumps.

    A position whose samples all lie in one window of width ``period`` and that jumps by more
    than half a period is a wrapped angle: it is unwrapped (the wheel must turn less than half a
    revolution between samples, else the direction is ambiguous). A jump of more than half a
    period in a position that is NOT confined to one window is a glitch or a reset: rejected.
    Returns (angle, number of wraps removed).
    """
    d = np.diff(phi)
    jumps = np.abs(d) > 0.5 * period
    if not np.any(jumps):
        return phi, 0
    span = float(phi.max() - phi.min())
    if span <= period * (1 + 1e-6):
        return np.unwrap(phi, period=period), int(jumps.sum())
    i = int(np.nonzero(jumps)[0][0]) + 1
    raise InputError(
        f"joint '{joint}' jumps by {d[i - 1]:+.3f} rad at message {i}, more than half a "
        "revolution between samples: an encoder reset or glitch, or a too-low sampling rate",
        path,
        None,
        topic,
    )


def joint_series(
    bag: BagContents,
    topic: str,
    right_joint: str | None = None,
    left_joint: str | None = None,
    ticks_per_rev: float | None = None,
) -> TopicSeries:
    """Right and left wheel angles (rad) from a JointState topic.

    Messages that do not carry both joints are skipped (several publishers may share
    ``/joint_states``). ``values``: 'right', 'left' (rad, cumulative, unwrapped).
    """
    msgs = bag.messages[topic]
    path = bag.path
    names: set[str] = set()
    for _, m in msgs:
        names.update(m.name)
    right = right_joint or _side_joint(names, "right", path, topic)
    left = left_joint or _side_joint(names, "left", path, topic)
    for j in (right, left):
        if j not in names:
            raise InputError(
                f"no joint '{j}'; joints: {', '.join(sorted(names)) or 'none'}", path, None, topic
            )
    if right == left:
        raise InputError(f"the right and left joints are both '{right}'", path, None, topic)
    kept, rows = [], []
    for item in msgs:
        m = item[1]
        nm = list(m.name)
        if right in nm and left in nm:
            pos = m.position
            ir, il = nm.index(right), nm.index(left)
            if len(pos) <= max(ir, il):
                raise InputError(
                    f"message {len(kept)}: {len(pos)} positions for {len(nm)} joint names",
                    path,
                    None,
                    topic,
                )
            kept.append(item)
            rows.append((pos[ir], pos[il]))
    _need(kept, path, topic)
    phi = np.array(rows, dtype=float)
    _finite(phi, path, topic, "a wheel position")
    t = _times(kept, path, topic, bag.start_ns)
    if ticks_per_rev is not None:
        if not (math.isfinite(ticks_per_rev) and ticks_per_rev > 0):
            raise InputError(f"ticks per revolution must be > 0, got {ticks_per_rev!r}")
        phi = phi * (2.0 * math.pi / ticks_per_rev)
    r, wr = _unwrap_wheel(phi[:, 0], 2.0 * math.pi, path, topic, right)
    lft, wl = _unwrap_wheel(phi[:, 1], 2.0 * math.pi, path, topic, left)
    return TopicSeries(
        topic,
        t,
        {"right": r, "left": lft},
        kept[0][1].header.frame_id,
        meta={"right_joint": right, "left_joint": left, "wraps_unwrapped": wr + wl},
    )


def static_rotation(bag: BagContents, child: str, parents: Sequence[str]):
    """R_parent_child, shape (3, 3), composed along ``/tf_static`` from ``child`` up to the first
    frame in ``parents``; (None, None) when there is no such chain."""
    from ..calibration.gyro import rotation_from_quaternion

    edges: dict[str, tuple[str, np.ndarray]] = {}
    for _, m in bag.messages.get("/tf_static", []):
        for tr in m.transforms:
            q = tr.transform.rotation
            edges[tr.child_frame_id.lstrip("/")] = (
                tr.header.frame_id.lstrip("/"),
                rotation_from_quaternion((q.x, q.y, q.z, q.w)),
            )
    frame, rot, seen = child.lstrip("/"), np.eye(3), set()
    while frame not in parents:
        if frame not in edges or frame in seen:
            return None, None
        seen.add(frame)
        parent, r = edges[frame]
        rot = r @ rot
        frame = parent
    return rot, frame


# --------------------------------------------------------------------------- recordings


def _start_frame(x, y, yaw):
    """Poses relative to the first one: (0, 0, 0) first, heading unwrapped. Shape (K, 3)."""
    c, s = math.cos(yaw[0]), math.sin(yaw[0])
    dx, dy = x - x[0], y - y[0]
    return np.column_stack([c * dx + s * dy, -s * dx + c * dy, yaw - yaw[0]])


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
            if cl < -0.5 < 0.5 < cr:
                which = ("left", ln)
            elif cr < -0.5 < 0.5 < cl:
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
    """Integrated gyro heading (rad) at ``t_ref`` (starting at 0) and how it was obtained.

    Without a geometry the wheels' angular rates stand in for the odometry: right minus left for
    the heading rate (axis detection) and both for standing still (bias).
    """
    from ..calibration import gyro

    w, t_i = imu.values["angular_velocity"], imu.time_s
    if len(t_ref) > 2:
        diff_rate = np.gradient(right - left, t_ref)
        mean_rate = np.gradient(0.5 * (right + left), t_ref)
    else:
        diff_rate = mean_rate = np.zeros_like(t_ref)
    rot, parent = static_rotation(bag, imu.frame_id, base_frames) if imu.frame_id else (None, None)
    warnings = []
    if imu_axis is not None:
        n, source = gyro.axis_vector(imu_axis), "flag"
    elif rot is not None:
        same = parent == imu.frame_id
        n = rot[2, :]
        source = (
            "imu frame_id is the base frame" if same else f"tf_static ({parent} -> {imu.frame_id})"
        )
    else:
        name, c, _ = gyro.detect_yaw_axis(t_i, w, t_ref, gyro.integrate_rate(t_ref, diff_rate))
        if c < 0.5:
            raise InputError(
                f"cannot detect the IMU's yaw axis (best {name}, correlation {c:.2f}); give it "
                "with the imu_axis option (--imu-axis)",
                bag.path,
                None,
                imu.topic,
            )
        n, source = gyro.axis_vector(name), "detected"
        warnings.append(f"IMU yaw axis detected from the data: {name} (correlation {c:.3f})")
    rate = w @ n
    # still: both wheels turn slower than 0.02 rad/s (the thresholds are wheel rates here)
    intervals = gyro.still_intervals(
        t_ref, diff_rate, mean_rate, max_speed_m_s=0.02, max_yaw_rate_rad_s=0.02, min_duration_s=1.0
    )
    est, se, _, _ = gyro.still_bias(t_i, rate, intervals)
    bias, bias_source, note = gyro.choose_bias("auto", est, se)
    if note:
        warnings.append(note)
    cum = gyro.integrate_rate(t_i, rate - bias)
    yaw = np.interp(t_ref, t_i, cum)
    return (
        yaw - yaw[0],
        {
            "imu_topic": imu.topic,
            "imu_mounting": source,
            "imu_yaw_axis": [float(c) for c in n],
            "gyro_bias_rad_s": bias,
            "gyro_bias_source": bias_source,
        },
        warnings,
    )


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
    p = _check_path(path)
    info = list_topics(p)
    jt = _pick_topic(info, joint_topic, (JOINT_STATE,), "wheel joints", p, "--joint-topic")
    gt_topic = truth_topic
    if gt_topic is None:
        gt_topic = _pick_topic(info, None, POSE_TYPES, "ground truth", p, "--truth-topic", False)
        if gt_topic is None:
            gt_topic = _pick_topic(
                info, None, (ODOMETRY,), "ground truth", p, "--truth-topic", False
            )
    else:
        _pick_topic(info, gt_topic, (*POSE_TYPES, ODOMETRY), "ground truth", p, "--truth-topic")
    it = _pick_topic(info, imu_topic, (IMU,), "gyro", p, "--imu-topic", required=False)
    names = {t.name for t in info}
    topics = (
        [jt] + [t for t in (gt_topic, it) if t] + (["/tf_static"] if "/tf_static" in names else [])
    )
    bag = read_bag(p, topics)
    joints = joint_series(bag, jt, right_joint, left_joint, ticks_per_rev)
    t = joints.time_s
    right = joints.values["right"] * (-1.0 if invert_right else 1.0)
    left = joints.values["left"] * (-1.0 if invert_left else 1.0)
    meta = {
        "bag": str(p),
        "joint_topic": jt,
        **joints.meta,
        "start_time_ns": bag.start_ns,
    }
    warnings: list[str] = []
    gt = None
    if gt_topic:
        ps = pose_series(bag, gt_topic)
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
        gt = _start_frame(x, y, yaw)
        meta["truth_topic"] = gt_topic
        if bag.msgtype(gt_topic) == ODOMETRY and truth_topic is None:
            warnings.append(
                f"ground truth taken from the Odometry topic '{gt_topic}': make sure it is an "
                "external reference, not the wheel odometry"
            )
        warnings += _check_wheel_signs(
            t,
            right - right[0],
            left - left[0],
            gt,
            p,
            jt,
            (meta["right_joint"], meta["left_joint"]),
        )
    right, left = right - right[0], left - left[0]
    gyro_yaw = None
    if it:
        imu = imu_series(bag, it)
        base = (ps.child_frame_id,) if gt is not None and ps.child_frame_id else ()
        gyro_yaw, gmeta, gw = _gyro_yaw(bag, imu, t, right, left, imu_axis, base + _BASE_FRAMES)
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


# --------------------------------------------------------------------------- gyro calibration


def fit_gyro_from_bag(
    path,
    *,
    odom_topic: str | None = None,
    imu_topic: str | None = None,
    joint_topic: str | None = None,
    imu_axis: str | None = None,
    wheel_geometry: WheelGeometry | None = None,
    imu_rotation=None,
    right_joint: str | None = None,
    left_joint: str | None = None,
    invert_right: bool = False,
    invert_left: bool = False,
    bias="auto",
    min_still_s: float = 1.0,
):
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
    Returns a :class:`~odocal.calibration.gyro.GyroResult`.
    """
    from ..calibration import gyro
    from ..errors import CalibrationError

    p = _check_path(path)
    info = list_topics(p)
    it = _pick_topic(info, imu_topic, (IMU,), "gyro", p, "--imu-topic")
    use_joints = joint_topic is not None
    if odom_topic is None and joint_topic is None:
        has_odom = any(t.msgtype == ODOMETRY for t in info)
        has_joints = any(t.msgtype == JOINT_STATE for t in info)
        use_joints = not has_odom and has_joints
    if use_joints:
        if wheel_geometry is None:
            raise InputError(
                "odometry from wheel joints needs the nominal wheel geometry (--robot)", p
            )
        src = _pick_topic(info, joint_topic, (JOINT_STATE,), "wheel joints", p, "--joint-topic")
    else:
        src = _pick_topic(info, odom_topic, (ODOMETRY,), "wheel odometry", p, "--odom-topic")
    names = {t.name for t in info}
    bag = read_bag(p, [it, src] + (["/tf_static"] if "/tf_static" in names else []))
    imu = imu_series(bag, it)
    meta = {"bag": str(p), "imu_topic": it, "odom_topic": src}
    if use_joints:
        js = joint_series(bag, src, right_joint, left_joint)
        g = wheel_geometry
        s_r = js.values["right"] * (0.5 * g.diameter_right_m * (-1.0 if invert_right else 1.0))
        s_l = js.values["left"] * (0.5 * g.diameter_left_m * (-1.0 if invert_left else 1.0))
        t_o, yaw = js.time_s, (s_r - s_l) / g.wheelbase_m
        speed = np.gradient(0.5 * (s_r + s_l), t_o) if len(t_o) > 2 else None
        base_frames = _BASE_FRAMES
        meta.update(odometry_source="joint_states", **js.meta)
    else:
        od = pose_series(bag, src)
        t_o, speed = od.time_s, od.values["speed"]
        yaw = od.values["yaw"]
        meta["odometry_source"] = "pose_yaw"
        if np.ptp(yaw) < 1e-9 and np.any(np.abs(od.values["yaw_rate"]) > 1e-6):
            yaw = gyro.integrate_rate(t_o, od.values["yaw_rate"])
            meta["odometry_source"] = "twist_integrated"
        base_frames = ((od.child_frame_id,) if od.child_frame_id else ()) + _BASE_FRAMES
    rotation, source = imu_rotation, ("rotation" if imu_rotation is not None else None)
    if imu_axis is None and imu_rotation is None and imu.frame_id:
        rot, parent = static_rotation(bag, imu.frame_id, base_frames)
        if rot is not None:
            same = parent == imu.frame_id.lstrip("/")
            rotation, source = rot, ("imu frame_id is the base frame" if same else "tf_static")
            meta["tf_chain"] = f"{parent} -> {imu.frame_id}"
    try:
        result = gyro.gyro_calibration(
            imu.time_s,
            imu.values["angular_velocity"],
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
        if use_joints and "opposite directions" in str(exc):
            hint = "; or the wheel joints are swapped"
        raise InputError(f"{exc}{hint} (IMU '{it}', odometry '{src}')", p) from None
    if wheel_geometry is not None:
        b = float(wheel_geometry.wheelbase_m)
        extra = {"wheelbase_used_m": b, "wheelbase_corrected_m": b * result.wheelbase_multiplier}
        result = replace(result, meta={**result.meta, **extra})
    return result
