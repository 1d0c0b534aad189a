"""Replaying recorded wheel rotations through the model: what a validation on recorded runs looks
like under the model (model.md).

Validating a calibration on recorded runs means dead-reckoning their wheel rotations phi with the
calibrated geometry and comparing with the ground truth. Under the model, the ground truth of
those same rotations is the TRUE geometry's path plus wheel noise (variance k |s| per wheel travel
s). :func:`replay_final_errors` simulates exactly that: for every trial one noisy true path of the
recorded rotations, and for every calibration of that trial the odometric path of the same
rotations; the final position error is the distance between their end points. Calibrations of one
trial share the trial's true path (as real calibrations are validated on the same recorded runs).

The rotations are merged into chunks (:func:`chunk_rotations`: no wheel changes direction within
a chunk and no wheel turns more than ``max_chunk_rad``), each integrated as an exact arc. Merging
leaves the deterministic part of each chunk exact in its end pose; the noise covariance differs
from the sample-by-sample one by O(1/K^2), as in the design's fast simulation.
"""

from __future__ import annotations

import math

import numpy as np
from numpy.typing import ArrayLike

from .model import ModelError, NonSystematicError, WheelGeometry
from .odometry import body_increments, midpoint_end, wheel_travel

__all__ = ["chunk_rotations", "replay_final_errors"]


def chunk_rotations(
    angle_right_rad: ArrayLike, angle_left_rad: ArrayLike, max_chunk_rad: float
) -> np.ndarray:
    """Cumulative wheel angles at chunk boundaries, shape (C + 1, 2) (right, left; rad), from
    cumulative angles of shape (K,) (module docstring)."""
    if not (math.isfinite(max_chunk_rad) and max_chunk_rad > 0):
        raise ModelError(f"max_chunk_rad must be > 0, got {max_chunk_rad!r}")
    a = np.column_stack(
        [np.asarray(angle_right_rad, dtype=float), np.asarray(angle_left_rad, dtype=float)]
    )
    d = np.diff(a, axis=0)
    keep = [0]
    sign = np.sign(d)
    last = np.zeros(2)  # the last non-zero direction of each wheel within the current chunk
    acc = np.zeros(2)
    for i in range(len(d)):
        s = sign[i]
        if (
            (s[0] * last[0] < 0)
            or (s[1] * last[1] < 0)
            or acc[0] + abs(d[i, 0]) > max_chunk_rad
            or acc[1] + abs(d[i, 1]) > max_chunk_rad
        ):
            if keep[-1] != i:
                keep.append(i)
            acc[:] = 0.0
            last[:] = 0.0
        acc += np.abs(d[i])
        if s[0]:
            last[0] = s[0]
        if s[1]:
            last[1] = s[1]
    if keep[-1] != len(a) - 1:
        keep.append(len(a) - 1)
    return a[keep]


def _scalar(geometry: WheelGeometry) -> WheelGeometry:
    """``geometry`` with its values as Python floats."""
    return WheelGeometry.unchecked(
        float(geometry.diameter_right_m),
        float(geometry.diameter_left_m),
        float(geometry.wheelbase_m),
    )


def _end_position(
    travel_right_m: np.ndarray, travel_left_m: np.ndarray, wheelbase_m: float | np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """End positions (x_m, y_m) of consecutive exact arcs (wheel travel: shape (..., C)) from
    the origin."""
    end = midpoint_end(*body_increments(travel_right_m, travel_left_m, wheelbase_m), chord="series")
    return end[..., 0], end[..., 1]


def replay_final_errors(
    chunks_rad: np.ndarray,
    true: WheelGeometry,
    noise: NonSystematicError,
    calibrated: WheelGeometry,
    rng: np.random.Generator | None,
) -> np.ndarray:
    """Final position errors (m) of replaying one recorded run (module docstring).

    Parameters
    ----------
    chunks_rad : ndarray, shape (C + 1, 2)
        Cumulative wheel angles at the chunk boundaries (:func:`chunk_rotations`).
    true : WheelGeometry
        The physical robot (scalar geometry).
    noise : NonSystematicError
        Wheel noise (k in metres); zero noise needs no ``rng``.
    calibrated : WheelGeometry
        Geometries to dead-reckon with, values of shape (M, T): M calibrations for each of T
        trials (or scalars / shape (T,) broadcast to it).

    Returns
    -------
    ndarray, shape (M, T): |p_true(trial) - p_odometric(calibration, trial)|.
    """
    dphi = np.diff(np.asarray(chunks_rad, dtype=float), axis=0)  # (C, 2)
    shape = np.broadcast_shapes(
        np.shape(calibrated.diameter_right_m),
        np.shape(calibrated.diameter_left_m),
        np.shape(calibrated.wheelbase_m),
    )
    if len(shape) == 0:
        shape = (1, 1)
    elif len(shape) == 1:
        shape = (1, shape[0])
    m, t = shape
    if not noise.is_zero and rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate noise")
    s_r, s_l = wheel_travel(dphi[:, 0], dphi[:, 1], _scalar(true))
    s_r = np.broadcast_to(s_r, (t, len(s_r))).copy()
    s_l = np.broadcast_to(s_l, (t, len(s_l))).copy()
    if noise.k_r_m > 0 and rng is not None:
        s_r += np.sqrt(noise.k_r_m * np.abs(s_r)) * rng.standard_normal(s_r.shape)
    if noise.k_l_m > 0 and rng is not None:
        s_l += np.sqrt(noise.k_l_m * np.abs(s_l)) * rng.standard_normal(s_l.shape)
    x_t, y_t = _end_position(s_r, s_l, float(true.wheelbase_m))  # (T,)

    d_r = np.broadcast_to(np.asarray(calibrated.diameter_right_m, dtype=float), shape)
    d_l = np.broadcast_to(np.asarray(calibrated.diameter_left_m, dtype=float), shape)
    b = np.broadcast_to(np.asarray(calibrated.wheelbase_m, dtype=float), shape)
    out = np.empty(shape)
    for i in range(m):  # one calibration row at a time: (T, C) work arrays
        row = WheelGeometry.unchecked(d_r[i][:, None], d_l[i][:, None], b[i][:, None])
        o_r, o_l = wheel_travel(dphi[:, 0], dphi[:, 1], row)
        x_o, y_o = _end_position(o_r, o_l, row.wheelbase_m)
        out[i] = np.hypot(x_t - x_o, y_t - y_o)
    return out
