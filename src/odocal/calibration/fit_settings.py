"""Settings of the fits from recorded runs, validated once where they enter (the command line or a
library call) and then passed down unchanged.

- :class:`TrajectorySettings`: how the trajectory fit compares runs with their ground truth
  (:func:`odocal.calibration.trajectory.fit_trajectory`), also used by the banded fit
  (:func:`odocal.calibration.banded.fit_banded`) and the log check
  (:func:`odocal.calibration.identifiability.check_recordings`), so that the check predicts the
  fit that is run.
- :class:`SquareSettings`: UMBmark and the heading method on recorded polygons
  (:func:`odocal.calibration.squares.fit_recorded_squares`).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

from ..errors import CalibrationError, InputError, ModelError
from .fit_methods import (
    BANDS,
    HEADING_SOURCES,
    RESIDUALS,
    RUN_WEIGHTS,
    UMBMARK_FORMS,
    WHEELBASE_MODELS,
    HeadingSource,
    Residual,
    RunWeight,
    UmbmarkForm,
    WheelbaseModel,
)

__all__ = [
    "check_heading_source",
    "check_method_settings",
    "MAX_HEADING_WEIGHT_M",
    "TrajectorySettings",
    "SquareSettings",
    "DEFAULT_TRAJECTORY",
    "DEFAULT_SQUARES",
]

# Largest heading weight (m of residual per rad): 1 km/rad already ignores the positions.
MAX_HEADING_WEIGHT_M = 1e3


@dataclass(frozen=True)
class TrajectorySettings:
    """How the trajectory fit weighs runs against their ground truth (validated on creation).

    Attributes
    ----------
    residual : {'pose', 'segment'}
        Sampled pose errors, or relative motions over path segments
        (:mod:`odocal.calibration.trajectory`).
    segment_m : float
        Segment travel (m) of the 'segment' residual (and of the outlier statistic).
    heading_weight_m : float
        Metres of residual per radian of heading error, 0 .. :data:`MAX_HEADING_WEIGHT_M`.
    run_weight : {'travel', 'equal'}
        Each run's total weight: its travel in m, or 1.
    samples_per_run : int
        Most pose samples compared per run ('pose' residual).
    exclude : tuple of str
        Runs left out: a run's name, its file name or a substring of it.
    drop_outliers : bool
        Refit once without the runs flagged as outliers (robust z > ``outlier_z``).
    outlier_z : float
        Robust z-score above which a run is an outlier.
    wheelbase_model : {'constant', 'banded'}
        One wheelbase, or one per band of motion (:mod:`odocal.calibration.banded`).
    motion_mix : mapping or None
        Band -> share of the robot's rotation: the banded model is fitted and the single
        exported wheelbase is the best one for this mix of its band wheelbases
        (:func:`odocal.calibration.turning.wheelbase_for_mix`; a share in a band the runs do not
        excite is refused); None: the constant fit's own wheelbase (banded: the runs' own mix).
    """

    residual: Residual = "pose"
    segment_m: float = 1.0
    heading_weight_m: float = 0.1
    run_weight: RunWeight = "travel"
    samples_per_run: int = 200
    exclude: tuple[str, ...] = ()
    drop_outliers: bool = False
    outlier_z: float = 3.5
    wheelbase_model: WheelbaseModel = "constant"
    motion_mix: Mapping[str, float] | None = field(default=None, hash=False)

    def __post_init__(self) -> None:
        if self.run_weight not in RUN_WEIGHTS:
            raise CalibrationError(
                f"run_weight must be one of {', '.join(RUN_WEIGHTS)}, got {self.run_weight!r}"
            )
        if self.residual not in RESIDUALS:
            raise CalibrationError(
                f"residual must be one of {', '.join(RESIDUALS)}, got {self.residual!r}"
            )
        if not 0.0 <= self.heading_weight_m <= MAX_HEADING_WEIGHT_M:  # also rejects NaN
            raise CalibrationError(
                f"heading_weight_m must be between 0 and {MAX_HEADING_WEIGHT_M:g} m/rad (beyond, "
                "the position no longer counts and the squares overflow), got "
                f"{self.heading_weight_m!r}"
            )
        if not (self.segment_m > 0 and math.isfinite(self.segment_m)):
            raise CalibrationError(f"segment_m must be finite and > 0, got {self.segment_m!r}")
        if not (isinstance(self.samples_per_run, int) and self.samples_per_run >= 1):
            raise CalibrationError(
                f"samples_per_run must be an integer >= 1, got {self.samples_per_run!r}"
            )
        if not self.outlier_z > 0:  # also rejects NaN
            raise CalibrationError(f"outlier_z must be > 0, got {self.outlier_z!r}")
        if self.wheelbase_model not in WHEELBASE_MODELS:
            raise InputError(
                f"wheelbase model must be one of {', '.join(WHEELBASE_MODELS)}, got "
                f"{self.wheelbase_model!r}",
                field="wheelbase-model",
            )
        object.__setattr__(self, "exclude", _patterns(self.exclude))
        if self.motion_mix is not None:
            object.__setattr__(self, "motion_mix", _checked_mix(self.motion_mix))


def _patterns(exclude: Iterable[str] | str) -> tuple[str, ...]:
    """``exclude`` as a tuple of patterns (one string is one pattern)."""
    return (exclude,) if isinstance(exclude, str) else tuple(exclude)


def _checked_mix(mix: Mapping[str, float]) -> dict[str, float]:
    """A copy of the motion mix ``mix`` (band -> share, in its order), its bands and shares
    checked (the shares are not normalised: the estimators weigh them relative to each other)."""
    out = dict(mix)
    for name, share in out.items():
        if name not in BANDS:
            raise CalibrationError(
                f"motion mix: band must be one of {', '.join(BANDS)}, got {name!r}"
            )
        if not (math.isfinite(share) and share >= 0):
            raise CalibrationError(f"motion mix: a share must be >= 0, got {share!r}")
    if out and sum(out.values()) <= 0:
        raise CalibrationError("motion mix: the shares must not all be 0")
    return out


@dataclass(frozen=True)
class SquareSettings:
    """UMBmark and the heading method on recorded polygons (validated on creation).

    Attributes
    ----------
    side_m : float or None
        The polygon's side (m); None: from the recordings' metadata.
    umbmark_form : {'x', 'y', 'mean'}
        UMBmark's equations from the x errors, the y errors or their mean.
    heading_source : {'truth', 'gyro'}
        The heading method's final heading errors from the ground truth or the integrated gyro.
    sides : int
        The heading method: the runs are regular ``sides``-gons.
    """

    side_m: float | None = None
    umbmark_form: UmbmarkForm = "mean"
    heading_source: HeadingSource = "truth"
    sides: int = 4

    def __post_init__(self) -> None:
        if self.heading_source not in HEADING_SOURCES:
            raise CalibrationError(
                f"heading source must be truth or gyro, got {self.heading_source!r}"
            )
        if self.umbmark_form not in UMBMARK_FORMS:
            raise ModelError(
                f"UMBmark form must be one of {', '.join(UMBMARK_FORMS)}, got {self.umbmark_form!r}"
            )


#: The defaults of every setting.
DEFAULT_TRAJECTORY = TrajectorySettings()
DEFAULT_SQUARES = SquareSettings()


def check_heading_source(method: str | None, heading_source: HeadingSource) -> None:
    """The gyro heading is for the heading method only."""
    if heading_source == "gyro" and method != "heading":
        raise InputError(f"--heading-source gyro is for --method heading, not {method}")


def check_method_settings(
    method: str, settings: TrajectorySettings, squares: SquareSettings
) -> None:
    """The settings that only some methods take."""
    if method != "trajectory" and (settings.wheelbase_model != "constant" or settings.motion_mix):
        raise InputError(
            "--wheelbase-model banded and --motion-mix need the trajectory method "
            "(--method trajectory)",
            field="method",
        )
    check_heading_source(method, squares.heading_source)
