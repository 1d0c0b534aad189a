"""A recorded run: wheel rotations over time, with optional ground truth and gyro heading.

All loaders (generic CSV, OptiOdom folders, ROS bags) produce this one type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .model import WheelGeometry

__all__ = ["Recording"]


@dataclass(frozen=True)
class Recording:
    """One run of a real robot.

    Attributes
    ----------
    name : str
        Where it came from (path, or path plus run number / topic).
    time_s : ndarray, shape (K,)
        Sample times (s), strictly increasing.
    wheel_angle_right_rad, wheel_angle_left_rad : ndarray, shape (K,)
        Cumulative wheel rotation (rad, forward positive), starting at 0.
        Wheel travel is angle * diameter / 2.
    ground_truth : ndarray, shape (K, 3) or None
        True pose (x_m, y_m, theta_rad) in the start frame (first row 0, 0, 0), theta unwrapped.
    gyro_yaw_rad : ndarray, shape (K,) or None
        Integrated gyro heading (rad, CCW +, unwrapped), starting at 0.
    ran_with : WheelGeometry or None
        Parameters the robot's own controller used while driving (firmware values).
    label : str or None
        What the run is ('cw', 'ccw', 'straight', 'spin-cw', ...), where known.
    meta : dict
        Loader-specific facts (side length, dataset id, ...).
    """

    name: str
    time_s: np.ndarray
    wheel_angle_right_rad: np.ndarray
    wheel_angle_left_rad: np.ndarray
    ground_truth: np.ndarray | None = None
    gyro_yaw_rad: np.ndarray | None = None
    ran_with: WheelGeometry | None = None
    label: str | None = None
    meta: dict = field(default_factory=dict)

    def __len__(self) -> int:
        return len(self.time_s)

    @property
    def dataset(self) -> str:
        """The data set the run belongs to: the loader's id (``meta['dataset']``, e.g. an
        OptiOdom folder's name), else the folder holding the run file or the bag."""
        given = self.meta.get("dataset")
        if given:
            return str(given)
        return str(Path(self.meta.get("bag") or self.name).parent)
