"""Result types of a test-track design: error summaries, candidates, the validation track.

A *candidate* is one test track (regular N-gon of one side length) with the statistics of the
calibration it gives. The recommendation, the JSON, the report and the figures work from a list of
candidates plus the floor and uncalibrated errors, whatever produced them (the Monte-Carlo sweep in
:mod:`odocal.design.sweep` or an analytic approximation): they only read the attributes listed in
:class:`Candidate` (``sides``, ``side_m``, ``travel_m``, ``systematic_share``,
``post_error_mean_m``, ``post_error_std_m``, ``post_error_ci95_m``, ``E_b_mean``, ``E_b_std``,
``E_d_mean``, ``E_d_std``, ``trials``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from ..core.model import ModelError
from ..core.tracks import Track, direction_sign, polygon

__all__ = [
    "ErrorSummary",
    "Candidate",
    "ValidationTrack",
    "DesignSpec",
    "DEFAULT_SIDE_LENGTHS_M",
    "scaled_sizes",
    "check_design_inputs",
    "shape_name",
    "rounded",
]


def rounded(value, digits: int = 9):
    """``value`` as a JSON-safe float rounded to ``digits`` significant digits (None for NaN).

    Rounding keeps the JSON identical for identical seeds even if a platform's libm differs in the
    last bit of a sine or cosine.
    """
    if value is None:
        return None
    v = float(value)
    if not math.isfinite(v):
        return None
    return float(f"{v:.{digits}g}")


@dataclass(frozen=True)
class ErrorSummary:
    """Statistics of a sample of final position errors (m).

    Attributes
    ----------
    mean_m, std_m : float
        Mean and unbiased standard deviation (ddof = 1) over the finite samples (m).
    ci95_m : tuple of float
        Central 95 % interval of the samples (2.5th and 97.5th percentiles, m): where 95 % of
        single outcomes land, not a confidence interval of the mean.
    n : int
        Number of finite samples.
    """

    mean_m: float
    std_m: float
    ci95_m: tuple[float, float]
    n: int

    @classmethod
    def from_samples(cls, samples) -> ErrorSummary:
        x = np.asarray(samples, dtype=float).ravel()
        x = x[np.isfinite(x)]
        if x.size == 0:
            return cls(math.nan, math.nan, (math.nan, math.nan), 0)
        std = float(x.std(ddof=1)) if x.size > 1 else math.nan
        lo, hi = np.percentile(x, [2.5, 97.5])
        return cls(float(x.mean()), std, (float(lo), float(hi)), int(x.size))

    def as_dict(self) -> dict:
        return {
            "mean_m": rounded(self.mean_m),
            "std_m": rounded(self.std_m),
            "ci95_m": [rounded(self.ci95_m[0]), rounded(self.ci95_m[1])],
            "n": self.n,
        }


@dataclass(frozen=True)
class Candidate:
    """One candidate test track and the calibration it gives.

    Attributes
    ----------
    sides : int
        Number of sides N of the regular polygon.
    side_m, travel_m : float
        Side length and total travel N L of one run (m).
    systematic_share : float
        beta^2 / (beta^2 + sigma_theta^2 / n) (0..1; see :mod:`odocal.design.metrics`).
    post_error_mean_m, post_error_std_m : float
        Mean and std (ddof = 1) of the final position error on the validation track after
        calibrating on this track (m).
    post_error_ci95_m : tuple of float
        Central 95 % interval of that error over the trials (m).
    E_b_mean, E_b_std, E_d_mean, E_d_std : float
        Distribution of the calibrated factors, relative to the parameters the robot ran with.
    trials : int or None
        Number of (successful) Monte-Carlo trials behind the statistics; None for expected
        values (an analytic candidate: no trials, no sampling error).
    leg_heading_systematic_rad, leg_heading_noise_rad : float
        |beta(L)| and sigma_theta(L) of one straight leg (rad; Fig. 3).
    residual_error_mean_m, residual_error_std_m : float
        The same validation drive WITHOUT wheel noise (m): the error left by the calibrated
        parameters alone, i.e. what the choice of test track controls (the validation run's own
        noise adds the floor on top of it).
    failed_trials : int
        Trials whose calibration equations were undefined (excluded from the statistics).
    post_errors_m : ndarray, shape (trials,), optional
        The per-trial errors (m), when simulated (NaN for a failed trial).
    residual_errors_m : ndarray, shape (trials,), optional
        The per-trial residuals (m), when simulated.
    E_corr : float
        Correlation of the calibrated E_b and E_d (analytic candidates; NaN otherwise).
    post_error_mean_xy_m : tuple of float
        Mean validation position error vector (x, y): the systematic residual (m; analytic).
    post_error_cov_xy_m2 : tuple of tuple of float
        Its covariance (m^2; analytic).
    """

    sides: int
    side_m: float
    travel_m: float
    systematic_share: float
    post_error_mean_m: float
    post_error_std_m: float
    post_error_ci95_m: tuple[float, float]
    E_b_mean: float
    E_b_std: float
    E_d_mean: float
    E_d_std: float
    trials: int | None
    leg_heading_systematic_rad: float = math.nan
    leg_heading_noise_rad: float = math.nan
    residual_error_mean_m: float = math.nan
    residual_error_std_m: float = math.nan
    failed_trials: int = 0
    post_errors_m: np.ndarray | None = field(default=None, repr=False, compare=False)
    residual_errors_m: np.ndarray | None = field(default=None, repr=False, compare=False)
    E_corr: float = math.nan
    post_error_mean_xy_m: tuple[float, float] = (math.nan, math.nan)
    post_error_cov_xy_m2: tuple[tuple[float, float], tuple[float, float]] = (
        (math.nan, math.nan),
        (math.nan, math.nan),
    )

    @property
    def label(self) -> str:
        return f"{shape_name(self.sides)} {self.side_m:g} m"


def shape_name(sides: int) -> str:
    return {3: "triangle", 4: "square", 5: "pentagon", 6: "hexagon", 8: "octagon"}.get(
        int(sides), f"{int(sides)}-gon"
    )


@dataclass(frozen=True)
class ValidationTrack:
    """The track the calibrated robot drives once per trial: a regular polygon.

    Attributes
    ----------
    sides : int
    side_m : float
        Side length (m).
    direction : str
        'cw' or 'ccw'.
    """

    sides: int
    side_m: float
    direction: str

    def __post_init__(self) -> None:
        polygon(self.sides, self.side_m, self.direction)  # validates
        direction_sign(self.direction)

    def track(self) -> Track:
        return polygon(self.sides, self.side_m, self.direction.lower())

    @property
    def label(self) -> str:
        d = self.direction.upper()
        if self.sides == 4:
            return f"{self.side_m:g} m x {self.side_m:g} m square {d}"
        return f"{self.side_m:g} m {shape_name(self.sides)} {d}"

    def as_dict(self) -> dict:
        return {"sides": self.sides, "side_m": self.side_m, "direction": self.direction.lower()}


def check_design_inputs(runs_per_direction: int, trials: int) -> None:
    if runs_per_direction < 1:
        raise ModelError(f"runs per direction must be >= 1, got {runs_per_direction}")
    if trials < 2:
        raise ModelError(f"trials must be >= 2 (a standard deviation is needed), got {trials}")


#: Default candidate side lengths (m): 0.5, 1.0, ..., 10 m (the paper's sweep).
DEFAULT_SIDE_LENGTHS_M = tuple(float(v) for v in np.arange(1, 21) * 0.5)

#: Candidate sizes scaled to the robot: the step is about this many wheelbases (1.3 x 0.385 m =
#: 0.5 m for the paper's robot), rounded to 1, 2, 2.5 or 5 x 10^k m; 20 candidates.
STEP_PER_WHEELBASE = 1.3
#: The validation square's side, in candidate steps (8 x 0.5 m = the paper's 4 m).
VALIDATION_STEPS = 8
_NICE = (1.0, 2.0, 2.5, 5.0)


def _nice(x: float) -> float:
    """``x`` rounded (in log scale) to 1, 2, 2.5 or 5 times a power of ten."""
    e = math.floor(math.log10(x))
    options = [m * 10.0**k for k in (e - 1, e, e + 1) for m in _NICE]
    return min(options, key=lambda v: abs(math.log(v / x)))


def scaled_sizes(wheelbase_m: float) -> tuple[tuple[float, ...], ValidationTrack]:
    """Candidate side lengths and validation square for a robot of wheelbase ``wheelbase_m``
    (m): 20 steps of about 1.3 wheelbases (rounded), and a square of 8 steps driven CCW. For the
    paper's robot (b = 0.385 m) this is its sweep (0.5 .. 10 m) and its 4 m x 4 m square; for a
    TurtleBot3 (b = 0.16 m) 0.2 .. 4 m and 1.6 m."""
    step = _nice(STEP_PER_WHEELBASE * float(wheelbase_m))
    lengths = tuple(float(round(step * k, 12)) for k in range(1, 21))
    return lengths, ValidationTrack(4, round(VALIDATION_STEPS * step, 12), "ccw")


@dataclass(frozen=True)
class DesignSpec:
    """What a track design compares: candidate shapes and sizes, runs and trials, the method and
    the validation track.

    Attributes
    ----------
    sides : tuple of int
        Polygon shapes; shapes after the first are compared at equal travel.
    side_lengths_m : tuple of float or None
        Candidate side lengths of the first shape (m); None: scaled to the robot
        (:func:`scaled_sizes`; the paper's 0.5 .. 10 m for the paper's robot).
    runs_per_direction, trials : int
        Test runs per direction; Monte-Carlo trials per candidate (2000 by default: with common
        random numbers that makes the pick stable from seed to seed; docs/design.md).
    method : str
        'heading' or 'umbmark' (squares only).
    validation : ValidationTrack or None
        None: a square scaled to the robot (the paper's 4 m x 4 m CCW for the paper's robot).
    """

    sides: tuple[int, ...] = (4,)
    side_lengths_m: tuple[float, ...] | None = None
    runs_per_direction: int = 5
    trials: int = 2000
    method: str = "heading"
    validation: ValidationTrack | None = None

    def __post_init__(self) -> None:
        check_design_inputs(self.runs_per_direction, self.trials)
        if not self.sides:
            raise ModelError("at least one polygon shape (sides) is needed")
        if self.method not in ("heading", "umbmark"):
            raise ModelError(f"method must be heading or umbmark, got {self.method!r}")
        if self.method == "umbmark" and any(s != 4 for s in self.sides):
            raise ModelError("UMBmark is defined for squares only (--sides 4)")
        if self.side_lengths_m is not None:
            lengths = np.asarray(self.side_lengths_m, dtype=float)
            if lengths.ndim != 1 or lengths.size == 0:
                raise ModelError("at least one candidate side length is needed")
            if not np.all(np.isfinite(lengths) & (lengths > 0)):
                raise ModelError(f"side lengths must be finite and > 0, got {lengths.tolist()}")

    def for_wheelbase(self, wheelbase_m: float) -> DesignSpec:
        """This spec with the sizes left open (None) scaled to a robot of ``wheelbase_m`` (m)."""
        lengths, validation = scaled_sizes(wheelbase_m)
        return replace(
            self,
            side_lengths_m=self.side_lengths_m if self.side_lengths_m is not None else lengths,
            validation=self.validation if self.validation is not None else validation,
        )

    @property
    def simulated_runs(self) -> int:
        """Test runs per direction a Monte-Carlo design simulates (candidates x trials x runs)."""
        n = len(self.side_lengths_m) if self.side_lengths_m is not None else 20
        return n * self.trials * self.runs_per_direction * len(self.sides)
