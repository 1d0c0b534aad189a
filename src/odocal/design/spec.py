"""What a test-track design is asked: the :class:`DesignSpec`, built once at the edge (the command
line, the Python API), validated once, and passed whole to the engines (the Monte-Carlo sweep
:func:`odocal.design.sweep.run_design`, the analytic :func:`odocal.design.analytic.
analytic_design_result`, the design over plausible errors :func:`odocal.design.robust.
range_design`).

The closed sets are :data:`Method`, :data:`Criterion` and :data:`Engine`.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from dataclasses import dataclass, replace
from typing import Literal, get_args

import numpy as np

from ..core.checks import check_int, check_number, check_positive_float
from ..core.model import ModelError
from ..core.tracks import MAX_POLYGON_SIDES
from .result import ValidationTrack

__all__ = [
    "Method",
    "Criterion",
    "Engine",
    "METHODS",
    "CRITERIA",
    "ENGINES",
    "DesignSpec",
    "DEFAULT_SIDE_LENGTHS_M",
    "scaled_sizes",
]

#: The calibration method a design simulates: the heading-error method (the paper's) or UMBmark
#: (mean form; squares only).
Method = Literal["heading", "umbmark"]
#: What the recommendation rule compares: the error after calibration on the validation track
#: ('error', the paper's quantity) or the residual, the same drive without wheel noise.
Criterion = Literal["error", "residual"]
#: How the candidates' statistics are computed: Monte Carlo with common random numbers, or
#: first-order propagation (expected values).
Engine = Literal["monte-carlo", "analytic"]

METHODS: tuple[Method, ...] = get_args(Method)
CRITERIA: tuple[Criterion, ...] = get_args(Criterion)
ENGINES: tuple[Engine, ...] = get_args(Engine)

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
    """What a track design compares and how it judges: candidate shapes and sizes, runs and
    trials, the method, the validation track and the recommendation rule's parameters.

    Attributes
    ----------
    sides : tuple of int
        Polygon shapes (duplicates dropped, order kept); shapes after the first are compared at
        equal travel.
    side_lengths_m : tuple of float or None
        Candidate side lengths of the first shape (m); None: scaled to the robot
        (:func:`scaled_sizes`; the paper's 0.5 .. 10 m for the paper's robot).
    runs_per_direction, trials : int
        Test runs per direction; Monte-Carlo trials per candidate (2000 by default: with common
        random numbers that makes the pick stable from seed to seed; docs/design.md). The
        analytic engines ignore ``trials`` (expected values).
    method : Method
        'heading' or 'umbmark' (squares only).
    validation : ValidationTrack or None
        None: a square scaled to the robot (the paper's 4 m x 4 m CCW for the paper's robot).
    alpha : float
        Significance level of the rule's one-sided tests, in (0, 1).
    tolerance : float
        A larger track must be better by more than this fraction, in [0, 1).
    criterion : Criterion
        What the rule compares ('error' or 'residual').

    :meth:`for_wheelbase` fills the sizes left open; the engines call it with the robot's
    nominal wheelbase, so a spec passed to them may leave them open.
    """

    sides: tuple[int, ...] = (4,)
    side_lengths_m: tuple[float, ...] | None = None
    runs_per_direction: int = 5
    trials: int = 2000
    method: Method = "heading"
    validation: ValidationTrack | None = None
    alpha: float = 0.05
    tolerance: float = 0.05
    criterion: Criterion = "error"

    def __post_init__(self) -> None:
        check_int("runs_per_direction", self.runs_per_direction, at_least=1)
        if check_int("trials", self.trials) < 2:
            raise ModelError(
                f"trials must be >= 2 (a standard deviation is needed), got {self.trials}"
            )
        if isinstance(self.sides, (str, bytes)) or not isinstance(self.sides, Iterable):
            raise ModelError(f"sides must be a sequence of whole numbers, got {self.sides!r}")
        sides = [check_int("sides", s, at_least=3, at_most=MAX_POLYGON_SIDES) for s in self.sides]
        object.__setattr__(self, "sides", tuple(dict.fromkeys(sides)))
        if not self.sides:
            raise ModelError("at least one polygon shape (sides) is needed")
        if self.method not in METHODS:
            raise ModelError(f"method must be heading or umbmark, got {self.method!r}")
        if self.method == "umbmark" and any(s != 4 for s in self.sides):
            raise ModelError("UMBmark is defined for squares only (--sides 4)")
        if self.criterion not in CRITERIA:
            raise ModelError(
                f"criterion must be one of {', '.join(CRITERIA)}, got {self.criterion!r}"
            )
        alpha = check_number("alpha", self.alpha, above=0.0, below=1.0)
        tolerance = check_number("tolerance", self.tolerance, at_least=0.0, below=1.0)
        object.__setattr__(self, "alpha", alpha)
        object.__setattr__(self, "tolerance", tolerance)
        if self.side_lengths_m is not None:
            given = self.side_lengths_m
            if isinstance(given, np.ndarray):
                given = given.tolist() if given.ndim == 1 else [given]
            if isinstance(given, (str, bytes)) or not isinstance(given, Iterable):
                raise ModelError(f"side_lengths_m must be a sequence of lengths, got {given!r}")
            lengths = tuple(check_positive_float("side_lengths_m", v, hint=" m") for v in given)
            if not lengths:
                raise ModelError("at least one candidate side length is needed")
            object.__setattr__(self, "side_lengths_m", lengths)

    def for_wheelbase(self, wheelbase_m: float) -> DesignSpec:
        """This spec with the sizes left open (None) scaled to a robot of ``wheelbase_m`` (m)."""
        if self.side_lengths_m is not None and self.validation is not None:
            return self
        lengths, validation = scaled_sizes(wheelbase_m)
        return replace(
            self,
            side_lengths_m=self.side_lengths_m if self.side_lengths_m is not None else lengths,
            validation=self.validation if self.validation is not None else validation,
        )

    @property
    def scaled(self) -> bool:
        """True when a size is left open (to be scaled to the robot)."""
        return self.side_lengths_m is None or self.validation is None

    @property
    def lengths_m(self) -> np.ndarray:
        """The candidate side lengths of the first shape (m), shape (S,); the spec must give
        them (see :meth:`for_wheelbase`)."""
        if self.side_lengths_m is None:
            raise ModelError("the candidate side lengths are open: call for_wheelbase first")
        return np.asarray(self.side_lengths_m, dtype=float)

    @property
    def validation_track(self) -> ValidationTrack:
        """The validation track; the spec must give it (see :meth:`for_wheelbase`)."""
        if self.validation is None:
            raise ModelError("the validation track is open: call for_wheelbase first")
        return self.validation

    @property
    def simulated_runs(self) -> int:
        """Test runs per direction a Monte-Carlo design simulates (candidates x trials x runs)."""
        n = len(self.side_lengths_m) if self.side_lengths_m is not None else 20
        return n * self.trials * self.runs_per_direction * len(self.sides)
