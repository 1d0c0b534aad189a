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
from dataclasses import dataclass, field

import numpy as np

from ..core.tracks import Track, direction_sign, polygon

__all__ = [
    "ErrorSummary",
    "Candidate",
    "ValidationTrack",
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
        """The summary of the finite entries of ``samples`` (m): mean, std (ddof 1; NaN with one),
        the central 95 % range and their number."""
        x = np.asarray(samples, dtype=float).ravel()
        x = x[np.isfinite(x)]
        if x.size == 0:
            return cls(math.nan, math.nan, (math.nan, math.nan), 0)
        std = float(x.std(ddof=1)) if x.size > 1 else math.nan
        lo, hi = np.percentile(x, [2.5, 97.5])
        return cls(float(x.mean()), std, (float(lo), float(hi)), int(x.size))

    def as_dict(self) -> dict:
        """JSON-ready (m, rounded; NaN as None)."""
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
        """Shape and side, e.g. 'square 1.5 m'."""
        return f"{shape_name(self.sides)} {self.side_m:g} m"


def shape_name(sides: int) -> str:
    """The name of a regular polygon of ``sides`` sides ('square', ...; 'N-gon' without one)."""
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
        """The polygon the robot drives (:func:`odocal.core.tracks.polygon`)."""
        return polygon(self.sides, self.side_m, self.direction.lower())

    @property
    def label(self) -> str:
        """Side, shape and direction, e.g. '4 m x 4 m square CW'."""
        d = self.direction.upper()
        if self.sides == 4:
            return f"{self.side_m:g} m x {self.side_m:g} m square {d}"
        return f"{self.side_m:g} m {shape_name(self.sides)} {d}"

    def as_dict(self) -> dict:
        """JSON-ready: the sides, the side length (m) and the direction ('cw' or 'ccw')."""
        return {"sides": self.sides, "side_m": self.side_m, "direction": self.direction.lower()}
