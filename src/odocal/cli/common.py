"""What the commands share: argument types (from one factory), argument groups, output helpers
and the progress bar. Command modules import from here, never from each other."""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from collections.abc import Callable, Iterable
from typing import Any

from ..core.checks import parse_float, parse_int
from ..errors import one_line
from ..io.bag_options import BagOptions
from ..io.limits import (
    HEADING_WEIGHT_MAX_M,
    LENGTH_MIN_M,
    SIGMA_THETA_MAX_DEG,
    SIGMA_XY_MAX_M,
    TICKS_PER_REV,
    TRACK_LENGTH_MAX_M,
    speed_problem,
    twist_window_problem,
)

__all__ = [
    "MAX_LENGTH_M",
    "number",
    "positive_float",
    "nonnegative_float",
    "length_m",
    "driven_length_m",
    "sigma_xy_m",
    "sigma_theta_deg",
    "speed_m_s",
    "twist_window_s",
    "ticks_per_rev",
    "heading_weight",
    "positive_int",
    "sides_int",
    "seed_int",
    "trials_int",
    "fraction",
    "noise_track",
    "motion_mix",
    "add_robot_args",
    "add_track_args",
    "add_export_args",
    "add_recording_args",
    "add_bag_args",
    "add_slam_args",
    "bag_options",
    "truth_frames",
    "print_json",
    "print_warnings",
    "print_table",
    "ProgressBar",
]

# Largest length a flag may give (m; odocal.io.limits): beyond 100 km a length is a unit
# mistake, and the statistics of a track that long overflow.
MAX_LENGTH_M = TRACK_LENGTH_MAX_M


def number(
    kind: type = float,
    *,
    above: float | None = None,
    at_least: float | None = None,
    below: float | None = None,
    at_most: float | None = None,
    hint: str = "",
) -> Callable[[str], Any]:
    """An argparse type: ``kind`` (float or int) within the given bounds, finite, written as a
    plain number (:func:`~odocal.core.checks.parse_float`: not ``0_1``, not `` 1``)."""

    def parse(text: str):
        try:
            v = parse_int(text) if kind is int else parse_float(text)
        except ValueError:
            what = "an integer" if kind is int else "a number"
            raise argparse.ArgumentTypeError(f"not {what}: {text!r}") from None
        if kind is float and not math.isfinite(v):
            raise argparse.ArgumentTypeError(f"must be a finite number, got {text!r}")
        bad = (
            (above is not None and not v > above)
            or (at_least is not None and not v >= at_least)
            or (below is not None and not v < below)
            or (at_most is not None and not v <= at_most)
        )
        if bad:
            parts = []
            if above is not None:
                parts.append(f"> {above:g}")
            if at_least is not None:
                parts.append(f">= {at_least:g}")
            if below is not None:
                parts.append(f"< {below:g}")
            if at_most is not None:
                parts.append(f"<= {at_most:g}")
            raise argparse.ArgumentTypeError(f"must be {' and '.join(parts)}{hint}, got {text!r}")
        return v

    return parse


positive_float = number(float, above=0)
nonnegative_float = number(float, at_least=0)
length_m = number(float, above=0, at_most=MAX_LENGTH_M, hint=" m (check the units)")
#: a distance a covariance or an estimate divides by (odocal noise): at least 0.1 mm
driven_length_m = number(
    float, at_least=LENGTH_MIN_M, at_most=MAX_LENGTH_M, hint=" m (check the units)"
)
sigma_xy_m = number(float, at_least=0, at_most=SIGMA_XY_MAX_M, hint=" m")
sigma_theta_deg = number(float, at_least=0, at_most=SIGMA_THETA_MAX_DEG, hint=" deg")


def _with_limit(problem: Callable[[float], str | None]) -> Callable[[str], float]:
    """An argparse type: a finite number > 0 that ``problem`` (odocal.io.limits) accepts; its
    message, with the reason, otherwise."""

    def parse(text: str) -> float:
        v = number(float, above=0)(text)
        said = problem(v)
        if said:
            raise argparse.ArgumentTypeError(said)
        return v

    return parse


speed_m_s = _with_limit(speed_problem)
twist_window_s = _with_limit(twist_window_problem)
ticks_per_rev = number(
    float,
    at_least=TICKS_PER_REV[0],
    at_most=TICKS_PER_REV[1],
    hint=" ticks per wheel turn (check the units)",
)
heading_weight = number(
    float,
    at_least=0,
    at_most=HEADING_WEIGHT_MAX_M,
    hint=" m per rad (a heavier weight lets the heading alone decide the fit)",
)
positive_int = number(int, at_least=1)
seed_int = number(int, at_least=0)
trials_int = number(int, at_least=2, hint=" (a standard deviation is needed)")


def sides_int(text: str) -> int:
    """A polygon's number of sides (the simulator bounds it from above, with its reason)."""
    v = positive_int(text)
    if v < 3:
        raise argparse.ArgumentTypeError(f"a polygon needs at least 3 sides, got {text!r}")
    return v


def fraction(lo_open: bool) -> Callable[[str], float]:
    """A number in (0, 1) (``lo_open``) or [0, 1)."""
    interval = "(0, 1)" if lo_open else "[0, 1)"
    check = number(float, above=0, below=1) if lo_open else number(float, at_least=0, below=1)

    def parse(text: str) -> float:
        try:
            return check(text)
        except argparse.ArgumentTypeError as exc:
            if "not a number" in str(exc):
                raise
            raise argparse.ArgumentTypeError(f"must be in {interval}, got {text!r}") from None

    return parse


def noise_track(text: str) -> tuple[str, float]:
    """'out-and-back:D' or 'straight:D' (D in m) as (kind, D)."""
    from ..calibration.noise import NOISE_TRACKS

    kind, sep, dist = text.partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in NOISE_TRACKS:
        raise argparse.ArgumentTypeError(
            f"expected out-and-back:D or straight:D (D in m), got {text!r}"
        )
    try:
        d = parse_float(dist.strip())
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a distance in m: {dist!r} in {text!r}") from None
    if not math.isfinite(d) or d < LENGTH_MIN_M:
        raise argparse.ArgumentTypeError(
            f"the distance must be at least {LENGTH_MIN_M:g} m (check the units), got {dist!r}"
        )
    if d > MAX_LENGTH_M:
        raise argparse.ArgumentTypeError(
            f"the distance must be at most {MAX_LENGTH_M:g} m (check the units), got {dist!r}"
        )
    return kind, d


def motion_mix(text: str) -> dict[str, float]:
    """'spot=0.2,wide=0.8': shares of the rotation per band of motion (normalised)."""
    from ..calibration.turning import parse_motion_mix
    from ..errors import CalibrationError

    try:
        return parse_motion_mix(text)
    except CalibrationError as exc:
        raise argparse.ArgumentTypeError(str(exc)) from None


def add_robot_args(p: argparse.ArgumentParser, params_help: str, required: bool = False) -> None:
    """``--robot`` and ``--params`` (with the command's own help for ``--params``); a
    ``required`` robot has no default (the command's app function says so when it is missing)."""
    from ..presets import DEFAULT_ROBOT, PRESETS

    if required:
        names = ", ".join(PRESETS)
        what = f"robot file, or a built-in by name: {names} (required: no default robot)"
    else:
        names = ", ".join(f"{n} (default)" if n == DEFAULT_ROBOT else n for n in PRESETS)
        what = f"robot file, or a built-in: {names}"
    p.add_argument("--robot", metavar="ROBOT.yaml", default=None, help=what)
    p.add_argument("--params", metavar="PARAMS.yaml", default=None, help=params_help)


def add_track_args(p: argparse.ArgumentParser, default_sides=4, default_side=4.0) -> None:
    """``--sides``, ``--side-length`` and ``--track`` with the command's defaults."""
    p.add_argument(
        "--sides",
        type=sides_int,
        default=default_sides,
        metavar="N",
        help=f"regular N-gon test track (default {default_sides}, a square)",
    )
    p.add_argument(
        "--side-length",
        type=length_m,
        default=default_side,
        metavar="L",
        help=f"side length in m (default {default_side:g})",
    )


def add_export_args(p: argparse.ArgumentParser, out_help: str) -> None:
    """Where a calibration goes: PARAMS.yaml and the ros2_control file (fit and calibrate)."""
    p.add_argument("--out", metavar="PARAMS.yaml", help=out_help)
    p.add_argument(
        "--ros2",
        metavar="FILE.yaml",
        help="write a ros2_control diff_drive_controller parameter file (nominal base values "
        "from --robot, the calibration in the multipliers)",
    )
    p.add_argument(
        "--controller-name",
        default="diff_drive_controller",
        metavar="NAME",
        help="controller name in the --ros2 file (default diff_drive_controller)",
    )


def add_recording_args(p: argparse.ArgumentParser) -> None:
    """Recorded runs (files, folders, bags) and how to read them (shared by fit and validate)."""
    p.add_argument("paths", nargs="+", metavar="RUN_OR_DIR", help="run file, folder or bag")
    p.add_argument(
        "--ticks-per-rev",
        type=ticks_per_rev,
        metavar="N",
        help="encoder ticks per wheel revolution for tick inputs that do not give it",
    )
    add_bag_args(p)


#: Exit status of a command whose answer is given but not to be trusted: ``check`` on a log
#: that is NOT enough, ``fit --method auto`` when its routes disagree or its checks fail
#: (2 is an error: nothing was answered).
NOT_ENOUGH = 3


def add_bag_args(p: argparse.ArgumentParser) -> None:
    """Topic and joint options for ROS bags."""
    g = p.add_argument_group("ROS bags")
    g.add_argument("--joint-topic", metavar="T", help="sensor_msgs/JointState wheel positions")
    g.add_argument("--truth-topic", metavar="T", help="ground-truth pose (PoseStamped/Odometry)")
    g.add_argument("--imu-topic", metavar="T", help="sensor_msgs/Imu topic")
    g.add_argument("--right-joint", metavar="NAME", help="right wheel joint name")
    g.add_argument("--left-joint", metavar="NAME", help="left wheel joint name")
    g.add_argument("--scan-topic", metavar="T", help="sensor_msgs/LaserScan topic (--method scan)")
    g.add_argument(
        "--time-offset",
        type=time_offset,
        action="append",
        default=[],
        metavar="SOURCE=SECONDS",
        help="fix the clock offset of a source against the wheels instead of estimating it: "
        "how late its stamps run (s, negative: early); SOURCE is truth, slam, laser or imu; "
        "repeatable",
    )


def add_slam_args(p: argparse.ArgumentParser) -> None:
    """A SLAM pose on /tf as ground truth (shared by fit and validate)."""
    s = p.add_argument_group("SLAM pose as ground truth (bags)")
    s.add_argument(
        "--truth-frames",
        metavar="PARENT:CHILD",
        help="the truth is the pose of CHILD in PARENT on /tf (e.g. map:base_link, composed "
        "through map -> odom -> base_link); only the relative motions between the SLAM's "
        "updates are used (docs/slam-truth.md)",
    )
    s.add_argument(
        "--slam-stamp-offset",
        type=number(float, at_least=-10, at_most=10, hint=" s"),
        default=0.0,
        metavar="S",
        help="seconds the SLAM post-dates its correction (slam_toolbox: transform_timeout, 0.2 "
        "by default; AMCL: transform_tolerance; negative: ante-dates); default 0. A clock "
        "offset between the SLAM and the wheels is estimated on top (--time-offset slam=S "
        "fixes it)",
    )


def bag_options(args: argparse.Namespace) -> BagOptions:
    """The bag topics, joints and IMU axis of the parsed flags (those the command has)."""
    return BagOptions(
        joint_topic=getattr(args, "joint_topic", None),
        truth_topic=getattr(args, "truth_topic", None),
        imu_topic=getattr(args, "imu_topic", None),
        odom_topic=getattr(args, "odom_topic", None),
        scan_topic=getattr(args, "scan_topic", None),
        right_joint=getattr(args, "right_joint", None),
        left_joint=getattr(args, "left_joint", None),
        imu_axis=getattr(args, "imu_axis", None),
        time_offsets=tuple(getattr(args, "time_offset", None) or ()),
    )


def time_offset(text: str) -> tuple[str, float]:
    """An argparse type: ``SOURCE=SECONDS`` (a known source, a plausible offset)."""
    from ..io.bag_options import MAX_TIME_OFFSET_S, TIME_OFFSET_SOURCES

    source, sep, value = text.partition("=")
    source = source.strip().lower()
    if not sep or source not in TIME_OFFSET_SOURCES:
        raise argparse.ArgumentTypeError(
            f"expected SOURCE=SECONDS with SOURCE one of {', '.join(TIME_OFFSET_SOURCES)}, "
            f"got {text!r}"
        )
    seconds = number(float, at_least=-MAX_TIME_OFFSET_S, at_most=MAX_TIME_OFFSET_S,
                     hint=" s: outside any plausible clock offset")(value.strip())  # fmt: skip
    return source, float(seconds)


def truth_frames(args: argparse.Namespace) -> tuple[str, str] | None:
    """The ``--truth-frames PARENT:CHILD`` of the parsed flags, or None."""
    if not getattr(args, "truth_frames", None):
        return None
    from ..io.bag_slam import parse_truth_frames

    return parse_truth_frames(args.truth_frames)


def print_warnings(warnings: Iterable[str], prefix: str = "") -> None:
    """Each warning as one line ``odocal: warning: ...`` on stderr (never on stdout)."""
    for w in warnings:
        print(f"odocal: warning: {one_line(prefix + w)}", file=sys.stderr)


def _non_finite(obj: Any, where: str = "") -> str | None:
    """The key path of the first non-finite number in ``obj`` (None if there is none)."""
    if isinstance(obj, float):
        return None if math.isfinite(obj) else (where or "the result")
    if isinstance(obj, dict):
        items: Iterable = ((f"{where}.{k}" if where else str(k), v) for k, v in obj.items())
    elif isinstance(obj, (list, tuple)):
        items = ((f"{where}[{i}]", v) for i, v in enumerate(obj))
    else:
        return None
    for key, value in items:
        found = _non_finite(value, key)
        if found is not None:
            return found
    return None


def print_json(obj: Any) -> None:
    """``obj`` as one JSON object on stdout, all or nothing. A non-finite number (JSON has none;
    undefined values are null) is never printed: OdocalError naming its key instead."""
    bad = _non_finite(obj)
    if bad is not None:
        from ..errors import OdocalError

        raise OdocalError(
            f"the result '{bad}' is not a finite number; nothing printed (please report this "
            "with the input that caused it)"
        )
    text = json.dumps(obj, indent=2, allow_nan=False)  # all or nothing: no half-printed object
    sys.stdout.write(text + "\n")


def print_table(rows: list[tuple], title: str | None = None) -> None:
    """Two or more columns, left column left-aligned, the rest right-aligned
    (:func:`odocal.app.text.table_lines`)."""
    from ..app.text import table_lines

    print("\n".join(table_lines(rows, title)))


class ProgressBar:
    """A one-line progress bar on stderr, drawn only when stderr is a terminal."""

    def __init__(self, label: str, enabled: bool = True, stream=None):
        self.stream = stream or sys.stderr
        self.enabled = enabled and getattr(self.stream, "isatty", lambda: False)()
        self.label = label
        self.start = time.monotonic()

    def __call__(self, done: int, total: int, what: str = "") -> None:
        """Show ``done`` of ``total`` (and what is being done) on stderr."""
        if not self.enabled:
            return
        width = 24
        filled = round(width * done / max(total, 1))
        bar = "#" * filled + "-" * (width - filled)
        elapsed = time.monotonic() - self.start
        self.stream.write(f"\r{self.label} [{bar}] {done}/{total} {elapsed:5.1f} s {what:<24}")
        self.stream.flush()

    def close(self) -> None:
        """End the bar's line."""
        if self.enabled:
            self.stream.write("\r\033[K")
            self.stream.flush()
