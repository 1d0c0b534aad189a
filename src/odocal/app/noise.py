"""``odocal noise``: the non-systematic error parameters k_r, k_l from repeated straight runs."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from ..calibration.noise import NoiseEstimate, estimate_k
from ..design.metrics import leg_heading_systematic_rad
from ..io.runs_csv import read_runs
from .common import RobotSpec, resolve_robot

__all__ = ["noise"]


def noise(
    runs_csv: str | Path,
    robot: RobotSpec = None,
    *,
    params=None,
    track: str = "out-and-back",
    distance_m: float,
    force: bool = False,
) -> NoiseEstimate:
    """Read RUNS.csv (direction 'fwd') of repeated ``track`` runs ('out-and-back' or 'straight'
    of ``distance_m``) and estimate k (m). The wheelbase is the robot's TRUE one (nominal x E_b);
    the systematic curvature of the forward path comes from ROBOT.yaml's systematic errors.
    ``force``: estimate even when the runs look dominated by a systematic part (a warning)."""
    r = resolve_robot(robot, params)
    notes: list[str] = []
    runs = read_runs(runs_csv, directions=("fwd",), warnings=notes)
    curvature = float(leg_heading_systematic_rad(r, 1.0))  # rad per metre of believed travel
    est = estimate_k(
        runs,
        track,
        distance_m,
        float(r.true_geometry.wheelbase_m),
        r.measurement,
        curvature_rad_per_m=curvature,
        strict=not force,
    )
    return replace(est, warnings=(*notes, *est.warnings)) if notes else est
