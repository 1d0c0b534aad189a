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
from ..io.bag_slam import load_slam_bag
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from ..io.robot_file import load_params, load_robot

__all__ = ["Validation", "validate", "validate_recordings"]


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
            "params": self.params.as_dict(),
        }
        if self.written:
            out["plots"] = [str(p) for p in self.written]
        return out


def validate_recordings(
    recordings: Sequence[Recording], params: WheelGeometry, nominal: WheelGeometry | None = None
) -> Validation:
    """Evaluate ``params`` and the nominal geometry on each run.

    The nominal geometry of a run is ``nominal`` if given, else the run's ``ran_with``.
    """
    require_ground_truth(list(recordings), "validate")
    runs, known = [], True
    for r in recordings:
        row = {"path": r.name, **evaluate(r, params)}
        nom = nominal or r.ran_with
        if nom is None:
            known = False
            row.update({f"nominal_{k}": None for k in list(row) if k != "path"})
        else:
            row.update({f"nominal_{k}": v for k, v in evaluate(r, nom).items()})
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
    plot: str | Path | None = None,
    ticks_per_rev: float | None = None,
    bag_options: dict | None = None,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
) -> Validation:
    """Dead-reckon the runs in ``paths`` with ``params`` (PARAMS.yaml or a geometry) and with the
    nominal geometry (ROBOT.yaml's, else each run's own ran-with parameters); with ``plot``, one
    PNG per run in that folder. With ``truth_frames`` (bags whose truth is a SLAM pose on /tf),
    the errors are measured at the SLAM's update instants only (docs/slam-truth.md)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
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
            for p in paths
        ]
    else:
        recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, **(bag_options or {}))
    nominal = load_robot(robot).nominal if robot else None
    result = validate_recordings(recordings, geometry, nominal)
    warnings = tuple(
        f"{r.name}: {w}" for r in recordings for w in (r.meta.get("warnings", ()) if r.meta else ())
    )
    written: tuple[Path, ...] = ()
    if plot is not None:
        from ..plot.trajectory import run_figure

        def figure(r: Recording):
            trajs = {}
            nom = nominal or r.ran_with
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
