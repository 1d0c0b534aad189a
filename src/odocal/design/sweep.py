"""The paper's track-design procedure as a vectorised Monte-Carlo sweep (docs/design.md).

For every candidate track (regular N-gon of side L) and every trial:

1. simulate n CW and n CCW test runs (wheel noise, then the instrument's measurement noise);
2. calibrate from the per-trial mean final errors (circular mean for headings) with the heading
   method (or UMBmark on squares);
3. install the calibrated geometry and drive the validation track once; record the final
   position error sqrt(eps_x^2 + eps_y^2) (the true error: no instrument noise).

On the same validation track, the *floor* (the robot running with its TRUE geometry) and the
*uncalibrated* error (running with the parameters it believed during the test) show what
calibration can gain. All candidate sizes x trials x runs of one shape go through one call of
:func:`odocal.core.simulate.drive` per direction; the validation of all calibrations is one more
call.

Simulation accuracy (:class:`SimulationSettings`): by default every segment is split into 10
increments integrated as exact arcs. The deterministic part is then exact, and the noise
covariance differs from the limit of infinitely small increments by O(1/K^2) (about 0.25 % of the
cross-track variance at K = 10), far below the sampling error of 800 trials. The heading method
reads only the final heading, whose distribution does not depend on the increments at all (the
heading change is the sum of the increments' wheel-travel differences over b, and their noise
variances add up to exactly k |s|), so its test runs use one increment per segment.
``SimulationSettings.reference()`` is the 1 cm midpoint simulation of ``odocal simulate``.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..calibration.heading import heading_factors
from ..calibration.umbmark import umbmark_factors
from ..core.model import ModelError, NonSystematicError, Robot, WheelGeometry
from ..core.simulate import drive, final_headings, measure
from ..core.stats import circular_mean, ttest_paired
from ..core.tracks import polygon
from .metrics import (
    leg_heading_noise_rad,
    leg_heading_systematic_rad,
    systematic_share,
    true_factors,
)
from .recommend import (
    Comparison,
    Recommendation,
    Stability,
    other_criterion,
    pick_spread,
    recommend,
    stability_of,
)
from .result import Candidate, ErrorSummary, ValidationTrack, rounded
from .spec import METHODS, DesignSpec, Method

__all__ = [
    "METHODS",
    "SimulationSettings",
    "FAST",
    "DesignResult",
    "Progress",
    "calibrate_trials",
    "validation_errors",
    "residual_errors",
    "simulate_candidates",
    "equal_travel_side_lengths",
    "run_design",
    "gain_warnings",
    "design_json",
]

#: progress callback: (stages done, stages in all, label of the stage just finished)
Progress = Callable[[int, int, str], None]


@dataclass(frozen=True)
class SimulationSettings:
    """How finely runs are integrated (see the module docstring).

    Attributes
    ----------
    steps_per_segment : int or None
        Increments per segment (fast mode); None to use ``max_step_m``.
    integration : str
        'exact' (exact arcs) or 'midpoint' (eq. 8).
    max_step_m : float or None
        Largest wheel travel of one increment (m), when ``steps_per_segment`` is None.
    single_step_heading_tests : bool
        Use one increment per segment for test runs calibrated by the heading method (exact).
    """

    steps_per_segment: int | None = 10
    integration: str = "exact"
    max_step_m: float | None = None
    single_step_heading_tests: bool = True

    @classmethod
    def reference(cls) -> SimulationSettings:
        """1 cm increments, midpoint update, everywhere: the slow reference."""
        return cls(None, "midpoint", 0.01, False)

    def options(self) -> dict:
        """The simulator's keyword arguments for these settings (steps, integration, largest step in
        m)."""
        return {
            "steps_per_segment": self.steps_per_segment,
            "integration": self.integration,
            "max_step_m": self.max_step_m,
        }

    def for_tests(self, method: Method) -> SimulationSettings:
        """The settings for the test runs calibrated by ``method`` (one increment per segment for
        the heading method when ``single_step_heading_tests``)."""
        if method == "heading" and self.single_step_heading_tests:
            return replace(self, steps_per_segment=1)
        return self

    def describe(self) -> str:
        """The integration in words, e.g. '10 exact increments per segment'."""
        if self.steps_per_segment is not None:
            return f"{self.steps_per_segment} {self.integration} increments per segment"
        step = float(self.max_step_m or 0.0)
        return f"increments of at most {step * 100:g} cm, {self.integration} update"


@dataclass(frozen=True)
class DesignResult:
    """Outcome of a track design.

    Attributes
    ----------
    candidates : tuple of Candidate
        In the order of the sweep (shape by shape, side lengths ascending).
    floor, uncalibrated : ErrorSummary
        Validation-track error with the TRUE geometry, and with the parameters the robot believed
        during the test (m).
    recommendation : Recommendation
    validation : ValidationTrack
    method : Method
        Calibration method ('heading' or 'umbmark').
    runs_per_direction : int
    trials : int or None
        Monte-Carlo trials per candidate; None for expected values (analytic).
    settings : SimulationSettings or None
        None for candidates that were not simulated.
    paired : bool
        The candidates share their random numbers trial by trial (common random numbers), so
        the rule uses paired tests.
    warnings : tuple of str
        E.g. when calibrating on the recommended track would not beat the uncalibrated robot.
    truth_factors : (float, float) or None
        The E_b, E_d a perfect calibration finds (relative to the parameters the robot ran with).
    other : Recommendation or None
        The rule under the other criterion ('error' <-> 'residual'); None when the candidates
        carry no statistics for it.
    """

    candidates: tuple[Candidate, ...]
    floor: ErrorSummary
    uncalibrated: ErrorSummary
    recommendation: Recommendation
    validation: ValidationTrack
    method: Method
    runs_per_direction: int
    trials: int | None
    settings: SimulationSettings | None = None
    paired: bool = False
    warnings: tuple[str, ...] = ()
    truth_factors: tuple[float, float] | None = None
    other: Recommendation | None = None

    @property
    def recommended(self) -> Candidate:
        """The candidate the recommendation rule picks."""
        return self.candidates[self.recommendation.index]

    @property
    def other_recommended(self) -> Candidate | None:
        """The candidate the rule picks under the other criterion (see ``other``)."""
        return None if self.other is None else self.candidates[self.other.index]

    @property
    def stability(self) -> Stability | None:
        """How stable the recommendation is (bootstrap of the trials), or None when not
        measured (analytic candidates, or no resamples)."""
        return stability_of(self.candidates, self.recommendation)

    @property
    def gain_m(self) -> float:
        """Uncalibrated minus the recommended track's mean error after calibration (m)."""
        return self.uncalibrated.mean_m - self.recommended.post_error_mean_m

    @property
    def failed_trials(self) -> int:
        """Trials, over all candidates, that gave no calibration (equations undefined)."""
        return sum(c.failed_trials for c in self.candidates)

    def error_ratio(self, comparison: Comparison) -> float:
        """Mean error after calibration of the compared candidate over the recommended one's."""
        return (
            self.candidates[comparison.other].post_error_mean_m / self.recommended.post_error_mean_m
        )

    @property
    def shape_picks(self) -> tuple[Candidate, ...]:
        """The candidate the rule picks among each shape alone, fewest sides first."""
        return tuple(self.candidates[i] for i in self.recommendation.per_shape.values())


# Largest number of test runs per direction simulated in one block of candidates.
_BLOCK_RUNS = 200_000

#: The default (fast) settings.
FAST = SimulationSettings()


def _batch(values: np.ndarray, trials: int, runs: int) -> np.ndarray:
    """Repeat each value ``trials * runs`` times: shape (C,) -> (C * trials * runs,)."""
    return np.repeat(np.asarray(values, dtype=float), trials * runs)


def calibrate_trials(
    robot: Robot,
    sides: int,
    side_lengths_m,
    runs_per_direction: int,
    trials: int,
    method: Method,
    rng: np.random.Generator,
    settings: SimulationSettings = FAST,
) -> tuple[np.ndarray, np.ndarray]:
    """Simulate the test runs of every (side length, trial) and calibrate.

    Returns E_b, E_d, each of shape (C, trials) for C side lengths, relative to the parameters
    the robot believed during the test; NaN where the calibration equations are undefined.
    """
    if method not in METHODS:
        raise ModelError(f"method must be one of {', '.join(METHODS)}, got {method!r}")
    if method == "umbmark" and sides != 4:
        raise ModelError(f"UMBmark is defined for squares only (sides 4), got sides {sides}")
    sides_m = np.asarray(side_lengths_m, dtype=float).ravel()
    n, t_, c = runs_per_direction, trials, sides_m.size
    side_batch = _batch(sides_m, t_, n)
    opts = settings.for_tests(method).options()
    means = {}
    for d in ("cw", "ccw"):
        track = polygon(sides, side_batch, d)
        args = (robot.true_geometry, robot.believed_geometry, robot.nonsystematic)
        if method == "heading":  # it reads the final headings only: the same draws, less work
            errors = np.zeros((side_batch.size, 3))
            errors[:, 2] = final_headings(track, *args, side_batch.size, rng, **opts)
            errors[:, 2] -= sum(seg.angle_rad for seg in track.segments)  # commanded heading
        else:
            errors = drive(track, *args, side_batch.size, rng, **opts).errors
        err = measure(errors, robot, rng).reshape(c, t_, n, 3)
        means[d] = (err[..., :2].mean(axis=2), circular_mean(err[..., 2], axis=-1))
    b_ran = robot.believed_geometry.wheelbase_m
    if method == "heading":
        E_b, E_d = heading_factors(means["cw"][1], means["ccw"][1], sides, sides_m[:, None], b_ran)
    else:
        E_b, E_d = umbmark_factors(means["cw"][0], means["ccw"][0], sides_m[:, None], b_ran)
    E_b, E_d = np.asarray(E_b, dtype=float), np.asarray(E_d, dtype=float)
    bad = ~(np.isfinite(E_b) & np.isfinite(E_d) & (E_b > 0) & (E_d > 0))
    E_b[bad] = np.nan
    E_d[bad] = np.nan
    return E_b, E_d


def validation_errors(
    robot: Robot,
    believed: WheelGeometry,
    validation: ValidationTrack,
    runs: int,
    rng: np.random.Generator,
    settings: SimulationSettings = FAST,
) -> np.ndarray:
    """Final position errors (m), shape (runs,), of ``runs`` drives of the validation track by
    the physical ``robot`` running with ``believed`` (scalar or batched of shape (runs,))."""
    res = drive(
        validation.track(),
        robot.true_geometry,
        believed,
        robot.nonsystematic,
        runs,
        rng,
        **settings.options(),
    )
    return np.hypot(res.errors[:, 0], res.errors[:, 1])


def calibrated_geometry(robot: Robot, E_b: np.ndarray, E_d: np.ndarray) -> WheelGeometry:
    """The batched geometry a calibration installs (NaN factors replaced by 1: mask them)."""
    ok = np.isfinite(E_b) & np.isfinite(E_d)
    return robot.believed_geometry.corrected(np.where(ok, E_b, 1.0), np.where(ok, E_d, 1.0))


def residual_errors(robot: Robot, E_b, E_d, validation: ValidationTrack) -> np.ndarray:
    """Final position error (m) of the validation track driven WITHOUT wheel noise by the robot
    running with the calibrations (E_b, E_d) (arrays of one shape; the result has it too, NaN
    where a factor is NaN). One exact increment per segment: exact for a noise-free drive."""
    E_b = np.asarray(E_b, dtype=float)
    E_d = np.asarray(E_d, dtype=float)
    res = drive(
        validation.track(),
        robot.true_geometry,
        calibrated_geometry(robot, E_b.ravel(), E_d.ravel()),
        NonSystematicError(),
        E_b.size,
        None,
        steps_per_segment=1,
        integration="exact",
    )
    err = np.hypot(res.errors[:, 0], res.errors[:, 1]).reshape(E_b.shape)
    err[~(np.isfinite(E_b) & np.isfinite(E_d))] = np.nan
    return err


def _stats(x: np.ndarray) -> tuple[float, float]:
    x = x[np.isfinite(x)]
    if x.size < 2:
        return (float(x.mean()) if x.size else math.nan), math.nan
    return float(x.mean()), float(x.std(ddof=1))


def simulate_candidates(
    robot: Robot,
    sides: int,
    side_lengths_m,
    runs_per_direction: int,
    trials: int,
    method: Method,
    validation: ValidationTrack,
    rng: np.random.Generator,
    settings: SimulationSettings = FAST,
    *,
    common_seeds: tuple[int, int] | None = None,
) -> list[Candidate]:
    """Monte-Carlo candidates for one polygon shape and several side lengths (m).

    ``common_seeds`` (test seed, validation seed): common random numbers. Every candidate
    simulates its test runs with a generator seeded by the first and its validation drives with
    one seeded by the second, so trial i of every candidate (and of the floor and the
    uncalibrated drive, when they use the validation seed too) shares its standard normal draws:
    the candidates differ only by their size, and paired tests compare them. Without it, one
    stream ``rng`` runs through all candidates (independent samples).
    """
    sides_m = np.asarray(side_lengths_m, dtype=float).ravel()
    if common_seeds is None:
        E_b, E_d = calibrate_trials(
            robot, sides, sides_m, runs_per_direction, trials, method, rng, settings
        )
        post = validation_errors(
            robot,
            calibrated_geometry(robot, E_b.ravel(), E_d.ravel()),
            validation,
            E_b.size,
            rng,
            settings,
        ).reshape(E_b.shape)
    else:
        test_seed, val_seed = common_seeds
        E_b = np.empty((sides_m.size, trials))
        E_d = np.empty((sides_m.size, trials))
        post = np.empty((sides_m.size, trials))
        for i, L in enumerate(sides_m):
            E_b[i], E_d[i] = (
                v[0]
                for v in calibrate_trials(
                    robot,
                    sides,
                    [L],
                    runs_per_direction,
                    trials,
                    method,
                    np.random.default_rng(test_seed),
                    settings,
                )
            )
            post[i] = validation_errors(
                robot,
                calibrated_geometry(robot, E_b[i], E_d[i]),
                validation,
                trials,
                np.random.default_rng(val_seed),
                settings,
            )
    post[~np.isfinite(E_b)] = np.nan
    residual = residual_errors(robot, E_b, E_d, validation)
    beta = np.abs(leg_heading_systematic_rad(robot, sides_m))
    sigma = leg_heading_noise_rad(robot, sides_m)
    share = systematic_share(beta, sigma, runs_per_direction)
    out = []
    for i, L in enumerate(sides_m):
        s = ErrorSummary.from_samples(post[i])
        eb, ed = _stats(E_b[i]), _stats(E_d[i])
        res = _stats(residual[i])
        out.append(
            Candidate(
                sides=int(sides),
                side_m=float(L),
                travel_m=float(sides * L),
                systematic_share=float(share[i]),
                post_error_mean_m=s.mean_m,
                post_error_std_m=s.std_m,
                post_error_ci95_m=s.ci95_m,
                E_b_mean=eb[0],
                E_b_std=eb[1],
                E_d_mean=ed[0],
                E_d_std=ed[1],
                trials=s.n,
                leg_heading_systematic_rad=float(beta[i]),
                leg_heading_noise_rad=float(sigma[i]),
                residual_error_mean_m=res[0],
                residual_error_std_m=res[1],
                failed_trials=int(trials - s.n),
                post_errors_m=post[i].copy(),
                residual_errors_m=residual[i].copy(),
            )
        )
    return out


def equal_travel_side_lengths(side_lengths_m, sides: Sequence[int]) -> dict[int, np.ndarray]:
    """Side lengths per shape: the first shape uses ``side_lengths_m``; every other shape gets
    the same total travels (side = travel / N), so shapes are compared at equal travel."""
    base = np.asarray(side_lengths_m, dtype=float)
    travel = base * sides[0]
    return {int(s): (base if i == 0 else travel / s) for i, s in enumerate(sides)}


class _Steps:
    """Progress of a design: stages done out of ``total``, reported to ``progress``."""

    def __init__(self, total: int, progress: Progress | None) -> None:
        self.total, self.done, self.progress = total, 0, progress

    def __call__(self, label: str) -> None:
        self.done += 1
        if self.progress is not None:
            self.progress(self.done, self.total, label)


def _blocks(spec: DesignSpec, common_random_numbers: bool) -> list[tuple[int, np.ndarray]]:
    """(sides, side lengths) of every block of candidates simulated at once.

    Candidates are simulated in blocks of at most _BLOCK_RUNS test runs per direction: this
    bounds memory and paces the progress bar. The blocks depend only on the spec, so the random
    stream (and the result) is the same on every machine. With common random numbers every
    candidate draws from its own freshly seeded generators (one block per candidate)."""
    per_candidate = spec.trials * spec.runs_per_direction
    block = 1 if common_random_numbers else max(1, _BLOCK_RUNS // per_candidate)
    shapes = equal_travel_side_lengths(spec.lengths_m, spec.sides)
    return [
        (s, lengths[i : i + block]) for s, lengths in shapes.items()
        for i in range(0, len(lengths), block)
    ]  # fmt: skip


def _recommendation(
    candidates: Sequence[Candidate],
    spec: DesignSpec,
    paired: bool,
    rng: np.random.Generator,
    resamples: int,
) -> Recommendation:
    """The rule on ``candidates``, with the stability of its pick over ``resamples``
    bootstrap resamples of the trials (drawn from ``rng``)."""
    rec = recommend(candidates, spec.alpha, spec.tolerance, spec.criterion, paired=paired)
    if not resamples:
        return rec
    spread = pick_spread(
        candidates,
        rng,
        spec.alpha,
        spec.tolerance,
        spec.criterion,
        paired=paired,
        resamples=resamples,
    )
    return replace(rec, spread=spread, resamples=resamples)


def run_design(
    robot: Robot,
    spec: DesignSpec,
    rng: np.random.Generator,
    *,
    settings: SimulationSettings = FAST,
    progress: Progress | None = None,
    common_random_numbers: bool = True,
    resamples: int = 200,
) -> DesignResult:
    """The design procedure (module docstring) for the candidates, runs, trials, method,
    validation track and rule of ``spec``.

    Parameters
    ----------
    robot : Robot
        The physical robot (systematic and non-systematic errors, measurement noise) and the
        parameters it runs with during the test (``robot.believed_geometry``).
    spec : DesignSpec
        Sizes it leaves open are scaled to the robot's nominal wheelbase
        (:meth:`DesignSpec.for_wheelbase`: the paper's 0.5 .. 10 m and 4 m x 4 m square CCW for
        the paper's robot). Shapes after the first are compared at equal travel
        (:func:`equal_travel_side_lengths`).
    rng : numpy.random.Generator
    common_random_numbers : bool
        Simulate every candidate with the same random numbers (trial by trial) and judge with
        paired tests (default); False: independent samples and Welch tests.
    resamples : int
        Bootstrap resamples of the trials that measure the stability of the pick (0: none).
    """
    spec = spec.for_wheelbase(float(robot.nominal.wheelbase_m))
    validation, trials = spec.validation_track, spec.trials
    blocks = _blocks(spec, common_random_numbers)
    step = _Steps(2 + len(blocks), progress)
    seeds = tuple(int(v) for v in rng.integers(0, 2**63 - 1, size=3))
    common = (seeds[0], seeds[1]) if common_random_numbers else None

    def val_rng() -> np.random.Generator:
        return np.random.default_rng(seeds[1]) if common_random_numbers else rng

    # floor and uncalibrated first, so they do not depend on the candidate list
    floor = ErrorSummary.from_samples(
        validation_errors(robot, robot.true_geometry, validation, trials, val_rng(), settings)
    )
    step("floor")
    uncal_samples = validation_errors(
        robot, robot.believed_geometry, validation, trials, val_rng(), settings
    )
    uncal = ErrorSummary.from_samples(uncal_samples)
    step("uncalibrated")
    candidates: list[Candidate] = []
    for s, lengths in blocks:
        candidates += simulate_candidates(
            robot,
            s,
            lengths,
            spec.runs_per_direction,
            trials,
            spec.method,
            validation,
            rng,
            settings,
            common_seeds=common,
        )
        step(f"{s}-gon up to {lengths[-1]:g} m")
    paired = common_random_numbers
    rec = _recommendation(candidates, spec, paired, np.random.default_rng(seeds[2]), resamples)
    result = DesignResult(
        tuple(candidates),
        floor,
        uncal,
        rec,
        validation,
        spec.method,
        spec.runs_per_direction,
        trials,
        settings,
        paired,
        truth_factors=true_factors(robot),
        other=other_criterion(candidates, rec, paired=paired),
    )
    return replace(result, warnings=gain_warnings(result, uncal_samples if paired else None))


def gain_warnings(result: DesignResult, uncalibrated_samples=None) -> tuple[str, ...]:
    """A warning when calibrating on the recommended track would not beat the uncalibrated
    robot on the validation track (its mean error is not smaller; with paired samples, not
    significantly smaller at the rule's alpha)."""
    r = result.recommended
    u = result.uncalibrated.mean_m
    worse = not r.post_error_mean_m < u
    rec = result.recommendation
    if not worse and uncalibrated_samples is not None and r.post_errors_m is not None:
        worse = not ttest_paired(r.post_errors_m, uncalibrated_samples).p_less < rec.alpha
    if not worse:
        return ()
    return (
        f"calibrating on the recommended {r.side_m:g} m track would not beat the uncalibrated "
        f"robot: {r.post_error_mean_m:.4g} m after calibration against {u:.4g} m without, on "
        f"the {result.validation.label}. The robot's errors (ROBOT.yaml 'systematic') are too "
        "small for this instrument and these runs to measure; keep its parameters, or use a "
        "more precise instrument or more runs",
    )


def _comparison_dict(result_candidates: Sequence[Candidate], comp: Comparison) -> dict:
    o, r = result_candidates[comp.other], result_candidates[comp.reference]
    test, rule = comp.test, comp.rule
    return {
        "track": {"sides": o.sides, "side_m": o.side_m},
        "versus": {"sides": r.sides, "side_m": r.side_m},
        "test": comp.kind,
        "t": None if test is None else rounded(test.t),
        "df": None if test is None else rounded(test.df),
        "p": None if test is None else rounded(test.p_two_sided),
        "mean_difference_m": rounded(comp.mean_difference),
        "rule_t": None if rule is None else rounded(rule.t),
        "rule_p": None if rule is None else rounded(rule.p_less),
        "significantly_better_beyond_tolerance": comp.significant,
    }


def _other_dict(result: DesignResult) -> dict | None:
    c = result.other_recommended
    if result.other is None or c is None:
        return None
    return {
        "criterion": result.other.criterion,
        "sides": c.sides,
        "side_m": rounded(c.side_m),
        "travel_m": rounded(c.travel_m),
    }


def design_json(result: DesignResult, **extra: object) -> dict:
    """The ``odocal design --json`` object (issue contract plus extra keys; floats rounded to 9
    significant digits, NaN as null). ``extra`` (e.g. seed, robot) is merged in."""
    cands = result.candidates
    rec = result.recommendation
    r = cands[rec.index]
    out = {
        "candidates": [
            {
                "sides": c.sides,
                "side_m": rounded(c.side_m),
                "travel_m": rounded(c.travel_m),
                "systematic_share": rounded(c.systematic_share),
                "post_error_mean_m": rounded(c.post_error_mean_m),
                "post_error_std_m": rounded(c.post_error_std_m),
                "post_error_ci95_m": [rounded(v) for v in c.post_error_ci95_m],
                "E_b_mean": rounded(c.E_b_mean),
                "E_b_std": rounded(c.E_b_std),
                "E_d_mean": rounded(c.E_d_mean),
                "E_d_std": rounded(c.E_d_std),
                "trials": c.trials,
                "leg_heading_systematic_deg": rounded(math.degrees(c.leg_heading_systematic_rad)),
                "leg_heading_noise_deg": rounded(math.degrees(c.leg_heading_noise_rad)),
                "residual_error_mean_m": rounded(c.residual_error_mean_m),
                "residual_error_std_m": rounded(c.residual_error_std_m),
                "failed_trials": c.failed_trials,
            }
            for c in cands
        ],
        "recommended": {
            "sides": r.sides,
            "side_m": rounded(r.side_m),
            "travel_m": rounded(r.travel_m),
            "post_error_mean_m": rounded(r.post_error_mean_m),
        },
        "floor_m": rounded(result.floor.mean_m),
        "uncalibrated_m": rounded(result.uncalibrated.mean_m),
        "floor": result.floor.as_dict(),
        "uncalibrated": result.uncalibrated.as_dict(),
        "recommended_by_other_criterion": _other_dict(result),
        "recommended_by_sides": {
            str(s): {"side_m": rounded(cands[i].side_m), "travel_m": rounded(cands[i].travel_m)}
            for s, i in rec.per_shape.items()
        },
        "ttests": [_comparison_dict(cands, comp) for comp in rec.neighbours],
        "rule_test": rec.test,
        "common_random_numbers": result.paired,
        "stability": None if result.stability is None else result.stability.as_dict(),
        "warnings": list(result.warnings),
        "criterion": rec.criterion,
        "alpha": rec.alpha,
        "tolerance": rec.tolerance,
        "method": result.method,
        "runs_per_direction": result.runs_per_direction,
        "trials": result.trials,
        "validation": result.validation.as_dict(),
    }
    if result.settings is not None:
        out["simulation"] = result.settings.describe()
    out.update(extra)
    return out
