"""OptiOdom data sets (Sousa et al. 2022): ``<id>_run-NN.csv`` plus ``<id>_metadata.csv``.

Run files: no header, columns time_s, x_gt_m, y_gt_m, theta_gt_rad, ticks_R, ticks_L; ticks are
increments per 50 ms at the motor encoder (before the gearbox), forward positive. Ticks per wheel
revolution = ngear x encRes. Run order: square and circular data sets hold N/2 CW runs then N/2
CCW runs; ivanjko data sets hold N/3 straight runs, N/3 CW spins, N/3 CCW spins.
"""

from __future__ import annotations

import csv
import io
import math
import re
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..errors import InputError
from .textfile import read_text

__all__ = [
    "CALIBRATION_CIRCLE_SET",
    "load_optiodom_split",
    "load_optiodom_experiment",
    "read_published",
    "load_optiodom_dataset",
    "load_optiodom_category",
    "is_optiodom_dataset",
    "is_optiodom_category",
    "read_metadata",
]

_RUN = re.compile(r"^(?P<id>.+)_run-(?P<n>\d+)\.csv$")


def is_optiodom_dataset(folder) -> bool:
    folder = Path(folder)
    return folder.is_dir() and any(folder.glob("*_metadata.csv"))


def is_optiodom_category(folder) -> bool:
    """True for a category folder (e.g. ``square/``) whose sub-folders are OptiOdom data sets."""
    folder = Path(folder)
    return folder.is_dir() and any(is_optiodom_dataset(d) for d in folder.iterdir())


def load_optiodom_category(folder) -> list[Recording]:
    """All runs of every data set in a category folder (e.g. ``square/``), data sets sorted."""
    folder = Path(folder)
    sets = sorted(d for d in folder.iterdir() if is_optiodom_dataset(d))
    if not sets:
        raise InputError("no OptiOdom data set folders (with *_metadata.csv) inside", folder)
    out: list[Recording] = []
    for d in sets:
        out += load_optiodom_dataset(d)
    return out


def read_metadata(path) -> dict[str, list[str]]:
    """The metadata file as key -> list of non-empty values."""
    meta: dict[str, list[str]] = {}
    for row in csv.reader(io.StringIO(read_text(path))):
        if row and row[0].strip():
            meta[row[0].strip()] = [v.strip() for v in row[1:] if v.strip()]
    return meta


def _meta_float(meta, key, path, index=0, required=True):
    vals = meta.get(key, [])
    if len(vals) <= index:
        if required:
            raise InputError(f"metadata key '{key}' is missing", path)
        return None
    try:
        v = float(vals[index])
    except ValueError:
        raise InputError(f"not a number: {vals[index]!r}", path, None, key) from None
    if not math.isfinite(v):
        raise InputError(f"must be finite, got {vals[index]!r}", path, None, key)
    return v


def _read_run(path: Path) -> np.ndarray:
    text = read_text(path)
    rows = []
    for i, line in enumerate(text.splitlines(), 1):
        if not line.strip():
            continue
        parts = line.split(",")
        if len(parts) != 6:
            raise InputError(f"expected 6 fields, got {len(parts)}", path, i)
        try:
            vals = [float(p) for p in parts]
        except ValueError:
            raise InputError("not a number", path, i) from None
        if not all(math.isfinite(v) for v in vals):
            raise InputError("values must be finite", path, i)
        rows.append(vals)
    if len(rows) < 2:
        raise InputError("a run needs at least two samples", path)
    data = np.array(rows)
    t = data[:, 0]
    bad = np.nonzero(np.diff(t) <= 0)[0]
    if len(bad):
        raise InputError("time is not strictly increasing", path, int(bad[0]) + 2, "time_s")
    return data


def _labels(kind: str, n: int) -> list[str | None]:
    if kind in ("square", "circular") and n % 2 == 0:
        return ["cw"] * (n // 2) + ["ccw"] * (n // 2)
    if kind == "ivanjko" and n % 3 == 0:
        k = n // 3
        return ["straight"] * k + ["spin-cw"] * k + ["spin-ccw"] * k
    return [None] * n


def load_optiodom_dataset(folder) -> list[Recording]:
    """All runs of one OptiOdom data set folder (e.g. ``square/230620202042``), in run order."""
    folder = Path(folder)
    metas = sorted(folder.glob("*_metadata.csv"))
    if not metas:
        raise InputError("not an OptiOdom data set folder (no *_metadata.csv)", folder)
    meta_path = metas[0]
    meta = read_metadata(meta_path)
    ticks_per_rev = _meta_float(meta, "ngear", meta_path) * _meta_float(meta, "encRes", meta_path)
    d_r = _meta_float(meta, "Di", meta_path, 0)
    d_l = _meta_float(meta, "Di", meta_path, 1, required=False) or d_r
    ran_with = WheelGeometry(d_r, d_l, _meta_float(meta, "Li", meta_path))
    side = _meta_float(meta, "L", meta_path, required=False)
    kind = folder.parent.name
    runs = sorted(
        (int(m.group("n")), p) for p in folder.glob("*_run-*.csv") if (m := _RUN.match(p.name))
    )
    if not runs:
        raise InputError("no *_run-NN.csv files", folder)
    labels = _labels(kind, len(runs))
    out = []
    for (num, path), label in zip(runs, labels, strict=True):
        data = _read_run(path)
        scale = 2.0 * math.pi / ticks_per_rev
        out.append(
            Recording(
                name=str(path),
                time_s=data[:, 0],
                wheel_angle_right_rad=np.cumsum(data[:, 4]) * scale,
                wheel_angle_left_rad=np.cumsum(data[:, 5]) * scale,
                ground_truth=data[:, 1:4],
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


def load_optiodom_experiment(folder):
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

    def sets(kind):
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


def read_published(folder, method: str = "Sousa", dataset: str = "ALL_DATASETS_COMBINED"):
    """Published calibrated geometry from ``reference_results_diff.csv`` (first row of
    ``method`` and ``dataset`` with no note), or None if the file is absent."""
    path = Path(folder) / "reference_results_diff.csv"
    if not path.is_file():
        return None
    out = {}
    for row in csv.DictReader(io.StringIO(read_text(path))):
        if row.get("method") != method or row.get("note"):
            continue
        try:
            g = WheelGeometry(float(row["cal_Dr_m"]), float(row["cal_Dl_m"]), float(row["cal_b_m"]))
        except (KeyError, ValueError):
            raise InputError("bad calibrated values", path, None, "cal_b_m") from None
        out[row["dataset"]] = g
    if dataset is None:
        return out
    return out.get(dataset)
