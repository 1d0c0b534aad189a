"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..design.analytic import analytic_design_result
from ..design.result import DesignSpec
from ..design.sweep import DesignResult, Progress, SimulationSettings, design_json, run_design
from ..errors import InputError
from ..io.outputs import OutputPlan
from .common import RobotSpec, input_paths, resolve_robot, robot_label

__all__ = ["ENGINES", "MAX_SIMULATED_RUNS", "DesignRun", "design"]

ENGINES = ("monte-carlo", "analytic")

# Largest number of simulated test runs per direction (candidates x trials x runs) a Monte-Carlo
# sweep may ask for: about 1 GB of work arrays at the most.
MAX_SIMULATED_RUNS = 20_000_000


@dataclass(frozen=True)
class DesignRun:
    """A design and how it was made (engine, seed, robot), plus the figures written."""

    result: DesignResult
    engine: str
    seed: int | None
    robot: str
    written: tuple[Path, ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal design --json``."""
        return design_json(self.result, seed=self.seed, robot=self.robot, engine=self.engine)


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
) -> DesignRun:
    """Run the design procedure for ``robot`` (default: the paper's Fig. 5 conditions) over the
    candidates of ``spec``, by Monte Carlo (seeded by ``seed``) or first-order propagation
    (``engine='analytic'``); write the figures into the folder ``plot``."""
    spec = spec or DesignSpec()
    if engine not in ENGINES:
        raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "monte-carlo" and spec.simulated_runs > MAX_SIMULATED_RUNS:
        raise InputError(
            f"{spec.simulated_runs} simulated runs per direction is too many (at most "
            f"{MAX_SIMULATED_RUNS}); reduce --trials or the number of side lengths"
        )
    plan = OutputPlan(input_paths(robot, params))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    r = resolve_robot(robot, params)
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
    return DesignRun(
        result,
        engine,
        seed,
        robot_label(robot, params),
        written,
    )
