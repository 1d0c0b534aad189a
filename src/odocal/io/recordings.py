"""One entry point for recorded runs: files, bags and folders -> a list of ``Recording``.

``load_recordings(paths)`` accepts, for each path:

- a generic run CSV (``io/generic_csv.py``; header row starting with ``time_s``), also a pipe
  or ``<(...)`` (every file is read once, sequentially);
- one OptiOdom run file ``<id>_run-NN.csv`` (its data set's metadata is read beside it);
- a ROS bag: ``.bag`` (ROS 1), ``.db3`` or ``.mcap`` (ROS 2), or a ROS 2 bag folder holding
  ``metadata.yaml`` (read by ``odocal.io.bag_recording``; needs the optional ``rosbags`` package);
- a folder of generic run CSVs (all ``*.csv`` files in it, sorted by name; each must be a run);
- a folder of bags (each bag in it, sorted by name; one data set);
- an OptiOdom data set folder (holds ``*_metadata.csv``, e.g. ``square/230620202042``);
- a collection: a folder whose sub-folders (to :data:`MAX_WALK_DEPTH` levels) hold data sets
  or run CSVs, e.g. a category folder (``square/``) or a whole ``optiodom_diff``. Its data sets
  and run CSVs are read in path order; whatever holds no runs (notes, result tables, unsynchronised
  raw data, bags: name those on their own) is skipped and listed in one warning.

The same run given twice (the same file twice, a folder and a file inside it, two links to one
file) is refused: it would count twice; so are two bags that are one recording (a copy, a log and
a part of it: :func:`odocal.core.recording.same_recording`). Two files with identical data are
warned about.
"""

from __future__ import annotations

import hashlib
import os
import re
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.recording import Recording, same_recording
from ..errors import InputError
from .bag_options import NO_BAG_OPTIONS, BagOptions
from .bags import BAG_SUFFIXES, is_bag
from .textfile import read_text

__all__ = [
    "load_recordings",
    "expand_folders",
    "refuse_repeated",
    "require_ground_truth",
    "MAX_WALK_DEPTH",
]

_OPTI_RUN = re.compile(r"^(?P<id>.+)_run-(?P<n>\d+)\.csv$")

#: How deep a collection folder is walked for data sets and run CSVs.
MAX_WALK_DEPTH = 4


def _load_bag(
    path: Path, bag: BagOptions, ticks_per_rev: float | None, ran_with: WheelGeometry | None
) -> list[Recording]:
    from .bag_recording import load_bag_run, reads_gyro
    from .bags import IMU, RUN_TYPES, read_bag_once

    # read once with each Odometry's frames known (one in 'map' is a truth, not the wheels);
    # the IMU only when the run's gyro heading is wanted (a bag's most numerous messages)
    types = RUN_TYPES if reads_gyro() else tuple(t for t in RUN_TYPES if t != IMU)
    named = (bag.joint_topic, bag.truth_topic, bag.imu_topic if reads_gyro() else None)
    return [load_bag_run(read_bag_once(path, named, types), bag, ticks_per_rev=ticks_per_rev,
                         ran_with=ran_with)]  # fmt: skip


def _load_file(path: Path, ticks_per_rev: float | None) -> list[Recording]:
    from .generic_csv import load_generic_csv, looks_like_generic_csv
    from .optiodom import is_optiodom_dataset, load_optiodom_dataset

    text = read_text(path)  # once: a pipe can be read only once
    generic = looks_like_generic_csv(path, text)
    m = _OPTI_RUN.match(path.name)
    if m and not generic:
        if not is_optiodom_dataset(path.parent):
            raise InputError(
                f"OptiOdom run file without its metadata: {m.group('id')}_metadata.csv is "
                "missing beside it",
                path,
            )
        runs = load_optiodom_dataset(path.parent)
        return [r for r in runs if Path(r.name).name == path.name]
    if path.suffix.lower() == ".tuple":
        raise InputError(
            "a .tuple file holds relative motions without a trajectory: only 'odocal fit' reads "
            "it (the relative-motion fit); this needs recorded runs (generic run CSVs, OptiOdom "
            f"data sets, bags: {', '.join(BAG_SUFFIXES)})",
            path,
        )
    if path.suffix.lower() != ".csv" and not generic:
        raise InputError(
            "unknown run file type: expected a generic run CSV (header starting with time_s), "
            f"an OptiOdom *_run-NN.csv or a bag ({', '.join(BAG_SUFFIXES)}); 'odocal fit' also "
            "reads .tuple files (a pipe of tuples with --method relative)",
            path,
        )
    return [load_generic_csv(path, ticks_per_rev=ticks_per_rev, text=text)]


def _csvs(folder: Path) -> list[Path]:
    return sorted(p for p in folder.iterdir() if p.suffix.lower() == ".csv" and p.is_file())


def _is_run_csv(path: Path) -> bool:
    from .generic_csv import looks_like_generic_csv

    return looks_like_generic_csv(path)


def _holds_runs(folder: Path, depth: int) -> bool:
    """True if ``folder`` is a data set or holds run CSVs or data sets (to MAX_WALK_DEPTH)."""
    from .optiodom import is_optiodom_dataset

    if is_optiodom_dataset(folder):
        return True
    if depth > MAX_WALK_DEPTH or is_bag(folder):
        return False
    try:
        entries = sorted(folder.iterdir())
    except OSError:
        return False
    if any(p.suffix.lower() == ".csv" and p.is_file() and _is_run_csv(p) for p in entries):
        return True
    return any(d.is_dir() and _holds_runs(d, depth + 1) for d in entries)


def _load_folder(
    path: Path, ticks_per_rev: float | None, skipped: list[str], depth: int = 0
) -> list[Recording]:
    """The runs in folder ``path``; what holds none is appended to ``skipped`` (relative)."""
    from .generic_csv import load_generic_csv
    from .optiodom import is_optiodom_dataset, load_optiodom_dataset

    if is_optiodom_dataset(path):
        return load_optiodom_dataset(path)
    try:
        entries = sorted(path.iterdir())
    except OSError as exc:
        raise InputError(f"cannot read the folder: {exc.strerror}", path) from None
    csvs = _csvs(path)
    below = [d for d in entries if d.is_dir() and _holds_runs(d, depth + 1)]
    if not below:
        # a folder of generic run CSVs: every CSV in it must be a run
        if any(_OPTI_RUN.match(p.name) for p in csvs):
            raise InputError(
                "OptiOdom run files without a *_metadata.csv (ngear, encRes, Li, Di are needed)",
                path,
            )
        if not csvs:
            raise InputError(
                "no runs found: expected generic run CSVs, an OptiOdom data set (*_metadata.csv), "
                "a folder of OptiOdom data sets, or a ROS 2 bag folder (metadata.yaml)",
                path,
            )
        return [load_generic_csv(p, ticks_per_rev=ticks_per_rev) for p in csvs]
    # a collection: its run CSVs and the folders below that hold runs, in path order; the rest
    # is skipped (and said)
    out: list[Recording] = []
    for p in entries:
        if p in below:
            inner: list[str] = []
            out += _load_folder(p, ticks_per_rev, inner, depth + 1)
            skipped += [f"{p.name}/{q}" for q in inner]
        elif p in csvs and _is_run_csv(p):
            out.append(load_generic_csv(p, ticks_per_rev=ticks_per_rev))
        elif not p.name.startswith("."):
            skipped.append(p.name + ("/" if p.is_dir() else ""))
    return out


def _folder_of(folder: Path) -> list[Path] | None:
    """The bags, or the ``.tuple`` files, that a folder holds when it holds nothing else that
    is read (no run CSV, no data set, not both kinds), in name order; else None."""
    from .optiodom import is_optiodom_dataset

    if is_bag(folder) or is_optiodom_dataset(folder):
        return None
    try:
        entries = sorted(folder.iterdir())
    except OSError:
        return None
    bags = [p for p in entries if not p.name.startswith(".") and is_bag(p)]
    tuples = [p for p in entries if p.is_file() and p.suffix.lower() == ".tuple"]
    if bool(bags) == bool(tuples) or _holds_runs(folder, 0):
        return None
    return bags or tuples


def expand_folders(paths: Sequence[str | Path]) -> list[str | Path]:
    """``paths`` with each folder of bags, or of ``.tuple`` files, replaced by them (in name
    order; a folder of bags is one data set: its runs share the folder). Other paths (files,
    bag folders, data sets, folders of run CSVs, collections) are kept as given."""
    out: list[str | Path] = []
    for p in paths:
        found = _folder_of(Path(p)) if Path(p).is_dir() else None
        out += found if found else [p]
    return out


def _identity(path: Path) -> tuple[int, int] | None:
    try:
        st = os.stat(path)
    except OSError:
        return None
    return (st.st_dev, st.st_ino)


def _source(r: Recording) -> Path:
    return Path(r.meta.get("bag") or r.name) if r.meta else Path(r.name)


def _fingerprint(r: Recording) -> str:
    h = hashlib.sha1()
    for a in (r.time_s, r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ground_truth):
        if a is not None:
            h.update(np.ascontiguousarray(a, dtype=float).tobytes())
    return h.hexdigest()


def load_recordings(
    paths: str | Path | Sequence[str | Path],
    *,
    ticks_per_rev: float | None = None,
    warnings: list[str] | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
    ran_with: WheelGeometry | None = None,
) -> list[Recording]:
    """Every run found in ``paths`` (files, bags, folders; see module docstring), in order.

    ``ticks_per_rev`` applies to generic CSVs with tick columns whose header does not give it,
    and to the joint positions of bags. ``bag``: the topics, joints and IMU axis of the bags
    (:func:`odocal.io.bag_recording.load_bag_recording`); ``ran_with``: the geometry the
    controller ran with, through which a bag without joint states has its odometry inverted
    into wheel rotations. ``warnings``: a list that receives
    what the reader has to say (folder entries skipped, runs with identical data).

    Raises InputError when a run is given twice (see module docstring) or none is found.
    """
    if isinstance(paths, (str, Path)):
        paths = [paths]
    paths = expand_folders(paths)
    out: list[Recording] = []
    notes: list[str] = []
    seen: dict[tuple[int, int], str | Path] = {}
    for p in paths:
        path = Path(p)
        if not path.exists():
            raise InputError("no such file or folder", path)
        if is_bag(path):
            found = _load_bag(path, bag, ticks_per_rev, ran_with)
        elif path.is_dir():
            skipped: list[str] = []
            found = _load_folder(path, ticks_per_rev, skipped)
            if skipped:
                more = f" and {len(skipped) - 8} more" if len(skipped) > 8 else ""
                notes.append(f"{path}: skipped what holds no runs: {', '.join(skipped[:8])}{more}")
        else:
            found = _load_file(path, ticks_per_rev)
        for r in found:
            key = _identity(_source(r))
            if key is None:
                continue
            if key in seen:
                how = f"as {seen[key]} and as {p}" if Path(seen[key]) != path else f"twice as {p}"
                raise InputError(
                    f"this run is given {how}: it would count twice; give each run once",
                    _source(r),
                )
            seen[key] = p
        out += found
    if not out:
        raise InputError("no runs found in " + ", ".join(str(p) for p in paths))
    _refuse_one_recording_twice(out)
    prints: dict[str, str] = {}
    for r in out:
        first = prints.setdefault(_fingerprint(r), r.name)
        if first != r.name:
            notes.append(
                f"{r.name} holds the same data as {first}: the same run copied twice? It counts "
                "twice"
            )
    if warnings is not None:
        warnings += notes
    return out


def _refuse_one_recording_twice(runs: Sequence[Recording]) -> None:
    """InputError when two runs are one recording given twice under two names (a bag and its
    copy, a log and a part of it: :func:`~odocal.core.recording.same_recording`): its samples
    would count twice."""
    timed = [r for r in runs if r.meta.get("start_s") is not None]
    for k, a in enumerate(timed):
        for b in timed[k + 1 :]:
            shared = same_recording(a, b)
            if shared is not None:
                lo, hi = shared
                raise InputError(
                    f"{_source(a)} and {_source(b)} cover the same time ({hi - lo:.3g} s of it) "
                    "with the same wheel samples: one recording given twice (a copy under another "
                    "name, or a log and a part of it) would count twice; give each once"
                )


def refuse_repeated(paths: Sequence[str | Path]) -> list[Path]:
    """``paths`` as Paths; InputError if two of them are the same file or folder (also through
    a link): the runs would count twice."""
    seen: dict = {}
    out = []
    for p in paths:
        path = Path(p)
        key = _identity(path)
        if key is not None and key in seen:
            raise InputError(
                f"given as {seen[key]} and as {p}: the runs would count twice; give each once",
                path,
            )
        if key is not None:
            seen[key] = p
        out.append(path)
    return out


def require_ground_truth(recordings: Sequence[Recording], purpose: str) -> None:
    """InputError naming the first run without ground truth (``purpose`` says who needs it)."""
    for r in recordings:
        if r.ground_truth is None:
            why = r.meta.get("no_truth") if r.meta else None
            raise InputError(
                f"{purpose} needs ground truth (x_m, y_m, theta_rad or a truth topic)"
                + (f"; {why}" if why else ""),
                r.name,
            )
