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

Blank lines are skipped; ``#`` lines before the header carry ``key: value`` settings.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from ..core.model import ModelError, WheelGeometry
from ..core.recording import Recording
from ..errors import InputError
from .textfile import read_text

__all__ = ["load_generic_csv", "write_generic_csv", "looks_like_generic_csv", "WRAP_JUMP_COUNTS"]

#: a single-sample tick jump larger than this is treated as a wrap-around (see module docstring)
WRAP_JUMP_COUNTS = 2**15

_SETTINGS_FLOAT = (
    "ticks_per_rev",
    "ticks_wrap",
    "side_m",
    "wheel_diameter_right_m",
    "wheel_diameter_left_m",
    "wheelbase_m",
)


def looks_like_generic_csv(path) -> bool:
    """True if the first non-comment line of ``path`` is a header holding ``time_s``."""
    try:
        with open(path, encoding="utf-8-sig", errors="replace") as fh:
            for line in fh:
                if line.strip() and not line.lstrip().startswith("#"):
                    return "time_s" in [c.strip() for c in line.split(",")]
    except OSError:
        return False
    return False


def _settings(lines: list[tuple[int, str]], path) -> dict:
    out: dict = {}
    for no, line in lines:
        body = line.lstrip()[1:].strip()
        if ":" not in body:
            continue
        key, value = (s.strip() for s in body.split(":", 1))
        if key in _SETTINGS_FLOAT:
            try:
                v = float(value)
            except ValueError:
                raise InputError(f"not a number: {value!r}", path, no, key) from None
            if not math.isfinite(v) or v <= 0:
                raise InputError(f"must be a finite number > 0, got {value!r}", path, no, key)
            out[key] = (v, no)
        elif key == "label":
            out[key] = (value, no)
    return out


def _unwrap_ticks(ticks: np.ndarray, lines: list[int], name: str, wrap, path) -> np.ndarray:
    d = np.diff(ticks)
    if wrap is not None:
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


def load_generic_csv(path, ticks_per_rev: float | None = None) -> Recording:
    """One run from a generic run CSV (see module docstring); InputError names file/line/field."""
    text = read_text(path)
    numbered = [(i + 1, line) for i, line in enumerate(text.splitlines()) if line.strip()]
    comments = [(n, ln) for n, ln in numbered if ln.lstrip().startswith("#")]
    body = [(n, ln) for n, ln in numbered if not ln.lstrip().startswith("#")]
    if not body:
        raise InputError("empty file, expected a header row starting with 'time_s'", path)
    header_no, header_line = body[0]
    header = [h.strip() for h in next(csv.reader([header_line]))]
    header_comments = [(n, ln) for n, ln in comments if n < header_no]
    settings = _settings(header_comments, path)
    col = {name: i for i, name in enumerate(header)}

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
    wanted = ["time_s", *wheel_cols, *present] + (["gyro_yaw_rad"] if "gyro_yaw_rad" in col else [])

    rows, line_nos = [], []
    for no, line in body[1:]:
        fields = next(csv.reader(io.StringIO(line)))
        if len(fields) != len(header):
            raise InputError(
                f"expected {len(header)} fields as in the header, got {len(fields)}", path, no
            )
        vals = []
        for name in wanted:
            raw = fields[col[name]].strip()
            try:
                v = float(raw)
            except ValueError:
                raise InputError(f"not a number: {raw!r}", path, no, name) from None
            if not math.isfinite(v):
                raise InputError(f"must be finite, got {raw!r}", path, no, name)
            vals.append(v)
        rows.append(vals)
        line_nos.append(no)
    if len(rows) < 2:
        raise InputError(f"a run needs at least two samples, got {len(rows)}", path)
    data = np.array(rows)
    t = data[:, 0]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise InputError(
            f"time is not strictly increasing ({t[i - 1]:g} s then {t[i]:g} s)",
            path,
            line_nos[i],
            "time_s",
        )

    meta: dict = {"format": "generic-csv"}
    right, left = data[:, 1], data[:, 2]
    if ticks:
        tpr = ticks_per_rev
        if tpr is None and "ticks_per_rev" in settings:
            tpr = settings["ticks_per_rev"][0]
        if tpr is None:
            raise InputError(
                "tick columns need the ticks per wheel revolution: add '# ticks_per_rev: N' "
                "above the header (or pass ticks_per_rev)",
                path,
                header_no,
                "ticks_per_rev",
            )
        wrap = settings.get("ticks_wrap", (None,))[0]
        scale = 2.0 * math.pi / tpr
        right = _unwrap_ticks(right, line_nos, "ticks_right", wrap, path) * scale
        left = _unwrap_ticks(left, line_nos, "ticks_left", wrap, path) * scale
        meta["ticks_per_rev"] = tpr
    else:
        right, left = right - right[0], left - left[0]

    gt = None
    if present:
        raw = data[:, 3:6]
        c, s = math.cos(raw[0, 2]), math.sin(raw[0, 2])
        dx, dy = raw[:, 0] - raw[0, 0], raw[:, 1] - raw[0, 1]
        gt = np.column_stack([c * dx + s * dy, -s * dx + c * dy, raw[:, 2] - raw[0, 2]])
    gyro = None
    if "gyro_yaw_rad" in col:
        gyro = data[:, -1] - data[0, -1]

    ran_with = None
    geo_keys = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
    given = [k for k in geo_keys if k in settings]
    if given:
        if len(given) < 3:
            missing = [k for k in geo_keys if k not in settings][0]
            raise InputError(
                "the parameters the robot ran with need all three of "
                f"{', '.join(geo_keys)} in the header",
                path,
                header_no,
                missing,
            )
        try:
            ran_with = WheelGeometry(*(settings[k][0] for k in geo_keys))
        except ModelError as exc:
            raise InputError(str(exc), path) from None
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
        ran_with=ran_with,
        label=label or None,
        meta=meta,
    )


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
