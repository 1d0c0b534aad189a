"""Gyro-only heading calibration: compare the rotation a gyro measures with wheel odometry's.

No external position sensor is needed (the paper's point: a heading sensor suffices). Over a run,

    rotation_ratio = gyro rotation / odometry rotation      (net heading change, rad / rad)

For a differential drive the odometric heading is theta = (s_R - s_L) / b, so if the gyro turns
``rotation_ratio`` times more than the odometry believes, the wheelbase that reproduces the gyro
is b / rotation_ratio:

    wheelbase_multiplier = 1 / rotation_ratio      (b_corrected = wheelbase_multiplier * b_used)

This is the direction of ros2_control's ``diff_drive_controller`` parameter
``wheel_separation_multiplier``: the controller uses ``wheel_separation_multiplier *
wheel_separation`` as b in its odometry (angular = (v_R - v_L) / b), so the new multiplier is the
old one times ``wheelbase_multiplier``. The ratio mixes the wheelbase error with the gyro's own
scale-factor error (typically 0.1 to 1 % for MEMS gyros); a closed run also lets per-leg curvature
(the diameter ratio E_d) contribute, which cancels for runs that turn on the spot.

Inputs are plain time series (numpy only; see :mod:`odocal.io.bags` for reading them from bags):

- IMU angular velocity, shape (K, 3) in the IMU frame, with times (s);
- odometry heading (rad, unwrapped) or heading rate (rad/s), and optionally its forward speed
  (m/s), with times (s).

IMU mounting: the base's z axis expressed in the IMU frame, from a rotation matrix
``R_base_imu`` (maps IMU-frame vectors to the base frame, as a ``base_link -> imu_link``
transform does), a named axis (``'x'``, ``'-y'``, ...), or detected from the data (the axis whose
rate correlates best with the odometry heading rate; a warning is added).

Gyro bias: estimated from still periods (odometry speed and heading rate near zero for at least
``min_still_s``) with a batch-means standard error. ``bias='auto'`` (default) removes it only when
it is statistically significant (|bias| > 2 standard errors), otherwise reports what removing it
would change; ``'still'`` always removes it, ``'none'`` never, a number (rad/s, on the yaw axis)
is removed as given.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..errors import CalibrationError
from .result import ABSURD_FRACTION

__all__ = [
    "AXES",
    "DEG_PER_RAD",
    "rotation_ratio_problem",
    "GyroResult",
    "axis_vector",
    "rotation_from_quaternion",
    "rotation_from_rpy",
    "integrate_rate",
    "still_intervals",
    "detect_yaw_axis",
    "still_bias",
    "choose_bias",
    "gyro_calibration",
    "ratio_stderr",
    "yaw_axis",
    "GyroHeading",
    "gyro_heading",
]

AXES = ("x", "y", "z", "-x", "-y", "-z")

# A detected axis must correlate at least this well with the odometry heading rate.
_MIN_DETECT_CORRELATION = 0.5


#: A gyro that reports deg/s turns this many times as much as the odometry.
DEG_PER_RAD = 180.0 / math.pi


def rotation_ratio_problem(gyro_rad: float, odometry_rad: float) -> str | None:
    """The gyro's rotation against the odometry's over the same stretch (rad, both non-zero):
    None when their ratio can be a robot's; else what is wrong: they turn in opposite
    directions (the IMU mounted upside down, or its yaw axis reversed), or the ratio is within
    :data:`~odocal.calibration.result.ABSURD_FRACTION` of :data:`DEG_PER_RAD` (the gyro in
    degrees, where sensor_msgs/Imu's unit is rad/s)."""
    ratio = gyro_rad / odometry_rad
    g, o = math.degrees(gyro_rad), math.degrees(odometry_rad)
    if ratio <= 0:
        return (
            f"the gyro ({g:+.1f} deg) and the odometry ({o:+.1f} deg) turn in opposite "
            "directions: the IMU is mounted upside down or its yaw axis is reversed; correct "
            "/tf_static or give --imu-axis"
        )
    if abs(ratio / DEG_PER_RAD - 1) <= ABSURD_FRACTION:
        return (
            f"the gyro turns {ratio:.4g} times as much as the odometry ({g:+.0f} deg against "
            f"{o:+.0f} deg), about 180/pi = {DEG_PER_RAD:.1f}: it is in degrees (deg/s), where "
            "sensor_msgs/Imu and odocal use radians (rad/s)"
        )
    return None


def axis_vector(axis: str) -> np.ndarray:
    """Unit vector, shape (3,), of a named IMU axis: 'x', 'y', 'z', optionally '+' or '-'."""
    a = str(axis).strip().lower()
    sign = -1.0 if a.startswith("-") else 1.0
    a = a.lstrip("+-")
    if a not in ("x", "y", "z"):
        raise CalibrationError(f"IMU axis must be one of {', '.join(AXES)}, got {axis!r}")
    v = np.zeros(3)
    v["xyz".index(a)] = sign
    return v


def _axis_name(v: np.ndarray) -> str | None:
    """'y', '-z', ... if ``v`` is (close to) a signed coordinate axis, else None."""
    i = int(np.argmax(np.abs(v)))
    if abs(abs(v[i]) - 1.0) < 1e-6:
        return ("-" if v[i] < 0 else "") + "xyz"[i]
    return None


def rotation_from_quaternion(q_xyzw: Sequence[float]) -> np.ndarray:
    """Rotation matrix, shape (3, 3), of a quaternion (x, y, z, w) (ROS order; normalised)."""
    x, y, z, w = (float(c) for c in q_xyzw)
    n = math.sqrt(x * x + y * y + z * z + w * w)
    if not math.isfinite(n) or n < 1e-9:
        raise CalibrationError(f"not a rotation quaternion: {tuple(q_xyzw)!r}")
    x, y, z, w = x / n, y / n, z / n, w / n
    return np.array(
        [
            [1 - 2 * (y * y + z * z), 2 * (x * y - z * w), 2 * (x * z + y * w)],
            [2 * (x * y + z * w), 1 - 2 * (x * x + z * z), 2 * (y * z - x * w)],
            [2 * (x * z - y * w), 2 * (y * z + x * w), 1 - 2 * (x * x + y * y)],
        ]
    )


def rotation_from_rpy(roll_rad: float, pitch_rad: float, yaw_rad: float) -> np.ndarray:
    """Rotation matrix, shape (3, 3), R = Rz(yaw) Ry(pitch) Rx(roll) (ROS/URDF rpy, fixed axes).

    Note that ``static_transform_publisher x y z yaw pitch roll`` takes them in the other order.
    """
    cr, sr = math.cos(roll_rad), math.sin(roll_rad)
    cp, sp = math.cos(pitch_rad), math.sin(pitch_rad)
    cy, sy = math.cos(yaw_rad), math.sin(yaw_rad)
    rz = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1]])
    ry = np.array([[cp, 0, sp], [0, 1, 0], [-sp, 0, cp]])
    rx = np.array([[1, 0, 0], [0, cr, -sr], [0, sr, cr]])
    return rz @ ry @ rx


def _vec3(v: Sequence[float] | np.ndarray) -> tuple[float, float, float]:
    return (float(v[0]), float(v[1]), float(v[2]))


def integrate_rate(time_s: ArrayLike, rate: ArrayLike) -> np.ndarray:
    """Cumulative trapezoid integral of ``rate`` (shape (K,)) over ``time_s`` (s), starting at 0."""
    t = np.asarray(time_s, dtype=float)
    r = np.asarray(rate, dtype=float)
    return np.concatenate([[0.0], np.cumsum(0.5 * (r[1:] + r[:-1]) * np.diff(t))])


def still_intervals(
    time_s: ArrayLike,
    yaw_rate_rad_s: ArrayLike,
    speed_m_s: ArrayLike | None = None,
    *,
    max_speed_m_s: float = 0.005,
    max_yaw_rate_rad_s: float = 0.005,
    min_duration_s: float = 1.0,
) -> list[tuple[float, float]]:
    """Intervals (start_s, end_s) where the odometry says the robot stands still.

    A sample is still when |yaw rate| <= ``max_yaw_rate_rad_s`` and (if given) |speed| <=
    ``max_speed_m_s``; consecutive still samples spanning at least ``min_duration_s`` form an
    interval. Arrays have shape (K,).
    """
    t = np.asarray(time_s, dtype=float)
    still = np.abs(np.asarray(yaw_rate_rad_s, dtype=float)) <= max_yaw_rate_rad_s
    if speed_m_s is not None:
        still &= np.abs(np.asarray(speed_m_s, dtype=float)) <= max_speed_m_s
    edges = np.diff(np.concatenate([[0], still.astype(np.int8), [0]]))
    starts = np.nonzero(edges == 1)[0]
    ends = np.nonzero(edges == -1)[0] - 1
    return [
        (float(t[s]), float(t[e]))
        for s, e in zip(starts, ends, strict=True)
        if t[e] - t[s] >= min_duration_s
    ]


def _rate(time_s: np.ndarray, angle: np.ndarray) -> np.ndarray:
    return np.gradient(angle, time_s) if len(time_s) > 2 else np.zeros_like(angle)


def detect_yaw_axis(
    imu_time_s: ArrayLike,
    angular_velocity: ArrayLike,
    odom_time_s: ArrayLike,
    odom_yaw_rad: ArrayLike,
) -> tuple[str, float, dict[str, float]]:
    """The IMU axis whose heading increments correlate best with the odometry's.

    Compares increments over the odometry sample intervals (so a small time lag hardly
    matters). Returns (axis name such as '-y', correlation in [0, 1], {'x': c, 'y': c, 'z': c}
    with signed correlations).
    """
    t_i = np.asarray(imu_time_s, dtype=float)
    w = np.asarray(angular_velocity, dtype=float)
    t_o = np.asarray(odom_time_s, dtype=float)
    th_o = np.asarray(odom_yaw_rad, dtype=float)
    inside = (t_o >= t_i[0]) & (t_o <= t_i[-1])
    t_c, d_o = t_o[inside], np.diff(th_o[inside])
    corr = {}
    slope = {}
    d_oo = float(np.dot(d_o, d_o)) if len(d_o) else 0.0
    for k, name in enumerate("xyz"):
        d_g = np.diff(np.interp(t_c, t_i, integrate_rate(t_i, w[:, k])))
        denom = math.sqrt(float(np.dot(d_g, d_g)) * d_oo)
        corr[name] = float(np.dot(d_g, d_o) / denom) if denom > 0 else 0.0
        slope[name] = float(np.dot(d_g, d_o) / d_oo) if d_oo > 0 else 0.0
    # Ranked by how much of the heading each axis carries (the regression slope of its
    # increments on the odometry's, ~1 on the yaw axis), not by the correlation alone: the
    # correlation is blind to scale, so an axis that sees the yaw rate only through a rounding
    # residue of the mounting rotation (1e-16 of it) correlates as well as the yaw axis itself.
    best = max("xyz", key=lambda a: (abs(slope[a]), "xyz".index(a) * -1))
    name = ("-" if corr[best] < 0 else "") + best
    return name, abs(corr[best]), corr


def _batch_stderr(samples: np.ndarray, time_s: np.ndarray, batch_s: float = 0.5) -> float:
    """Standard error of the mean of a correlated series by batch means (batches of ~batch_s)."""
    n = len(samples)
    if n < 2:
        return math.inf
    dt = float(np.median(np.diff(time_s))) if n > 1 else batch_s
    m = max(1, int(round(batch_s / dt))) if dt > 0 else 1
    nb = n // m
    if nb >= 4:
        means = samples[: nb * m].reshape(nb, m).mean(axis=1)
        return float(means.std(ddof=1) / math.sqrt(nb))
    return float(samples.std(ddof=1) / math.sqrt(n))


def still_bias(
    time_s: ArrayLike, yaw_rate_rad_s: ArrayLike, intervals: Sequence[tuple[float, float]]
) -> tuple[float | None, float | None, int, float]:
    """Gyro yaw-rate bias from the samples inside still ``intervals``.

    Returns (mean rad/s or None, batch-means standard error rad/s or None, samples, seconds).
    """
    t = np.asarray(time_s, dtype=float)
    r = np.asarray(yaw_rate_rad_s, dtype=float)
    inside = np.zeros(len(t), dtype=bool)
    for a, b in intervals:
        inside |= (t >= a) & (t <= b)
    n = int(inside.sum())
    seconds = float(sum(b - a for a, b in intervals))
    if n < 2:
        return None, None, n, seconds
    return float(r[inside].mean()), _batch_stderr(r[inside], t[inside]), n, seconds


def choose_bias(
    bias: str | float, estimate: float | None, stderr: float | None, min_still_s: float = 1.0
) -> tuple[float, str, str | None]:
    """Apply the ``bias`` policy (module docstring) to a still-period estimate.

    Returns (bias to remove rad/s, source label, warning text or None).
    """
    if isinstance(bias, str):
        mode = bias.lower()
        if mode not in ("auto", "still", "none"):
            raise CalibrationError(
                f"bias must be 'auto', 'still', 'none' or a number, got {bias!r}"
            )
    else:
        if not math.isfinite(float(bias)):
            raise CalibrationError(f"bias must be finite, got {bias!r}")
        return float(bias), "given", None
    if mode == "none":
        return 0.0, "none", None
    if estimate is None:
        return (
            0.0,
            "none",
            f"no still period of at least {min_still_s:g} s: gyro bias not removed "
            "(record some seconds standing still before and after driving)",
        )
    assert stderr is not None  # an estimate comes with its standard error
    if mode == "still" or abs(estimate) > 2.0 * stderr:
        return float(estimate), "still", None
    return 0.0, "none (still-period estimate not significant)", None


@dataclass(frozen=True)
class GyroResult:
    """Outcome of a gyro-only heading calibration (see the module docstring).

    Angles in rad, rates in rad/s, times in s.
    """

    rotation_ratio: float
    wheelbase_multiplier: float
    gyro_rotation_rad: float
    odometry_rotation_rad: float
    odometry_abs_rotation_rad: float
    rotation_ratio_uncorrected: float
    rotation_ratio_bias_corrected: float | None
    rotation_ratio_stderr: float | None
    yaw_axis_in_imu: tuple[float, float, float]
    axis: str
    mounting_source: str
    axis_correlation: dict
    bias_rad_s: float
    bias_source: str
    bias_estimate_rad_s: float | None
    bias_stderr_rad_s: float | None
    still_duration_s: float
    still_samples: int
    imu_samples: int
    odometry_samples: int
    start_s: float
    duration_s: float
    warnings: tuple[str, ...] = ()
    meta: dict = field(default_factory=dict)

    @property
    def total_rotations(self) -> float:
        """Net odometric rotation in turns (signed, CCW +)."""
        return self.odometry_rotation_rad / (2.0 * math.pi)

    def as_dict(self) -> dict:
        """The JSON of ``odocal fit BAG --method gyro --json`` (non-finite values as None)."""

        def num(v: float | None) -> float | None:
            return None if v is None or not math.isfinite(v) else float(v)

        d = {
            "method": "gyro",
            "rotation_ratio": num(self.rotation_ratio),
            "wheelbase_multiplier": num(self.wheelbase_multiplier),
            "gyro_rotation_rad": num(self.gyro_rotation_rad),
            "odometry_rotation_rad": num(self.odometry_rotation_rad),
            "odometry_abs_rotation_rad": num(self.odometry_abs_rotation_rad),
            "total_rotations": num(self.total_rotations),
            "rotation_ratio_uncorrected": num(self.rotation_ratio_uncorrected),
            "rotation_ratio_bias_corrected": num(self.rotation_ratio_bias_corrected),
            "rotation_ratio_stderr": num(self.rotation_ratio_stderr),
            "axis": self.axis,
            "yaw_axis_in_imu": [float(c) for c in self.yaw_axis_in_imu],
            "mounting_source": self.mounting_source,
            "axis_correlation": {k: num(v) for k, v in self.axis_correlation.items()},
            "bias_rad_s": num(self.bias_rad_s),
            "bias_source": self.bias_source,
            "bias_estimate_rad_s": num(self.bias_estimate_rad_s),
            "bias_stderr_rad_s": num(self.bias_stderr_rad_s),
            "still_duration_s": num(self.still_duration_s),
            "still_samples": int(self.still_samples),
            "imu_samples": int(self.imu_samples),
            "odometry_samples": int(self.odometry_samples),
            "start_s": num(self.start_s),
            "duration_s": num(self.duration_s),
            "warnings": list(self.warnings),
        }
        for k, v in self.meta.items():
            d.setdefault(k, v)
        return d


def yaw_axis(
    imu_time_s: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    ref_time_s: ArrayLike,
    ref_heading: ArrayLike,
    *,
    rotation: ArrayLike | None = None,
    imu_axis: str | None = None,
    mounting_source: str | None = None,
) -> tuple[np.ndarray, str, str, dict[str, float], list[str]]:
    """The base's z axis in IMU coordinates: from ``rotation`` (R_base_imu), else the named
    ``imu_axis``, else detected from the data (the axis whose integrated rate correlates best with
    ``ref_heading``, any series proportional to the heading, e.g. right minus left wheel angle).

    Returns (n shape (3,), source, detected axis name, signed correlations per axis, warnings).
    A given mounting that the data contradict is kept, with a warning.
    """
    detected, det_corr, corr = detect_yaw_axis(
        imu_time_s, angular_velocity_rad_s, ref_time_s, ref_heading
    )
    warnings = []
    if rotation is not None:
        r = np.asarray(rotation, dtype=float)
        if r.shape != (3, 3) or not np.allclose(r @ r.T, np.eye(3), atol=1e-6):
            raise CalibrationError("rotation must be a 3x3 rotation matrix")
        n = r[2, :].copy()
        source = mounting_source or "rotation"
    elif imu_axis is not None:
        n = axis_vector(imu_axis)
        source = mounting_source or "flag"
    else:
        if det_corr < _MIN_DETECT_CORRELATION:
            raise CalibrationError(
                "cannot detect the IMU's yaw axis: no axis correlates with the odometry heading "
                f"rate (best {detected}, correlation {det_corr:.2f}); give the IMU axis"
            )
        n = axis_vector(detected)
        source = "detected"
        warnings.append(
            f"IMU mounting detected from the data: yaw on the IMU's {detected} axis "
            f"(correlation {det_corr:.3f}); give the axis or publish /tf_static to make it explicit"
        )
    if source != "detected":
        c = float(np.dot(n, [corr["x"], corr["y"], corr["z"]]))
        axis = _axis_name(n) or "rotation"
        if det_corr >= _MIN_DETECT_CORRELATION and c < 0.5 * det_corr:
            warnings.append(
                f"the given IMU mounting ({source}, yaw on {axis}) correlates {c:.2f} with the "
                f"odometry, the data suggest {detected} ({det_corr:.2f})"
            )
    return n, source, detected, corr, warnings


@dataclass(frozen=True)
class GyroHeading:
    """The integrated gyro heading at reference times, and how it was obtained.

    ``yaw_rad`` shape (M,), starting at 0 (rad, CCW +, unwrapped); ``yaw_axis_in_imu`` the base z
    axis in IMU coordinates; ``bias_rad_s`` the bias removed and ``bias_source`` why.
    """

    yaw_rad: np.ndarray
    yaw_axis_in_imu: tuple[float, float, float]
    mounting_source: str
    bias_rad_s: float
    bias_source: str
    warnings: tuple[str, ...] = ()


def gyro_heading(
    imu_time_s: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    time_s: ArrayLike,
    turn_rad: ArrayLike,
    travel_rad: ArrayLike | None = None,
    *,
    rotation: ArrayLike | None = None,
    imu_axis: str | None = None,
    mounting_source: str | None = None,
    bias: str | float = "auto",
    max_still_rate: float = 0.02,
    min_still_s: float = 1.0,
) -> GyroHeading:
    """Integrate a gyro into a heading at ``time_s`` (s, shape (M,)), mounting and bias handled.

    Without a wheel geometry, wheel angles stand in for the odometry: ``turn_rad`` (shape (M,),
    e.g. right minus left wheel angle, rad) for the axis detection and ``travel_rad`` (e.g. the
    mean wheel angle) with it for standing still: still where both change slower than
    ``max_still_rate`` (rad/s of wheel angle) for ``min_still_s``. Bias policy as
    :func:`choose_bias`. Mounting as :func:`yaw_axis`.
    """
    t_i = np.asarray(imu_time_s, dtype=float)
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    t = np.asarray(time_s, dtype=float)
    turn = np.asarray(turn_rad, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3:
        raise CalibrationError(f"angular velocity must have shape (K, 3), got {w.shape}")
    _check_series("IMU", t_i, w)
    n, source, _, _, warnings = yaw_axis(
        t_i, w, t, turn, rotation=rotation, imu_axis=imu_axis, mounting_source=mounting_source
    )
    rate = w @ n
    turn_rate = _rate(t, turn)
    travel_rate = None if travel_rad is None else _rate(t, np.asarray(travel_rad, dtype=float))
    b = _bias(
        t_i, rate, t, turn_rate, travel_rate, max_still_rate, max_still_rate, min_still_s, bias
    )
    applied, bias_source = b.applied, b.source
    warnings += b.notes
    yaw = np.interp(t, t_i, integrate_rate(t_i, rate - applied))
    return GyroHeading(
        yaw - yaw[0],
        _vec3(n),
        source,
        float(applied),
        bias_source,
        tuple(warnings),
    )


@dataclass(frozen=True)
class _Bias:
    estimate: float | None
    stderr: float | None
    samples: int
    seconds: float
    applied: float
    source: str
    notes: tuple[str, ...]


def _bias(
    imu_time_s: ArrayLike,
    yaw_rate: ArrayLike,
    ref_time_s: ArrayLike,
    ref_turn_rate: ArrayLike,
    ref_speed: ArrayLike | None,
    max_speed: float,
    max_turn: float,
    min_s: float,
    policy: str | float,
) -> _Bias:
    """The gyro bias from the reference's still periods, and what the policy removes."""
    intervals = still_intervals(
        ref_time_s,
        ref_turn_rate,
        ref_speed,
        max_speed_m_s=max_speed,
        max_yaw_rate_rad_s=max_turn,
        min_duration_s=min_s,
    )
    est, se, n, seconds = still_bias(imu_time_s, yaw_rate, intervals)
    applied, source, note = choose_bias(policy, est, se, min_s)
    return _Bias(est, se, n, seconds, applied, source, (note,) if note else ())


def _check_series(name: str, t: np.ndarray, values: np.ndarray) -> None:
    if t.ndim != 1 or len(t) < 2:
        raise CalibrationError(f"{name}: need at least two samples, got {len(t)}")
    if len(values) != len(t):
        raise CalibrationError(f"{name}: {len(values)} values for {len(t)} times")
    if not (np.all(np.isfinite(t)) and np.all(np.isfinite(values))):
        raise CalibrationError(f"{name}: values must be finite")
    if np.any(np.diff(t) <= 0):
        raise CalibrationError(f"{name}: times must be strictly increasing")


#: Interval length (s) of the ratio's uncertainty model.
_RATIO_INTERVAL_S = 1.0


def ratio_stderr(
    imu_time_s: np.ndarray,
    gyro_yaw_rad: np.ndarray,
    odom_time_s: np.ndarray,
    odom_yaw_rad: np.ndarray,
    lo: float,
    hi: float,
    odom_net_rad: float,
    bias_applied: float,
    still_estimate: float | None,
    still_stderr: float | None,
    still_applied: bool,
) -> float | None:
    """Standard error of the net rotation ratio ``R = (G - b T) / O`` over ``[lo, hi]`` (the
    gyro's raw rotation G with the bias b applied, the odometry's O, the span T), from a model
    of the run cut into intervals of about 1 s:

        g_k = rho o_k + beta dt_k + e_k

    fitted by least squares (the gyro's rotation g_k over each interval against the
    odometry's o_k and the interval's duration). Two terms:

    - the bias error ``(T / O)^2 V_b``: the still periods' standard error when their bias was
      removed; their estimate and its error when it was not (``est^2 + se^2``); without a still
      period, the bias the intervals say (``beta - b``) and its cluster-robust error, which is
      large when the run turns at one steady rate (the bias and the ratio cannot be told apart)
      and small when it turns both ways or stops;
    - the noise and drift ``V_E / O^2``: the residuals summed over contiguous time blocks
      (:func:`~odocal.calibration.time_offset.time_blocks`), then squared and added, so that a
      bias that wanders (a random walk) or turns the model cannot follow count as what they are.

    None when the run is too short for two blocks."""
    from .robust_covariance import cluster_covariance
    from .time_offset import time_blocks

    n = int((hi - lo) // _RATIO_INTERVAL_S)
    if n < 4:
        return None
    edges = np.linspace(lo, hi, n + 1)
    g = np.diff(np.interp(edges, imu_time_s, gyro_yaw_rad))
    o = np.diff(np.interp(edges, odom_time_s, odom_yaw_rad))
    dt = np.diff(edges)
    x = np.column_stack([o, dt])
    coef, *_ = np.linalg.lstsq(x, g, rcond=None)
    resid = g - x @ coef
    blocks = time_blocks(edges[:-1])
    m = int(blocks.max()) + 1
    if m < 2:
        return None
    sums = np.bincount(blocks, weights=resid, minlength=m)
    v_noise = float(np.sum(sums**2)) * m / (m - 1)
    span = hi - lo
    if still_estimate is not None and still_stderr is not None and math.isfinite(still_stderr):
        v_bias = still_stderr**2 if still_applied else still_estimate**2 + still_stderr**2
    else:
        try:
            cov = cluster_covariance(x, resid, blocks).covariance
            beta_se = math.sqrt(max(float(cov[1, 1]), 0.0))
        except CalibrationError:  # no turning to tell the bias from the ratio
            return None
        v_bias = (float(coef[1]) - bias_applied) ** 2 + beta_se**2
    var = (span / odom_net_rad) ** 2 * v_bias + v_noise / odom_net_rad**2
    return math.sqrt(var) if math.isfinite(var) else None


def gyro_calibration(
    imu_time_s: ArrayLike,
    angular_velocity_rad_s: ArrayLike,
    odom_time_s: ArrayLike,
    *,
    odom_yaw_rad: ArrayLike | None = None,
    odom_yaw_rate_rad_s: ArrayLike | None = None,
    odom_speed_m_s: ArrayLike | None = None,
    rotation: ArrayLike | None = None,
    imu_axis: str | None = None,
    mounting_source: str | None = None,
    bias: str | float = "auto",
    max_still_speed_m_s: float = 0.005,
    max_still_yaw_rate_rad_s: float = 0.005,
    min_still_s: float = 1.0,
    min_rotation_rad: float = math.pi / 2,
    meta: dict | None = None,
) -> GyroResult:
    """Gyro rotation / odometry rotation over a run, with bias and mounting handled.

    Parameters
    ----------
    imu_time_s : ndarray, shape (K,)
        IMU sample times (s), strictly increasing.
    angular_velocity_rad_s : ndarray, shape (K, 3)
        Angular velocity (rad/s) in the IMU frame.
    odom_time_s : ndarray, shape (M,)
        Odometry sample times (s), strictly increasing, on the same clock.
    odom_yaw_rad, odom_yaw_rate_rad_s : ndarray, shape (M,)
        Odometric heading (rad, unwrapped) or heading rate (rad/s); give one (the heading is
        preferred: it covers dropped samples).
    odom_speed_m_s : ndarray, shape (M,), optional
        Forward speed (m/s); with it, still periods also need the robot not to translate.
    rotation : ndarray, shape (3, 3), optional
        R_base_imu, mapping IMU-frame vectors to the base frame (a ``base -> imu`` transform).
    imu_axis : str, optional
        'x', 'y', 'z', '-x', '-y' or '-z': the IMU axis that points up (base z). Ignored when
        ``rotation`` is given. Neither: detected from the data, with a warning.
    mounting_source : str, optional
        How ``rotation`` was obtained (e.g. 'tf_static'), for the report.
    bias : 'auto', 'still', 'none' or float
        Gyro yaw-rate bias handling (module docstring); a float is a bias in rad/s.
    max_still_speed_m_s, max_still_yaw_rate_rad_s, min_still_s
        Still-period thresholds (m/s, rad/s, s).
    min_rotation_rad : float
        Least net odometric rotation (rad) for a meaningful ratio (default 90 deg).
    meta : dict, optional
        Extra facts copied into the result (path, topics, odometry source).
    """
    t_i = np.asarray(imu_time_s, dtype=float)
    w = np.asarray(angular_velocity_rad_s, dtype=float)
    t_o = np.asarray(odom_time_s, dtype=float)
    if w.ndim != 2 or w.shape[1] != 3:
        raise CalibrationError(f"angular velocity must have shape (K, 3), got {w.shape}")
    _check_series("IMU", t_i, w)
    if odom_yaw_rad is not None:
        th_o = np.asarray(odom_yaw_rad, dtype=float)
        _check_series("odometry heading", t_o, th_o)
        rate_o = _rate(t_o, th_o)
    elif odom_yaw_rate_rad_s is not None:
        rate_o = np.asarray(odom_yaw_rate_rad_s, dtype=float)
        _check_series("odometry heading rate", t_o, rate_o)
        th_o = integrate_rate(t_o, rate_o)
    else:
        raise CalibrationError("give the odometry heading or its rate")
    speed = None
    if odom_speed_m_s is not None:
        speed = np.asarray(odom_speed_m_s, dtype=float)
        _check_series("odometry speed", t_o, speed)

    # common time span
    lo, hi = max(t_i[0], t_o[0]), min(t_i[-1], t_o[-1])
    if hi - lo <= 0:
        raise CalibrationError("the IMU and odometry time spans do not overlap")
    warnings: list[str] = []

    # mounting: the base z axis in IMU coordinates
    n, source, detected, corr, mount_warnings = yaw_axis(
        t_i, w, t_o, th_o, rotation=rotation, imu_axis=imu_axis, mounting_source=mounting_source
    )
    warnings += mount_warnings
    axis = _axis_name(n) or "rotation"
    yaw_rate = w @ n  # rad/s about base z

    # bias from still periods
    b = _bias(
        t_i,
        yaw_rate,
        t_o,
        rate_o,
        speed,
        max_still_speed_m_s,
        max_still_yaw_rate_rad_s,
        min_still_s,
        bias,
    )
    est, se, still_n, still_s = b.estimate, b.stderr, b.samples, b.seconds
    applied, bias_source = b.applied, b.source
    warnings += b.notes

    # net rotations over the common span
    g_cum = integrate_rate(t_i, yaw_rate)
    g_raw = float(np.interp(hi, t_i, g_cum) - np.interp(lo, t_i, g_cum))
    span = hi - lo
    o_net = float(np.interp(hi, t_o, th_o) - np.interp(lo, t_o, th_o))
    inside = (t_o >= lo) & (t_o <= hi)
    o_abs = float(np.sum(np.abs(np.diff(np.interp(np.r_[lo, t_o[inside], hi], t_o, th_o)))))
    if abs(o_net) < min_rotation_rad:
        raise CalibrationError(
            f"the odometry turns only {math.degrees(o_net):+.1f} deg net over the run; a gyro "
            f"calibration needs at least {math.degrees(min_rotation_rad):.0f} deg net rotation "
            "(drive circles or spin on the spot, mostly in one direction)"
        )
    g_net = g_raw - applied * span
    ratio = g_net / o_net
    ratio_raw = g_raw / o_net
    ratio_corr = (g_raw - est * span) / o_net if est is not None else None
    ratio_se = ratio_stderr(
        t_i, g_cum, t_o, th_o, lo, hi, o_net, applied, est, se, bias_source.startswith("still")
    )
    if bias_source.startswith("none (") and ratio_corr is not None:
        warnings.append(
            f"still-period gyro bias {est:+.3g} +- {se:.2g} rad/s ({still_s:.1f} s still) is not "
            f"significant and was not removed; removing it would give a ratio of {ratio_corr:.4f}"
        )
    if ratio <= 0:
        raise CalibrationError(
            f"the gyro ({math.degrees(g_net):+.1f} deg) and the odometry "
            f"({math.degrees(o_net):+.1f} deg) turn in opposite directions: the IMU mounting is "
            f"wrong (yaw taken on the IMU's {axis} axis; the data suggest {detected})"
        )
    units = rotation_ratio_problem(g_net, o_net)
    if units is not None:
        raise CalibrationError(units)
    if not 0.5 < ratio < 2.0:
        warnings.append(
            f"rotation ratio {ratio:.3f} is far from 1: check the IMU axis and the odometry topic"
        )
    return GyroResult(
        rotation_ratio=float(ratio),
        wheelbase_multiplier=float(1.0 / ratio),
        gyro_rotation_rad=float(g_net),
        odometry_rotation_rad=o_net,
        odometry_abs_rotation_rad=o_abs,
        rotation_ratio_uncorrected=float(ratio_raw),
        rotation_ratio_bias_corrected=None if ratio_corr is None else float(ratio_corr),
        rotation_ratio_stderr=None if ratio_se is None else float(ratio_se),
        yaw_axis_in_imu=_vec3(n),
        axis=axis,
        mounting_source=source,
        axis_correlation=corr,
        bias_rad_s=float(applied),
        bias_source=bias_source,
        bias_estimate_rad_s=est,
        bias_stderr_rad_s=se,
        still_duration_s=still_s,
        still_samples=still_n,
        imu_samples=int(np.count_nonzero((t_i >= lo) & (t_i <= hi))),
        odometry_samples=int(np.count_nonzero(inside)),
        start_s=float(lo),
        duration_s=float(span),
        warnings=tuple(warnings),
        meta=dict(meta or {}),
    )
