"""Reader of ``.tuple`` files: relative-motion tuples for ``calibration.censi``.

The format of Censi et al.'s calibration software (AndreaCensi/calibration): one JSON object per
interval, one per line::

    { "T": 0.794396, "phi_l": 0.1401765, "phi_r": -0.1373157, "sm": [0.00109, -0.00051, -0.02749] }

- ``T``: duration of the interval (s, > 0).
- ``phi_l``, ``phi_r``: AVERAGE angular velocity of the left and right wheel over the interval
  (rad/s). The wheel rotation is ``phi * T`` (rad). Verified: with this reading odocal reproduces
  the authors' published results to their printed digits (docs/censi.md).
- ``sm``: ``[x_m, y_m, theta_rad]``, the sensor's rigid displacement over the interval (scan
  matching), in the sensor frame at the start of the interval.

Other keys are ignored. Blank lines are skipped; lines end with LF, CRLF or CR. Where the
authors concatenated per-experiment files without a final newline, two objects share a line (the
full l90/lmov/lstraight files have a few such lines); objects separated only by white space on
one line are therefore accepted, as their JSON-stream reader accepts them.

Every problem raises ``InputError`` naming the file, line and field: invalid JSON, a value that
is not an object, missing or duplicated keys, non-numeric, NaN or infinite values (Python's json
would accept ``NaN``), non-positive ``T``, ``sm`` not three numbers, absurd magnitudes, lines
longer than ``MAX_LINE_BYTES``, an empty file. The file is read once, sequentially, so pipes and
process substitutions (``<(...)``) work.
"""

from __future__ import annotations

import json
import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.censi import MIN_WHEEL_ROTATION_RAD
from ..errors import InputError

__all__ = [
    "TupleData",
    "read_tuples",
    "refuse_still_tuples",
    "refuse_repeated_tuples",
    "MAX_LINE_BYTES",
    "LIMITS",
    "MIN_SENSOR_MOTION",
]

#: Longest accepted line (bytes); the authors' lines are about 120 bytes.
MAX_LINE_BYTES = 4096
#: Largest accepted magnitude per field (unit of the field): a tuple is one short interval.
LIMITS = {
    "T": 1e5,  # s (more than a day)
    "phi_l": 1e4,  # rad/s (about 95 000 rpm)
    "phi_r": 1e4,
    "sm.x": 1e4,  # m
    "sm.y": 1e4,
    "sm.theta": 1e3,  # rad
}
_KEYS = ("T", "phi_l", "phi_r", "sm")
#: Below this motion (m and rad) in every tuple the sensor does not move: finer than any scan
#: matcher resolves.
MIN_SENSOR_MOTION = 1e-6


@dataclass(frozen=True)
class TupleData:
    """Tuples read from a file.

    Attributes
    ----------
    phi_right_rad, phi_left_rad : ndarray, shape (n,)
        Total wheel rotation over each interval (rad) = average speed (rad/s) * duration (s).
    sensor_motion : ndarray, shape (n, 3)
        (x_m, y_m, theta_rad) of the sensor, in its frame at the interval start.
    duration_s : ndarray, shape (n,)
        Interval durations T (s).
    line : ndarray of int, shape (n,)
        1-based line of each tuple in the file (to report dropped tuples).
    path : str
    """

    phi_right_rad: np.ndarray
    phi_left_rad: np.ndarray
    sensor_motion: np.ndarray
    duration_s: np.ndarray
    line: np.ndarray
    path: str

    def __len__(self) -> int:
        return len(self.duration_s)


class _Duplicate(ValueError):
    pass


def _no_duplicates(pairs):
    out = {}
    for k, v in pairs:
        if k in out:
            raise _Duplicate(k)
        out[k] = v
    return out


def _constant(name: str) -> float:
    # json calls this for NaN, Infinity, -Infinity (not JSON); _number refuses them by field
    return float(name.replace("Infinity", "inf"))


_DECODER = json.JSONDecoder(object_pairs_hook=_no_duplicates, parse_constant=_constant)


def _number(value, path, line_no: int, field: str, limit_key: str) -> float:
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise InputError(f"expected a number, got {json.dumps(value)[:40]}", path, line_no, field)
    try:
        x = float(value)
    except OverflowError:  # an integer beyond the float range
        x = math.inf
    if not math.isfinite(x):
        shown = repr(value) if len(repr(value)) <= 24 else repr(value)[:20] + "..."
        raise InputError(f"not a finite number: {shown}", path, line_no, field)
    if abs(x) > LIMITS[limit_key]:
        raise InputError(
            f"absurd magnitude {x:.6g} (limit {LIMITS[limit_key]:g})", path, line_no, field
        )
    return x


def _objects(text: str, path, line_no: int):
    """The JSON objects on one line (one, or several separated by white space)."""
    pos = 0
    n = len(text)
    while True:
        while pos < n and text[pos] in " \t\r\n":
            pos += 1
        if pos >= n:
            return
        try:
            obj, end = _DECODER.raw_decode(text, pos)
        except _Duplicate as exc:
            raise InputError("duplicated key", path, line_no, str(exc)) from None
        except (json.JSONDecodeError, RecursionError) as exc:
            msg = exc.msg if isinstance(exc, json.JSONDecodeError) else "nested too deeply"
            col = f" at column {exc.colno}" if isinstance(exc, json.JSONDecodeError) else ""
            raise InputError(f"invalid JSON{col}: {msg}", path, line_no) from None
        if not isinstance(obj, dict):
            raise InputError(
                f"expected a JSON object {{...}}, got {type(obj).__name__}", path, line_no
            )
        yield obj
        pos = end


def _tuple(obj: dict, path, line_no: int):
    missing = [k for k in _KEYS if k not in obj]
    if missing:
        raise InputError(
            "missing key; a tuple needs T, phi_l, phi_r and sm", path, line_no, missing[0]
        )
    t = _number(obj["T"], path, line_no, "T", "T")
    if not t > 0:
        raise InputError(f"duration must be > 0 s, got {t:g}", path, line_no, "T")
    phi_l = _number(obj["phi_l"], path, line_no, "phi_l", "phi_l")
    phi_r = _number(obj["phi_r"], path, line_no, "phi_r", "phi_r")
    sm = obj["sm"]
    if not isinstance(sm, list) or len(sm) != 3:
        raise InputError("expected 3 numbers [x_m, y_m, theta_rad]", path, line_no, "sm")
    motion = [
        _number(v, path, line_no, f"sm[{i}]", key)
        for i, (v, key) in enumerate(zip(sm, ("sm.x", "sm.y", "sm.theta"), strict=True))
    ]
    return t, phi_l, phi_r, motion


_LINE_END = re.compile(rb"\r\n|\r|\n")
_CHUNK_BYTES = 1 << 16


def _lines(fh, path) -> Iterator[tuple[int, bytes]]:
    """(1-based number, bytes) of each line of ``fh``, read once in chunks; LF, CRLF and CR-only
    line ends (a CR at a chunk's end waits for the next chunk's first byte)."""
    pending = b""
    line_no = 0
    while True:
        try:
            chunk = fh.read(_CHUNK_BYTES)
        except OSError as exc:
            raise InputError(f"cannot read: {exc.strerror}", path, line_no + 1) from None
        data = pending + chunk
        pos = 0
        for m in _LINE_END.finditer(data):
            if chunk and m.end() == len(data) and m.group() == b"\r":
                break  # maybe the CR of a CRLF split between chunks
            line_no += 1
            _check_length(m.start() - pos, path, line_no)
            yield line_no, data[pos : m.start()]
            pos = m.end()
        pending = data[pos:]
        if not chunk:
            if pending:
                line_no += 1
                _check_length(len(pending), path, line_no)
                yield line_no, pending
            return
        _check_length(len(pending), path, line_no + 1)


def _check_length(n: int, path, line_no: int) -> None:
    if n > MAX_LINE_BYTES:
        raise InputError(
            f"line longer than {MAX_LINE_BYTES} bytes; a tuple is one short JSON object",
            path,
            line_no,
        )


def read_tuples(path) -> TupleData:
    """Read a ``.tuple`` file (module docstring) into arrays.

    Parameters
    ----------
    path : str or os.PathLike
        The file; read once and sequentially (a pipe or ``/dev/fd/N`` works).

    Returns
    -------
    TupleData
        Wheel rotations (rad), sensor motions (m, m, rad), durations (s), line numbers.

    Raises
    ------
    InputError
        One line naming the file, the line and the field of the first problem.
    """
    path = Path(path)
    rows: list[tuple[float, float, float, list[float]]] = []
    lines: list[int] = []
    try:
        fh = open(path, "rb")  # closed by the with-block below
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a .tuple file", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    with fh:
        for line_no, raw in _lines(fh, path):
            if b"\x00" in raw:
                raise InputError("binary data, expected a text file", path, line_no)
            try:
                text = raw.decode("utf-8-sig" if line_no == 1 else "utf-8")
            except UnicodeDecodeError:
                raise InputError("not UTF-8 text", path, line_no) from None
            for obj in _objects(text, path, line_no):
                rows.append(_tuple(obj, path, line_no))
                lines.append(line_no)
    if not rows:
        raise InputError("no tuples: the file is empty (expected one JSON object per line)", path)
    t = np.array([r[0] for r in rows])
    phi_l = np.array([r[1] for r in rows])
    phi_r = np.array([r[2] for r in rows])
    motion = np.array([r[3] for r in rows], dtype=float).reshape(-1, 3)
    return TupleData(
        phi_right_rad=phi_r * t,
        phi_left_rad=phi_l * t,
        sensor_motion=motion,
        duration_s=t,
        line=np.array(lines, dtype=int),
        path=str(path),
    )


def refuse_still_tuples(data: Sequence[TupleData]) -> None:
    """InputError naming the file whose wheels turn in no tuple (every rotation below
    :data:`~odocal.calibration.censi.MIN_WHEEL_ROTATION_RAD`: a duration T in the wrong unit?)
    or whose sensor moves in none (every ``sm`` within :data:`MIN_SENSOR_MOTION`: no sensor
    motion to calibrate against). Checked before anything else: such a file's tuples may repeat
    each other, and its fit fails for a reason that hides the cause."""
    for d in data:
        turned = float(np.max(np.abs(np.r_[d.phi_right_rad, d.phi_left_rad])))
        if not turned >= MIN_WHEEL_ROTATION_RAD:
            raise InputError(
                f"the wheels do not turn in any tuple (largest rotation {turned:.3g} rad; a "
                "duration T in the wrong unit?)",
                d.path,
            )
        moved = float(np.max(np.abs(d.sensor_motion)))
        if not moved >= MIN_SENSOR_MOTION:
            raise InputError(
                f"the sensor never moves: every tuple's sm is within {MIN_SENSOR_MOTION:g} m and "
                f"rad of 0 (largest {moved:.3g}) while the wheels turn up to {turned:.3g} rad; "
                "no sensor motion to calibrate against (was the scan matcher running?)",
                d.path,
            )


def refuse_repeated_tuples(data: Sequence[TupleData]) -> None:
    """InputError when one interval appears twice among ``data`` (one file or several): every
    number of a tuple the same (T, both wheels, the sensor's motion) cannot happen twice in a
    real log; it is a row copied, a file concatenated with itself or with its own decimation, or
    a copy under another name, and it would count twice (standard errors too small by up to
    sqrt 2). Intervals in which neither wheel turns are exempt: a robot standing still at a fixed
    rate can log them more than once."""
    moving = [(d, np.nonzero((d.phi_right_rad != 0) | (d.phi_left_rad != 0))[0]) for d in data]
    rows = np.concatenate(
        [
            np.column_stack([d.duration_s, d.phi_right_rad, d.phi_left_rad, d.sensor_motion])[k]
            for d, k in moving
        ]
    )
    where = [(d.path, int(d.line[i])) for d, k in moving for i in k]
    if len(rows) < 2:
        return
    _, first, inverse = np.unique(rows, axis=0, return_index=True, return_inverse=True)
    repeats = np.nonzero(first[inverse.ravel()] != np.arange(len(rows)))[0]
    if len(repeats):
        j = int(repeats[0])
        (p0, l0), (p1, l1) = where[int(first[inverse.ravel()[j]])], where[j]
        raise InputError(
            f"the same tuple as {'line' if p0 == p1 else f'{p0}, line'} {l0}: an interval given "
            "twice would count twice (a row copied, a file concatenated with itself or with its "
            "own decimation, or a copy of a file under another name?); give each interval once",
            p1,
            l1,
        )
