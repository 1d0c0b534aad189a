"""A recorded run: wheel rotations over time, with optional ground truth and gyro heading.

All loaders (generic CSV, OptiOdom folders, ROS bags) produce this one type.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from .model import WheelGeometry

__all__ = ["Recording", "same_recording", "with_truth_at"]


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


def with_truth_at(
    name: str,
    time_s: np.ndarray,
    right_rad: np.ndarray,
    left_rad: np.ndarray,
    truth_time_s: np.ndarray,
    truth_pose: np.ndarray,
    meta: dict,
) -> Recording:
    """The wheel-rate run with a truth measured only at ``truth_time_s`` (on the wheels' clock:
    any offset already removed): those instants inserted into the wheel time base (the angles
    interpolated there), the truth valid only at them (``meta['truth_samples']`` lists their
    indices; other samples are NaN), cut to the span both cover, time and angles from zero, the
    truth in the frame of its first pose. Yaw must be unwrapped."""
    t = np.asarray(time_s, dtype=float)
    t_u = np.asarray(truth_time_s, dtype=float)
    pose_u = np.asarray(truth_pose, dtype=float)
    on = (t_u >= t[0]) & (t_u <= t[-1])
    t_u, pose_u = t_u[on], pose_u[on]
    tt = np.union1d(t[(t >= t_u[0]) & (t <= t_u[-1])], t_u)
    rr, ll = np.interp(tt, t, right_rad), np.interp(tt, t, left_rad)
    idx = np.searchsorted(tt, t_u)
    gt = np.full((len(tt), 3), np.nan)
    gt[idx] = pose_u
    c, s = np.cos(pose_u[0, 2]), np.sin(pose_u[0, 2])
    dx, dy = gt[:, 0] - pose_u[0, 0], gt[:, 1] - pose_u[0, 1]
    gt = np.column_stack([c * dx + s * dy, -s * dx + c * dy, gt[:, 2] - pose_u[0, 2]])
    return Recording(
        name=name,
        time_s=tt - tt[0],
        wheel_angle_right_rad=rr - rr[0],
        wheel_angle_left_rad=ll - ll[0],
        ground_truth=gt,
        meta={**meta, "truth_samples": [int(i) for i in idx]},
    )


#: Increments (rad, m) equal to this are one measurement, and stamps equal to a microsecond one
#: instant.
SAME_INCREMENT = 1e-9


def _channels(r: Recording, other: Recording) -> list[np.ndarray]:
    """What both runs measured, as cumulative series whose increments are comparable however
    each run's start frame lies: the wheel angles, the gyro heading and the true heading and
    distance travelled, where both have them."""
    out = [np.asarray(r.wheel_angle_right_rad, float), np.asarray(r.wheel_angle_left_rad, float)]
    if r.gyro_yaw_rad is not None and other.gyro_yaw_rad is not None:
        out.append(np.asarray(r.gyro_yaw_rad, float))
    if r.ground_truth is not None and other.ground_truth is not None:
        gt = np.asarray(r.ground_truth, float)
        step = np.hypot(np.diff(gt[:, 0]), np.diff(gt[:, 1]))
        out += [gt[:, 2], np.concatenate([[0.0], np.cumsum(step)])]
    return out


def same_recording(a: Recording, b: Recording) -> tuple[float, float] | None:
    """The time (from, to; s since the epoch) that runs ``a`` and ``b`` share when they are one
    recording given twice (a bag and its copy, a log and a part of it), else None. Their
    instants come from the loaders' ``meta['start_s']`` (bags; None for runs without it). One
    recording: their times overlap, at least half of the samples of that time in the one with
    fewer fall on the other's stamps, and between those stamps the wheels move and at least
    half of the moving increments of every channel both measured (wheels, gyro, truth) are the
    other's too. Two runs that merely share a clock (a simulator's time restarting at zero, a
    robot whose clock starts at the same date at every boot) share stamps, not measurements."""
    if a.meta.get("start_s") is None or b.meta.get("start_s") is None:
        return None
    ta = float(a.meta["start_s"]) + np.asarray(a.time_s, dtype=float)
    tb = float(b.meta["start_s"]) + np.asarray(b.time_s, dtype=float)
    if not (len(ta) and len(tb)):
        return None
    lo, hi = max(ta[0], tb[0]), min(ta[-1], tb[-1])
    if not lo < hi:
        return None
    ka, kb = np.round(ta * 1e6).astype(np.int64), np.round(tb * 1e6).astype(np.int64)
    # first the samples from where the wheels start to move in the shared time (two runs on
    # one clock differ there at once), then all of it
    start = int(np.searchsorted(ta, lo))
    turns = np.abs(np.diff(a.wheel_angle_right_rad[start:])) + np.abs(
        np.diff(a.wheel_angle_left_rad[start:])
    )
    start += int(np.argmax(turns > SAME_INCREMENT)) if len(turns) else 0
    window = ka[start : start + 256]
    at = np.minimum(np.searchsorted(kb, window), len(kb) - 1)
    hit = kb[at] == window
    if _verdict(a, b, start + np.flatnonzero(hit), at[hit]) is False:
        return None
    fewer = min(
        np.count_nonzero((ta >= lo) & (ta <= hi)), np.count_nonzero((tb >= lo) & (tb <= hi))
    )
    _, ia, ib = np.intersect1d(ka, kb, assume_unique=True, return_indices=True)
    if len(ia) < 0.5 * fewer:
        return None
    order = np.argsort(ia)
    return (float(lo), float(hi)) if _verdict(a, b, ia[order], ib[order]) else None


def _verdict(a: Recording, b: Recording, ia: np.ndarray, ib: np.ndarray) -> bool | None:
    """Over the common samples ``ia`` of ``a`` and ``ib`` of ``b`` (in time order): True when
    the wheels move and at least half of the moving increments of every channel both measured
    are equal, False when a channel's are not, None when the wheels stand still (or fewer than
    two common samples)."""
    if len(ia) < 2:
        return None
    wheels_move = False
    for k, (ca, cb) in enumerate(zip(_channels(a, b), _channels(b, a), strict=True)):
        da, db = np.diff(ca[ia]), np.diff(cb[ib])
        moves = (np.abs(da) > SAME_INCREMENT) | (np.abs(db) > SAME_INCREMENT)
        shared = moves & (np.abs(da - db) <= SAME_INCREMENT)
        if shared.sum() < 0.5 * moves.sum():
            return False  # a channel measured otherwise: two runs
        wheels_move |= k < 2 and bool(moves.any())
    return True if wheels_move else None
