"""``odocal check BAG... --kinematics skid-steer``: is this log enough for a skid-steer robot's
effective track?

A skid-steer robot's random error is its slip, not its wheels' noise, and a stated ``k`` and
tracker noise say nothing of it. So the standard errors this check prints
are the skid-steer fit's own (cluster-robust over 15 s blocks of the log's own residuals, the
truth's clock offset's share added: :func:`~odocal.calibration.skid_steer.fit_skid_logs`),
mapped onto D_R, D_L and b (the effective track), and judged by the differential-drive check's
thresholds; the motion, its degenerate motions and the blind directions are the
differential-drive check's of the same motion (:mod:`odocal.app.check`), linearised at the fitted
effective geometry. It also says at which turn rates the multiplier's curve can be read.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import numpy as np

from ..calibration.identifiability import NoiseModel, with_prediction
from ..calibration.skid_steer import (
    SkidIntervals,
    SkidLog,
    fit_skid_logs,
    offset_at,
    skid_intervals,
    turn_rate_knots,
)
from ..calibration.time_offset import TimeOffset
from ..core.model import Robot, WheelGeometry
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from .check import CheckResult, check_loaded
from .fit_skid import EXPORTED, read_skid_logs, skid_recordings

__all__ = ["check_skid", "check_skid_logs", "SKID_NOISE"]

#: Where the check's standard errors come from, in words.
SKID_NOISE = (
    "the skid-steer fit's own errors (cluster-robust over 15 s blocks of the log's residuals: "
    "its slip; the truth's clock offset's share added), as D_R, D_L and the effective track b"
)


def _covariance(
    logs: Sequence[SkidLog], nominal: WheelGeometry, offsets: Sequence[TimeOffset]
) -> tuple[WheelGeometry | None, np.ndarray | None, str]:
    """The exported model fitted to ``logs`` (effective track, a wheel scale per side) and the
    covariance of (D_R, D_L, b) it implies; (None, None, why) when it cannot be fitted."""
    try:
        fit, _ = fit_skid_logs(logs, nominal, EXPORTED[0], offsets=offsets,
                               wheel_scales=EXPORTED[1])  # fmt: skip
    except CalibrationError as exc:
        return None, None, str(exc)
    names = ("scale_right", "scale_left", "track_multiplier")
    idx = [fit.names.index(n) for n in names]
    jac = np.diag([nominal.diameter_right_m, nominal.diameter_left_m, nominal.wheelbase_m])
    cov = jac @ fit.covariance[np.ix_(idx, idx)] @ jac.T
    geometry = WheelGeometry(
        nominal.diameter_right_m * fit.value("scale_right"),
        nominal.diameter_left_m * fit.value("scale_left"),
        nominal.wheelbase_m * fit.value("track_multiplier"),
    )
    return geometry, cov, ""


def _curve_note(
    logs: Sequence[SkidLog],
    nominal: WheelGeometry,
    offsets: Sequence[TimeOffset],
    multiplier: float | None,
) -> str:
    """At which turn rates the multiplier's curve can be read (the turn-rate model's knots: the
    nominal wheels' yaw rates; over ``multiplier``, about the robot's)."""
    parts = [
        skid_intervals(log, offset_s=offset_at(o, log))
        for log, o in zip(logs, offsets, strict=True)
    ]
    try:
        knots = turn_rate_knots(SkidIntervals.concatenate(parts), nominal)
    except CalibrationError as exc:
        return f"the multiplier against the turn rate cannot be read: {exc}"
    rates = ", ".join(f"{k / (multiplier or 1.0):.2g}" for k in knots)
    what = "yaw rates of about" if multiplier else "nominal wheel yaw rates"
    return (
        f"the multiplier against the turn rate can be read at {what} {rates} rad/s (each with "
        "a full turn near it); a controller turning faster or slower is extrapolated"
    )


def check_skid_logs(logs: Sequence[SkidLog], robot: Robot) -> CheckResult:
    """The check of skid-steer logs already read (module docstring)."""
    if not logs:
        raise InputError("no recording to check")
    nominal = robot.nominal
    recordings, offsets = skid_recordings(logs)
    geometry, cov, why = _covariance(logs, nominal, offsets)
    stated = "the motion's findings at the stated noise (a skid-steer log's own is its slip)"
    res = check_loaded(
        recordings, geometry or nominal, robot, noise=(NoiseModel(), stated)
    )  # fmt: skip
    if cov is not None:
        chk = with_prediction(res.check, cov, "the skid-steer fit (its own residuals)")
        res = replace(res, check=chk, noise_source=SKID_NOISE)
    notes = []
    for o in offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        notes.append(f"clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.how}; applied)")
    if cov is None:
        notes.append(f"no skid-steer fit of this log ({why}): the errors are the stated noise's")
    mult = None if geometry is None else float(geometry.wheelbase_m / nominal.wheelbase_m)
    notes.append(_curve_note(logs, nominal, offsets, mult))
    return replace(
        res, kinematics="skid-steer", notes=tuple(notes),
        load_warnings=tuple(w for o in offsets for w in o.warnings),
    )  # fmt: skip


def check_skid(
    paths: Sequence[str | Path],
    robot: Robot | None,
    bag: BagOptions,
    ticks_per_rev: float | None = None,
) -> CheckResult:
    """``check BAG... --kinematics skid-steer``: the bags read as the skid-steer fit reads them,
    checked (:func:`check_skid_logs`)."""
    if robot is None:
        raise InputError(
            "--kinematics skid-steer needs the robot file (--robot ROBOT.yaml): the nominal "
            "wheel diameter and wheelbase the effective track is relative to"
        )
    return check_skid_logs(read_skid_logs(paths, bag, robot, ticks_per_rev), robot)
