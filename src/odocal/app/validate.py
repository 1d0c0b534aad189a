"""``odocal validate``: how well given parameters dead-reckon recorded runs, against nominal."""

from __future__ import annotations

import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.time_offset import TimeOffset
from ..core.model import Kinematics, Robot, WheelGeometry
from ..core.odometry import dead_reckon, evaluate
from ..core.path_drift import PathDrift, path_drift, path_length, piece_length_for, pool_drift
from ..core.recording import Recording
from ..errors import InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from ..io.robot_file import load_params, load_robot
from .common import RobotSpec, kinematics_of, load_warnings, refuse_still_runs, unused_offsets
from .slam_bags import load_slam_bags
from .text import Presented, Text, emits_warnings

__all__ = ["NOMINAL_SOURCES", "Validation", "validate", "validate_recordings"]


@dataclass(frozen=True)
class Validation(Presented):
    """Per-run errors of ``params`` and of the nominal geometry on recorded runs.

    runs : list of dict, one per run: ``path``, ``final_error_m``, ``max_error_m``,
    ``final_heading_error_rad``, ``max_heading_error_rad`` (for ``params``) and the same keys
    prefixed ``nominal_`` (None where the nominal geometry is unknown).
    nominal_source : str
        Where the "nominal" column's geometry came from: 'robot' (ROBOT.yaml's nominal),
        'firmware' (each run's own ran-with parameters, e.g. an OptiOdom data set's firmware
        values) or 'unknown'.
        Each run's row names the geometry used as ``nominal_params``.
    """

    runs: list[dict[str, Any]]
    params: WheelGeometry
    nominal_known: bool
    nominal_source: str = "firmware"
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    params_label: str = "the given geometry"
    robot_label: str | None = None
    drift: PathDrift | None = None
    nominal_drift: PathDrift | None = None
    kinematics: Kinematics = "differential"
    offsets: tuple[TimeOffset, ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal validate --json``: the per-run errors, their means (m, rad), the
        nominal geometry's source and the parameters validated (m)."""

        def mean(key: str) -> float | None:
            vals = [r[key] for r in self.runs if r[key] is not None]
            return float(np.mean(vals)) if vals else None

        out: dict[str, Any] = {
            "runs": self.runs,
            "mean_final_error_m": mean("final_error_m"),
            "mean_max_error_m": mean("max_error_m"),
            "mean_final_heading_error_rad": mean("final_heading_error_rad"),
            "mean_nominal_final_error_m": mean("nominal_final_error_m"),
            "mean_nominal_max_error_m": mean("nominal_max_error_m"),
            "mean_nominal_final_heading_error_rad": mean("nominal_final_heading_error_rad"),
            "nominal_source": self.nominal_source,
            "nominal_params": (
                self.runs[0]["nominal_params"]
                if self.nominal_source == "robot" and self.runs
                else None
            ),
            "params": self.params.as_dict(),
        }
        out["drift_percent_per_10m"] = drift_dict(self.drift)
        out["nominal_drift_percent_per_10m"] = drift_dict(self.nominal_drift)
        out["drift_alignment"] = SKID_ALIGNMENT if self.offsets else DRIFT_ALIGNMENT
        out["kinematics"] = self.kinematics
        if self.offsets:
            out["time_offsets"] = [o.as_dict() for o in self.offsets]
        if self.written:
            out["plots"] = [str(p) for p in self.written]
        return out

    def text(self) -> str:
        """The text of ``odocal validate``: per run, the final and largest errors with these
        parameters and with the nominal ones, and their means."""
        out = Text()
        result, d = self, self.as_dict()

        def mm(v: float | None) -> str:
            return "-" if v is None else f"{1000 * v:.1f}"

        def deg(v: float | None) -> str:
            return "-" if v is None else f"{math.degrees(v):.2f}"

        col = {"robot": "robot", "firmware": "firmware"}.get(result.nominal_source, "nominal")
        rows = [
            (
                "run",
                "final mm",
                "max mm",
                "final deg",
                f"{col} final mm",
                f"{col} max mm",
                f"{col} final deg",
            )
        ]
        for r in result.runs:
            rows.append(
                (
                    Path(r["path"]).name,
                    mm(r["final_error_m"]),
                    mm(r["max_error_m"]),
                    deg(r["final_heading_error_rad"]),
                    mm(r["nominal_final_error_m"]),
                    mm(r["nominal_max_error_m"]),
                    deg(r["nominal_final_heading_error_rad"]),
                )
            )
        rows.append(
            (
                "mean",
                mm(d["mean_final_error_m"]),
                mm(d["mean_max_error_m"]),
                deg(d["mean_final_heading_error_rad"]),
                mm(d["mean_nominal_final_error_m"]),
                mm(d["mean_nominal_max_error_m"]),
                deg(d["mean_nominal_final_heading_error_rad"]),
            )
        )
        source = {
            "robot": f"ROBOT.yaml's nominal geometry ({self.robot_label}; --nominal robot)",
            "firmware": "each run's firmware values, the parameters it ran with "
            "(--nominal firmware)",
            "unknown": "unknown for some runs (they do not say what they ran with; give --robot)",
        }
        out(f"  {col} columns: {source[result.nominal_source]}")
        if self.kinematics == "skid-steer":
            out("  skid-steer: the parameters' wheelbase is the effective track")
        for o in self.offsets:
            pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
            out(f"  clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.found}; applied)")
        for what, drift in (("these parameters", self.drift), (col, self.nominal_drift)):
            if drift is not None and drift.pieces:
                out(
                    f"drift with {what}: median {drift.median_pct:.2f} %, mean "
                    f"{drift.mean_pct:.2f} % of {drift.length_m:g} m of truth path "
                    f"({drift.pieces} pieces), heading {drift.median_heading_deg_per_10m:.2f} deg "
                    "per 10 m (KITTI style: each piece re-anchored to the truth at its start)"
                )
        out.table(rows, title=f"{len(result.runs)} run(s), parameters from {self.params_label}")
        if result.written:
            out(f"wrote {len(result.written)} plot(s) to {result.written[0].parent}")
        return str(out)


NOMINAL_SOURCES = ("robot", "firmware")
#: How the drift's pieces are aligned to the truth: what evo_rpe needs to reproduce it.
DRIFT_ALIGNMENT = (
    "each piece re-anchored to the truth at its start (SE(2), no scale); the truth as "
    "recorded, on the wheels' clock (no time offset applied); evo_rpe tum truth.tum "
    "calibrated.tum --delta L --delta_unit m --pairs_from_reference gives the same errors in "
    "metres"
)
#: The same for skid-steer bags: their truth (a lidar ICP, a SLAM) is placed on the wheels'
#: clock by its estimated offset first.
SKID_ALIGNMENT = (
    "each piece re-anchored to the truth at its start (SE(2), no scale); the truth shifted onto "
    "the wheels' clock by its estimated offset (time_offsets: its stamp minus the offset); no "
    "piece spans a hole of over 2 s in the truth; evo_rpe tum truth.tum calibrated.tum --delta "
    "L --delta_unit m --pairs_from_reference gives the same errors in metres on the pieces "
    "without such a hole (the TUM files carry the shifted stamps; evo's pieces may span holes)"
)


def drift_dict(d: PathDrift | None) -> dict[str, Any] | None:
    """The JSON contract's drift (:meth:`~odocal.core.path_drift.PathDrift.contract`); None
    without pieces."""
    return None if d is None or not d.pieces else d.contract()


def _truth_samples(r: Recording) -> np.ndarray:
    """The samples whose truth is valid (a SLAM truth: only at its update instants)."""
    valid = r.meta.get("truth_samples") if r.meta else None
    if valid is not None:
        return np.asarray(valid, dtype=int)
    assert r.ground_truth is not None
    return np.flatnonzero(np.all(np.isfinite(r.ground_truth), axis=1))


def piece_length(recordings: Sequence[Recording]) -> float:
    """The drift's piece length for these runs (:func:`~odocal.core.path_drift.
    piece_length_for`)."""
    lengths = []
    for r in recordings:
        assert r.ground_truth is not None
        k = _truth_samples(r)
        lengths.append(float(path_length(r.ground_truth[k, :2])[-1]) if len(k) else 0.0)
    return piece_length_for(lengths)


def recordings_drift(
    recordings: Sequence[Recording], geometry_of: Any, length_m: float
) -> PathDrift | None:
    """The KITTI-style drift (:func:`~odocal.core.path_drift.path_drift`) of dead reckoning with
    ``geometry_of(run)`` (None: skipped) over every run, the pieces pooled; None without any."""
    parts = []
    for r in recordings:
        g = geometry_of(r)
        if g is None or r.ground_truth is None:
            continue
        k = _truth_samples(r)
        if len(k) < 2:
            continue
        est = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, g)[k]
        gap = (r.meta or {}).get("truth_max_gap_s")  # a skid-steer log: cut at the truth's holes
        breaks = None if gap is None else np.flatnonzero(np.diff(r.time_s[k]) > gap) + 1
        parts.append(path_drift(r.ground_truth[k], est, length_m=length_m, breaks=breaks))
    return pool_drift(parts)


def validate_recordings(
    recordings: Sequence[Recording], params: WheelGeometry, nominal: WheelGeometry | None = None
) -> Validation:
    """Evaluate ``params`` and the nominal geometry on each run.

    The nominal geometry of a run is ``nominal`` if given (source 'robot'), else the run's
    ``ran_with`` (source 'firmware'; 'unknown' where a run has none). Each run's row holds the
    geometry its nominal columns used (``nominal_params``, None where unknown).
    """
    require_ground_truth(list(recordings), "validate")
    runs, known = [], True
    for r in recordings:
        row = {"path": r.name, **evaluate(r, params)}
        nom = nominal or r.ran_with
        if nom is None:
            known = False
            row.update({f"nominal_{k}": None for k in list(row) if k != "path"})
            row["nominal_params"] = None
        else:
            row.update({f"nominal_{k}": v for k, v in evaluate(r, nom).items()})
            row["nominal_params"] = nom.as_dict()
        runs.append(row)
    source = "robot" if nominal is not None else ("firmware" if known else "unknown")
    length = piece_length(recordings)
    drift = recordings_drift(recordings, lambda r: params, length)
    nom_drift = recordings_drift(recordings, lambda r: nominal or r.ran_with, length)
    return Validation(runs, params, known, source, drift=drift, nominal_drift=nom_drift)


def _plot_names(recordings: Sequence[Recording]) -> list[str]:
    used: set[str] = set()
    names = []
    for r in recordings:
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(r.name).stem) or "run"
        name, i = stem, 1
        while name in used:
            i += 1
            name = f"{stem}-{i}"
        used.add(name)
        names.append(f"{name}.png")
    return names


def _nominal_source(nominal: str | None, robot: RobotSpec) -> str:
    """The source of the "nominal" column, checked against ``robot`` (validate's docstring)."""
    if nominal is None:
        nominal = "robot" if robot else "firmware"
    if nominal not in NOMINAL_SOURCES:
        raise InputError(
            f"--nominal must be one of {', '.join(NOMINAL_SOURCES)}, got {nominal!r}",
            field="nominal",
        )
    if nominal == "robot" and not robot:
        raise InputError("--nominal robot needs --robot ROBOT.yaml")
    if nominal == "firmware" and robot:
        raise InputError(
            "--nominal firmware compares with each run's own parameters: --robot is not used; "
            "leave it out, or choose --nominal robot"
        )
    return nominal


def _require_firmware(recordings: Sequence[Recording]) -> None:
    """Every run says which parameters it ran with (``--nominal firmware`` chosen)."""
    missing = [r.name for r in recordings if r.ran_with is None]
    if missing:
        raise InputError(
            "--nominal firmware: this run does not say which parameters it ran with (give "
            "them in its header, or --robot ROBOT.yaml with --nominal robot)",
            missing[0],
        )


def _load(
    paths: Sequence[str | Path],
    bag: BagOptions,
    ticks_per_rev: float | None,
    truth_frames: tuple[str, str] | None,
    slam_stamp_offset_s: float,
    notes: list[str],
) -> list[Recording]:
    """The runs; with ``truth_frames``, the SLAM bags' runs (truth at the updates only)."""
    if truth_frames is None:
        return load_recordings(paths, ticks_per_rev=ticks_per_rev, warnings=notes, bag=bag)
    slam = load_slam_bags(
        paths, truth_frames, bag, ticks_per_rev=ticks_per_rev, stamp_offset_s=slam_stamp_offset_s
    )
    return [b.recording for b in slam]


def _load_skid(
    paths: Sequence[str | Path],
    bag: BagOptions,
    robot: RobotSpec,
    ticks_per_rev: float | None,
    truth_frames: tuple[str, str] | None,
) -> tuple[list[Recording], tuple[TimeOffset, ...]]:
    """Skid-steer bags read as the skid-steer fit reads them (:func:`~odocal.io.bag_skid.
    read_skid_log`: a world-frame odometry or a SLAM /tf as the truth), each truth placed on the
    wheels' clock by its estimated offset."""
    from .fit_skid import read_skid_logs, skid_recordings

    if truth_frames is not None:
        raise InputError(
            "--truth-frames: with --kinematics skid-steer a SLAM /tf truth is found as the "
            "skid-steer fit finds it (leave the flag out)",
            field="truth-frames",
        )
    logs = read_skid_logs(paths, bag, load_robot(robot) if robot else None, ticks_per_rev)
    return skid_recordings(logs, bag.time_offset("truth"))


def _tum_files(
    recordings: Sequence[Recording],
    folder: Path,
    geometry: WheelGeometry,
    nominal: WheelGeometry | None,
) -> dict[Path, str]:
    """Each run's truth and dead reckonings as TUM text (at the truth's valid samples, stamped
    in seconds since the epoch when the run says when it started)."""
    from ..io.tum import tum_text

    out: dict[Path, str] = {}
    for r, name in zip(recordings, _plot_names(recordings), strict=True):
        assert r.ground_truth is not None  # validate requires it
        stem = name.removesuffix(".png")
        k = _truth_samples(r)
        t = np.asarray(r.time_s, dtype=float)[k] + float((r.meta or {}).get("start_s") or 0.0)
        trajs = {"truth": r.ground_truth[k]}
        trajs["calibrated"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad,
                                          geometry)[k]  # fmt: skip
        nom = nominal or r.ran_with
        if nom is not None:
            trajs["nominal"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad,
                                           nom)[k]  # fmt: skip
        for what, poses in trajs.items():
            out[folder / f"{stem}.{what}.tum"] = tum_text(
                t, poses, comment=f"odocal validate: {r.name}, {what} (start frame)"
            )
    return out


def _figure(r: Recording, geometry: WheelGeometry, nominal: WheelGeometry | None) -> Any:
    """One run: its ground truth against its dead reckoning with the nominal geometry (given,
    else the run's own) and with ``geometry``."""
    from ..plot.trajectory import run_figure

    assert r.ground_truth is not None  # validate requires it
    trajs = {}
    nom = nominal or r.ran_with
    if nom is not None:
        trajs["nominal"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, nom)
    trajs["calibrated"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, geometry)
    title = Path(r.name).name + (f" ({r.label})" if r.label else "")
    valid = r.meta.get("truth_samples") if r.meta else None
    if valid is not None:  # truth only at these samples (a SLAM pose at its updates)
        return run_figure(title, r.ground_truth[valid], trajs, truth_marker="o")
    return run_figure(title, r.ground_truth, trajs)


@emits_warnings
def validate(
    paths: str | Path | Sequence[str | Path],
    params: str | Path | WheelGeometry,
    *,
    robot: RobotSpec = None,
    nominal: str | None = None,
    plot: str | Path | None = None,
    ticks_per_rev: float | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
    tum: str | Path | None = None,
    kinematics: Kinematics | None = None,
) -> Validation:
    """Dead-reckon the runs in ``paths`` with ``params`` (PARAMS.yaml or a geometry) and with the
    nominal geometry; with ``plot``, one PNG per run in that folder.

    ``nominal`` chooses the "nominal" column: 'robot' (ROBOT.yaml's nominal geometry; needs
    ``robot``), 'firmware' (each run's own ran-with parameters, e.g. an OptiOdom data set's
    firmware values; every run must carry them), or None: 'robot' when ``robot`` is given, else
    each run's firmware values where it has them (the result's ``nominal_source`` says which:
    'robot', 'firmware' or 'unknown'). ``bag``: the topics and joints of bags. With
    ``truth_frames`` (bags whose truth is a SLAM pose on /tf), the errors are measured at the
    SLAM's update instants only (docs/slam-truth.md). With ``tum``, each run's truth and its
    dead reckoning with ``params`` and with the nominal geometry are written into that folder as
    TUM trajectories (``RUN.truth.tum``, ``RUN.calibrated.tum``, ``RUN.nominal.tum``), all or
    none with the plots. ``kinematics`` (default: the robot file's, else differential):
    'skid-steer' reads bags as the skid-steer fit does (docs/skid-steer.md), estimates each
    truth's clock offset and applies it (the result's ``offsets``); the parameters' wheelbase
    is then the effective track."""
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    source = _nominal_source(nominal, robot)
    inputs = [*map(Path, paths)]
    for extra in (params, robot):
        if isinstance(extra, (str, Path)) and Path(extra).exists():
            inputs.append(Path(extra))
    plan = OutputPlan(inputs)
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    if tum is not None:
        plan.folder(tum, "--tum")
    geometry = params if isinstance(params, WheelGeometry) else load_params(params)
    notes: list[str] = []
    kind = kinematics_of(kinematics, robot)
    offsets: tuple[TimeOffset, ...] = ()
    if kind == "skid-steer":
        recordings, offsets = _load_skid(paths, bag, robot, ticks_per_rev, truth_frames)
        notes.extend(w for o in offsets for w in o.warnings)
        notes.extend(unused_offsets(bag.time_offsets, ["truth"]))
    else:
        recordings = _load(paths, bag, ticks_per_rev, truth_frames, slam_stamp_offset_s, notes)
    nominal_geometry = load_robot(robot).nominal if source == "robot" else None
    require_ground_truth(recordings, "validate")
    refuse_still_runs(recordings)  # its errors are 0 mm: no validation at all
    if source == "firmware" and nominal is not None:
        _require_firmware(recordings)
    result = validate_recordings(recordings, geometry, nominal_geometry)
    written: tuple[Path, ...] = ()
    files: dict[Path, Any] = {}
    if plot is not None:
        files.update({
            Path(plot) / name: (lambda r=r: _figure(r, geometry, nominal_geometry))
            for r, name in zip(recordings, _plot_names(recordings), strict=True)
        })  # fmt: skip
    if tum is not None:
        files.update(_tum_files(recordings, Path(tum), geometry, nominal_geometry))
    if files:
        written = tuple(plan.commit(files))
    return replace(
        result,
        load_warnings=tuple(notes) + load_warnings(recordings),
        written=written,
        params_label=str(params) if isinstance(params, (str, Path)) else "the given geometry",
        robot_label=None if robot is None or isinstance(robot, Robot) else str(robot),
        kinematics=kind,
        offsets=offsets,
    )
