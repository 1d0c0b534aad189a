"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..core.checks import check_seed
from ..core.model import MeasurementNoise, Robot
from ..core.plausibility import track_size_problem
from ..design.analytic import analytic_design_result
from ..design.robust import RangeDesign, range_design, unknown_errors
from ..design.spec import ENGINES, DesignSpec, Engine
from ..design.sweep import DesignResult, Progress, SimulationSettings, design_json, run_design
from ..errors import InputError, ModelError
from ..io.outputs import OutputPlan
from ..io.robot_file import load_params
from ..presets import PRESETS
from .common import RobotSpec, input_paths, optional_robot, resolve_robot, robot_label
from .text import Presented, emits_warnings

if TYPE_CHECKING:
    from .measured import MeasuredRobot

__all__ = ["ENGINES", "MAX_SIMULATED_RUNS", "DesignRun", "design"]

# Largest number of simulated test runs per direction (candidates x trials x runs) a Monte-Carlo
# sweep may ask for: about 1 GB of work arrays at the most.
MAX_SIMULATED_RUNS = 20_000_000


@dataclass(frozen=True)
class DesignRun(Presented):
    """A design and how it was made (engine, seed, robot), plus the figures written.

    ``result`` is a :class:`~odocal.design.sweep.DesignResult`, or a
    :class:`~odocal.design.robust.RangeDesign` when the robot's errors were not given (a design
    over plausible errors); both have ``recommended`` and ``warnings``. ``spec`` is the design
    spec as run (sizes scaled to the robot where they were left open); ``notes`` say what was
    assumed (e.g. a perfect instrument); ``measured``: the robot measured from recordings
    (``robot_from``), if any.
    """

    result: DesignResult | RangeDesign
    engine: Engine
    seed: int | None
    robot: str
    written: tuple[Path, ...] = ()
    spec: DesignSpec | None = None
    scaled: bool = False
    notes: tuple[str, ...] = ()
    measured: MeasuredRobot | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        """The design's warnings (those of its result)."""
        return tuple(self.result.warnings)

    def text(self) -> str:
        """The text of ``odocal design``."""
        from .design_text import design_text

        return design_text(
            self.result,
            self.robot,
            seed=self.seed,
            measured=self.measured,
            notes=self.notes,
            written=self.written,
        )

    def as_dict(self) -> dict:
        """The JSON of ``odocal design --json``."""
        extra: dict[str, object] = {"seed": self.seed, "robot": self.robot, "engine": self.engine}
        extra |= {"sizes_scaled_to_robot": self.scaled, "notes": list(self.notes)}
        if self.measured is not None:
            extra["robot_measured"] = self.measured.as_dict()
        if isinstance(self.result, RangeDesign):
            return self.result.as_dict() | extra
        return design_json(self.result, **extra)


def _robot_from(
    paths: Sequence[str | Path],
    robot: RobotSpec,
    params: str | Path | None,
    measurement: MeasurementNoise | None,
) -> MeasuredRobot:
    """The robot measured from recordings: nominal from ``robot`` (ROBOT.yaml) or the
    recordings' metadata; the instrument ``measurement`` (else ROBOT.yaml's, else the tracker's
    jitter)."""
    from ..io.recordings import load_recordings, require_ground_truth  # only for --robot-from
    from .measured import measure_robot

    recordings = load_recordings(list(paths))
    require_ground_truth(recordings, "--robot-from")
    base = optional_robot(robot) if robot else None
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


def _check_work(spec: DesignSpec, engine: str) -> None:
    """The engine is one of :data:`ENGINES`; a Monte-Carlo sweep stays under the work cap."""
    if engine not in ENGINES:
        raise InputError(f"engine must be one of {', '.join(ENGINES)}, got {engine!r}")
    if engine == "monte-carlo" and spec.simulated_runs > MAX_SIMULATED_RUNS:
        raise InputError(
            f"{spec.simulated_runs} simulated runs per direction is too many (at most "
            f"{MAX_SIMULATED_RUNS}); reduce --trials or the number of side lengths"
        )


def _the_robot(
    robot: RobotSpec,
    params: str | Path | None,
    robot_from: Sequence[str | Path] | None,
    measurement: MeasurementNoise | None,
) -> tuple[Robot, str, MeasuredRobot | None]:
    """The robot designed for, its label, and the measured robot (``robot_from``) or None."""
    if robot_from:
        measured = _robot_from(robot_from, robot, params, measurement)
        label = "robot measured from " + ", ".join(str(p) for p in robot_from)
        return measured.robot, label, measured
    r = resolve_robot(robot, params)
    if measurement is not None:
        r = dataclasses.replace(r, measurement=measurement)
    return r, robot_label(robot, params), None


def _check_sizes(robot: Robot, spec: DesignSpec) -> None:
    """The whole sweep (or the validation track) smaller than the robot: a unit slip."""
    b = float(robot.believed_geometry.wheelbase_m)
    for what, side in (
        ("largest candidate", max(spec.lengths_m)),
        ("validation", spec.validation_track.side_m),
    ):
        problem = track_size_problem(b, float(side), what)
        if problem:
            raise InputError(problem)


def _notes(robot: Robot, given: RobotSpec, measured: bool) -> tuple[str, ...]:
    """What the design assumes that the user may not know it assumes."""
    if robot.measurement.is_zero and not (given is None or str(given) in PRESETS) and not measured:
        return (
            "no instrument noise in ROBOT.yaml: the design assumes end poses measured "
            "perfectly; a tape measure and a protractor are about 1 cm and 1 deg "
            "(measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1}), which moves the answer "
            "to larger tracks",
        )
    return ()


def _run_engine(
    robot: Robot,
    spec: DesignSpec,
    engine: Engine,
    seed: int,
    reference_sim: bool,
    progress: Progress | None,
) -> DesignResult:
    """The design of ``robot`` by ``engine`` (the errors as given)."""
    if engine == "analytic":
        return analytic_design_result(robot, spec)
    settings = SimulationSettings.reference() if reference_sim else SimulationSettings()
    return run_design(
        robot, spec, np.random.default_rng(seed), settings=settings, progress=progress
    )


def _figures(result: DesignResult | RangeDesign) -> dict[str, Any]:
    """File name -> figure of a design."""
    if isinstance(result, RangeDesign):
        from ..plot.design import range_figures

        return range_figures(result)
    from ..plot.design import design_figures

    return design_figures(result)


@emits_warnings
def design(
    robot: RobotSpec = None,
    spec: DesignSpec | None = None,
    *,
    params: str | Path | None = None,
    engine: Engine = "monte-carlo",
    seed: int = 0,
    reference_sim: bool = False,
    plot: str | Path | None = None,
    progress: Progress | None = None,
    error_range: bool | None = None,
    robot_from: Sequence[str | Path] | None = None,
    measurement: MeasurementNoise | None = None,
) -> DesignRun:
    """Run the design procedure for ``robot`` (default: the paper's Fig. 5 conditions) over the
    candidates of ``spec`` (with its rule: alpha, tolerance, criterion), by Monte Carlo with
    common random numbers (seeded by ``seed``) or first-order propagation
    (``engine='analytic'``); write the figures into the folder ``plot``.

    Sizes ``spec`` leaves open (None) are scaled to the robot's wheelbase
    (:func:`odocal.design.spec.scaled_sizes`). ``error_range`` (default: when the robot gives
    no systematic or no non-systematic errors) designs over the typical ranges of the unknown
    errors instead (:mod:`odocal.design.robust`; analytic engine).

    ``robot_from``: recorded runs to measure the robot from (systematic errors, k and, unless
    ``measurement`` or ROBOT.yaml give it, the tracker's precision; :func:`measure_robot`);
    ``robot`` then only gives the nominal geometry. ``measurement``: the instrument's noise per
    measured final pose, replacing the robot's."""
    spec = spec or DesignSpec()
    if not isinstance(spec, DesignSpec):
        raise ModelError(f"spec must be a DesignSpec, got {spec!r}")
    seed = check_seed("seed", seed)
    _check_work(spec, engine)
    plan = OutputPlan(input_paths(robot, params, *(robot_from or ())))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    r, label, measured = _the_robot(robot, params, robot_from, measurement)
    scaled = spec.scaled
    spec = spec.for_wheelbase(float(r.nominal.wheelbase_m))
    _check_sizes(r, spec)
    notes = _notes(r, robot, bool(robot_from))
    unknown = unknown_errors(r)
    result: DesignResult | RangeDesign
    over_ranges = bool(unknown) if error_range is None else error_range
    if over_ranges:
        unknown = unknown or ("systematic", "nonsystematic")
        result = range_design(r, spec, unknown=unknown, progress=progress)
        engine = "analytic"
    else:
        result = _run_engine(r, spec, engine, seed, reference_sim, progress)
    written: tuple[Path, ...] = ()
    if plot is not None:
        figs = _figures(result)
        written = tuple(plan.commit({Path(plot) / name: fig for name, fig in figs.items()}))
    run_seed = seed if engine == "monte-carlo" else None
    return DesignRun(result, engine, run_seed, label, written, spec, scaled, notes, measured)
