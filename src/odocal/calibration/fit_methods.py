"""The fit methods and the closed sets of their settings: one registry for the library and the
command line.

Light on purpose (it imports ``typing`` only): ``odocal fit --help`` takes its ``--method``
choices and their help from here without importing numpy, scipy or the app modules.

=============  ==========================================================  ===================
method         what it fits                                                route (odocal.app)
=============  ==========================================================  ===================
trajectory     nonlinear least squares of whole runs against ground truth  ``fit_runs``
linear         Antonelli et al. 2005, the runs' final poses                ``fit_runs``
umbmark        recorded CW and CCW squares (Borenstein & Feng)             ``fit_runs``
heading        recorded CW and CCW polygons, final heading only            ``fit_runs``
gyro           the IMU's rotation against the wheel odometry's (bags)      ``fit_gyro``
relative       relative motions and the sensor's mounting (Censi 2013)     ``fit_relative``
scan           scan matching of a 2D laser, then ``relative``              ``fit_relative``
=============  ==========================================================  ===================
"""

from __future__ import annotations

from typing import Literal, get_args

__all__ = [
    "FitMethod",
    "FIT_METHODS",
    "METHOD_HELP",
    "GROUND_TRUTH_METHODS",
    "RELATIVE_METHODS",
    "methods_help",
    "Residual",
    "RESIDUALS",
    "RunWeight",
    "RUN_WEIGHTS",
    "WheelbaseModel",
    "WHEELBASE_MODELS",
    "HeadingSource",
    "HEADING_SOURCES",
    "UmbmarkForm",
    "UMBMARK_FORMS",
    "Band",
    "BANDS",
]

#: A calibration method of ``odocal fit``.
FitMethod = Literal[
    "trajectory", "linear", "umbmark", "heading", "gyro", "relative", "scan", "auto"
]
#: Every fit method, in the order of ``odocal fit --help``.
FIT_METHODS: tuple[FitMethod, ...] = get_args(FitMethod)

#: What each method does, in a few words (``odocal fit --help``; methods with the same words are
#: listed together).
METHOD_HELP: dict[FitMethod, str] = {
    "trajectory": "nonlinear least squares, default",
    "linear": "Antonelli et al. 2005",
    "umbmark": "recorded CW and CCW squares",
    "heading": "recorded CW and CCW squares",
    "gyro": "IMU vs wheel rotation, bags",
    "relative": "Censi et al. 2013: relative motions with the sensor's mounting; the default "
    "for .tuple files and --truth-frames",
    "scan": "bags with a 2D laser: scan matching, then relative; the laser's mounting too",
    "auto": "one bag: every route it allows, cross-checked, one answer (the default for a "
    "bag when no method and no truth are named); runs with ground truth (folders): the method "
    "and runs with the lowest leave-one-data-set-out error",
}

#: Methods that fit recorded runs against their ground truth (or a gyro heading): one route.
GROUND_TRUTH_METHODS: tuple[FitMethod, ...] = ("trajectory", "linear", "umbmark", "heading")
#: Methods that fit relative motions with the sensor's mounting: one route.
RELATIVE_METHODS: tuple[FitMethod, ...] = ("relative", "scan")

#: The trajectory fit's residual: sampled pose errors, or relative motions over path segments.
Residual = Literal["pose", "segment"]
RESIDUALS: tuple[Residual, ...] = get_args(Residual)
#: The weight of a run in the trajectory fit: its travel in m, or one per run.
RunWeight = Literal["travel", "equal"]
RUN_WEIGHTS: tuple[RunWeight, ...] = get_args(RunWeight)
#: One wheelbase, or one per band of motion (:mod:`odocal.calibration.turning`).
WheelbaseModel = Literal["constant", "banded"]
WHEELBASE_MODELS: tuple[WheelbaseModel, ...] = get_args(WheelbaseModel)
#: Where the heading method takes each run's final heading from.
HeadingSource = Literal["truth", "gyro"]
HEADING_SOURCES: tuple[HeadingSource, ...] = get_args(HeadingSource)
#: Which UMBmark equations: from the x errors, the y errors or their mean.
UmbmarkForm = Literal["x", "y", "mean"]
UMBMARK_FORMS: tuple[UmbmarkForm, ...] = get_args(UmbmarkForm)
#: A band of motion (:mod:`odocal.calibration.turning`), from the tightest turning to straight.
Band = Literal["spot", "tight", "wide", "straight"]
BANDS: tuple[str, ...] = get_args(Band)


def methods_help() -> str:
    """The ``--method`` help: every method with its words, methods that share them together
    ('umbmark / heading (recorded CW and CCW squares)')."""
    parts: list[str] = []
    names: list[str] = []
    for i, name in enumerate(FIT_METHODS):
        names.append(name)
        following = FIT_METHODS[i + 1] if i + 1 < len(FIT_METHODS) else None
        if following is None or METHOD_HELP[following] != METHOD_HELP[name]:
            parts.append(f"{' / '.join(names)} ({METHOD_HELP[name]})")
            names = []
    return ", ".join(parts)
