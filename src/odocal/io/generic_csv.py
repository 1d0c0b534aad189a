"""The generic run CSV format: one recorded run per file, column names carry their units.

Example (wheel angles)::

    # odocal run
    # label: ccw                      (optional: cw, ccw, straight, spin-cw, spin-ccw, ...)
    # side_m: 4.0                     (optional: square side, for --method umbmark/heading)
    # wheel_diameter_right_m: 0.150   (optional: the parameters the robot RAN WITH,
    # wheel_diameter_left_m: 0.150     all three or none)
    # wheelbase_m: 0.385
    time_s,wheel_right_rad,wheel_left_rad,x_m,y_m,theta_rad,gyro_yaw_rad
    0.00,0.0,0.0,0.0,0.0,0.0,0.0
    0.05,0.12,0.12,0.0090,0.0,0.0,0.0
    ...

Columns (any order; extra columns are ignored):

- ``time_s`` (s): strictly increasing.
- Wheel rotation, one pair of: ``wheel_right_rad``/``wheel_left_rad`` (cumulative wheel angle,
  rad, forward positive) or ``ticks_right``/``ticks_left`` (CUMULATIVE encoder counts at the
  wheel, forward positive) with ``# ticks_per_rev: N`` in the header (or the ``ticks_per_rev``
  option). Wheel travel = angle x diameter / 2.
- Ground truth (optional for ``fit --method gyro``, needed by every other method and by
  ``validate``): ``x_m``, ``y_m``, ``theta_rad`` (rad, CCW positive, UNWRAPPED), the true pose of
  the robot centre. Any frame: the loader re-expresses it in the start frame (first row at
  0, 0, 0, model.md).
- ``gyro_yaw_rad`` (optional): integrated gyro heading (rad, CCW +, unwrapped).

Encoder wrap-around (documented rule): counters that overflow (e.g. 16-bit) show a jump between
two samples. With ``# ticks_wrap: M`` (the counter modulus, e.g. 65536) every difference is
taken modulo M into [-M/2, M/2) before summing, which is exact as long as a wheel turns less
than M/2 counts per sample. Without it, a jump of more than 2^15 counts in one sample is
rejected as a probable wrap-around (InputError naming the line), never silently integrated.
Values M or more apart cannot come from a counter wrapping at M (``# ticks_wrap: 16``, the bits
for the modulus): InputError.

Blank lines are skipped; ``#`` lines before the header carry ``key: value`` settings.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.pose import start_frame
from ..core.recording import Recording
from ..errors import InputError
from .limits import (
    HEADING_MAX_RAD,
    POSITION_MAX_M,
    ROBOT_LENGTH_M,
    SIDE_MIN_M,
    TICKS_MAX,
    TICKS_PER_REV,
    TICKS_WRAP,
    TIME_MAX_S,
    TRACK_LENGTH_MAX_M,
    WHEEL_ANGLE_MAX_RAD,
    WHEEL_STEP_MAX_RAD,
)
from .table import MAX_FIELD_CHARS, Table, parse_number, read_table

__all__ = [
    "load_generic_csv",
    "write_generic_csv",
    "looks_like_generic_csv",
    "check_wheel_steps",
    "WRAP_JUMP_COUNTS",
    "LABELS",
]

#: a single-sample tick jump larger than this is treated as a wrap-around (see module docstring)
WRAP_JUMP_COUNTS = 2**15

# Settings (``# key: value`` above the header) and their plausible ranges (odocal.io.limits):
# beyond them a value is a typo or a unit slip.
_SETTINGS_RANGE = {
    "ticks_per_rev": TICKS_PER_REV,
    "ticks_wrap": TICKS_WRAP,
    "side_m": (SIDE_MIN_M, TRACK_LENGTH_MAX_M),
    "wheel_diameter_right_m": ROBOT_LENGTH_M,
    "wheel_diameter_left_m": ROBOT_LENGTH_M,
    "wheelbase_m": ROBOT_LENGTH_M,
}
_SETTINGS = (*_SETTINGS_RANGE, "label")

# Largest magnitude of a value per column (odocal.io.limits).
_COLUMN_MAX = {
    "time_s": TIME_MAX_S,
    "wheel_right_rad": WHEEL_ANGLE_MAX_RAD,
    "wheel_left_rad": WHEEL_ANGLE_MAX_RAD,
    "ticks_right": TICKS_MAX,
    "ticks_left": TICKS_MAX,
    "x_m": POSITION_MAX_M,
    "y_m": POSITION_MAX_M,
    "theta_rad": HEADING_MAX_RAD,
    "gyro_yaw_rad": HEADING_MAX_RAD,
}

#: The run kinds the methods know in a ``# label:`` (read in any case; other labels are free text).
LABELS = ("cw", "ccw", "straight", "spin-cw", "spin-ccw", "fwd")


def looks_like_generic_csv(path, text: str | None = None) -> bool:
    """True if the first non-comment line of ``path`` (or of ``text``) is a header holding
    ``time_s``."""
    try:
        lines = (
            text.splitlines()
            if text is not None
            else open(path, encoding="utf-8-sig", errors="replace")
        )
        for line in lines:
            if line.strip() and not line.lstrip().startswith("#"):
                return "time_s" in [c.strip() for c in line.split(",")]
    except OSError:
        return False
    return False


def _settings(table, path) -> dict:
    out: dict = {}
    for key, (value, no) in table.settings.items():
        if key == "label":
            if len(value) > MAX_FIELD_CHARS:
                raise InputError(f"over-long value ({len(value)} characters)", path, no, key)
            # the kinds the methods know are read in any case (CW as cw); others are free text
            out[key] = (value.lower() if value.lower() in LABELS else value, no)
            continue
        lo, hi = _SETTINGS_RANGE[key]
        v = parse_number(value, path, no, key, positive=True)
        if not lo <= v <= hi:
            raise InputError(
                f"implausible value {value!r} (expected {lo:g} .. {hi:g}; check the units)",
                path,
                no,
                key,
            )
        out[key] = (v, no)
    return out


def check_wheel_steps(right, left, lines, path, names=("wheel_right_rad", "wheel_left_rad")):
    """InputError naming the line and column of the first sample where a wheel turns more than
    :data:`~odocal.io.limits.WHEEL_STEP_MAX_RAD` (rad) since the previous one: a glitch, a reset
    or a unit slip (no wheel turns 160 times between two samples). ``right``/``left``: wheel
    angles (rad), ``lines``: the line of each sample."""
    for angles, name in ((right, names[0]), (left, names[1])):
        big = np.nonzero(np.abs(np.diff(angles)) > WHEEL_STEP_MAX_RAD)[0]
        if len(big):
            i = int(big[0]) + 1
            raise InputError(
                f"the wheel turns {angles[i] - angles[i - 1]:+.4g} rad in one sample (at most "
                f"{WHEEL_STEP_MAX_RAD:g}): a glitch, a counter reset or a unit slip",
                path,
                lines[i],
                name,
            )


def _unwrap_ticks(ticks: np.ndarray, lines, name: str, wrap, path) -> np.ndarray:
    d = np.diff(ticks)
    if wrap is not None:
        span = float(np.ptp(ticks))
        if span >= wrap:
            spread = np.maximum.accumulate(ticks) - np.minimum.accumulate(ticks)
            i = int(np.argmax(spread >= wrap))  # the first row the counter cannot have reached
            raise InputError(
                f"the counter takes values {span:.0f} apart, but '# ticks_wrap: {wrap:g}' says it "
                "wraps at that modulus; give the number of counts the counter wraps at (65536 "
                "for a 16-bit counter), not its bits",
                path,
                lines[i],
                name,
            )
        d = (d + wrap / 2) % wrap - wrap / 2
    else:
        big = np.nonzero(np.abs(d) > WRAP_JUMP_COUNTS)[0]
        if len(big):
            i = int(big[0])
            raise InputError(
                f"the tick counter jumps by {d[i]:.0f} counts in one sample: this looks like an "
                "encoder wrap-around; give the counter modulus as '# ticks_wrap: 65536' (16-bit)",
                path,
                lines[i + 1],
                name,
            )
    return np.concatenate([[0.0], np.cumsum(d)])


def load_generic_csv(
    path: str | Path, ticks_per_rev: float | None = None, text: str | None = None
) -> Recording:
    """One run from a generic run CSV (see module docstring); InputError names file/line/field.

    ``text``: the file's content when it was already read (a pipe can be read only once)."""
    table = read_table(
        path, what="a header row starting with 'time_s'", text=text, settings=_SETTINGS
    )
    settings = _settings(table, path)
    wheel_cols, ticks, present = _columns(table, path)
    col = table.header
    wanted = ["time_s", *wheel_cols, *present] + (["gyro_yaw_rad"] if "gyro_yaw_rad" in col else [])
    data = table.numbers(wanted, at_most=_COLUMN_MAX)
    if len(data) < 2:
        raise InputError(f"a run needs at least two samples, got {len(data)}", path)
    t = data[:, 0]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise InputError(
            f"time is not strictly increasing ({t[i - 1]:g} s then {t[i]:g} s)",
            path,
            table.lines[i],
            "time_s",
        )

    meta: dict = {"format": "generic-csv"}
    right, left = data[:, 1], data[:, 2]
    if ticks:
        tpr = _ticks_per_rev(ticks_per_rev, settings, table, path)
        wrap = settings.get("ticks_wrap", (None,))[0]
        scale = 2.0 * math.pi / tpr
        right = _unwrap_ticks(right, table.lines, "ticks_right", wrap, path) * scale
        left = _unwrap_ticks(left, table.lines, "ticks_left", wrap, path) * scale
        meta["ticks_per_rev"] = tpr
    else:
        right, left = right - right[0], left - left[0]
    check_wheel_steps(right, left, table.lines, path, wheel_cols)

    gt = start_frame(data[:, 3], data[:, 4], data[:, 5]) if present else None
    gyro = data[:, -1] - data[0, -1] if "gyro_yaw_rad" in col else None
    if "side_m" in settings:
        meta["side_m"] = settings["side_m"][0]
    label = settings.get("label", (None,))[0]
    return Recording(
        name=str(path),
        time_s=t,
        wheel_angle_right_rad=right,
        wheel_angle_left_rad=left,
        ground_truth=gt,
        gyro_yaw_rad=gyro,
        ran_with=_ran_with(settings, table, path),
        label=label or None,
        meta=meta,
    )


def _columns(table: Table, path: str | Path) -> tuple[tuple[str, str], bool, list[str]]:
    """The wheel columns (angles, or ticks: the flag), and the ground-truth columns present
    (none or all three), checked against the header."""
    header_no = table.header_line
    col = table.header
    if "time_s" not in col:
        raise InputError("missing column 'time_s' in the header", path, header_no, "time_s")
    if "wheel_right_rad" in col or "wheel_left_rad" in col:
        wheel_cols, ticks = ("wheel_right_rad", "wheel_left_rad"), False
    elif "ticks_right" in col or "ticks_left" in col:
        wheel_cols, ticks = ("ticks_right", "ticks_left"), True
    else:
        raise InputError(
            "missing wheel columns: give wheel_right_rad,wheel_left_rad or ticks_right,ticks_left",
            path,
            header_no,
        )
    for c in wheel_cols:
        if c not in col:
            raise InputError(f"missing column '{c}'", path, header_no, c)
    gt_cols = ("x_m", "y_m", "theta_rad")
    present = [c for c in gt_cols if c in col]
    if present and len(present) < 3:
        missing = [c for c in gt_cols if c not in col][0]
        raise InputError(
            f"missing column '{missing}' (ground truth needs x_m, y_m and theta_rad)",
            path,
            header_no,
            missing,
        )
    return wheel_cols, ticks, present


def _ticks_per_rev(given: float | None, settings: dict, table: Table, path: str | Path) -> float:
    """The ticks per wheel revolution: the argument, else the file's setting."""
    tpr = given
    if tpr is None and "ticks_per_rev" in settings:
        tpr = settings["ticks_per_rev"][0]
    if tpr is None:
        raise InputError(
            "tick columns need the ticks per wheel revolution: add '# ticks_per_rev: N' "
            "above the header (or pass ticks_per_rev)",
            path,
            table.header_line,
            "ticks_per_rev",
        )
    return tpr


def _ran_with(settings: dict, table: Table, path: str | Path) -> WheelGeometry | None:
    """The parameters the robot ran with, from the header settings (all three or none)."""
    geo_keys = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
    given = [k for k in geo_keys if k in settings]
    if not given:
        return None
    if len(given) < 3:
        missing = [k for k in geo_keys if k not in settings][0]
        raise InputError(
            "the parameters the robot ran with need all three of "
            f"{', '.join(geo_keys)} in the header",
            path,
            table.header_line,
            missing,
        )
    return WheelGeometry(*(settings[k][0] for k in geo_keys))


def write_generic_csv(path, recording: Recording) -> None:
    """Write ``recording`` in the generic format (wheel angles in rad), atomically."""
    from .textfile import atomic_write

    lines = ["# odocal run"]
    if recording.label:
        lines.append(f"# label: {recording.label}")
    if recording.meta.get("side_m"):
        lines.append(f"# side_m: {recording.meta['side_m']:.9g}")
    if recording.ran_with is not None:
        for k, v in recording.ran_with.as_dict().items():
            lines.append(f"# {k}: {v:.9g}")
    cols = ["time_s", "wheel_right_rad", "wheel_left_rad"]
    arrays = [recording.time_s, recording.wheel_angle_right_rad, recording.wheel_angle_left_rad]
    if recording.ground_truth is not None:
        cols += ["x_m", "y_m", "theta_rad"]
        arrays += list(recording.ground_truth.T)
    if recording.gyro_yaw_rad is not None:
        cols.append("gyro_yaw_rad")
        arrays.append(recording.gyro_yaw_rad)
    lines.append(",".join(cols))
    for row in np.column_stack(arrays):
        lines.append(",".join(f"{v:.10g}" for v in row))
    atomic_write(path, "\n".join(lines) + "\n")
