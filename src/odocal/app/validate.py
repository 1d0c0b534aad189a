"""``odocal validate``: how well given parameters dead-reckon recorded runs, against nominal."""

from __future__ import annotations

import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry
from ..core.odometry import dead_reckon, evaluate
from ..core.recording import Recording
from ..errors import InputError
from ..io.bag_slam import load_slam_bag
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, refuse_repeated, require_ground_truth
from ..io.robot_file import load_params, load_robot

__all__ = ["NOMINAL_SOURCES", "Validation", "validate", "validate_recordings"]


@dataclass(frozen=True)
class Validation:
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

    runs: list
    params: WheelGeometry
    nominal_known: bool
    nominal_source: str = "firmware"
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()

    def as_dict(self) -> dict:
        def mean(key):
            vals = [r[key] for r in self.runs if r[key] is not None]
            return float(np.mean(vals)) if vals else None

        out = {
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
        if self.written:
            out["plots"] = [str(p) for p in self.written]
        return out


NOMINAL_SOURCES = ("robot", "firmware")


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
    return Validation(runs, params, known, source)


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


def validate(
    paths: Sequence[str | Path],
    params: str | Path | WheelGeometry,
    *,
    robot=None,
    nominal: str | None = None,
    plot: str | Path | None = None,
    ticks_per_rev: float | None = None,
    bag_options: dict | None = None,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
) -> Validation:
    """Dead-reckon the runs in ``paths`` with ``params`` (PARAMS.yaml or a geometry) and with the
    nominal geometry; with ``plot``, one PNG per run in that folder.

    ``nominal`` chooses the "nominal" column: 'robot' (ROBOT.yaml's nominal geometry; needs
    ``robot``), 'firmware' (each run's own ran-with parameters, e.g. an OptiOdom data set's
    firmware values; every run must carry them), or None: 'robot' when ``robot`` is given, else
    each run's firmware values where it has them (the result's ``nominal_source`` says which:
    'robot', 'firmware' or 'unknown'). With ``truth_frames`` (bags whose truth is a SLAM pose on
    /tf), the errors are measured at the SLAM's update instants only (docs/slam-truth.md)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    chosen = nominal is not None
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
    inputs = [*map(Path, paths)]
    for extra in (params, robot):
        if isinstance(extra, (str, Path)) and Path(extra).exists():
            inputs.append(Path(extra))
    plan = OutputPlan(inputs)
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    geometry = params if isinstance(params, WheelGeometry) else load_params(params)
    notes: list[str] = []
    if truth_frames is not None:
        opts = bag_options or {}
        recordings = [
            load_slam_bag(
                p,
                truth_frames,
                joint_topic=opts.get("joint_topic"),
                right_joint=opts.get("right_joint"),
                left_joint=opts.get("left_joint"),
                ticks_per_rev=ticks_per_rev,
                stamp_offset_s=slam_stamp_offset_s,
            ).recording
            for p in refuse_repeated(paths)
        ]
    else:
        recordings = load_recordings(
            paths, ticks_per_rev=ticks_per_rev, warnings=notes, **(bag_options or {})
        )
    nominal_geometry = load_robot(robot).nominal if nominal == "robot" else None
    require_ground_truth(recordings, "validate")
    if nominal == "firmware" and chosen:
        missing = [r.name for r in recordings if r.ran_with is None]
        if missing:
            raise InputError(
                "--nominal firmware: this run does not say which parameters it ran with (give "
                "them in its header, or --robot ROBOT.yaml with --nominal robot)",
                missing[0],
            )
    result = validate_recordings(recordings, geometry, nominal_geometry)
    warnings = tuple(notes) + tuple(
        f"{r.name}: {w}" for r in recordings for w in (r.meta.get("warnings", ()) if r.meta else ())
    )
    written: tuple[Path, ...] = ()
    if plot is not None:
        from ..plot.trajectory import run_figure

        def figure(r: Recording):
            trajs = {}
            nom = nominal_geometry or r.ran_with
            if nom is not None:
                trajs["nominal"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, nom)
            trajs["calibrated"] = dead_reckon(
                r.wheel_angle_right_rad, r.wheel_angle_left_rad, geometry
            )
            title = Path(r.name).name + (f" ({r.label})" if r.label else "")
            valid = r.meta.get("truth_samples") if r.meta else None
            if valid is not None:  # truth only at these samples (a SLAM pose at its updates)
                return run_figure(title, r.ground_truth[valid], trajs, truth_marker="o")
            return run_figure(title, r.ground_truth, trajs)

        figures = {
            Path(plot) / name: (lambda r=r: figure(r))
            for r, name in zip(recordings, _plot_names(recordings), strict=True)
        }
        written = tuple(plan.commit(figures))
    return Validation(
        result.runs, geometry, result.nominal_known, result.nominal_source, warnings, written
    )
