"""RUNS.csv: the measured final pose of each test run.

Header row, then one row per run::

    direction,x_m,y_m,theta_deg
    cw,-0.2531,-0.2770,7.49
    ccw,-0.3958,0.4690,-12.12

``x_m``, ``y_m``, ``theta_deg`` are the final pose ERROR, actual - odometric, in the start frame
(+x the start heading, +y to the left, theta CCW positive and unwrapped; for a closed track this
is simply the robot's final pose measured from its start pose). Extra columns are ignored; blank
lines and lines starting with '#' are skipped.

The track the runs drove is data of the sheet: ``# sides: N`` and ``# side_m: L`` (m) lines
above the header (``odocal plan`` and ``odocal simulate`` write them; ``odocal calibrate`` reads
them, and refuses a --sides/--side-length that disagrees).

The BCPT runs format (``odocal calibrate --method bcpt``) has one row per circle run::

    direction,radius_m
    cw,1.015798
    ccw,1.004270

``radius_m`` is the measured axle-centre radius of the run (m, > 0), e.g. a least-squares circle
fit to tracked points (``odocal.calibration.circle_fit.fit_circle``). Same rules as RUNS.csv.

Every command that writes a table (``plan``'s blank run sheet, ``simulate --out``) replaces an
existing file only when it cannot hold measurements (:func:`refuse_replacing_measurements`): an
empty file, or a table the same command wrote (its signature comment line, e.g. ``# odocal
simulate:``) that, for a blank sheet, is still blank (no measured value, no note of the user's, the
same columns). Anything else, a real run sheet above all, needs ``--force``.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..core.plausibility import circle_radius_problem
from ..core.runs import CircleRuns, EndPoseRuns
from ..core.tracks import MAX_POLYGON_SIDES
from ..errors import InputError, one_line
from .limits import MEASURED_MAX, TRACK_LENGTH_MAX_M
from .table import Cells, parse_number, read_table
from .textfile import atomic_write, read_text

__all__ = [
    "RunSheet",
    "read_run_sheet",
    "read_runs",
    "read_circle_runs",
    "write_runs",
    "runs_csv_text",
    "REQUIRED_COLUMNS",
    "CIRCLE_COLUMNS",
    "holds_measurements",
    "refuse_replacing_measurements",
]

REQUIRED_COLUMNS = ("direction", "x_m", "y_m", "theta_deg")
# Largest magnitude of a measured value (m or deg; odocal.io.limits): 1000 km, or 2778 turns.
MAX_MAGNITUDE = MEASURED_MAX
CIRCLE_COLUMNS = ("direction", "radius_m")
# Longest side a sheet may name (m), as the command-line flags (odocal.io.limits).
MAX_LENGTH_M = TRACK_LENGTH_MAX_M
#: ``# key: value`` settings of a run sheet: the polygon the runs drove.
TRACK_SETTINGS = ("sides", "side_m")


@dataclass(frozen=True)
class RunSheet:
    """A RUNS.csv as read: the runs, the line of each run, and the track it names (if any).

    Attributes
    ----------
    runs : EndPoseRuns
    lines : ndarray of int
        Line number of each run's row in the file.
    sides : int or None
    side_m : float or None
        The ``# sides:`` and ``# side_m:`` settings (None when absent).
    setting_lines : dict of str to int
        Where each setting was given.
    path : str
    """

    runs: EndPoseRuns
    lines: np.ndarray
    sides: int | None = None
    side_m: float | None = None
    setting_lines: dict = field(default_factory=dict)
    path: str = ""


def _track_settings(table) -> tuple[int | None, float | None, dict]:
    sides = side = None
    where = {k: table.settings[k][1] for k in TRACK_SETTINGS if k in table.settings}
    if "sides" in table.settings:
        raw, no = table.settings["sides"]
        v = parse_number(raw, table.path, no, "sides", positive=True, at_most=MAX_POLYGON_SIDES)
        if v != int(v) or v < 3:
            raise InputError(f"must be a whole number >= 3, got {raw!r}", table.path, no, "sides")
        sides = int(v)
    if "side_m" in table.settings:
        raw, no = table.settings["side_m"]
        side = parse_number(raw, table.path, no, "side_m", positive=True, at_most=MAX_LENGTH_M)
    return sides, side, where


def _parse_row(path, line_no, fields, col, columns, directions, required, positive):
    """One row split line by line: its direction and values (every problem named)."""
    raw_dir = fields[col[columns[0]]]
    d = raw_dir.lower()
    if d not in directions:
        raise InputError(
            f"unknown direction {raw_dir!r}; expected {' or '.join(directions)}",
            path,
            line_no,
            columns[0],
        )
    row = []
    for name in columns[1:]:
        raw = fields[col[name]]
        if not raw and name not in required:
            row.append(math.nan)
            continue
        # no floor measurement is this large; the statistics would overflow
        row.append(parse_number(raw, path, line_no, name, positive=positive, at_most=MAX_MAGNITUDE))
    return directions.index(d), row


def _fast_rows(cells, columns, directions, required, positive):
    """Direction codes and values of a chunk split in one vectorised pass, or None when a
    row needs the line-by-line parse (which names what is wrong, or reads what this did not:
    spaces around a value, an upper-case direction, ...)."""
    names = np.asarray([d.encode() for d in directions])
    codes = np.full(len(cells.lines), -1)
    for k, name in enumerate(names):
        codes[cells.columns[0] == name] = k
    if np.any(codes < 0):
        return None
    values = np.empty((len(cells.lines), len(columns) - 1))
    for k, (name, raw) in enumerate(zip(columns[1:], cells.columns[1:], strict=True)):
        empty = raw == b""
        if name in required and np.any(empty):
            return None
        try:
            v = np.where(empty, b"0", raw).astype(np.float64)
        except ValueError:
            return None
        filled = v[~empty]
        if not np.all(np.isfinite(filled)) or np.any(np.abs(filled) > MAX_MAGNITUDE):
            return None
        if positive and np.any(filled <= 0):
            return None
        v[empty] = math.nan
        values[:, k] = v
    return codes, values


def _repeats(codes: np.ndarray, values: np.ndarray, lines: np.ndarray, path) -> list[str]:
    """A note for every row with the same direction and values as an earlier one (not for rows
    without any value). Rows are grouped by a 64-bit hash of their values (a stable sort keeps
    each group in file order), then compared in full."""
    if len(codes) < 2:
        return []
    key = np.column_stack([codes.astype(np.float64), values])
    key[np.isnan(key)] = np.inf  # an empty value: equal to another empty one
    key += 0.0  # -0.0 as 0.0
    bits = key.view(np.uint64)
    digest = bits[:, 0].copy()
    for j in range(1, bits.shape[1]):
        digest = (digest * np.uint64(0x100000001B3)) ^ bits[:, j]
    order = np.argsort(digest, kind="stable")
    same = digest[order[1:]] == digest[order[:-1]]
    if not np.any(same):
        return []
    same &= np.all(key[order[1:]] == key[order[:-1]], axis=1)
    # runs of equal keys in sorted order start at their first row in the file
    first = order[np.r_[0, np.flatnonzero(~same) + 1]][np.cumsum(np.r_[True, ~same]) - 1]
    repeat = np.flatnonzero(np.r_[False, same])
    firsts = dict(zip(order[repeat].tolist(), first[repeat].tolist(), strict=True))
    rows = np.sort(order[repeat])
    filled = ~np.all(np.isnan(values[rows]), axis=1)
    return [
        f"{path}: line {lines[r]} repeats line {lines[firsts[r]]} exactly: the same run entered "
        "twice? Each row counts as a run"
        for r in rows[filled].tolist()
    ]


def _read_runs_table(
    path, columns: tuple[str, ...], directions, required, positive=False, warnings=None
):
    """Rows of a runs table: ``columns[0]`` is the direction, the rest are numbers.

    Returns (table, directions, values of shape (n, len(columns) - 1), line numbers); an empty
    value not in ``required`` is NaN. Every problem raises InputError naming the file, line and
    field; two rows with the same direction and values (the same run entered twice?) are
    appended to ``warnings``. Chunks of a few megabytes are parsed in vectorised passes; one
    that fails is parsed line by line, which names the first bad line or field.
    """
    table = read_table(path, what=f"a header row '{','.join(columns)}'", settings=TRACK_SETTINGS)
    table.require(columns)
    col = {c: table.index(c) for c in columns}
    directions = tuple(directions)
    code_parts, value_parts, line_parts = [], [], []
    for chunk in table.row_chunks(columns):
        if isinstance(chunk, Cells):
            fast = _fast_rows(chunk, columns, directions, required, positive)
            if fast is not None:
                code_parts.append(fast[0])
                value_parts.append(fast[1])
                line_parts.append(chunk.lines)
                continue
        rows = table.split(chunk) if isinstance(chunk, Cells) else chunk
        parsed = [
            _parse_row(path, no, f, col, columns, directions, required, positive) for no, f in rows
        ]
        code_parts.append(np.array([c for c, _ in parsed], dtype=int))
        value_parts.append(np.array([v for _, v in parsed], float).reshape(-1, len(columns) - 1))
        line_parts.append(np.array([no for no, _ in rows], dtype=int))
    codes = np.concatenate(code_parts) if code_parts else np.empty(0, dtype=int)
    if not len(codes):
        raise InputError("no runs: the file has a header but no data rows", path)
    values = np.concatenate(value_parts)
    lines = np.concatenate(line_parts)
    if warnings is not None:
        warnings += _repeats(codes, values, lines, path)
    labels = np.array(directions, dtype=object)[codes]
    return table, tuple(labels.tolist()), values, lines


def read_run_sheet(
    path,
    directions: tuple[str, ...] = ("cw", "ccw"),
    required: tuple[str, ...] = ("x_m", "y_m", "theta_deg"),
    warnings: list[str] | None = None,
) -> RunSheet:
    """Parse RUNS.csv with its line numbers and track settings (see :func:`read_runs`)."""
    table, dirs, err, lines = _read_runs_table(
        path, REQUIRED_COLUMNS, directions, required, warnings=warnings
    )
    err[:, 2] = np.radians(err[:, 2])
    sides, side, where = _track_settings(table)
    return RunSheet(EndPoseRuns(dirs, err), lines, sides, side, where, str(path))


def read_runs(
    path,
    directions: tuple[str, ...] = ("cw", "ccw"),
    required: tuple[str, ...] = ("x_m", "y_m", "theta_deg"),
    warnings: list[str] | None = None,
) -> EndPoseRuns:
    """Parse RUNS.csv; every problem raises InputError naming the file, line and field.

    All four columns must be present. A value column not in ``required`` may be left empty in a
    row (the method does not use it, e.g. x_m and y_m for the heading-error method): it is read
    as NaN. An empty required value is reported as not filled in. ``warnings`` receives a note
    for every row that repeats an earlier one exactly.
    """
    return read_run_sheet(path, directions, required, warnings).runs


def read_circle_runs(
    path, warnings: list[str] | None = None, commanded_radius_m: float | None = None
) -> CircleRuns:
    """Parse a BCPT runs file (``direction,radius_m``); every problem raises InputError naming
    the file, line and field (``warnings`` as in :func:`read_runs`). With ``commanded_radius_m``
    (m), a radius no run of that circle can have (a unit slip) is refused too."""
    _, dirs, radii, lines = _read_runs_table(
        path, CIRCLE_COLUMNS, ("cw", "ccw"), ("radius_m",), positive=True, warnings=warnings
    )
    if commanded_radius_m is not None:
        for line, r in zip(lines, radii[:, 0], strict=True):
            problem = circle_radius_problem(float(r), commanded_radius_m)
            if problem:
                raise InputError(problem, path, line, "radius_m")
    return CircleRuns(dirs, radii[:, 0])


def track_settings_text(sides: int, side_m: float) -> str:
    """The ``# sides:`` and ``# side_m:`` lines of a run sheet (the track as data)."""
    return f"# sides: {int(sides)}\n# side_m: {float(side_m):.12g}\n"


def runs_csv_text(
    runs: EndPoseRuns,
    extra: dict[str, list] | None = None,
    track: tuple[int, float] | None = None,
    signature: str | None = None,
) -> str:
    """RUNS.csv text for ``runs``; ``extra`` adds columns (e.g. ``run``); ``track`` (sides,
    side_m) writes the track settings above the header, then ``signature`` (a comment line
    naming the command that wrote the sheet; :func:`holds_measurements`)."""
    buf = io.StringIO()
    if track is not None:
        buf.write(track_settings_text(*track))
    if signature is not None:
        buf.write(f"{one_line(signature)}\n")
    w = csv.writer(buf, lineterminator="\n")
    extra = extra or {}
    w.writerow([*REQUIRED_COLUMNS, *extra])
    for i, (d, e) in enumerate(zip(runs.directions, runs.errors, strict=True)):
        w.writerow(
            [d, f"{e[0]:.9g}", f"{e[1]:.9g}", f"{math.degrees(e[2]):.9g}"]
            + [v[i] for v in extra.values()]
        )
    return buf.getvalue()


def write_runs(
    path,
    runs: EndPoseRuns,
    extra: dict[str, list] | None = None,
    track: tuple[int, float] | None = None,
) -> None:
    """Write RUNS.csv atomically."""
    atomic_write(path, runs_csv_text(runs, extra, track))


def holds_measurements(
    path: str | Path, signature: str, blank: tuple[Sequence[str], Sequence[str]] | None = None
) -> bool:
    """Whether replacing the existing file ``path`` could lose measurements (module docstring).

    False only for an empty file, or a table with a comment line above its header that starts
    with ``signature`` (the command that writes it). ``blank`` = (header, comment lines) for a
    command that writes blank sheets: then the table must also still have that header, no value
    in its measured columns (x_m, y_m, theta_deg, radius_m) and no comment line of its own
    besides the signature, the track settings and those comment lines."""
    path = Path(path)
    try:
        text = read_text(path)
        if not text.strip():
            return False
        table = read_table(path, text=text)
    except InputError:
        return True  # not a table: not ours
    head = [ln.strip() for ln in text.splitlines()[: table.header_line - 1]]
    if not any(ln.startswith(signature) for ln in head):
        return True
    if blank is None:
        return False
    header, comments = blank
    if table.header != tuple(header):
        return True
    own = ("# sides:", "# side_m:", signature)
    if any(ln.startswith("#") and ln not in comments and not ln.startswith(own) for ln in head):
        return True  # a note of the user's
    if any(ln.strip().startswith("#") for ln in text.splitlines()[table.header_line :]):
        return True
    measured = [table.index(c) for c in (*REQUIRED_COLUMNS[1:], "radius_m") if table.has(c)]
    return any(f[j] != "" for _, f in table.rows for j in measured)


def refuse_replacing_measurements(
    path: str | Path,
    flag: str,
    command: str,
    signature: str,
    *,
    force: bool = False,
    blank: tuple[Sequence[str], Sequence[str]] | None = None,
) -> None:
    """The one rule of every command that writes a table: an existing ``path`` that may hold
    measurements (:func:`holds_measurements`) is not replaced without ``force`` (InputError)."""
    if force or not Path(path).is_file() or not holds_measurements(path, signature, blank):
        return
    what = "a filled-in run sheet" if blank is not None else "a file it did not write"
    raise InputError(
        f"{flag}: already holds measured runs, or may: {command} will not replace {what}; "
        f"choose another {flag.split()[0]} name (or --force to replace it)",
        path,
    )
