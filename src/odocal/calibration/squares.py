"""UMBmark and the heading-error method on RECORDED square runs.

For each run, the final error is actual - odometric (model.md): the ground-truth final pose minus
the final pose dead-reckoned from the wheel rotations with the parameters the robot RAN WITH
(``Recording.ran_with``, its firmware values; the ``ran_with`` argument is the fallback for
runs without that metadata). For a closed
square driven on the robot's own odometry the odometric final pose is near the start, so this is
the classic closing error.

Direction from the data: a run is CW if its total true rotation (ground truth theta, unwrapped)
is negative, CCW if positive; a run whose total rotation is not within 45 degrees of +-2 pi
(one closed square) is rejected. A label that disagrees with the data is reported in the
warnings (the data win).

Pooling several data sets: each data set (``meta['dataset']``, else the run's folder) may have run
with its own firmware parameters, so each is calibrated on its own and its correction composed
with ITS parameters (``CalibrationResult.corrected``). Neither method sees the absolute wheel
scale (a closed square cannot; model.md), so the data sets are combined through scale-free
quantities, weighted by their number of runs: the diameter ratio D_R/D_L and the ratio of the
wheelbase to the mean diameter, b/D; the pooled geometry then takes the mean diameter of the
nominal geometry (``nominal``; default the most common ``ran_with``).
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from ..core.model import WheelGeometry, wheel_factors
from ..core.odometry import dead_reckon
from ..core.recording import Recording
from ..core.runs import EndPoseRuns
from ..errors import CalibrationError
from .fit_methods import HEADING_SOURCES, HeadingSource, UmbmarkForm
from .gyro import rotation_ratio_problem
from .heading import calibrate_heading
from .result import DataSetCalibration, GeometryFit, SquaresDetails
from .umbmark import calibrate_umbmark

__all__ = ["recorded_end_errors", "direction_from_data", "fit_recorded_squares", "track_problem"]

_TOL = math.radians(45.0)


def direction_from_data(total_rotation_rad: float) -> str | None:
    """'cw' / 'ccw' for a total rotation within 45 deg of -2 pi / +2 pi, else None."""
    if abs(total_rotation_rad + 2 * math.pi) < _TOL:
        return "cw"
    if abs(total_rotation_rad - 2 * math.pi) < _TOL:
        return "ccw"
    return None


def recorded_end_errors(
    recordings: Sequence[Recording],
    ran_with: WheelGeometry | None = None,
    heading_source: str = "truth",
) -> tuple[EndPoseRuns, list[str]]:
    """EndPoseRuns (directions from the data) and warnings, for closed polygon runs.

    ``heading_source``: 'truth' (the ground truth's final pose) or 'gyro' (the integrated gyro
    heading, bias and mounting handled by the loader; no position: x and y are NaN), the paper's
    point that its method needs only a heading sensor."""
    if heading_source not in HEADING_SOURCES:
        raise CalibrationError(f"heading source must be truth or gyro, got {heading_source!r}")
    dirs, errs, warnings = [], [], []
    for r in recordings:
        geo = r.ran_with or ran_with
        if geo is None:
            raise CalibrationError(
                f"{r.name}: the parameters the robot ran with are unknown (no metadata): "
                "give --robot ROBOT.yaml"
            )
        odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, geo)
        if heading_source == "gyro":
            if r.gyro_yaw_rad is None:
                raise CalibrationError(
                    f"{r.name}: no gyro heading (an IMU topic, or a gyro_yaw_rad column)"
                )
            total = float(r.gyro_yaw_rad[-1] - r.gyro_yaw_rad[0])
            _refuse_gyro_units(r, total, float(odo[-1, 2]))
        else:
            if r.ground_truth is None:
                raise CalibrationError(f"{r.name}: no ground truth (use --heading-source gyro)")
            total = float(r.ground_truth[-1, 2] - r.ground_truth[0, 2])
        d = direction_from_data(total)
        if d is None:
            raise CalibrationError(
                f"{r.name}: not a closed square run (total rotation {math.degrees(total):+.0f} "
                "deg, expected about -360 (CW) or +360 (CCW)); UMBmark and the heading method "
                "need square runs"
            )
        if r.label in ("cw", "ccw") and r.label != d:
            warnings.append(
                f"{Path(r.name).name}: labelled {r.label.upper()} but the data turn "
                f"{d.upper()} ({math.degrees(total):+.0f} deg); using {d.upper()}"
            )
        if heading_source == "gyro":
            gyro = r.gyro_yaw_rad
            assert gyro is not None  # checked above
            errs.append([math.nan, math.nan, (gyro[-1] - gyro[0]) - odo[-1, 2]])
        else:
            assert r.ground_truth is not None  # checked above
            errs.append(r.ground_truth[-1] - odo[-1])
        dirs.append(d)
    return EndPoseRuns(tuple(dirs), np.array(errs)), warnings


def _refuse_gyro_units(r: Recording, gyro_rad: float, odometry_rad: float) -> None:
    """CalibrationError naming the run and its gyro (the IMU topic, or the gyro_yaw_rad column)
    when the gyro's rotation over a run (rad) cannot be the odometry's (rad), the run turning
    (:func:`~odocal.calibration.gyro.rotation_ratio_problem`: mounted upside down, deg/s)."""
    if abs(odometry_rad) < math.pi / 2:  # not a closed polygon: said below
        return
    problem = rotation_ratio_problem(gyro_rad, odometry_rad)
    if problem is not None:
        topic = (r.meta or {}).get("imu_topic")
        source = f"IMU '{topic}'" if topic else "its gyro_yaw_rad column"
        raise CalibrationError(f"{r.name}: {problem} ({source})")


#: A run's odometric travel within this fraction of the polygon's perimeter (sides x side).
TRAVEL_TOLERANCE = 0.10
#: The odometric heading at each side's middle within this fraction of a corner of the turn
#: the polygon has made by then.
CORNER_TOLERANCE = 0.4


def track_problem(
    right_rad: np.ndarray, left_rad: np.ndarray, geometry: WheelGeometry, sides: int, side_m: float
) -> str | None:
    """The recorded wheel motion of one closed run (wheel angles, rad; dead-reckoned with
    ``geometry``, the parameters it ran with) against the polygon it is said to be (``sides``
    sides of ``side_m``, m): None if it drove that polygon, else what differs. The travel must
    be the perimeter within :data:`TRAVEL_TOLERANCE`, and at the middle of side k the heading
    must have turned k corners (within :data:`CORNER_TOLERANCE` of one): a wrong --sides or
    --side-length would otherwise bias the heading method without a word."""
    odo = dead_reckon(right_rad, left_rad, geometry)
    step = np.hypot(np.diff(odo[:, 0]), np.diff(odo[:, 1]))
    travel = np.concatenate([[0.0], np.cumsum(step)])
    perimeter = sides * side_m
    if abs(travel[-1] / perimeter - 1) > TRAVEL_TOLERANCE:
        return (
            f"the wheels travel {travel[-1]:.3g} m, where {sides} sides of {side_m:g} m are "
            f"{perimeter:.3g} m: a wrong --side-length or --sides?"
        )
    corner = 2 * math.pi / sides
    turned = odo[:, 2] - odo[0, 2]
    sign = 1.0 if turned[-1] >= 0 else -1.0
    for k in range(sides):
        i = min(int(np.searchsorted(travel, (k + 0.5) * side_m)), len(travel) - 1)
        if abs(sign * turned[i] - k * corner) > CORNER_TOLERANCE * corner:
            return (
                f"halfway along side {k + 1} the odometry has turned "
                f"{math.degrees(sign * turned[i]):.0f} deg, where a {sides}-gon has turned "
                f"{math.degrees(k * corner):.0f} deg: a wrong --sides or --side-length?"
            )
    return None


def _group(recordings: Sequence[Recording]) -> dict[str, list[Recording]]:
    groups: dict[str, list[Recording]] = {}
    for r in recordings:
        groups.setdefault(r.dataset, []).append(r)
    return groups


def fit_recorded_squares(
    recordings: Sequence[Recording],
    method: str,
    *,
    side_m: float | None = None,
    ran_with: WheelGeometry | None = None,
    nominal: WheelGeometry | None = None,
    umbmark_form: UmbmarkForm = "mean",
    heading_source: HeadingSource = "truth",
    sides: int = 4,
) -> GeometryFit:
    """UMBmark (``method='umbmark'``) or the heading method (``'heading'``) on recorded squares
    (the heading method: any regular ``sides``-gon), per data set, pooled as the module
    docstring says. ``heading_source='gyro'``: the final heading errors from the integrated
    gyro instead of the ground truth (heading method only)."""
    if method not in ("umbmark", "heading"):
        raise CalibrationError(f"method must be umbmark or heading, got {method!r}")
    if method == "umbmark" and (heading_source != "truth" or sides != 4):
        raise CalibrationError(
            "UMBmark needs the final positions of squares measured: use the heading method with "
            "a gyro, or ground truth"
        )
    per_set, warnings = [], []
    for key, runs in _group(recordings).items():
        ends, set_warnings = recorded_end_errors(runs, ran_with, heading_source)
        side = side_m or runs[0].meta.get("side_m")
        if not side:
            raise CalibrationError(
                f"{runs[0].name}: the square side length is unknown: give --side-length"
            )
        geo = runs[0].ran_with or ran_with
        if geo is None:  # recorded_end_errors has refused such runs already
            raise CalibrationError(f"{runs[0].name}: the parameters the robot ran with are unknown")
        for r in runs:
            problem = track_problem(
                r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ran_with or geo, sides, side
            )
            if problem:
                raise CalibrationError(f"{r.name}: not the track given: {problem}")
        warnings += set_warnings
        try:
            if method == "umbmark":
                res = calibrate_umbmark(ends, side, geo, umbmark_form)
            else:
                res = calibrate_heading(ends, sides, side, geo)
        except CalibrationError as exc:
            raise CalibrationError(f"data set {key}: {exc}") from None
        per_set.append((key, len(runs), res, ends))
    if nominal is None:
        counts = Counter((r.ran_with or ran_with) for r in recordings)
        if None in counts:
            del counts[None]
        nominal = counts.most_common(1)[0][0]
    assert nominal is not None
    w = np.array([n for _, n, _, _ in per_set], dtype=float)
    ratio = np.array([res.corrected.diameter_ratio for _, _, res, _ in per_set])
    b_over_d = np.array(
        [res.corrected.wheelbase_m / res.corrected.mean_diameter_m for _, _, res, _ in per_set]
    )
    e_d = float(np.average(ratio, weights=w))
    k = float(np.average(b_over_d, weights=w))
    d_mean = float(nominal.mean_diameter_m)
    c_r, c_l = wheel_factors(e_d)
    geometry = WheelGeometry(d_mean * c_r, d_mean * c_l, k * d_mean)
    data_sets = tuple(
        DataSetCalibration(key, n, ends.count("cw"), ends.count("ccw"), res)
        for key, n, res, ends in per_set
    )
    stderr = dict.fromkeys(("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"))
    if len(per_set) > 1:
        # spread of the per-data-set results (rescaled to the pooled mean diameter)
        vals = np.array(
            [
                [
                    d_mean * 2 * r / (r + 1),
                    d_mean * 2 / (r + 1),
                    kb * d_mean,
                ]
                for r, kb in zip(ratio, b_over_d, strict=True)
            ]
        )
        sd = vals.std(axis=0, ddof=1) / math.sqrt(len(per_set))
        stderr = dict(zip(stderr, map(float, sd), strict=True))
    elif (one := per_set[0][2].uncertainty) is not None:
        # one data set: the run-to-run spread (delta method), kept relative to each value
        res = per_set[0][2]
        unc = one.stderr[2:]
        own = (
            res.corrected.diameter_right_m,
            res.corrected.diameter_left_m,
            res.corrected.wheelbase_m,
        )
        got = (geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m)
        stderr = {k: float(u * g / o) for k, u, g, o in zip(stderr, unc, got, own, strict=True)}
    return GeometryFit(
        method=method,
        geometry=geometry,
        stderr=stderr,
        covariance=None,
        runs=[r.name for r in recordings],
        warnings=warnings,
        squares=SquaresDetails(
            data_sets,
            heading_source,
            sides,
            umbmark_form if method == "umbmark" else None,
        ),
    )
