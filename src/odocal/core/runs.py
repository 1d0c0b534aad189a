"""Measured outcomes of test runs: final pose errors (polygons, straight runs) and circle radii.

What a person measures on the floor (RUNS.csv) or a tracker records, before any calibration.
"""

from __future__ import annotations

import functools
from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError
from .stats import circular_mean

__all__ = ["EndPoseRuns", "CircleRuns", "check_both_directions"]


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

    @functools.cached_property
    def _labels(self) -> np.ndarray:
        return np.asarray(self.directions, dtype=object)

    def select(self, direction: str) -> np.ndarray:
        """Errors of the runs in ``direction``, shape (k, 3)."""
        return self.errors[self._labels == direction]

    def mean(self, direction: str) -> np.ndarray:
        """Mean error (x, y arithmetic; theta circular) of the runs in ``direction``, shape (3,)."""
        e = self.select(direction)
        if len(e) == 0:
            raise CalibrationError(f"no {direction.upper()} runs")
        return np.array([e[:, 0].mean(), e[:, 1].mean(), float(circular_mean(e[:, 2]))])

    def count(self, direction: str) -> int:
        """Number of runs in ``direction`` ('cw' or 'ccw')."""
        return int(np.count_nonzero(self._labels == direction))


@dataclass(frozen=True)
class CircleRuns:
    """Measured circle runs for BCPT.

    Attributes
    ----------
    directions : tuple of str
        'cw' or 'ccw' per run.
    radii_m : ndarray, shape (n,)
        Measured (fitted) axle-centre radius of each run (m).
    """

    directions: tuple[str, ...]
    radii_m: np.ndarray

    def select(self, direction: str) -> np.ndarray:
        """Radii (m) of the runs in ``direction``, shape (k,)."""
        mask = np.array([d == direction for d in self.directions], dtype=bool)
        return np.asarray(self.radii_m, dtype=float)[mask]

    def count(self, direction: str) -> int:
        """Number of runs in ``direction`` ('cw' or 'ccw')."""
        return int(sum(d == direction for d in self.directions))

    def mean(self, direction: str) -> float:
        """Mean radius (m) of the runs in ``direction``; CalibrationError when there are none."""
        r = self.select(direction)
        if len(r) == 0:
            raise CalibrationError(
                f"BCPT needs CW and CCW circles; there are no {direction.upper()} runs"
            )
        return float(r.mean())


def check_both_directions(runs: EndPoseRuns | CircleRuns) -> None:
    """CalibrationError unless there are CW and CCW runs."""
    missing = [d.upper() for d in ("cw", "ccw") if runs.count(d) == 0]
    if missing:
        raise CalibrationError(
            f"runs in both directions are needed; there are no {' and no '.join(missing)} runs"
        )
