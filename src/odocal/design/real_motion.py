"""How recorded runs were driven, for the real experiment's evidence
(:mod:`odocal.design.real_experiment`): the speeds and turn rates of their straight stretches and
spot turns, and where a square's closing heading error comes from (spot turns or the rest)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..calibration.squares import direction_from_data
from ..core.model import WheelGeometry
from ..core.recording import Recording

__all__ = ["MotionProfile", "motion_profile", "ClosingHeading", "closing_heading_split"]


@dataclass(frozen=True)
class MotionProfile:
    """How runs drive: 90th percentiles of the forward speed on straight stretches (m/s) and of
    the turn rate in spot turns (rad/s); None where fewer than 20 samples drive so."""

    straight_speed_m_s: float | None
    spot_turn_rate_rad_s: float | None

    def as_dict(self) -> dict:
        """JSON-ready (m/s, rad/s; None where too few samples)."""
        return {
            "straight_speed_m_s": self.straight_speed_m_s,
            "spot_turn_rate_rad_s": self.spot_turn_rate_rad_s,
        }


def motion_profile(recordings: Sequence[Recording], geometry: WheelGeometry) -> MotionProfile:
    """How the runs drive (:class:`MotionProfile`), from the wheel rotations."""
    v_straight, w_spot = [], []
    for r in recordings:
        dt = np.diff(np.asarray(r.time_s, dtype=float))
        vr = np.diff(r.wheel_angle_right_rad) * (0.5 * geometry.diameter_right_m) / dt
        vl = np.diff(r.wheel_angle_left_rad) * (0.5 * geometry.diameter_left_m) / dt
        k = np.ones(9) / 9
        sr, sl = np.convolve(vr, k, "same"), np.convolve(vl, k, "same")
        tot = np.abs(sr) + np.abs(sl)
        moving = tot > 0.01
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.abs(sr - sl) / tot
        v_straight.append(np.abs(0.5 * (sr + sl))[moving & (s < 0.04)])
        w_spot.append(np.abs((sr - sl) / geometry.wheelbase_m)[moving & (s >= 0.8)])

    def p90(parts: list[np.ndarray]) -> float | None:
        a = np.concatenate(parts) if parts else np.zeros(0)
        return float(np.percentile(a, 90)) if a.size >= 20 else None

    return MotionProfile(p90(v_straight), p90(w_spot))


@dataclass(frozen=True)
class ClosingHeading:
    """Where a square's closing heading error comes from, for one direction: the mean odometric
    rotation (rad) and the mean heading error actual - odometric (rad) of the samples in spot
    turns and of all the others (legs, and the arcs that start or finish a turn)."""

    spot_rotation_rad: float
    spot_error_rad: float
    other_rotation_rad: float
    other_error_rad: float

    def as_dict(self) -> dict:
        """JSON-ready (rad)."""
        return {
            "spot_rotation_rad": self.spot_rotation_rad,
            "spot_error_rad": self.spot_error_rad,
            "other_rotation_rad": self.other_rotation_rad,
            "other_error_rad": self.other_error_rad,
        }


def closing_heading_split(
    recordings: Sequence[Recording], reference: WheelGeometry
) -> dict[str, ClosingHeading]:
    """Direction ('cw', 'ccw'; those the runs drove) -> :class:`ClosingHeading` of the squares;
    bands from :func:`odocal.calibration.turning.band_of_increments` with the reference's
    diameters."""
    from ..calibration.turning import band_of_increments

    acc: dict[str, list] = {"cw": [], "ccw": []}
    for r in recordings:
        gt = np.asarray(r.ground_truth, dtype=float)
        d = direction_from_data(float(gt[-1, 2] - gt[0, 2]))
        if d is None:
            continue
        band = band_of_increments(
            r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.time_s, reference
        )
        dr = np.diff(r.wheel_angle_right_rad) * (0.5 * reference.diameter_right_m)
        dl = np.diff(r.wheel_angle_left_rad) * (0.5 * reference.diameter_left_m)
        dth = (dr - dl) / reference.wheelbase_m
        err = np.diff(gt[:, 2]) - dth
        spot = band == 0
        acc[d].append([dth[spot].sum(), err[spot].sum(), dth[~spot].sum(), err[~spot].sum()])
    out = {}
    for d, rows in acc.items():
        if rows:
            m = np.mean(rows, axis=0)
            out[d] = ClosingHeading(float(m[0]), float(m[1]), float(m[2]), float(m[3]))
    return out
