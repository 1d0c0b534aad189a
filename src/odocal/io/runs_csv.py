"""RUNS.csv: the measured final pose of each test run.

Header row, then one row per run::

    direction,x_m,y_m,theta_deg
    cw,-0.2531,-0.2770,7.49
    ccw,-0.3958,0.4690,-12.12

``x_m``, ``y_m``, ``theta_deg`` are the final pose ERROR, actual - odometric, in the start frame
(+x the start heading, +y to the left, theta CCW positive and unwrapped; for a closed track this
is simply the robot's final pose measured from its start pose). Extra columns are ignored; blank
lines and lines starting with '#' are skipped.

The BCPT runs format (``odocal calibrate --method bcpt``) has one row per circle run::

    direction,radius_m
    cw,1.015798
    ccw,1.004270

``radius_m`` is the measured axle-centre radius of the run (m, > 0), e.g. a least-squares circle
fit to tracked points (``odocal.calibration.circle_fit.fit_circle``). Same rules as RUNS.csv.
"""

from __future__ import annotations

import csv
import io
import math

import numpy as np

from ..core.runs import CircleRuns, EndPoseRuns
from ..errors import InputError
from .limits import MEASURED_MAX
from .table import parse_number, read_table
from .textfile import atomic_write

__all__ = [
    "read_runs",
    "read_circle_runs",
    "write_runs",
    "runs_csv_text",
    "REQUIRED_COLUMNS",
    "CIRCLE_COLUMNS",
]

REQUIRED_COLUMNS = ("direction", "x_m", "y_m", "theta_deg")
# Largest magnitude of a measured value (m or deg; odocal.io.limits): 1000 km, or 2778 turns.
MAX_MAGNITUDE = MEASURED_MAX
CIRCLE_COLUMNS = ("direction", "radius_m")


def _read_runs_table(
    path, columns: tuple[str, ...], directions, required, positive=False, warnings=None
):
    """Rows of a runs table: ``columns[0]`` is the direction, the rest are numbers.

    Returns (directions, values of shape (n, len(columns) - 1)); an empty value not in
    ``required`` is NaN. Every problem raises InputError naming the file, line and field; two
    rows with the same direction and values (the same run entered twice?) are appended to
    ``warnings``.
    """
    table = read_table(path, what=f"a header row '{','.join(columns)}'")
    table.require(columns)
    col = {c: table.index(c) for c in columns}
    dirs: list[str] = []
    values: list[list[float]] = []
    seen: dict[tuple, int] = {}
    for line_no, fields in table.rows:
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
            row.append(
                parse_number(raw, path, line_no, name, positive=positive, at_most=MAX_MAGNITUDE)
            )
        dirs.append(d)
        values.append(row)
        key = (d, *(fields[col[c]] for c in columns[1:]))
        if warnings is not None and key in seen and any(fields[col[c]] for c in columns[1:]):
            warnings.append(
                f"{path}: line {line_no} repeats line {seen[key]} exactly: the same run entered "
                "twice? Each row counts as a run"
            )
        seen.setdefault(key, line_no)
    if not values:
        raise InputError("no runs: the file has a header but no data rows", path)
    return tuple(dirs), np.array(values)


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
    dirs, err = _read_runs_table(path, REQUIRED_COLUMNS, directions, required, warnings=warnings)
    err[:, 2] = np.radians(err[:, 2])
    return EndPoseRuns(dirs, err)


def read_circle_runs(path, warnings: list[str] | None = None) -> CircleRuns:
    """Parse a BCPT runs file (``direction,radius_m``); every problem raises InputError naming
    the file, line and field (``warnings`` as in :func:`read_runs`)."""
    dirs, radii = _read_runs_table(
        path, CIRCLE_COLUMNS, ("cw", "ccw"), ("radius_m",), positive=True, warnings=warnings
    )
    return CircleRuns(dirs, radii[:, 0])


def runs_csv_text(runs: EndPoseRuns, extra: dict[str, list] | None = None) -> str:
    """RUNS.csv text for ``runs``; ``extra`` adds columns (e.g. ``run``)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    extra = extra or {}
    w.writerow([*REQUIRED_COLUMNS, *extra])
    for i, (d, e) in enumerate(zip(runs.directions, runs.errors, strict=True)):
        w.writerow(
            [d, f"{e[0]:.9g}", f"{e[1]:.9g}", f"{math.degrees(e[2]):.9g}"]
            + [v[i] for v in extra.values()]
        )
    return buf.getvalue()


def write_runs(path, runs: EndPoseRuns, extra: dict[str, list] | None = None) -> None:
    """Write RUNS.csv atomically."""
    atomic_write(path, runs_csv_text(runs, extra))
