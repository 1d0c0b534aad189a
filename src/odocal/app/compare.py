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
    RealComparison,
    compare_real,
    published_agreement,
)
from ..comparison.simulated import SimulatedComparison, compare_simulated
from ..errors import InputError
from ..io.optiodom import load_optiodom_split, read_published
from ..io.outputs import OutputPlan
from .common import RobotSpec, input_paths, resolve_robot

__all__ = ["Comparison", "compare", "comparison_document", "MAX_TRIAL_RUNS"]

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
    published_same_method : list of dict
        Per data set, our geometry against the published one of the same method.
    """

    simulated: SimulatedComparison
    real: RealComparison | None
    published_same_method: list
    written: tuple[Path, ...] = ()


def run_comparison(
    robot,
    trials: int = 200,
    seed: int = 0,
    runs: int = 10,
    travel_m: float | None = None,
    ivanjko_straight_m: float | None = None,
    realdata=None,
    circle_set: str | None = None,
) -> Comparison:
    """The simulated comparison on ``robot`` and, with ``realdata`` (an ``optiodom_diff``
    folder), the held-out comparison on real runs. See ``odocal.calibration.compare``."""
    sim = compare_simulated(
        robot, trials=trials, seed=seed, budget=Budget(runs, travel_m, ivanjko_straight_m)
    )
    if realdata is None:
        return Comparison(sim, None, [])
    datasets, heldout = load_optiodom_split(realdata, circle_set)
    real = compare_real(datasets, heldout, published=read_published(realdata))
    return Comparison(sim, real, published_agreement(real, realdata))


def comparison_document(comparison: Comparison, **extra) -> dict:
    """The JSON document of ``odocal compare --json``."""
    sim, real = comparison.simulated, comparison.real
    doc: dict = dict(extra)
    if sim is not None:
        nom = sim.nominal_final_error_m
        doc["simulated"] = {
            "trials": sim.trials,
            "seed": sim.seed,
            "budget": {"runs": sim.budget_runs, "travel_m": sim.budget_travel_m},
            "validation_track": sim.validation,
            "nominal": {
                "final_error_m": {
                    "mean": float(nom.mean()),
                    "std": float(nom.std(ddof=1)),
                    "p95": float(np.quantile(nom, 0.95)),
                },
                "systematic_final_error_m": sim.nominal_systematic_error_m,
            },
            "methods": [m.summary() for m in sim.methods],
        }
    if real is not None:
        doc["realdata"] = {
            "heldout_runs": real.heldout,
            "nominal_mean_final_error_m": real.nominal_mean_final_error_m,
            "published": real.published,
            "methods": [m.summary() for m in real.methods],
            "failures": real.failures,
            "published_same_method": comparison.published_same_method,
        }
    return doc


def compare(
    robot: RobotSpec = None,
    *,
    params=None,
    trials: int = 200,
    seed: int = 0,
    runs: int = 10,
    travel_m: float | None = None,
    ivanjko_straight_m: float | None = None,
    realdata: str | Path | None = None,
    circle_set: str | None = None,
    plot: str | Path | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> Comparison:
    """Every method of the registry on ``robot`` over ``trials`` Monte-Carlo trials with the same
    budget (``runs`` runs, ``travel_m`` of wheel travel); with ``realdata`` (an optiodom_diff
    folder), also calibrated from real runs and validated on held-out ones; the figure into
    the folder ``plot`` (compare.png)."""
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
    plan = OutputPlan(input_paths(robot, params, realdata))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    r = resolve_robot(robot, params)
    if travel_m is not None:
        turns_m = math.pi * float(np.mean(r.believed_geometry.wheelbase_m))
        if travel_m / runs <= turns_m:
            raise InputError(
                f"--travel {travel_m:g} m is too little for {runs} runs: each run's turns alone "
                f"(a square's four 90 deg turns) take {turns_m:.3g} m of wheel travel",
                field="travel",
            )
    # one progress scale: the simulated methods, then loading and calibrating the real runs
    n_sim = len(METHOD_REGISTRY)
    n_real = (1 + sum(e.real is not None for e in METHOD_REGISTRY)) if realdata else 0

    def stage(offset: int, prefix: str):
        if progress is None:
            return None
        return lambda done, total, what: progress(offset + done, n_sim + n_real, f"{prefix}{what}")

    sim = compare_simulated(
        r,
        trials=trials,
        seed=seed,
        budget=Budget(runs, travel_m, ivanjko_straight_m),
        progress=stage(0, "simulated: "),
    )
    real, agreement = None, []
    if realdata is not None:
        datasets, heldout = load_optiodom_split(realdata, circle_set)
        if progress is not None:
            progress(n_sim + 1, n_sim + n_real, "real runs loaded")
        real = compare_real(
            datasets,
            heldout,
            published=read_published(realdata),
            progress=stage(n_sim + 1, "real: "),
        )
        published = {
            column: read_published(realdata, column, None) or {}
            for column in PUBLISHED_SAME_METHOD.values()
        }
        agreement = published_agreement(real, published)
    written: tuple[Path, ...] = ()
    if plot is not None:
        from ..plot.compare import comparison_figure

        written = tuple(plan.commit({Path(plot) / "compare.png": comparison_figure(sim, real)}))
    return Comparison(sim, real, agreement, written)
