"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ..core.model import MeasurementNoise
from ..design.analytic import analytic_design_result
from ..design.result import DesignSpec
from ..design.sweep import DesignResult, Progress, SimulationSettings, design_json, run_design
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from ..io.robot_file import load_params, load_robot
from .common import RobotSpec, input_paths, resolve_robot, robot_label
from .measured import MeasuredRobot, measure_robot

__all__ = ["ENGINES", "MAX_SIMULATED_RUNS", "DesignRun", "design"]

ENGINES = ("monte-carlo", "analytic")

# Largest number of simulated test runs per direction (candidates x trials x runs) a Monte-Carlo
# sweep may ask for: about 1 GB of work arrays at the most.
MAX_SIMULATED_RUNS = 20_000_000


@dataclass(frozen=True)
class DesignRun:
    """A design and how it was made (engine, seed, robot), plus the figures written.
    ``measured``: the robot measured from recordings (``robot_from``), if any."""

    result: DesignResult
    engine: str
    seed: int | None
    robot: str
    written: tuple[Path, ...] = ()
    measured: MeasuredRobot | None = None

    def as_dict(self) -> dict:
        """The JSON of ``odocal design --json`` (with ``robot_measured`` for --robot-from)."""
        out = design_json(self.result, seed=self.seed, robot=self.robot, engine=self.engine)
        if self.measured is not None:
            out["robot_measured"] = self.measured.as_dict()
        return out


def _robot_from(paths, robot, params, measurement: MeasurementNoise | None) -> MeasuredRobot:
    """The robot measured from recordings: nominal from ``robot`` (ROBOT.yaml) or the
    recordings' metadata; the instrument ``measurement`` (else ROBOT.yaml's, else the tracker's
    jitter)."""
    recordings = load_recordings(list(paths))
    require_ground_truth(recordings, "--robot-from")
    base = load_robot(robot) if robot else None
    if base is not None:
        nominal = base.nominal
        if measurement is None and not base.measurement.is_zero:
            measurement = base.measurement
    else:
        known = [r.ran_with for r in recordings if r.ran_with is not None]
        if not known:
            raise InputError("--robot-from: the nominal geometry is unknown; give --robot")
        nominal = max(set(known), key=known.count)
    measured = measure_robot(recordings, nominal, measurement=measurement)
    if params is not None:
        measured = replace(measured, robot=measured.robot.with_believed(load_params(params)))
    return measured


def design(
    robot: RobotSpec = None,
    spec: DesignSpec | None = None,
    *,
    params=None,
    engine: str = "monte-carlo",
    seed: int = 0,
    alpha: float = 0.05,
    tolerance: float = 0.05,
    criterion: str = "error",
    reference_sim: bool = False,
    plot: str | Path | None = None,
    progress: Progress | None = None,
    robot_from: Sequence[str | Path] | None = None,
    measurement: MeasurementNoise | None = None,
) -> DesignRun:
    """Run the design procedure for ``robot`` (default: the paper's Fig. 5 conditions) over the
    candidates of ``spec``, by Monte Carlo (seeded by ``seed``) or first-order propagation
    (``engine='analytic'``); write the figures into the folder ``plot``.

    ``robot_from``: recorded runs to measure the robot from (systematic errors, k and, unless
    ``measurement`` or ROBOT.yaml give it, the tracker's precision; :func:`measure_robot`);
    ``robot`` then only gives the nominal geometry. ``measurement``: the instrument's noise per
    measured final pose, replacing the robot's."""
    spec = spec or DesignSpec()
    if engine not in ENGINES:
        raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "monte-carlo" and spec.simulated_runs > MAX_SIMULATED_RUNS:
        raise InputError(
            f"{spec.simulated_runs} simulated runs per direction is too many (at most "
            f"{MAX_SIMULATED_RUNS}); reduce --trials or the number of side lengths"
        )
    plan = OutputPlan(input_paths(robot, params, *(robot_from or ())))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    measured = None
    if robot_from:
        measured = _robot_from(robot_from, robot, params, measurement)
        r = measured.robot
        label = "robot measured from " + ", ".join(str(p) for p in robot_from)
    else:
        r = resolve_robot(robot, params)
        if measurement is not None:
            r = dataclasses.replace(r, measurement=measurement)
        label = robot_label(robot, params)
    common = dict(
        sides=spec.sides,
        side_lengths_m=np.asarray(spec.side_lengths_m, dtype=float),
        runs_per_direction=spec.runs_per_direction,
        trials=spec.trials,
        method=spec.method,
        validation=spec.validation,
        alpha=alpha,
        tolerance=tolerance,
        criterion=criterion,
    )
    if engine == "analytic":
        result = analytic_design_result(r, **common)
    else:
        settings = SimulationSettings.reference() if reference_sim else SimulationSettings()
        result = run_design(
            r, np.random.default_rng(seed), settings=settings, progress=progress, **common
        )
    written: tuple[Path, ...] = ()
    if plot is not None:
        from ..plot.design import design_figures

        figs = design_figures(result)
        written = tuple(plan.commit({Path(plot) / name: fig for name, fig in figs.items()}))
    return DesignRun(result, engine, seed, label, written, measured)
