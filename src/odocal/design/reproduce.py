"""The paper's simulations and experiment, regenerated from its stated conditions.

- Figs. 3 and 4 (``paper-fig3``): leg heading errors and the systematic share, closed forms.
- Fig. 5 (``paper-fig5``): post-calibration error against the side of the square test track,
  validation on the 4 m x 4 m square CCW.
- Fig. 6: the same with regular octagons, at the squares' total travels (2 ... 40 m).
- Figs. 8 and 9 (``paper-experiment``): share and post-calibration error for the experimental
  robot.
- Sensitivity: Fig. 5 again with a heading instrument of 1 deg standard deviation.
- Tables 1-3: what the model predicts for the experiment (2, 4, 6 m squares, 5 runs per direction;
  validation on the 4 m x 4 m square CCW and the 5 m triangle CW, 5 runs per parameter set), and
  the model's validation error when the robot runs with the paper's own Table 1 parameters.

Every part draws from its own random stream spawned from one seed, so a part's numbers do not
change when another part changes.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from dataclasses import dataclass, replace
from typing import Any

import numpy as np

from ..core.model import MeasurementNoise, Robot
from ..core.parallel import run_tasks
from ..core.stats import ttest_from_stats
from ..presets import PRESETS
from .metrics import LegHeadingCurve, leg_heading_curve
from .recommend import recommend
from .result import ValidationTrack
from .spec import DesignSpec
from .sweep import (
    FAST,
    DesignResult,
    Progress,
    SimulationSettings,
    calibrate_trials,
    calibrated_geometry,
    run_design,
    validation_errors,
)

__all__ = [
    "PAPER",
    "ExperimentTTest",
    "ValidationPrediction",
    "ExperimentPrediction",
    "Reproduction",
    "predict_experiment",
    "reproduce",
    "residual_recommendation",
]

#: The paper's stated numbers (paper-digest.md).
PAPER: dict[str, Any] = {
    "fig4_share_at_4m": 0.91,
    "fig8_share_at_4m": 0.915,
    "chosen_side_m": 4.0,
    "chosen_travel_m": 16.0,
    "worst_travel_m": 2.0,
    "table1": {2.0: (1.1370, 1.0025), 4.0: (1.0247, 1.0016), 6.0: (1.0213, 1.0015)},
    "fig10_square_ccw_m": {2.0: 1.69, 4.0: 0.14, 6.0: 0.09},
    "fig11_triangle_cw_m": {2.0: 2.28, 4.0: 0.24, 6.0: 0.14},
    # (t, p, mean difference m), Student, df = 8
    "table2": {"2 vs 4": (26.855, 0.000, 1.553), "6 vs 4": (-0.873, 0.408, -0.046)},
    "table3": {"2 vs 4": (30.327, 0.000, 2.038), "6 vs 4": (-1.734, 0.121, -0.105)},
}

EXPERIMENT_SIDES_M = (2.0, 4.0, 6.0)
#: Heading-instrument noise (rad) of the sensitivity study: 1 deg per measured final heading. An
#: assumption of odocal (the paper states no accuracy for its instrument).
INSTRUMENT_SIGMA_THETA_DEG = 1.0
SQUARE_SIDES_M = np.arange(1, 21) * 0.5
FIG3_SIDES_M = np.linspace(0.05, 10.0, 200)


@dataclass(frozen=True)
class ExperimentTTest:
    """Predicted distribution of one of the paper's t-tests (Student, 5 vs 5 runs) over trials.

    Attributes
    ----------
    label : str
        '2 vs 4' or '6 vs 4' (side lengths in m).
    median_t, median_p : float
        Medians over the simulated experiments.
    fraction_significant : float
        Share of simulated experiments with two-sided p < 0.05.
    mean_difference_m : float
        Mean over the experiments of the difference of the 5-run mean errors (m).
    paper : tuple
        The paper's (t, p, mean difference m).
    """

    label: str
    median_t: float
    median_p: float
    fraction_significant: float
    mean_difference_m: float
    paper: tuple[float, float, float]


@dataclass(frozen=True)
class ValidationPrediction:
    """One validation track of the experiment (Fig. 10 or Fig. 11; Table 2 or 3).

    Attributes
    ----------
    track : ValidationTrack
    paper_mean_m : tuple of float
        The paper's mean errors for the 2, 4, 6 m calibrations (m).
    mean_m, run_std_m : ndarray, shape (3,)
        Predicted mean and single-run std of the final position error (m), over simulated
        calibrations and 5 runs each.
    with_paper_params_m : ndarray, shape (3,)
        Predicted mean error (m) when the robot runs with the paper's Table 1 parameters.
    ttests : tuple of ExperimentTTest
    """

    track: ValidationTrack
    paper_mean_m: tuple[float, float, float]
    mean_m: np.ndarray
    run_std_m: np.ndarray
    with_paper_params_m: np.ndarray
    ttests: tuple[ExperimentTTest, ...]


@dataclass(frozen=True)
class ExperimentPrediction:
    """The model's prediction of the paper's experiment (Tables 1-3).

    E_b and E_d statistics have shape (3,) for the 2, 4, 6 m squares; ``*_range`` are central
    95 % intervals, shape (3, 2).
    """

    side_m: tuple[float, ...]
    runs_per_direction: int
    trials: int
    E_b_mean: np.ndarray
    E_b_std: np.ndarray
    E_b_range: np.ndarray
    E_d_mean: np.ndarray
    E_d_std: np.ndarray
    E_d_range: np.ndarray
    validations: tuple[ValidationPrediction, ...]


@dataclass(frozen=True)
class Reproduction:
    """Everything ``odocal reproduce`` computes (see the module docstring)."""

    trials: int
    seed: int
    fig3: LegHeadingCurve
    fig5: DesignResult
    fig6: DesignResult
    fig8: LegHeadingCurve
    fig9: DesignResult
    experiment: ExperimentPrediction
    instrument: DesignResult
    precision: PrecisionSweep | None = None


#: Ground-truth instruments from motion capture to a tape measure and protractor:
#: (sigma_xy_m, sigma_theta_deg), one standard deviation per measured coordinate / heading.
INSTRUMENT_LEVELS = (
    (0.001, 0.1),
    (0.002, 0.25),
    (0.005, 0.5),
    (0.01, 1.0),
    (0.02, 2.0),
    (0.03, 3.0),
)


@dataclass(frozen=True)
class PrecisionSweep:
    """How the recommended track size moves with the precision of the ground-truth instrument.

    Attributes
    ----------
    levels : tuple of (sigma_xy_m, sigma_theta_deg)
    recommended_side_m : dict
        ``(method, criterion) -> tuple`` of the recommended side length (m) per level, for
        method 'heading' and 'umbmark' and criterion 'error' and 'residual'.
    """

    levels: tuple[tuple[float, float], ...]
    recommended_side_m: dict


def precision_sweep(
    robot: Robot, levels=INSTRUMENT_LEVELS, side_lengths_m=None, trials: int | None = None
) -> PrecisionSweep:
    """Recommended square size per instrument precision, by the analytic design (first order;
    expected values, so the curve shows the trend without Monte-Carlo scatter). ``trials`` is
    ignored (kept for callers of earlier versions)."""
    from ..core.tracks import polygon
    from .analytic import analytic_design

    side_lengths_m = SQUARE_SIDES_M if side_lengths_m is None else side_lengths_m
    out: dict = {}
    for sxy, sth in levels:
        r = dataclasses.replace(robot, measurement=MeasurementNoise.from_degrees(sxy, sth))
        for method in ("heading", "umbmark"):
            # the candidates of `design --analytic` (squares, 4 m validation square)
            candidates = analytic_design(
                r,
                4,
                side_lengths_m,
                method=method,
                validate_track=polygon(4, 4.0, "ccw"),
                intervals=False,
            )
            for criterion in ("error", "residual"):
                idx = recommend(candidates, 0.05, 0.05, criterion).index
                out.setdefault((method, criterion), []).append(candidates[idx].side_m)
    return PrecisionSweep(tuple(levels), {k: tuple(v) for k, v in out.items()})


def residual_recommendation(result: DesignResult) -> int:
    """Index of the candidate the rule picks when judged on the residual error alone (the
    validation drive without wheel noise)."""
    rec = result.recommendation
    return recommend(
        result.candidates, rec.alpha, rec.tolerance, "residual", paired=result.paired
    ).index


def _experiment_tests(err: np.ndarray, paper: dict) -> tuple[ExperimentTTest, ...]:
    """err: shape (3, trials, runs) errors for the 2, 4, 6 m calibrations."""
    out = []
    mean, std, n = err.mean(axis=2), err.std(axis=2, ddof=1), err.shape[2]
    for label, i in (("2 vs 4", 0), ("6 vs 4", 2)):
        tests = [
            ttest_from_stats(mean[i, m], std[i, m], n, mean[1, m], std[1, m], n, equal_var=True)
            for m in range(err.shape[1])
        ]
        t = np.array([x.t for x in tests])
        p = np.array([x.p_two_sided for x in tests])
        diff = np.array([x.mean_difference for x in tests])
        out.append(
            ExperimentTTest(
                label,
                float(np.median(t)),
                float(np.median(p)),
                float(np.mean(p < 0.05)),
                float(diff.mean()),
                paper[label],
            )
        )
    return tuple(out)


def predict_experiment(
    robot: Robot,
    rng: np.random.Generator,
    trials: int,
    runs_per_direction: int = 5,
    validation_runs: int = 5,
    settings: SimulationSettings = FAST,
) -> ExperimentPrediction:
    """Simulate the paper's experiment ``trials`` times (module docstring)."""
    sides_m = np.array(EXPERIMENT_SIDES_M)
    E_b, E_d = calibrate_trials(
        robot, 4, sides_m, runs_per_direction, trials, "heading", rng, settings
    )
    believed = calibrated_geometry(
        robot, np.repeat(E_b.ravel(), validation_runs), np.repeat(E_d.ravel(), validation_runs)
    )
    paper_params = np.array([PAPER["table1"][s] for s in EXPERIMENT_SIDES_M])
    with_paper = robot.nominal.corrected(
        np.repeat(paper_params[:, 0], trials), np.repeat(paper_params[:, 1], trials)
    )
    validations = []
    for track, paper_key, table_key in (
        (ValidationTrack(4, 4.0, "ccw"), "fig10_square_ccw_m", "table2"),
        (ValidationTrack(3, 5.0, "cw"), "fig11_triangle_cw_m", "table3"),
    ):
        n = E_b.size * validation_runs
        err = validation_errors(robot, believed, track, n, rng, settings)
        err = err.reshape(len(sides_m), trials, validation_runs)
        err_paper = validation_errors(robot, with_paper, track, 3 * trials, rng, settings)
        validations.append(
            ValidationPrediction(
                track,
                tuple(PAPER[paper_key][s] for s in EXPERIMENT_SIDES_M),
                err.mean(axis=(1, 2)),
                err.reshape(len(sides_m), -1).std(axis=1, ddof=1),
                err_paper.reshape(3, trials).mean(axis=1),
                _experiment_tests(err, PAPER[table_key]),
            )
        )

    def rng95(x):
        return np.percentile(x, [2.5, 97.5], axis=1).T

    return ExperimentPrediction(
        tuple(EXPERIMENT_SIDES_M),
        runs_per_direction,
        trials,
        np.nanmean(E_b, axis=1),
        np.nanstd(E_b, axis=1, ddof=1),
        rng95(E_b),
        np.nanmean(E_d, axis=1),
        np.nanstd(E_d, axis=1, ddof=1),
        rng95(E_d),
        tuple(validations),
    )


def reproduce(
    trials: int = 800,
    seed: int = 0,
    settings: SimulationSettings = FAST,
    progress: Progress | None = None,
    meanwhile: Callable[[], object] | None = None,
) -> Reproduction:
    """Regenerate the paper's simulations and predict its experiment (module docstring).
    ``meanwhile``: other work for this process while worker processes compute (run once)."""
    streams = np.random.default_rng(seed).spawn(5)
    squares = DesignSpec(
        sides=(4,),
        side_lengths_m=tuple(SQUARE_SIDES_M),
        trials=trials,
        validation=ValidationTrack(4, 4.0, "ccw"),  # the paper's
    )
    octagons = replace(squares, sides=(8,), side_lengths_m=tuple(SQUARE_SIDES_M * 4 / 8))
    fig5_robot, experiment_robot = PRESETS["paper-fig5"], PRESETS["paper-experiment"]
    instrument_robot = with_heading_instrument(fig5_robot, INSTRUMENT_SIGMA_THETA_DEG)
    # independent pieces (each with its own stream, or none), on the cores there are
    tasks: dict[str, Callable[[], Any]] = {
        "precision": lambda: precision_sweep(fig5_robot),
        "Fig. 5": lambda: run_design(fig5_robot, squares, streams[0], settings=settings),
        "Fig. 6": lambda: run_design(fig5_robot, octagons, streams[1], settings=settings),
        "instrument sensitivity": lambda: run_design(
            instrument_robot, squares, streams[4], settings=settings
        ),
        "Fig. 9": lambda: run_design(experiment_robot, squares, streams[2], settings=settings),
        "Tables 1-3": lambda: predict_experiment(
            experiment_robot, streams[3], trials, settings=settings
        ),
    }
    names = list(tasks)
    finished = 0

    def step(i: int) -> None:
        nonlocal finished
        finished += 1
        if progress is not None:
            progress(finished, len(names), names[i])

    results: dict[str, Any] = dict(
        zip(names, run_tasks(list(tasks.values()), done=step, meanwhile=meanwhile), strict=True)
    )
    return Reproduction(
        trials,
        seed,
        leg_heading_curve(PRESETS["paper-fig3"], FIG3_SIDES_M),
        results["Fig. 5"],
        results["Fig. 6"],
        leg_heading_curve(experiment_robot, FIG3_SIDES_M),
        results["Fig. 9"],
        results["Tables 1-3"],
        results["instrument sensitivity"],
        results["precision"],
    )


def with_heading_instrument(robot: Robot, sigma_theta_deg: float) -> Robot:
    """The same robot whose final headings are measured with ``sigma_theta_deg`` (deg) noise."""
    return dataclasses.replace(
        robot,
        measurement=MeasurementNoise.from_degrees(robot.measurement.sigma_xy_m, sigma_theta_deg),
    )
