"""Trajectories in the TUM RGB-D format, as evo and most SLAM benchmarks read them.

One pose per line, ``timestamp x y z qx qy qz qw`` separated by spaces (seconds, metres, a unit
quaternion child -> parent with w last). A planar pose (x, y, yaw) is written with z = 0 and the
quaternion of a rotation by yaw about z: (0, 0, sin(yaw / 2), cos(yaw / 2)).

Two files written at the same timestamps (the truth's, say) compare in evo without time
association tolerance problems: ``evo_rpe tum truth.tum est.tum --delta 10 --delta_unit m
--pairs_from_reference`` reproduces :func:`odocal.core.path_drift.path_drift` (docs/skid-steer.md
says exactly which mode matches which).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, ModelError
from .table import parse_number
from .textfile import atomic_write, read_text

__all__ = ["tum_text", "write_tum", "read_tum"]


def tum_text(time_s: ArrayLike, poses: ArrayLike, *, comment: str | None = None) -> str:
    """The TUM text of planar ``poses`` (n, 3) (x_m, y_m, yaw_rad) at ``time_s`` (n,) (s)."""
    t = np.asarray(time_s, dtype=float)
    p = np.asarray(poses, dtype=float)
    if t.ndim != 1 or p.shape != (len(t), 3):
        raise ModelError(f"need times (n,) and poses (n, 3), got {t.shape} and {p.shape}")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(p))):
        raise ModelError("times and poses must be finite")
    half = 0.5 * p[:, 2]
    cols = np.column_stack(
        [t, p[:, 0], p[:, 1], np.zeros(len(t)), np.zeros(len(t)), np.zeros(len(t)),
         np.sin(half), np.cos(half)]
    )  # fmt: skip
    lines = [f"# {line}" for line in comment.splitlines()] if comment else []
    lines.append("# timestamp x y z qx qy qz qw")
    lines += [
        f"{r[0]:.9f} {r[1]:.9g} {r[2]:.9g} 0 0 0 {r[6]:.12g} {r[7]:.12g}" for r in cols.tolist()
    ]
    return "\n".join(lines) + "\n"


def write_tum(
    path: str | Path, time_s: ArrayLike, poses: ArrayLike, *, comment: str | None = None
) -> None:
    """Write :func:`tum_text` to ``path`` atomically."""
    atomic_write(path, tum_text(time_s, poses, comment=comment))


def read_tum(path: str | Path) -> tuple[np.ndarray, np.ndarray]:
    """Times (n,) and planar poses (n, 3) (x, y, yaw unwrapped) of a TUM file; the yaw is the
    rotation about z of the quaternion (tilts are ignored). InputError naming the line for a
    line that is not 8 numbers."""
    text = read_text(path)
    rows = []
    for no, line in enumerate(text.splitlines(), start=1):
        s = line.strip()
        if not s or s.startswith("#"):
            continue
        fields = s.split()
        if len(fields) != 8:
            raise InputError(f"expected 8 numbers, got {len(fields)} fields", path, no)
        rows.append(
            [parse_number(f, path, no, name) for f, name in zip(fields, _NAMES, strict=True)]
        )
    if not rows:
        raise InputError("no poses", path)
    a = np.asarray(rows)
    qx, qy, qz, qw = a[:, 4], a[:, 5], a[:, 6], a[:, 7]
    yaw = np.arctan2(2 * (qw * qz + qx * qy), 1 - 2 * (qy * qy + qz * qz))
    return a[:, 0], np.column_stack([a[:, 1], a[:, 2], np.unwrap(yaw)])


_NAMES = ("timestamp", "x", "y", "z", "qx", "qy", "qz", "qw")
