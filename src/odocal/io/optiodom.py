"""OptiOdom data sets (Sousa et al. 2022): ``<id>_run-NN.csv`` plus ``<id>_metadata.csv``.

Run files: no header, columns time_s, x_gt_m, y_gt_m, theta_gt_rad, ticks_R, ticks_L; ticks are
increments per 50 ms at the motor encoder (before the gearbox), forward positive. Ticks per wheel
revolution = ngear x encRes. Run order: square and circular data sets hold N/2 CW runs then N/2
CCW runs; ivanjko data sets hold N/3 straight runs, N/3 CW spins, N/3 CCW spins (labels go by the
run NUMBER and the metadata's N, so a deleted run file shifts no label).

Every value is checked where it enters (odocal.io.limits): the metadata's ngear, encRes, Li, Di,
L and N (count of values, plausible range, a key given twice), and every field of the run files
(finite, plausible magnitude, time strictly increasing, no wheel turning 160 times in a sample).
"""

from __future__ import annotations

import csv
import math
import re
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.pose import start_frame
from ..core.recording import Recording
from ..errors import InputError
from .generic_csv import check_wheel_steps
from .limits import (
    ENCODER_COUNTS,
    GEAR_RATIO,
    HEADING_MAX_RAD,
    POSITION_MAX_M,
    ROBOT_LENGTH_M,
    SIDE_MIN_M,
    TICKS_PER_REV,
    TICKS_PER_SAMPLE_MAX,
    TIME_MAX_S,
    TRACK_LENGTH_MAX_M,
)
from .table import MAX_LINE_CHARS, LineNumbers, parse_number, read_table
from .textfile import read_text

__all__ = [
    "CALIBRATION_CIRCLE_SET",
    "load_optiodom_split",
    "load_optiodom_experiment",
    "read_published",
    "load_optiodom_dataset",
    "is_optiodom_dataset",
    "read_metadata",
]

_RUN = re.compile(r"^(?P<id>.+)_run-(?P<n>\d+)\.csv$")


def is_optiodom_dataset(folder) -> bool:
    """True for a folder holding an OptiOdom data set (a ``*_metadata.csv`` file)."""
    folder = Path(folder)
    return folder.is_dir() and any(folder.glob("*_metadata.csv"))


# Metadata keys odocal reads, with their plausible ranges (odocal.io.limits) and how many values
# each holds: ngear (gear ratio), encRes (counts per motor turn), Li (wheelbase, m), Di (right and
# optionally left diameter, m), L (square side, m; squares only), N (number of runs).
_META = {
    "ngear": (GEAR_RATIO, 1, 1),
    "encRes": (ENCODER_COUNTS, 1, 1),
    "Li": (ROBOT_LENGTH_M, 1, 1),
    "Di": (ROBOT_LENGTH_M, 1, 2),
    "L": ((SIDE_MIN_M, TRACK_LENGTH_MAX_M), 0, 1),
    "N": ((1, 10_000), 0, 1),
}


def _metadata(path) -> dict[str, tuple[list[str], int]]:
    """key -> (non-empty values, line); a key given twice is an error."""
    meta: dict[str, tuple[list[str], int]] = {}
    for no, line in enumerate(read_text(path).splitlines(), start=1):
        if len(line) > MAX_LINE_CHARS:
            raise InputError(f"over-long line ({len(line)} characters)", path, no)
        try:
            row = next(csv.reader([line]), [])
        except csv.Error as exc:
            raise InputError(f"not valid CSV: {exc}", path, no) from None
        if not row or not row[0].strip():
            continue
        key = row[0].strip()
        if key in meta:
            raise InputError(f"key given twice (first on line {meta[key][1]})", path, no, key)
        meta[key] = ([v.strip() for v in row[1:] if v.strip()], no)
    return meta


def read_metadata(path) -> dict[str, list[str]]:
    """The metadata file as key -> list of non-empty values (a key given twice is an error)."""
    return {k: v for k, (v, _) in _metadata(path).items()}


def _meta_values(meta, key: str, path) -> list[float]:
    """The values of ``key``, checked: count and plausible range (see ``_META``)."""
    (lo, hi), least, most = _META[key]
    values, line = meta.get(key, ([], None))
    if len(values) < least:
        raise InputError(f"metadata key '{key}' is missing", path, line, key if line else None)
    if len(values) > most:
        raise InputError(
            f"expected {'one value' if most == 1 else f'at most {most} values'}, got {len(values)}",
            path,
            line,
            key,
        )
    out = []
    for raw in values:
        v = parse_number(raw, path, line, key, positive=True)
        if not lo <= v <= hi:
            raise InputError(
                f"implausible value {raw!r} (expected {lo:g} .. {hi:g}; check the units)",
                path,
                line,
                key,
            )
        out.append(v)
    return out


# Columns of a run file, and the largest magnitude of each (odocal.io.limits).
_RUN_COLUMNS = ("time_s", "x_gt_m", "y_gt_m", "theta_gt_rad", "ticks_R", "ticks_L")
_RUN_MAX = {
    "time_s": TIME_MAX_S,
    "x_gt_m": POSITION_MAX_M,
    "y_gt_m": POSITION_MAX_M,
    "theta_gt_rad": HEADING_MAX_RAD,
    "ticks_R": TICKS_PER_SAMPLE_MAX,
    "ticks_L": TICKS_PER_SAMPLE_MAX,
}


def _read_run(path: Path) -> tuple[np.ndarray, LineNumbers]:
    """The run's values, shape (K, 6), and the line of each row."""
    table = read_table(path, what="rows of time_s,x,y,theta,ticks_R,ticks_L", columns=_RUN_COLUMNS)
    data = table.numbers(_RUN_COLUMNS, at_most=_RUN_MAX)
    if len(data) < 2:
        raise InputError("a run needs at least two samples", path)
    lines = table.lines
    t = data[:, 0]
    dt = np.diff(t)
    bad = np.nonzero(dt <= 0)[0]
    if len(bad):
        i = int(bad[0]) + 1
        raise InputError(
            f"time is not strictly increasing ({t[i - 1]:g} s then {t[i]:g} s)",
            path,
            lines[i],
            "time_s",
        )
    # the ticks are increments per sample: a missing sample loses its increments silently
    gap = np.nonzero(dt > 1.5 * np.median(dt))[0]
    if len(gap):
        i = int(gap[0]) + 1
        raise InputError(
            f"a sample is missing: {dt[i - 1]:g} s after the previous one in a run sampled "
            f"every {np.median(dt):g} s; its tick increments would be lost",
            path,
            lines[i],
            "time_s",
        )
    return data, lines


def _labels(kind: str, numbers: list[int], n_runs: int | None) -> list[str | None]:
    """Labels by run NUMBER (run k of N), so that a missing run file shifts no label."""
    n = n_runs or len(numbers)
    if kind in ("square", "circular") and n % 2 == 0:
        return ["cw" if k <= n // 2 else "ccw" for k in numbers]
    if kind == "ivanjko" and n % 3 == 0:
        third = n // 3
        return [
            "straight" if k <= third else "spin-cw" if k <= 2 * third else "spin-ccw"
            for k in numbers
        ]
    return [None] * len(numbers)


def load_optiodom_dataset(folder) -> list[Recording]:
    """All runs of one OptiOdom data set folder (e.g. ``square/230620202042``), in run order."""
    folder = Path(folder)
    metas = sorted(folder.glob("*_metadata.csv"))
    if not metas:
        raise InputError("not an OptiOdom data set folder (no *_metadata.csv)", folder)
    if len(metas) > 1:
        raise InputError(
            f"{len(metas)} metadata files ({', '.join(m.name for m in metas)}): one data set per "
            "folder",
            folder,
        )
    meta_path = metas[0]
    meta = _metadata(meta_path)
    (ngear,), (enc,) = (
        _meta_values(meta, "ngear", meta_path),
        _meta_values(meta, "encRes", meta_path),
    )
    ticks_per_rev = ngear * enc
    lo, hi = TICKS_PER_REV
    if not lo <= ticks_per_rev <= hi:
        raise InputError(
            f"ngear x encRes = {ticks_per_rev:g} ticks per wheel turn is implausible (expected "
            f"{lo:g} .. {hi:g})",
            meta_path,
            meta["ngear"][1],
            "ngear",
        )
    diameters = _meta_values(meta, "Di", meta_path)
    (wheelbase,) = _meta_values(meta, "Li", meta_path)
    ran_with = WheelGeometry(diameters[0], diameters[-1], wheelbase)
    sides = _meta_values(meta, "L", meta_path)
    side = sides[0] if sides else None
    n_meta = _meta_values(meta, "N", meta_path)
    n_runs = int(n_meta[0]) if n_meta else None
    kind = folder.parent.name
    runs = sorted(
        (int(m.group("n")), p) for p in folder.glob("*_run-*.csv") if (m := _RUN.match(p.name))
    )
    if not runs:
        raise InputError("no *_run-NN.csv files", folder)
    if n_runs is not None and (n_meta[0] != n_runs or runs[-1][0] > n_runs):
        what = (
            "a whole number" if n_meta[0] != n_runs else f"{n_runs}, but there is run {runs[-1][0]}"
        )
        raise InputError(
            f"the number of runs N must be {what} (which runs are CW and which CCW depends on N)",
            meta_path,
            meta["N"][1],
            "N",
        )
    labels = _labels(kind, [num for num, _ in runs], n_runs)
    scale = 2.0 * math.pi / ticks_per_rev
    out = []
    for (num, path), label in zip(runs, labels, strict=True):
        data, lines = _read_run(path)
        # the first row's increments lie before the first pose: angles start at 0 there
        right = (np.cumsum(data[:, 4]) - data[0, 4]) * scale
        left = (np.cumsum(data[:, 5]) - data[0, 5]) * scale
        check_wheel_steps(right, left, lines, path, ("ticks_R", "ticks_L"))
        out.append(
            Recording(
                name=str(path),
                time_s=data[:, 0],
                wheel_angle_right_rad=right,
                wheel_angle_left_rad=left,
                ground_truth=start_frame(data[:, 1], data[:, 2], data[:, 3]),
                ran_with=ran_with,
                label=label,
                meta={
                    "dataset": folder.name,
                    "kind": kind,
                    "run": num,
                    "side_m": side,
                    "ticks_per_rev": ticks_per_rev,
                },
            )
        )
    return out


# OptiOdom circle data set used to calibrate BCPT (first arc radius 0.85 m); the other circle
# data set (250620202104, first arc 0.375 m) is held out with free/.
CALIBRATION_CIRCLE_SET = "231220200121"


def load_optiodom_split(folder, calibration_circle_set: str | None = None):
    """Calibration data sets and held-out runs from an ``optiodom_diff`` folder.

    Returns ``(datasets, heldout)``: ``datasets`` maps 'square', 'ivanjko' and
    'circular-calibration' to lists of data sets (lists of Recording); ``heldout`` is the runs of
    free/ and of every circular data set except the calibration one: ``calibration_circle_set``
    (a data set id; default :data:`CALIBRATION_CIRCLE_SET`, or the first circular data set found
    if that one is absent).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a folder (expected an optiodom_diff folder)", folder)

    def sets(kind):
        base = folder / kind
        if not base.is_dir():
            return []
        return [d for d in sorted(base.iterdir()) if is_optiodom_dataset(d)]

    found = {k: sets(k) for k in ("square", "ivanjko", "circular", "free")}
    if not any(found.values()):
        raise InputError(
            "no OptiOdom data sets (expected square/, ivanjko/, circular/, free/ sub-folders)",
            folder,
        )
    circles = found["circular"]
    if calibration_circle_set is not None:
        cal = [d for d in circles if d.name == calibration_circle_set]
        if not cal:
            raise InputError(
                f"no circular data set '{calibration_circle_set}' (found: "
                f"{', '.join(d.name for d in circles) or 'none'})",
                folder / "circular",
            )
    else:
        cal = [d for d in circles if d.name == CALIBRATION_CIRCLE_SET] or circles[:1]
    datasets = {
        "square": [load_optiodom_dataset(d) for d in found["square"]],
        "ivanjko": [load_optiodom_dataset(d) for d in found["ivanjko"]],
        "circular-calibration": [load_optiodom_dataset(d) for d in cal],
    }
    heldout = []
    for d in found["free"] + [c for c in circles if c not in cal]:
        heldout += load_optiodom_dataset(d)
    if not heldout:
        raise InputError("no held-out runs (free/ or a second circular/ data set)", folder)
    return datasets, heldout


def load_optiodom_experiment(
    folder: str | Path,
) -> tuple[dict[float, list[Recording]], list[Recording], list[Recording], str]:
    """The runs of the real experiment of ``odocal reproduce --realdata`` from an
    ``optiodom_diff`` folder.

    Returns ``(squares_by_side, ivanjko, heldout, split)``: the square runs of every data set
    grouped by side length (m; from the metadata), the Ivanjko runs (straight lines and spins,
    used only by odocal's default fit and the robot model), the held-out runs (every circular
    and free data set) and a sentence saying so. This split differs from ``odocal compare``'s
    (:func:`load_optiodom_split`, which calibrates BCPT on one circle set): here no circle is
    used for calibration, so all circle and free runs are held out.
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a folder (expected an optiodom_diff folder)", folder)

    def sets(kind: str) -> list[Path]:
        base = folder / kind
        if not base.is_dir():
            raise InputError(
                f"no {kind}/ folder (an optiodom_diff folder holds square/, "
                "ivanjko/, circular/ and free/)",
                folder,
            )
        found = [d for d in sorted(base.iterdir()) if is_optiodom_dataset(d)]
        if not found:
            raise InputError("no OptiOdom data sets (with *_metadata.csv) inside", base)
        return found

    by_side: dict[float, list[Recording]] = {}
    for d in sets("square"):
        runs = load_optiodom_dataset(d)
        side = runs[0].meta.get("side_m")
        if not side:
            raise InputError("square data set without a side length (metadata key 'L')", d)
        by_side.setdefault(float(side), []).extend(runs)
    ivanjko = [r for d in sets("ivanjko") for r in load_optiodom_dataset(d)]
    circles = [r for d in sets("circular") for r in load_optiodom_dataset(d)]
    heldout = circles + [r for d in sets("free") for r in load_optiodom_dataset(d)]
    n_c = len(circles)
    split = (
        f"calibration: square/ ({sum(len(v) for v in by_side.values())} runs: "
        + ", ".join(f"{len(v)} of {s:g} m" for s, v in sorted(by_side.items()))
        + f"), plus ivanjko/ ({len(ivanjko)} runs) for odocal's default fit and the robot model; "
        f"held out: every circular/ ({n_c}) and free/ ({len(heldout) - n_c}) run, "
        f"{len(heldout)} runs (odocal compare uses another split: one circle set calibrates "
        "BCPT there)"
    )
    return by_side, ivanjko, heldout, split


def read_published(folder, method: str = "Sousa", dataset: str | None = "ALL_DATASETS_COMBINED"):
    """Published calibrated geometry from ``reference_results_diff.csv`` (first row of
    ``method`` and ``dataset`` with no note), or None if the file is absent; ``dataset`` None:
    {data set: geometry} of every data set."""
    path = Path(folder) / "reference_results_diff.csv"
    if not path.is_file():
        return None
    table = read_table(path, what="a header row")
    table.require(("method", "dataset", "note", "cal_Dr_m", "cal_Dl_m", "cal_b_m"))
    col = {c: table.index(c) for c in table.header}
    lo, hi = ROBOT_LENGTH_M
    out = {}
    for no, row in table.rows:
        if row[col["method"]] != method or row[col["note"]]:
            continue
        values = []
        for key in ("cal_Dr_m", "cal_Dl_m", "cal_b_m"):
            v = parse_number(row[col[key]], path, no, key, positive=True)
            if not lo <= v <= hi:
                raise InputError(f"implausible value (expected {lo:g} .. {hi:g} m)", path, no, key)
            values.append(v)
        out[row[col["dataset"]]] = WheelGeometry(*values)
    if dataset is None:
        return out
    return out.get(dataset)
