"""Clock offset between the wheel data and another sensor, by temporal registration of headings.

Every route that pairs the wheels with another source (motion capture, SLAM poses, scan
matching, an IMU) compares the two over the same instants. When the source's stamps are late
by ``offset_s`` (it lags the wheels: its sample stamped ``t`` saw the robot at wheel time
``t - offset_s``), every comparison is made at the wrong wheel time, and while the robot turns
that looks like a wheelbase error: on the MIT CSAIL log a 0.1 s laser lag moves the SLAM
route's wheelbase by 5 % and makes it call a fifth of the ordinary turns loop closures.

The estimate registers the two heading curves in time (Kelly & Sukhatme's temporal
registration, here over intervals): the source gives the heading change ``dtheta_k`` over
intervals ``[a_k, b_k]`` of its own clock; for a candidate offset ``d`` the wheels give their
rotations ``phi_R, phi_L`` over ``[a_k - d, b_k - d]``, and the model of every differential
drive, ``dtheta = J22 phi_R + J21 phi_L`` (``J22 = D_R / 2b``, ``J21 = -D_L / 2b``), is linear in
its two coefficients (Censi et al. 2013, step 1). So the parameters are profiled out exactly at
each candidate: the offset is the one whose fit leaves the smallest robust loss (a Cauchy loss
of the residual over a fixed scale, so that a few intervals the model cannot explain, such as a
loop closure or a stalled odometry, do not steer it), on a grid refined by a parabola. Only the
rotation enters, so the offset does not depend on the diameters' scale or on the sensor's
position; it needs turning, at speeds that change within the searched range.

The offset is applied (the wheels taken at ``stamp - offset``) only when it stands out of its
own noise, more than :data:`APPLY_Z` standard errors from 0: an offset estimated at 5 +- 5 ms
on a log that is synchronised would add as much timing noise as it removes (on OptiOdom's data
sets the estimates scatter by about that much around zero). A given offset is always applied.

Its standard error is a block bootstrap: contiguous time blocks of intervals are resampled
with replacement and the minimum found again on the resampled loss profile (each interval's
loss at each candidate is kept, so a replicate costs one sum). Blocks keep the correlation of
neighbouring intervals (a slow heading drift, a wheel slipping over a second) that an
interval-by-interval resampling would hide.

**One rule for every route** (:func:`resolve_offset`): each source (:data:`TIME_SOURCES`: the
wheels are the reference clock; a truth track, a SLAM pose, a laser, an IMU are aligned to them)
takes the offset the user fixed (``--time-offset SOURCE=SECONDS``), else the estimate, else,
when it cannot be estimated, 0 with a warning that says why.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from typing import Literal

import numpy as np
from numpy.typing import ArrayLike

from ..core.pose import start_frame
from ..core.recording import Recording
from ..errors import CalibrationError

__all__ = [
    "TimeSource",
    "TIME_SOURCES",
    "resolve_offset",
    "TimeOffset",
    "TimingCheck",
    "timing_consistency",
    "truth_offset",
    "shift_truth",
    "truth_on_wheel_clock",
    "pooled_offset_s",
    "offset_covariance",
    "estimate_time_offset",
    "wheel_rotations",
    "time_blocks",
    "MAX_OFFSET_S",
]

#: The clocks a route aligns: the wheels (the reference: their offset is 0 by definition) and
#: the sources compared with them.
TimeSource = Literal["wheels", "truth", "slam", "laser", "imu"]
TIME_SOURCES: tuple[TimeSource, ...] = ("wheels", "truth", "slam", "laser", "imu")

#: An estimated offset is applied when it is more than this many standard errors from 0.
APPLY_Z = 2.0
#: Default half-width of the searched range (s): far beyond any clock offset a careful
#: recording has, well inside the duration of a turn.
MAX_OFFSET_S = 0.5
# Fewest intervals that turn (|dtheta| above the noise) for an estimate.
_MIN_TURNING = 10
# Bootstrap replicates for the standard error.
_BOOTSTRAP = 400
# Bootstrap replicates of the timing check (its standard errors need less precision).
_TIMING_BOOTSTRAP = 100
# The smallest difference of the turning ratio between interval lengths that the timing check
# reports: half a per cent (a wheelbase a calibration would move by less is not worth a doubt).
_TIMING_MATTERS = 0.005
# Blocks for the bootstrap: about this many over the log, each at least _MIN_BLOCK_S long.
_BLOCKS = 25
_MIN_BLOCK_S = 2.0


@dataclass(frozen=True)
class TimeOffset:
    """A source's clock offset against the wheels.

    Attributes
    ----------
    source : str
        What was aligned: one of :data:`TIME_SOURCES` (the wheels excepted).
    offset_s : float
        Seconds by which the source's stamps are late (> 0: it lags the wheels; its sample
        stamped t saw the robot at wheel time t - offset_s).
    stderr_s : float or None
        Block-bootstrap standard error (s); None when the offset was given.
    how : str
        'estimated' or 'given'.
    intervals : int
        Intervals behind the estimate (0 when given).
    grid_s, loss : ndarray, shape (G,)
        The searched offsets and the robust loss at each (empty when given).
    warnings : tuple of str
    applied : bool
        Whether the routes use it (given, or estimated beyond :data:`APPLY_Z` standard errors
        from 0).
    part : str
        Which part of the log it belongs to, when each has its own (a data set's name), else ''.
    """

    source: TimeSource
    offset_s: float
    stderr_s: float | None
    how: str
    intervals: int = 0
    grid_s: np.ndarray = field(default_factory=lambda: np.zeros(0))
    loss: np.ndarray = field(default_factory=lambda: np.zeros(0))
    warnings: tuple[str, ...] = ()
    applied: bool = True
    part: str = ""

    @classmethod
    def given(cls, source: TimeSource, offset_s: float) -> TimeOffset:
        """An offset the user fixed (``--time-offset SOURCE=SECONDS``)."""
        return cls(source, float(offset_s), None, "given")

    @classmethod
    def not_estimated(cls, source: TimeSource, why: str) -> TimeOffset:
        """No estimate (``why``): taken as 0, with a warning that says why."""
        return cls(source, 0.0, None, "not estimated", warnings=(f"{why}; taken as 0",))

    @property
    def label(self) -> str:
        """The source, and the part of the log it belongs to: 'truth (DATASET)'."""
        return f"{self.source} ({self.part})" if self.part else self.source

    @property
    def found(self) -> str:
        """How it was found ('estimated', 'given', 'not estimated'), without what the
        differential routes' rule does with it (for a route that always uses it)."""
        return self.how.split(",")[0]

    @property
    def applied_s(self) -> float:
        """The offset the routes use (s): this one when applied, else 0."""
        return self.offset_s if self.applied else 0.0

    def as_dict(self) -> dict:
        """JSON-ready: the offset, its standard error, how it was found."""
        return {
            "source": self.label,
            "offset_s": self.offset_s,
            "stderr_s": self.stderr_s,
            "how": self.how,
            "applied": self.applied,
            "intervals": self.intervals,
            "warnings": list(self.warnings),
        }


def wheel_rotations(
    time_s: np.ndarray,
    angle_right_rad: np.ndarray,
    angle_left_rad: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
) -> tuple[np.ndarray, np.ndarray]:
    """Wheel rotations (rad) over intervals ``[start_s, end_s]`` of the wheel clock, from the
    cumulative angles sampled at ``time_s`` (linear between samples, held beyond the ends).
    Inputs of any shape broadcast together; returns (right, left) of that shape."""
    a = np.asarray(start_s, dtype=float)
    b = np.asarray(end_s, dtype=float)
    r = np.interp(b, time_s, angle_right_rad) - np.interp(a, time_s, angle_right_rad)
    lft = np.interp(b, time_s, angle_left_rad) - np.interp(a, time_s, angle_left_rad)
    return r, lft


def time_blocks(
    time_s: np.ndarray, blocks: int = _BLOCKS, min_block_s: float = _MIN_BLOCK_S
) -> np.ndarray:
    """Block index (0, 1, ...) of each instant: ``blocks`` contiguous blocks of equal duration
    over the span, fewer when a block would be shorter than ``min_block_s``; empty blocks are
    dropped from the numbering."""
    t = np.asarray(time_s, dtype=float)
    if len(t) == 0:
        return np.zeros(0, dtype=int)
    span = float(t.max() - t.min())
    n = max(1, min(int(blocks), int(span // min_block_s) if min_block_s > 0 else int(blocks)))
    edges = t.min() + span * np.arange(1, n) / n
    raw = np.searchsorted(edges, t, side="right")
    _, idx = np.unique(raw, return_inverse=True)
    return idx.astype(int)


def _fit_rotation(
    phi_r: np.ndarray, phi_l: np.ndarray, dtheta: np.ndarray, scale: float
) -> np.ndarray:
    """Robust (Cauchy IRLS) fit of dtheta = J22 phi_R + J21 phi_L at every candidate (rows);
    returns the residuals, shape (G, n)."""
    w = np.ones_like(phi_r)
    for _ in range(8):
        a11 = np.sum(w * phi_r * phi_r, axis=1)
        a12 = np.sum(w * phi_r * phi_l, axis=1)
        a22 = np.sum(w * phi_l * phi_l, axis=1)
        b1 = np.sum(w * phi_r * dtheta, axis=1)
        b2 = np.sum(w * phi_l * dtheta, axis=1)
        det = a11 * a22 - a12 * a12
        # one regressor alone (a heading, not two wheels; or one wheel that never turns):
        # its own coefficient, the other's zero
        alone = ~(det > 1e-12 * np.maximum(a11 * a22, 1e-300))
        det = np.where(alone, np.inf, det)
        j22 = np.where(alone, b1 / np.where(a11 > 0, a11, np.inf), (a22 * b1 - a12 * b2) / det)
        j21 = np.where(alone, 0.0, (a11 * b2 - a12 * b1) / det)
        res = dtheta - j22[:, None] * phi_r - j21[:, None] * phi_l
        w = 1.0 / (1.0 + (res / scale) ** 2)
    return res


def _argmin_refined(grid: np.ndarray, loss: np.ndarray) -> float:
    """The minimum of a sampled profile, refined by the parabola through it and its neighbours."""
    k = int(np.argmin(loss))
    if k == 0 or k == len(grid) - 1:
        return float(grid[k])
    y0, y1, y2 = loss[k - 1], loss[k], loss[k + 1]
    den = y0 - 2 * y1 + y2
    step = grid[k + 1] - grid[k]
    if den <= 0:
        return float(grid[k])
    return float(grid[k] + 0.5 * step * (y0 - y2) / den)


def _losses(
    t: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    dth: np.ndarray,
    grid: np.ndarray,
    scale: float | None,
) -> tuple[np.ndarray, float]:
    """Each interval's robust loss at each candidate offset, shape (G, n), and the scale used
    (given, else the smallest MAD over the candidates of the plain fits' residuals)."""
    phi_r, phi_l = wheel_rotations(
        t, right, left, a[None, :] - grid[:, None], b[None, :] - grid[:, None]
    )
    if scale is None:
        plain = _fit_rotation(phi_r, phi_l, dth, np.inf)
        scale = max(float(np.min(1.4826 * np.median(np.abs(plain), axis=1))), 1e-6)
    res = _fit_rotation(phi_r, phi_l, dth, scale)
    return np.log1p((res / scale) ** 2), scale


def _polish(
    t: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    a: np.ndarray,
    b: np.ndarray,
    dth: np.ndarray,
    scale: float,
    rough: float,
    step_s: float,
) -> float:
    """The minimum of the continuous loss within a grid step of ``rough`` (bounded Brent): the
    grid's parabola is off by a fraction of a step where the loss is not a parabola."""
    from scipy.optimize import minimize_scalar  # here: a slow import

    def loss(d: float) -> float:
        return float(_losses(t, right, left, a, b, dth, np.array([d]), scale)[0].sum())

    sol = minimize_scalar(
        loss, bounds=(rough - step_s, rough + step_s), method="bounded",
        options={"xatol": 1e-7},
    )  # fmt: skip
    return float(sol.x) if sol.fun <= loss(rough) else rough


def _block_bootstrap(
    grid: np.ndarray, per: np.ndarray, start_s: np.ndarray, rng: np.random.Generator | None
) -> tuple[float, int]:
    """Standard error of the profile's minimum over resampled time blocks, and the blocks."""
    gen = rng if rng is not None else np.random.default_rng(0)
    blk = time_blocks(start_s)
    nb = int(blk.max()) + 1
    if nb < 2:
        return math.inf, nb
    per_block = np.stack([per[:, blk == k].sum(axis=1) for k in range(nb)], axis=1)
    draws = gen.integers(0, nb, size=(_BOOTSTRAP, nb))
    reps = [_argmin_refined(grid, per_block[:, d].sum(axis=1)) for d in draws]
    return float(np.std(reps, ddof=1)), nb


def estimate_time_offset(
    wheel_time_s: ArrayLike,
    wheel_angle_right_rad: ArrayLike,
    wheel_angle_left_rad: ArrayLike,
    start_s: ArrayLike,
    end_s: ArrayLike,
    heading_change_rad: ArrayLike,
    *,
    source: TimeSource,
    max_offset_s: float = MAX_OFFSET_S,
    step_s: float | None = None,
    rng: np.random.Generator | None = None,
) -> TimeOffset:
    """The source's clock offset (module docstring) from its heading changes over intervals.

    Parameters
    ----------
    wheel_time_s : ndarray, shape (K,)
        Wheel sample times (s, the wheels' clock), increasing.
    wheel_angle_right_rad, wheel_angle_left_rad : ndarray, shape (K,)
        Cumulative wheel angles (rad).
    start_s, end_s : ndarray, shape (n,)
        The source's intervals, in its own stamps (s).
    heading_change_rad : ndarray, shape (n,)
        The source's heading change over each interval (rad, CCW +).
    source : str
        Its name in the result and the messages.
    max_offset_s : float
        Half-width of the searched range (s).
    step_s : float, optional
        Grid step (s); default a tenth of the finer of the two sampling periods, within
        1-10 ms.
    rng : numpy.random.Generator, optional
        For the block bootstrap (default: seeded 0, so that the result is repeatable).

    Raises
    ------
    CalibrationError
        Too few intervals that turn, or no wheel data around them.
    """
    t = np.asarray(wheel_time_s, dtype=float)
    right = np.asarray(wheel_angle_right_rad, dtype=float)
    left = np.asarray(wheel_angle_left_rad, dtype=float)
    a = np.asarray(start_s, dtype=float)
    b = np.asarray(end_s, dtype=float)
    dth = np.asarray(heading_change_rad, dtype=float)
    if not (math.isfinite(max_offset_s) and max_offset_s > 0):
        raise CalibrationError(f"max_offset_s must be > 0 (s), got {max_offset_s!r}")
    # intervals whose shifted window stays inside the wheel data at every candidate
    inside = (a - max_offset_s >= t[0]) & (b + max_offset_s <= t[-1]) & np.isfinite(dth)
    a, b, dth = a[inside], b[inside], dth[inside]
    turning = np.abs(dth) > math.radians(0.5)
    if int(turning.sum()) < _MIN_TURNING:
        raise CalibrationError(
            f"cannot estimate the {source} clock offset: only {int(turning.sum())} of "
            f"{len(dth)} intervals turn by more than 0.5 deg within the wheel data (need "
            f"{_MIN_TURNING}); drive turns that start and stop, or give the offset"
        )
    if step_s is None:
        periods = [float(np.median(np.diff(t))), float(np.median(b - a))]
        step_s = min(0.01, max(0.001, 0.1 * min(periods)))
    # coarse pass over the whole range, then a fine grid around its minimum
    coarse_step = max(step_s, 0.01)
    n_half = int(math.ceil(max_offset_s / coarse_step))
    coarse = coarse_step * np.arange(-n_half, n_half + 1)
    per_c, scale = _losses(t, right, left, a, b, dth, coarse, None)
    loss = per_c.sum(axis=1)
    centre = coarse[int(np.argmin(loss))]
    n_fine = int(math.ceil(5 * coarse_step / step_s))
    fine = centre + step_s * np.arange(-n_fine, n_fine + 1)
    fine = fine[np.abs(fine) <= max_offset_s + 1e-12]
    per, _ = _losses(t, right, left, a, b, dth, fine, scale)
    rough = _argmin_refined(fine, per.sum(axis=1))
    # to the microsecond: no clock is known better, and an exact synthetic log then gets 0
    best = round(_polish(t, right, left, a, b, dth, scale, rough, step_s), 6) + 0.0
    warnings = []
    if abs(best) >= coarse[-1] - 0.5 * coarse_step:
        warnings.append(
            f"the {source} clock offset lies at the edge of the searched range "
            f"(+-{max_offset_s:g} s): the data may not be synchronised at all"
        )
    stderr, nb = _block_bootstrap(fine, per, a, rng)
    if nb < 5:
        warnings.append(
            f"the {source} clock offset's standard error rests on only {nb} time blocks"
        )
    applied = bool(abs(best) > APPLY_Z * stderr) if math.isfinite(stderr) else False
    how = (
        "estimated"
        if applied
        else f"estimated, not applied (within {APPLY_Z:g} standard errors of 0)"
    )
    return TimeOffset(
        source, best, stderr, how, int(len(dth)), coarse, loss, tuple(warnings), applied
    )


def resolve_offset(
    source: TimeSource, given: float | None, estimate: Callable[[], TimeOffset]
) -> TimeOffset:
    """The one rule of every route (module docstring): ``given`` (s) when the user fixed it,
    else ``estimate()``, else (a CalibrationError: too little turning, no overlap) 0 with a
    warning naming why."""
    if given is not None:
        return TimeOffset.given(source, given)
    try:
        return estimate()
    except CalibrationError as exc:
        return TimeOffset.not_estimated(source, str(exc))


@dataclass(frozen=True)
class TimingCheck:
    """How the wheels' turning agrees with the source's over intervals of growing length.

    Attributes
    ----------
    lengths_s : tuple of float
        Median duration of the intervals at each scale (1, 2, 4, 8 consecutive intervals).
    turn_ratio : tuple of float
        The source's rotation per unit of the wheels' nominal rotation at each scale
        ((J22 - J21) of a robust fit, relative to the first scale's).
    stderr : tuple of float
        Block-bootstrap standard errors of ``turn_ratio``.
    consistent : bool
        No scale differs from the first by more than 3 combined standard errors.
    warning : str or None
        What to do when not consistent.
    """

    lengths_s: tuple[float, ...]
    turn_ratio: tuple[float, ...]
    stderr: tuple[float, ...]
    consistent: bool
    warning: str | None

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {
            "lengths_s": list(self.lengths_s),
            "turn_ratio": list(self.turn_ratio),
            "stderr": list(self.stderr),
            "consistent": self.consistent,
            "warning": self.warning,
        }


def _turns(phi_r: np.ndarray, phi_l: np.ndarray, dth: np.ndarray, mult: np.ndarray) -> np.ndarray:
    """J22 - J21 of the robust (Cauchy IRLS) rotation fit of a set of intervals, once per row of
    ``mult`` (B, n): how many times each interval counts (1 for the data, a bootstrap
    replicate's multiplicities otherwise); one robust scale, the plain fit's on the data."""
    plain = _fit_rotation(phi_r[None, :], phi_l[None, :], dth, np.inf)[0]
    scale = max(float(1.4826 * np.median(np.abs(plain))), 1e-6)
    w = mult.astype(float)
    j22 = j21 = np.zeros(len(w))
    for _ in range(10):
        a11, a12 = (w * phi_r * phi_r).sum(axis=1), (w * phi_r * phi_l).sum(axis=1)
        a22 = (w * phi_l * phi_l).sum(axis=1)
        b1, b2 = (w * phi_r * dth).sum(axis=1), (w * phi_l * dth).sum(axis=1)
        det = a11 * a22 - a12 * a12
        det = np.where(det > 1e-12 * np.maximum(a11 * a22, 1e-300), det, np.inf)
        j22, j21 = (a22 * b1 - a12 * b2) / det, (a11 * b2 - a12 * b1) / det
        res = dth - j22[:, None] * phi_r - j21[:, None] * phi_l
        w = mult / (1.0 + (res / scale) ** 2)
    return j22 - j21


def timing_consistency(
    phi_right_rad: np.ndarray,
    phi_left_rad: np.ndarray,
    heading_change_rad: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
    *,
    source: str,
    rng: np.random.Generator | None = None,
) -> TimingCheck | None:
    """Does the wheels' turning per unit of the source's stay the same when consecutive
    intervals are composed into longer ones (2, 4, 8)? With a constant clock offset removed it
    should: the rotation coefficients of one robot do not depend on how the log is cut. When
    they differ, the odometry's timing is not a constant offset (it stalls and catches up,
    it is filtered), short intervals see that, and a fit's answer depends on the interval
    length beyond its uncertainty; the warning says which length to prefer. None when the
    intervals do not chain."""
    a, b = np.asarray(start_s, float), np.asarray(end_s, float)
    n = len(a)
    if n < 4 * _MIN_TURNING:
        return None
    dt = float(np.median(b - a))
    gap = np.abs(a[1:] - b[:-1]) > 1e-6 + 1e-3 * dt
    chains = np.split(np.arange(n), np.flatnonzero(gap) + 1)
    gen = rng if rng is not None else np.random.default_rng(0)
    lengths, ratios, errs = [], [], []
    base = None
    for size in (1, 2, 4, 8):
        groups = [c[i : i + size] for c in chains for i in range(0, len(c) - size + 1, size)]
        if len(groups) < 3 * _MIN_TURNING:
            break
        idx = np.array(groups)
        pr = np.asarray(phi_right_rad)[idx].sum(axis=1)
        pl = np.asarray(phi_left_rad)[idx].sum(axis=1)
        th = np.asarray(heading_change_rad)[idx].sum(axis=1)
        t0 = a[idx[:, 0]]
        c = float(_turns(pr, pl, th, np.ones((1, len(th))))[0])
        blk = time_blocks(t0)
        nb = int(blk.max()) + 1
        se = math.inf
        if nb > 1:
            # each replicate: how many times each block (so each interval) is drawn
            draws = gen.integers(0, nb, size=(_TIMING_BOOTSTRAP, nb))
            per_block = np.stack([np.bincount(d, minlength=nb) for d in draws])
            reps = _turns(pr, pl, th, per_block[:, blk])
            se = float(np.std(reps, ddof=1))
        base = c if base is None else base
        lengths.append(float(np.median(b[idx[:, -1]] - t0)))
        ratios.append(c / base)
        errs.append(se / abs(base))
    if len(ratios) < 2:
        return None
    z = [abs(r - 1.0) / math.hypot(e, errs[0]) for r, e in zip(ratios[1:], errs[1:], strict=True)]
    # beyond 3 combined standard errors AND by more than a difference that matters (a noise-free
    # log has tiny errors: 0.01 % apart is not a timing fault)
    big = [abs(r - 1.0) > _TIMING_MATTERS for r in ratios[1:]]
    consistent = not any(zi > 3.0 and b for zi, b in zip(z, big, strict=True))
    warning = None
    if not consistent:
        k = 1 + int(np.argmax(z))
        warning = (
            f"the wheels' turning against the {source}'s depends on the interval length: "
            f"{100 * (ratios[k] - 1):+.1f} % over {lengths[k]:.2g} s against {lengths[0]:.2g} s "
            f"({max(z):.1f} standard errors): the odometry's timing is not a constant offset "
            "(it stalls and catches up, or is filtered), so the calibration depends on how the "
            "log is cut: compare interval lengths, and trust the one the held-out check favours"
        )
    return TimingCheck(tuple(lengths), tuple(ratios), tuple(errs), consistent, warning)


def truth_offset(
    recordings: Sequence[Recording],
    *,
    source: TimeSource = "truth",
    window_s: float = 0.25,
    max_offset_s: float = 0.3,
) -> TimeOffset:
    """The clock offset of the ground truth of ``recordings`` (one recording setup, e.g. one
    data set) against their wheels, from the truth's heading changes over windows of about
    ``window_s`` (:func:`estimate_time_offset`; the runs are strung on one clock with their
    wheel angles continued, and no window closer than ``max_offset_s`` to a run's ends)."""
    t_all, r_all, l_all, a_all, b_all, d_all = [], [], [], [], [], []
    clock, right0, left0 = 0.0, 0.0, 0.0
    for rec in recordings:
        gt = rec.ground_truth
        if gt is None or len(rec.time_s) < 4 or not np.all(np.isfinite(gt)):
            continue
        t = np.asarray(rec.time_s, dtype=float)
        t = t - t[0] + clock
        dt = float(np.median(np.diff(t)))
        step = max(1, int(round(window_s / dt))) if dt > 0 else 1
        k = np.arange(0, len(t) - step, step)
        inner = (t[k] - t[0] >= max_offset_s) & (t[-1] - t[k + step] >= max_offset_s)
        k = k[inner]
        right = np.asarray(rec.wheel_angle_right_rad, dtype=float)
        left = np.asarray(rec.wheel_angle_left_rad, dtype=float)
        t_all.append(t)
        r_all.append(right - right[0] + right0)
        l_all.append(left - left[0] + left0)
        a_all.append(t[k])
        b_all.append(t[k + step])
        d_all.append(gt[k + step, 2] - gt[k, 2])
        clock = float(t[-1]) + 10.0 * max_offset_s + 1.0
        right0, left0 = float(r_all[-1][-1]), float(l_all[-1][-1])
    if not t_all:
        raise CalibrationError(f"no run with a ground truth to align the {source}'s clock with")
    return estimate_time_offset(
        np.concatenate(t_all), np.concatenate(r_all), np.concatenate(l_all),
        np.concatenate(a_all), np.concatenate(b_all), np.concatenate(d_all),
        source=source, max_offset_s=max_offset_s,
    )  # fmt: skip


def shift_truth(recording: Recording, offset_s: float) -> Recording:
    """``recording`` with its ground truth moved onto the wheels' clock: the truth stamped t
    saw the robot at wheel time t - ``offset_s``, so the truth at wheel time tau is the
    recorded truth at tau + offset_s (linear between samples, held at the ends), re-expressed
    relative to its first pose."""
    gt = recording.ground_truth
    if gt is None or offset_s == 0.0:
        return recording
    t = np.asarray(recording.time_s, dtype=float)
    q = np.clip(t + offset_s, t[0], t[-1])
    moved = np.column_stack([np.interp(q, t, gt[:, k]) for k in range(3)])
    return replace(recording, ground_truth=start_frame(moved[:, 0], moved[:, 1], moved[:, 2]))


def truth_on_wheel_clock(
    recordings: Sequence[Recording], given: float | None
) -> tuple[list[Recording], tuple[TimeOffset, ...]]:
    """The runs with their truth moved onto the wheels' clock (:func:`shift_truth`): one offset
    per data set (one recording setup, ``Recording.dataset``), estimated
    (:func:`truth_offset`) unless ``given``; a data set whose offset cannot be estimated keeps
    its truth (a warning says so). Returns the runs and each data set's offset, sources named
    'truth (DATASET)'."""
    by_set: dict[str, list[Recording]] = {}
    for r in recordings:
        if r.ground_truth is not None:
            by_set.setdefault(r.dataset, []).append(r)
    offsets: dict[str, TimeOffset] = {}
    for name, runs in by_set.items():

        def estimate(runs: Sequence[Recording] = runs) -> TimeOffset:
            return truth_offset(runs)

        offsets[name] = replace(resolve_offset("truth", given, estimate), part=name)
    moved = [
        shift_truth(r, offsets[r.dataset].applied_s) if r.dataset in offsets else r
        for r in recordings
    ]
    return moved, tuple(offsets.values())


def pooled_offset_s(offsets: Sequence[TimeOffset]) -> float:
    """One clock offset (s) from several estimates of it (e.g. one per data set): their mean
    weighted by the inverse squared standard errors when every one has a finite positive error,
    else their median."""
    values = [o.offset_s for o in offsets]
    errs = [o.stderr_s for o in offsets]
    if all(e is not None and e > 0 and np.isfinite(e) for e in errs):
        w = np.array([1.0 / float(e) ** 2 for e in errs if e is not None])
        return float(np.sum(w * np.array(values)) / np.sum(w))
    return float(np.median(values))


def offset_covariance(
    fit_at: Callable[[float], np.ndarray], offset: TimeOffset
) -> np.ndarray | None:
    """What the clock offset's own uncertainty adds to the covariance of parameters fitted at
    it: J J^T se^2, with J = (p(d + se) - p(d - se)) / (2 se) from two refits ``fit_at(d)``
    (the parameters, shape (p,), with the wheels taken ``d`` earlier). None when the offset was
    given (no uncertainty) or its standard error is unknown."""
    se = offset.stderr_s
    if offset.how == "given" or se is None or not math.isfinite(se) or se <= 0:
        return None
    d = offset.applied_s
    jac = (np.asarray(fit_at(d + se)) - np.asarray(fit_at(d - se))) / (2.0 * se)
    return np.outer(jac, jac) * se * se
