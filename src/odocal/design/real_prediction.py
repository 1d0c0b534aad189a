"""What the design predicts for the real experiment (:mod:`odocal.design.real_experiment`): the
robot model measured from the runs drives the paper's procedure, n CW + n CCW runs on each
candidate square and a heading calibration, validated by replaying the held-out runs' recorded
wheel rotations through the model (:mod:`odocal.core.replay`), which is exactly what the real
validation does with the real robot. Candidates: a sweep of sizes (equal runs per direction; the
design's preference) and the two real configurations (their real run counts; the predicted
errors and the predicted paired t-test)."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..core.model import Robot, WheelGeometry
from ..core.recording import Recording
from ..core.replay import chunk_rotations, replay_final_errors
from .metrics import leg_heading_noise_rad, leg_heading_systematic_rad, systematic_share
from .recommend import Recommendation, recommend
from .result import Candidate, ErrorSummary
from .sweep import FAST, SimulationSettings, calibrate_trials

__all__ = ["REPLAY_CHUNK_M", "PredictedTTest", "Prediction", "predict"]

#: Wheel travel of one replay chunk (m): the deterministic part is exact at any size, the noise
#: covariance off by O(1/K^2).
REPLAY_CHUNK_M = 0.05


@dataclass(frozen=True)
class PredictedTTest:
    """The predicted paired t-test of the two real configurations (first side minus second)
    over the simulated experiments: median t and p, the shares of experiments with p < 0.05
    (either way, the first side better, the second better), the share where the first side is
    worse, and the mean difference (m) with its central 95 % range."""

    first_side_m: float
    second_side_m: float
    median_t: float
    median_p: float
    fraction_significant: float
    fraction_first_significantly_better: float
    fraction_second_significantly_better: float
    fraction_first_worse: float
    mean_difference_m: float
    difference_ci95_m: tuple[float, float]
    kind: str = "paired"

    def as_dict(self) -> dict:
        """JSON-ready: the two sides (m), the median statistics, the shares and the mean difference
        (m) with its range."""
        return {
            "first_side_m": self.first_side_m,
            "second_side_m": self.second_side_m,
            "kind": self.kind,
            "median_t": self.median_t,
            "median_p": self.median_p,
            "fraction_significant": self.fraction_significant,
            "fraction_first_significantly_better": self.fraction_first_significantly_better,
            "fraction_second_significantly_better": self.fraction_second_significantly_better,
            "fraction_first_worse": self.fraction_first_worse,
            "mean_difference_m": self.mean_difference_m,
            "difference_ci95_m": list(self.difference_ci95_m),
        }


@dataclass(frozen=True)
class Prediction:
    """What the design (the model with the measured robot) predicts.

    Attributes
    ----------
    robot : Robot
        The model robot (nominal, systematic errors, k, instrument), running with ``reference``.
    sweep : tuple of Candidate
        Candidate squares with ``runs_per_direction`` runs each; validation error = mean
        held-out error of a replay (module docstring).
    recommendation : Recommendation
        The design's rule over ``sweep``.
    real : dict of float to Candidate
        Side (m) -> Candidate with the real run counts.
    floor, uncalibrated : ErrorSummary
        Mean held-out error with the TRUE geometry, and with the reference (uncalibrated).
    ttest : PredictedTTest
        Predicted paired t-test of the two real configurations (first side minus second).
    trials, runs_per_direction : int
    """

    robot: Robot
    sweep: tuple[Candidate, ...]
    recommendation: Recommendation
    real: dict[float, Candidate]
    floor: ErrorSummary
    uncalibrated: ErrorSummary
    ttest: PredictedTTest
    trials: int
    runs_per_direction: int

    @property
    def preferred(self) -> Candidate:
        """The candidate the recommendation rule picks from the sweep."""
        return self.sweep[self.recommendation.index]


def _candidates(
    robot: Robot,
    sides_m,
    n: int,
    trials: int,
    rng: np.random.Generator,
    chunks: Sequence[np.ndarray],
    settings: SimulationSettings,
) -> tuple[list[Candidate], np.ndarray]:
    """Simulated calibrations on squares of ``sides_m`` (n runs per direction) validated by
    replaying the held-out chunks; returns candidates and per-run errors (C, runs, T)."""
    sides_m = np.asarray(sides_m, dtype=float)
    E_b, E_d = calibrate_trials(robot, 4, sides_m, n, trials, "heading", rng, settings)
    ok = np.isfinite(E_b) & np.isfinite(E_d)
    geos = robot.believed_geometry.corrected(np.where(ok, E_b, 1.0), np.where(ok, E_d, 1.0))
    per_run = np.stack(
        [
            replay_final_errors(c, robot.true_geometry, robot.nonsystematic, geos, rng)
            for c in chunks
        ],
        axis=1,
    )  # (C, runs, T)
    per_run[np.broadcast_to(~ok[:, None, :], per_run.shape)] = np.nan
    mean = per_run.mean(axis=1)  # (C, T)
    beta = np.abs(leg_heading_systematic_rad(robot, sides_m))
    sigma = leg_heading_noise_rad(robot, sides_m)
    share = systematic_share(beta, sigma, n)
    out = []
    for i, L in enumerate(sides_m):
        s = ErrorSummary.from_samples(mean[i])
        eb, ed = E_b[i][ok[i]], E_d[i][ok[i]]
        out.append(
            Candidate(
                sides=4,
                side_m=float(L),
                travel_m=float(4 * L),
                systematic_share=float(share[i]),
                post_error_mean_m=s.mean_m,
                post_error_std_m=s.std_m,
                post_error_ci95_m=s.ci95_m,
                E_b_mean=float(eb.mean()),
                E_b_std=float(eb.std(ddof=1)),
                E_d_mean=float(ed.mean()),
                E_d_std=float(ed.std(ddof=1)),
                trials=s.n,
                leg_heading_systematic_rad=float(beta[i]),
                leg_heading_noise_rad=float(sigma[i]),
                failed_trials=int(trials - s.n),
                post_errors_m=mean[i].copy(),
            )
        )
    return out, per_run


def _predicted_ttest(a: float, b: float, d: np.ndarray) -> PredictedTTest:
    """The paired t-test of sides ``a`` against ``b`` in every simulated experiment, from the
    per-run differences ``d`` of their held-out errors, shape (runs, T)."""
    n_runs = d.shape[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = d.mean(axis=0) / (d.std(axis=0, ddof=1) / math.sqrt(n_runs))
    from scipy.special import stdtr

    p = 2.0 * stdtr(n_runs - 1, -np.abs(t))
    diff = d.mean(axis=0)
    fin = np.isfinite(t)
    lo, hi = (float(v) for v in np.percentile(diff[fin], [2.5, 97.5]))
    return PredictedTTest(
        a,
        b,
        float(np.median(t[fin])),
        float(np.median(p[fin])),
        float(np.mean(p[fin] < 0.05)),
        float(np.mean((p[fin] < 0.05) & (diff[fin] < 0))),
        float(np.mean((p[fin] < 0.05) & (diff[fin] > 0))),
        float(np.mean(diff[fin] > 0)),
        float(np.mean(diff[fin])),
        (lo, hi),
    )


def predict(
    robot: Robot,
    heldout: Sequence[Recording],
    real_runs_per_direction: dict[float, int],
    sweep_sides_m,
    runs_per_direction: int,
    trials: int,
    rng: np.random.Generator,
    settings: SimulationSettings = FAST,
    alpha: float = 0.05,
    tolerance: float = 0.05,
) -> Prediction:
    """The design's prediction (module docstring). ``real_runs_per_direction``: side (m) ->
    runs per direction of the real configuration (two sides, compared in that order)."""
    chunk_rad = REPLAY_CHUNK_M / (0.5 * float(robot.nominal.mean_diameter_m))
    chunks = [
        chunk_rotations(r.wheel_angle_right_rad, r.wheel_angle_left_rad, chunk_rad) for r in heldout
    ]

    def replayed(geometry: WheelGeometry) -> np.ndarray:
        """Mean over the held-out runs of their replayed final errors with ``geometry``."""
        batch = _batch(geometry, trials)
        return np.mean(
            [
                replay_final_errors(c, robot.true_geometry, robot.nonsystematic, batch, rng)[0]
                for c in chunks
            ],
            axis=0,
        )

    floor = replayed(robot.true_geometry)  # in this order: they share the stream
    uncal = replayed(robot.believed_geometry)
    sweep, _ = _candidates(robot, sweep_sides_m, runs_per_direction, trials, rng, chunks, settings)
    rec = recommend(sweep, alpha, tolerance, "error")
    real: dict[float, Candidate] = {}
    per_run: dict[float, np.ndarray] = {}
    for side, n in real_runs_per_direction.items():
        cands, pr = _candidates(robot, [side], n, trials, rng, chunks, settings)
        real[side] = cands[0]
        per_run[side] = pr[0]  # (runs, T)
    (a, b) = list(real_runs_per_direction)[:2]
    ttest = _predicted_ttest(a, b, per_run[a] - per_run[b])
    return Prediction(
        robot,
        tuple(sweep),
        rec,
        real,
        ErrorSummary.from_samples(floor),
        ErrorSummary.from_samples(uncal),
        ttest,
        trials,
        runs_per_direction,
    )


def _batch(g: WheelGeometry, n: int) -> WheelGeometry:
    return WheelGeometry.unchecked(
        np.full((1, n), float(g.diameter_right_m)),
        np.full((1, n), float(g.diameter_left_m)),
        np.full((1, n), float(g.wheelbase_m)),
    )
