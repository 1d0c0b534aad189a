"""``odocal compare``: every calibration method on the same simulated robot (and real runs)."""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..comparison.methods import METHOD_REGISTRY, Budget
from ..comparison.real import (
    PUBLISHED_SAME_METHOD,
    AgreementSummary,
    PublishedAgreement,
    RealComparison,
    compare_real,
    published_agreement,
    summarize_agreement,
)
from ..comparison.simulated import SimulatedComparison, compare_simulated
from ..core.checks import check_int, check_seed
from ..core.model import Robot
from ..errors import InputError
from ..io.optiodom import load_optiodom_split, read_published
from ..io.outputs import OutputPlan
from .common import RobotSpec, input_paths, resolve_robot

__all__ = ["Comparison", "compare", "comparison_document", "MAX_TRIAL_RUNS"]

#: progress callback: (stages done, stages in all, label of the stage just finished)
Progress = Callable[[int, int, str], None]

# Largest trials x runs per method: the work arrays grow with it (2000 x 10 needs about 2 GB).
MAX_TRIAL_RUNS = 20_000


@dataclass(frozen=True)
class Comparison:
    """What ``odocal compare`` computes.

    Attributes
    ----------
    simulated : SimulatedComparison
    real : RealComparison or None
        Only with a real-data folder.
    published_same_method : tuple of PublishedAgreement
        Per data set, our geometry against the published one of the same method.
    written : tuple of Path
        The figure written (``plot``), if any.
    agreement : tuple of AgreementSummary
        ``published_same_method`` per pair of methods: data sets, largest and median difference.
    """

    simulated: SimulatedComparison
    real: RealComparison | None
    published_same_method: tuple[PublishedAgreement, ...] = ()
    written: tuple[Path, ...] = ()
    agreement: tuple[AgreementSummary, ...] = ()


def _simulated_document(sim: SimulatedComparison) -> dict:
    return {
        "trials": sim.trials,
        "seed": sim.seed,
        "budget": {"runs": sim.budget_runs, "travel_m": sim.budget_travel_m},
        "validation_track": sim.validation,
        "nominal": {
            "final_error_m": sim.nominal_final_error.as_dict(),
            "systematic_final_error_m": sim.nominal_systematic_error_m,
        },
        "methods": [m.summary() for m in sim.methods],
    }


def comparison_document(comparison: Comparison, **extra: object) -> dict:
    """The JSON document of ``odocal compare --json`` (``extra``, e.g. the robot and the seed,
    first)."""
    real = comparison.real
    doc: dict = dict(extra)
    doc["simulated"] = _simulated_document(comparison.simulated)
    if real is not None:
        doc["realdata"] = {
            "heldout_runs": list(real.heldout),
            "nominal_mean_final_error_m": real.nominal_mean_final_error_m,
            "published": None if real.published is None else real.published.as_dict(),
            "methods": [m.summary() for m in real.methods],
            "failures": [f.as_dict() for f in real.failures],
            "published_same_method": [a.as_dict() for a in comparison.published_same_method],
        }
    return doc


def _check(trials: int, runs: int) -> None:
    trials, runs = check_int("trials", trials), check_int("runs", runs)
    if trials < 2:
        raise InputError(f"--trials must be >= 2, got {trials}")
    if runs < 3:
        raise InputError(
            f"--runs must be >= 3 (Ivanjko needs straight runs and two spins), got {runs}"
        )
    if trials * runs > MAX_TRIAL_RUNS:
        raise InputError(
            f"--trials x --runs = {trials * runs} is too much work (at most {MAX_TRIAL_RUNS}; "
            "2000 trials of 10 runs take about 2 GB and 5 minutes)"
        )


def _check_travel(robot: Robot, travel_m: float | None, runs: int) -> None:
    if travel_m is None:
        return
    turns_m = math.pi * float(np.mean(robot.believed_geometry.wheelbase_m))
    if travel_m / runs <= turns_m:
        raise InputError(
            f"--travel {travel_m:g} m is too little for {runs} runs: each run's turns alone "
            f"(a square's four 90 deg turns) take {turns_m:.3g} m of wheel travel",
            field="travel",
        )


def _real(
    realdata: str | Path, circle_set: str | None, progress: Progress | None, n_sim: int
) -> tuple[RealComparison, tuple[PublishedAgreement, ...]]:
    """The real-data comparison of the ``optiodom_diff`` folder ``realdata`` and our methods'
    agreement with the published ones; progress stages after the ``n_sim`` simulated ones."""
    n_real = 1 + sum(e.real is not None for e in METHOD_REGISTRY)
    datasets, heldout = load_optiodom_split(realdata, circle_set)
    if progress is not None:
        progress(n_sim + 1, n_sim + n_real, "real runs loaded")
    real = compare_real(
        datasets,
        heldout,
        published=read_published(realdata),
        progress=_stage(progress, n_sim + 1, n_sim + n_real, "real: "),
    )
    published = {
        column: read_published(realdata, column, None) or {}
        for column in PUBLISHED_SAME_METHOD.values()
    }
    return real, published_agreement(real, published)


def _stage(progress: Progress | None, offset: int, total: int, prefix: str) -> Progress | None:
    """``progress`` for one stage of a longer run: its steps after ``offset`` of ``total``."""
    if progress is None:
        return None
    return lambda done, _, what: progress(offset + done, total, f"{prefix}{what}")


def compare(
    robot: RobotSpec = None,
    *,
    params: str | Path | None = None,
    trials: int = 200,
    seed: int = 0,
    runs: int = 10,
    travel_m: float | None = None,
    ivanjko_straight_m: float | None = None,
    realdata: str | Path | None = None,
    circle_set: str | None = None,
    plot: str | Path | None = None,
    progress: Progress | None = None,
) -> Comparison:
    """Every method of the registry on ``robot`` over ``trials`` Monte-Carlo trials with the same
    budget (``runs`` runs, ``travel_m`` of wheel travel); with ``realdata`` (an optiodom_diff
    folder), also calibrated from real runs and validated on held-out ones; the figure into
    the folder ``plot`` (compare.png)."""
    _check(trials, runs)
    seed = check_seed("seed", seed)
    plan = OutputPlan(input_paths(robot, params, realdata))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    r = resolve_robot(robot, params)
    _check_travel(r, travel_m, runs)
    # one progress scale: the simulated methods, then loading and calibrating the real runs
    n_sim = len(METHOD_REGISTRY)
    n_real = (1 + sum(e.real is not None for e in METHOD_REGISTRY)) if realdata else 0
    sim = compare_simulated(
        r,
        trials=trials,
        seed=seed,
        budget=Budget(runs, travel_m, ivanjko_straight_m),
        progress=_stage(progress, 0, n_sim + n_real, "simulated: "),
    )
    real: RealComparison | None = None
    agreement: tuple[PublishedAgreement, ...] = ()
    if realdata is not None:
        real, agreement = _real(realdata, circle_set, progress, n_sim)
    summary = summarize_agreement(agreement)
    written: tuple[Path, ...] = ()
    if plot is not None:  # written last, once every number is computed
        from ..plot.compare import comparison_figure

        written = tuple(plan.commit({Path(plot) / "compare.png": comparison_figure(sim, real)}))
    return Comparison(sim, real, agreement, written, summary)
