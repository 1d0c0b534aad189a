"""One entry point for recorded runs: files, bags and folders -> a list of ``Recording``.

``load_recordings(paths)`` accepts, for each path:

- a generic run CSV (``io/generic_csv.py``; header row starting with ``time_s``);
- one OptiOdom run file ``<id>_run-NN.csv`` (its data set's metadata is read beside it);
- a ROS bag: ``.bag`` (ROS 1), ``.db3`` or ``.mcap`` (ROS 2), or a ROS 2 bag folder holding
  ``metadata.yaml`` (read by ``odocal.io.bag_recording``; needs the optional ``rosbags`` package);
- a folder: an OptiOdom data set folder (holds ``*_metadata.csv``, e.g. ``square/230620202042``),
  an OptiOdom category folder holding several data sets (e.g. ``square/``), or a folder of
  generic run CSVs (all ``*.csv`` files in it, sorted by name).
"""

from __future__ import annotations

import re
from pathlib import Path

from ..core.recording import Recording
from ..errors import InputError
from .bags import BAG_SUFFIXES, is_bag

__all__ = ["load_recordings", "require_ground_truth"]

_OPTI_RUN = re.compile(r"^(?P<id>.+)_run-(?P<n>\d+)\.csv$")


def _load_bag(path: Path, bag_options: dict) -> list[Recording]:
    from .bag_recording import load_bag_recording

    opts = {k: v for k, v in bag_options.items() if v is not None}
    return [load_bag_recording(path, **opts)]


def _load_file(path: Path, ticks_per_rev) -> list[Recording]:
    from .generic_csv import load_generic_csv, looks_like_generic_csv
    from .optiodom import is_optiodom_dataset, load_optiodom_dataset

    m = _OPTI_RUN.match(path.name)
    if m and not looks_like_generic_csv(path):
        if not is_optiodom_dataset(path.parent):
            raise InputError(
                f"OptiOdom run file without its metadata: {m.group('id')}_metadata.csv is "
                "missing beside it",
                path,
            )
        runs = load_optiodom_dataset(path.parent)
        hit = [r for r in runs if Path(r.name).name == path.name]
        return hit
    if path.suffix.lower() != ".csv" and not looks_like_generic_csv(path):
        raise InputError(
            "unknown run file type: expected a generic run CSV (header starting with time_s), "
            f"an OptiOdom *_run-NN.csv, or a bag ({', '.join(BAG_SUFFIXES)})",
            path,
        )
    return [load_generic_csv(path, ticks_per_rev=ticks_per_rev)]


def _load_folder(path: Path, ticks_per_rev) -> list[Recording]:
    from .generic_csv import load_generic_csv
    from .optiodom import (
        is_optiodom_category,
        is_optiodom_dataset,
        load_optiodom_category,
        load_optiodom_dataset,
    )

    if is_optiodom_dataset(path):
        return load_optiodom_dataset(path)
    if is_optiodom_category(path):
        return load_optiodom_category(path)
    csvs = sorted(path.glob("*.csv"))
    if any(_OPTI_RUN.match(p.name) for p in csvs):
        raise InputError(
            "OptiOdom run files without a *_metadata.csv (ngear, encRes, Li, Di are needed)", path
        )
    if not csvs:
        raise InputError(
            "no runs found: expected generic run CSVs, an OptiOdom data set (*_metadata.csv), "
            "a folder of OptiOdom data sets, or a ROS 2 bag folder (metadata.yaml)",
            path,
        )
    return [load_generic_csv(p, ticks_per_rev=ticks_per_rev) for p in csvs]


def load_recordings(paths, *, ticks_per_rev: float | None = None, **bag_options) -> list[Recording]:
    """Every run found in ``paths`` (files, bags, folders; see module docstring), in order.

    ``ticks_per_rev`` applies to generic CSVs with tick columns whose header does not give it.
    ``bag_options`` (joint_topic, truth_topic, imu_topic, right_joint, left_joint,
    ticks_per_rev) are passed to ``odocal.io.bag_recording.load_bag_recording``; None values are
    dropped.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    out: list[Recording] = []
    for p in paths:
        path = Path(p)
        if not path.exists():
            raise InputError("no such file or folder", path)
        if is_bag(path):
            out += _load_bag(path, {**bag_options, "ticks_per_rev": ticks_per_rev})
        elif path.is_dir():
            out += _load_folder(path, ticks_per_rev)
        else:
            out += _load_file(path, ticks_per_rev)
    if not out:
        raise InputError("no runs found in " + ", ".join(str(p) for p in paths))
    return out


def require_ground_truth(recordings: list[Recording], purpose: str) -> None:
    """InputError naming the first run without ground truth (``purpose`` says who needs it)."""
    for r in recordings:
        if r.ground_truth is None:
            raise InputError(
                f"{purpose} needs ground truth (x_m, y_m, theta_rad or a truth topic)", r.name
            )
