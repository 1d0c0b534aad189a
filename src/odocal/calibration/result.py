"""Calibration results and the measured end poses they are computed from."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..core.model import ModelError, WheelGeometry

__all__ = ["EndPoseRuns", "CalibrationResult", "CalibrationError", "circular_mean"]


class CalibrationError(ModelError):
    """The measurements do not allow a calibration (e.g. an equation is undefined)."""


def circular_mean(angles_rad, axis=-1):
    """Circular mean of unwrapped angles that keeps their unwrapped scale.

    The mean direction is taken relative to the first sample, so a set of errors near -2 pi stays
    near -2 pi (and small errors stay small) instead of being wrapped into (-pi, pi].
    """
    a = np.asarray(angles_rad, dtype=float)
    ref = np.take(a, [0], axis=axis)
    d = a - ref
    return np.squeeze(ref, axis=axis) + np.arctan2(
        np.mean(np.sin(d), axis=axis), np.mean(np.cos(d), axis=axis)
    )


@dataclass(frozen=True)
class EndPoseRuns:
    """Measured final pose errors of test runs (actual - odometric, start frame).

    Attributes
    ----------
    directions : tuple of str
        'cw' or 'ccw' per run (or 'fwd' for straight-line runs).
    errors : ndarray, shape (n, 3)
        x_m, y_m, theta_rad per run.
    """

    directions: tuple[str, ...]
    errors: np.ndarray

    def select(self, direction: str) -> np.ndarray:
        """Errors of the runs in ``direction``, shape (k, 3)."""
        mask = np.array([d == direction for d in self.directions], dtype=bool)
        return self.errors[mask]

    def mean(self, direction: str) -> np.ndarray:
        """Mean error (x, y arithmetic; theta circular) of the runs in ``direction``, shape (3,)."""
        e = self.select(direction)
        if len(e) == 0:
            raise CalibrationError(f"no {direction.upper()} runs")
        return np.array([e[:, 0].mean(), e[:, 1].mean(), float(circular_mean(e[:, 2]))])

    def count(self, direction: str) -> int:
        return int(sum(d == direction for d in self.directions))


@dataclass(frozen=True)
class CalibrationResult:
    """A calibration: E_b, E_d relative to the parameters the robot ran with, and the corrected
    geometry (those parameters composed with the correction).

    Attributes
    ----------
    method : str
    E_b, E_d : float
        Wheelbase factor and diameter ratio relative to ``ran_with`` (dimensionless).
    ran_with : WheelGeometry
        The parameters the robot used during the test runs.
    corrected : WheelGeometry
        ``ran_with.corrected(E_b, E_d)``: what to install in the robot.
    inputs : dict
        What the result was computed from (track, run counts, mean errors, form ...).
    """

    method: str
    E_b: float
    E_d: float
    ran_with: WheelGeometry
    corrected: WheelGeometry
    inputs: dict = field(default_factory=dict)

    @classmethod
    def from_factors(cls, method: str, E_b, E_d, ran_with: WheelGeometry, **inputs):
        if not (np.all(np.isfinite(E_b)) and np.all(np.isfinite(E_d))):
            raise CalibrationError(f"{method}: the equations are undefined for these errors")
        if not (np.all(np.asarray(E_b) > 0) and np.all(np.asarray(E_d) > 0)):
            raise CalibrationError(
                f"{method}: the errors give a non-physical result (E_b={E_b}, E_d={E_d}); "
                "check the direction labels, the signs (error = actual - odometric) and the units"
            )
        return cls(method, E_b, E_d, ran_with, ran_with.corrected(E_b, E_d), dict(inputs))

    def as_dict(self) -> dict:
        """The JSON contract of ``odocal calibrate --json``."""
        return {
            "method": self.method,
            "E_b": float(self.E_b),
            "E_d": float(self.E_d),
            **self.corrected.as_dict(),
        }


def check_both_directions(runs: EndPoseRuns) -> None:
    missing = [d.upper() for d in ("cw", "ccw") if runs.count(d) == 0]
    if missing:
        raise CalibrationError(
            f"runs in both directions are needed; there are no {' and no '.join(missing)} runs"
        )
