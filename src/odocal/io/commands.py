"""Velocity-command files: ``t,v,omega`` (s, m/s, rad/s), one row per command change, the
command holding until the next row's time; what ``odocal plan --route`` writes and
``odocal design --route --validate FILE.csv`` reads."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from ..core.maneuvers import CommandSeries, Maneuver, commanded
from ..errors import InputError
from .table import read_table

__all__ = ["COMMAND_HEADER", "command_csv", "read_commands", "MAX_SPEED_M_S", "MAX_RATE_RAD_S"]

COMMAND_HEADER = "t,v,omega"

#: Commands beyond these are not a wheeled robot's (a unit slip): refused.
MAX_SPEED_M_S = 5.0
MAX_RATE_RAD_S = 10.0
MAX_DURATION_S = 3600.0


def command_csv(series: CommandSeries) -> str:
    """The command file of ``series``: a ``t,v,omega`` header, then one row per command change
    (the last row stops the robot)."""
    rows = series.rows()
    keep = np.ones(len(rows), bool)
    keep[1:-1] = np.any(np.diff(rows[:-1, 1:], axis=0) != 0, axis=1)
    lines = [COMMAND_HEADER] + [f"{t:.3f},{v:.6g},{w:.6g}" for t, v, w in rows[keep]]
    return "\n".join(lines) + "\n"


def read_commands(path: str | Path, flag: str = "--validate") -> Maneuver:
    """The driving of a command file as one maneuver; InputError (naming ``flag``, the file and
    the line) for what the model cannot simulate: a missing column, a value that is not a
    finite number, speeds or turn rates beyond a wheeled robot's, times that do not increase,
    more than an hour of driving, or no motion at all."""
    table = read_table(path, what=f"a header row {COMMAND_HEADER}")
    table.require(("t", "v", "omega"))
    try:
        values = table.numbers(
            ("t", "v", "omega"),
            at_most={"t": 1e6, "v": MAX_SPEED_M_S, "omega": MAX_RATE_RAD_S},
            unit_hint="a wheeled robot's commands are in s, m/s and rad/s",
        )
    except InputError as e:
        raise InputError(f"{flag}: the model cannot simulate this driving: {e}") from None
    if len(values) < 2:
        raise InputError(
            f"{flag}: the model cannot simulate this driving: fewer than two rows", path
        )
    t, v, w = values.T
    bad = np.flatnonzero(np.diff(t) <= 0)
    if bad.size:
        raise InputError(
            f"{flag}: the model cannot simulate this driving: the times do not increase",
            path,
            table.line_of(int(bad[0]) + 1),
        )
    if t[-1] - t[0] > MAX_DURATION_S:
        raise InputError(
            f"{flag}: {t[-1] - t[0]:.0f} s of driving is more than the model simulates "
            f"({MAX_DURATION_S:.0f} s)",
            path,
        )
    if not np.any((v[:-1] != 0) | (w[:-1] != 0)):
        raise InputError(f"{flag}: the commands never move the robot", path)
    return commanded(t - t[0], v, w, f"the commands of {Path(path).name}")
