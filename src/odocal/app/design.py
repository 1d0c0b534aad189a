"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from ..core.model import MeasurementNoise
from ..core.plausibility import track_size_problem
from ..design.analytic import analytic_design_result
from ..design.result import DesignSpec
from ..design.robust import RangeDesign, range_design, unknown_errors
from ..design.sweep import DesignResult, Progress, SimulationSettings, design_json, run_design
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.robot_file import load_params, load_robot
from ..presets import PRESETS
from .common import RobotSpec, input_paths, resolve_robot, robot_label

if TYPE_CHECKING:
    from .measured import MeasuredRobot

__all__ = ["ENGINES", "MAX_SIMULATED_RUNS", "DesignRun", "design"]

ENGINES = ("monte-carlo", "analytic")

# Largest number of simulated test runs per direction (candidates x trials x runs) a Monte-Carlo
# sweep may ask for: about 1 GB of work arrays at the most.
MAX_SIMULATED_RUNS = 20_000_000


@dataclass(frozen=True)
class DesignRun:
    """A design and how it was made (engine, seed, robot), plus the figures written.

    ``result`` is a :class:`~odocal.design.sweep.DesignResult`, or a
    :class:`~odocal.design.robust.RangeDesign` when the robot's errors were not given (a design
    over plausible errors); both have ``recommended`` and ``warnings``. ``spec`` is the design
    spec as run (sizes scaled to the robot where they were left open); ``notes`` say what was
    assumed (e.g. a perfect instrument); ``measured``: the robot measured from recordings
    (``robot_from``), if any.
    """

    result: DesignResult | RangeDesign
    engine: str
    seed: int | None
    robot: str
    written: tuple[Path, ...] = ()
    spec: DesignSpec | None = None
    scaled: bool = False
    notes: tuple[str, ...] = ()
    measured: MeasuredRobot | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        return tuple(self.result.warnings)

    def as_dict(self) -> dict:
        """The JSON of ``odocal design --json``."""
        extra = {"seed": self.seed, "robot": self.robot, "engine": self.engine}
        extra |= {"sizes_scaled_to_robot": self.scaled, "notes": list(self.notes)}
        if self.measured is not None:
            extra["robot_measured"] = self.measured.as_dict()
        if isinstance(self.result, RangeDesign):
            return self.result.as_dict() | extra
        return design_json(self.result, **extra)


def _robot_from(paths, robot, params, measurement: MeasurementNoise | None) -> MeasuredRobot:
    """The robot measured from recordings: nominal from ``robot`` (ROBOT.yaml) or the
    recordings' metadata; the instrument ``measurement`` (else ROBOT.yaml's, else the tracker's
    jitter)."""
    from ..io.recordings import load_recordings, require_ground_truth  # only for --robot-from
    from .measured import measure_robot

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
    error_range: bool | None = None,
    robot_from: Sequence[str | Path] | None = None,
    measurement: MeasurementNoise | None = None,
) -> DesignRun:
    """Run the design procedure for ``robot`` (default: the paper's Fig. 5 conditions) over the
    candidates of ``spec``, by Monte Carlo with common random numbers (seeded by ``seed``) or
    first-order propagation (``engine='analytic'``); write the figures into the folder ``plot``.

    Sizes ``spec`` leaves open (None) are scaled to the robot's wheelbase
    (:func:`odocal.design.result.scaled_sizes`). ``error_range`` (default: when the robot gives
    no systematic or no non-systematic errors) designs over the typical ranges of the unknown
    errors instead (:mod:`odocal.design.robust`; analytic engine).

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
    scaled = spec.side_lengths_m is None or spec.validation is None
    spec = spec.for_wheelbase(float(r.nominal.wheelbase_m))
    assert spec.side_lengths_m is not None and spec.validation is not None
    b = float(r.believed_geometry.wheelbase_m)
    # the whole sweep (or the validation track) smaller than the robot: a unit slip
    for what, side in (("largest candidate", max(spec.side_lengths_m)), ("validation", None)):
        problem = track_size_problem(b, spec.validation.side_m if side is None else side, what)
        if problem:
            raise InputError(problem)
    notes = []
    if r.measurement.is_zero and not (robot is None or str(robot) in PRESETS) and not robot_from:
        notes.append(
            "no instrument noise in ROBOT.yaml: the design assumes end poses measured "
            "perfectly; a tape measure and a protractor are about 1 cm and 1 deg "
            "(measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1}), which moves the answer "
            "to larger tracks"
        )
    unknown = unknown_errors(r)
    if error_range is None:
        error_range = bool(unknown)
    written: tuple[Path, ...] = ()
    if error_range:
        result: DesignResult | RangeDesign = range_design(
            r,
            sides=spec.sides,
            side_lengths_m=spec.side_lengths_m,
            runs_per_direction=spec.runs_per_direction,
            method=spec.method,
            validation=spec.validation,
            tolerance=tolerance,
            unknown=unknown or ("systematic", "nonsystematic"),
            progress=progress,
        )
        engine = "analytic"
        if plot is not None:
            from ..plot.design import range_figures

            figs = range_figures(result)
            written = tuple(plan.commit({Path(plot) / name: fig for name, fig in figs.items()}))
        return DesignRun(result, engine, None, label, written, spec, scaled, tuple(notes), measured)
    common = dict(
        sides=spec.sides,
        side_lengths_m=np.asarray(spec.side_lengths_m, dtype=float),
        runs_per_direction=spec.runs_per_direction,
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
            r,
            np.random.default_rng(seed),
            trials=spec.trials,
            settings=settings,
            progress=progress,
            **common,
        )
    if plot is not None:
        from ..plot.design import design_figures

        figs = design_figures(result)
        written = tuple(plan.commit({Path(plot) / name: fig for name, fig in figs.items()}))
    return DesignRun(
        result,
        engine,
        seed if engine == "monte-carlo" else None,
        label,
        written,
        spec,
        scaled,
        tuple(notes),
        measured,
    )
