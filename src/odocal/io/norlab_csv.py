"""The CSV form of the Norlab DRIVE skid-steer recordings (realdata/norlab_skid/SOURCE.md).

One row per 20 Hz logger sample: ``t_s, left_wheel_rad_s, right_wheel_rad_s, left_wheel_rad,
right_wheel_rad, cmd_v_m_s, cmd_omega_rad_s, icp_x_m, icp_y_m, icp_yaw_rad, imu_wz_rad_s,
icp_update``; ``#`` comment lines above the header carry the source, the robot, the units and the
absolute start time (``absolute t0 = <ns> ns``). The ICP cells are empty before the first pose
and hold the latest pose (sample-and-hold) elsewhere; ``icp_update`` = 1 marks the rows where a
new pose arrived, which are the truth's own samples.

A small reader for evaluations: the product path for these robots is their ROS 2 bags.
"""

from __future__ import annotations

import datetime as _dt
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.skid_steer import SkidLog
from ..errors import InputError
from .table import parse_number, read_table

__all__ = ["NorlabCsv", "read_norlab_csv"]

_COLUMNS = (
    "t_s", "left_wheel_rad_s", "right_wheel_rad_s", "left_wheel_rad", "right_wheel_rad",
    "cmd_v_m_s", "cmd_omega_rad_s", "icp_update",
)  # fmt: skip
_ICP = ("icp_x_m", "icp_y_m", "icp_yaw_rad")
_T0 = re.compile(r"absolute t0 = (\d+) ns")


@dataclass(frozen=True)
class NorlabCsv:
    """One Norlab recording.

    Attributes
    ----------
    path : str
    time_s : ndarray, shape (K,)
        Logger time since the first row (s).
    rate_right_rad_s, rate_left_rad_s : ndarray, shape (K,)
        Measured wheel rates (rad/s).
    angle_right_rad, angle_left_rad : ndarray, shape (K,)
        Wheel angles, the trapezoid integral of the rates (rad).
    cmd_v_m_s, cmd_omega_rad_s : ndarray, shape (K,)
        Commanded body twist.
    imu_wz_rad_s : ndarray, shape (K,)
        IMU yaw rate (NaN where empty).
    icp_time_s : ndarray, shape (M,)
        Logger times of the rows where a new ICP pose arrived (s).
    icp_pose : ndarray, shape (M, 3)
        Those poses (x_m, y_m, yaw_rad; map frame), yaw unwrapped.
    start_ns : int or None
        Absolute start time (ns since the epoch) from the header, where given.
    """

    path: str
    time_s: np.ndarray
    rate_right_rad_s: np.ndarray
    rate_left_rad_s: np.ndarray
    angle_right_rad: np.ndarray
    angle_left_rad: np.ndarray
    cmd_v_m_s: np.ndarray
    cmd_omega_rad_s: np.ndarray
    imu_wz_rad_s: np.ndarray
    icp_time_s: np.ndarray
    icp_pose: np.ndarray
    start_ns: int | None

    @property
    def name(self) -> str:
        """The file name without its extension."""
        return Path(self.path).stem

    @property
    def day(self) -> str:
        """The UTC date of the start (YYYY-MM-DD), or '' when the header has no start time."""
        if self.start_ns is None:
            return ""
        t = _dt.datetime.fromtimestamp(self.start_ns / 1e9, tz=_dt.UTC)
        return t.date().isoformat()

    def skid_log(self, group: str | None = None) -> SkidLog:
        """The wheels and the ICP truth as a :class:`~odocal.calibration.skid_steer.SkidLog`
        (``group`` default: :attr:`day`)."""
        return SkidLog(
            self.name, self.time_s, self.angle_right_rad, self.angle_left_rad, self.icp_time_s,
            self.icp_pose, self.day if group is None else group,
        )  # fmt: skip


def _optional(table, name: str) -> np.ndarray:
    """A column whose empty cells are NaN (other cells must be finite numbers)."""
    out = []
    for no, text in table.cells(name):
        out.append(np.nan if text == "" else parse_number(text, table.path, no, name))
    return np.asarray(out, dtype=float)


def read_norlab_csv(path: str | Path) -> NorlabCsv:
    """Read a Norlab recording CSV (module docstring); InputError naming the file and line for
    a missing column, a non-number, time not increasing, or no ICP update."""
    table = read_table(path, what="the Norlab CSV header")
    table.require([*_COLUMNS, *_ICP, "imu_wz_rad_s"])
    head = table.text[: table.body]
    m = _T0.search(head)
    start_ns = int(m.group(1)) if m else None
    num = table.numbers(list(_COLUMNS))
    t = num[:, 0]
    if len(t) < 2 or not np.all(np.diff(t) > 0):
        raise InputError("t_s must increase from row to row", path, None, "t_s")
    icp = np.column_stack([_optional(table, c) for c in _ICP])
    update = num[:, 7] == 1
    if not update.any():
        raise InputError("no row with icp_update = 1 (no ICP pose)", path, None, "icp_update")
    if not np.all(np.isfinite(icp[update])):
        raise InputError("a row with icp_update = 1 has an empty ICP cell", path, None, "icp_x_m")
    pose = icp[update].copy()
    pose[:, 2] = np.unwrap(pose[:, 2])
    return NorlabCsv(
        str(path), t, num[:, 2], num[:, 1], num[:, 4], num[:, 3], num[:, 5], num[:, 6],
        _optional(table, "imu_wz_rad_s"), t[update], pose, start_ns,
    )  # fmt: skip
