"""A skid-steer robot's effective track from a gyro: yaw rate against the wheels' yaw rate over
short intervals.

Over each interval i (about 1 s) of a log, the wheel odometry turns by ``u_i`` (its heading
change, computed through a reference track ``b_ref``: the nominal one for joint states, the one
the controller ran with for its own odometry) and the gyro by ``y_i`` (its yaw rate, the bias
removed, integrated). A skid-steer robot turns by ``g`` times what its wheels say, ``g = b_ref /
b_eff`` when the wheels roll as the reference says, so

    y_i = g(|u_i| / dt_i) * u_i + beta * dt_i + e_i

with ``beta`` the bias the still periods left in. ``g`` is one number (the effective track) or
piecewise linear in the wheels' turn rate between knots (the track against the turn rate, the
form a controller's users can read theirs from). Least squares, with one pass that drops the
intervals beyond 6 robust standard deviations (a bump, a slip of the IMU); the standard errors
are the delete-one-block jackknife's over contiguous blocks of the log (15 s: the slip and the
gyro's drift are correlated within a block, not across; on 30 simulated robots with slip
correlated over 2 s the multiplier's rms z was 1.11 with it, 1.19 with the sandwich). A gyro
measures heading only: the wheels' rolling scale is not seen (it is held at the nominal), and
the gyro's own scale-factor error (typically 0.1-1 %) is in ``g``.

Which model to export is decided on held-out data: fitted on one part (a recording, or a half),
each scored by the rms of its heading error accumulated over ``window_s`` on the other.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError
from .robust_covariance import cluster_jackknife_covariance

__all__ = [
    "HeadingIntervals",
    "heading_intervals",
    "rate_knots",
    "GyroGainFit",
    "fit_gyro_gain",
    "HeldOutHeading",
    "held_out_heading",
]

#: Candidate knots (|wheel yaw rate|, rad/s) of the turn-rate model.
RATE_LADDER: tuple[float, ...] = (0.05, 0.1, 0.2, 0.4, 0.8, 1.6, 3.2)
#: A knot is kept when the intervals near it turn by this much in all (rad): one full turn.
MIN_KNOT_TURN_RAD = 2 * math.pi
#: Intervals whose residual is beyond this many robust standard deviations are dropped once.
_OUTLIER_SIGMAS = 6.0


@dataclass(frozen=True)
class HeadingIntervals:
    """The log cut into intervals: the wheels' heading change ``u`` (rad), the gyro's ``y``
    (rad), each interval's duration ``dt`` (s), start time ``start_s`` and block label ``block``
    (contiguous time blocks, for the cluster-robust errors), and ``part`` (the recording it
    came from, for held-out checks)."""

    u: np.ndarray
    y: np.ndarray
    dt: np.ndarray
    start_s: np.ndarray
    block: np.ndarray
    part: np.ndarray

    def __len__(self) -> int:
        return len(self.u)

    def subset(self, keep: np.ndarray) -> HeadingIntervals:
        """The intervals where ``keep`` (a boolean mask or indices)."""
        return HeadingIntervals(
            self.u[keep], self.y[keep], self.dt[keep], self.start_s[keep], self.block[keep],
            self.part[keep],
        )  # fmt: skip

    @property
    def rate(self) -> np.ndarray:
        """The wheels' |yaw rate| over each interval (rad/s)."""
        return np.abs(self.u) / self.dt

    @classmethod
    def concatenate(cls, parts: Sequence[HeadingIntervals]) -> HeadingIntervals:
        """The intervals of several logs (their blocks kept apart)."""
        offset, blocks = 0, []
        for p in parts:
            blocks.append(p.block + offset)
            offset += int(p.block.max()) + 1 if len(p.block) else 0
        cat = np.concatenate
        return cls(
            cat([p.u for p in parts]), cat([p.y for p in parts]), cat([p.dt for p in parts]),
            cat([p.start_s for p in parts]), cat(blocks), cat([p.part for p in parts]),
        )  # fmt: skip


def heading_intervals(
    odo_time_s: np.ndarray,
    odo_yaw_rad: np.ndarray,
    gyro_time_s: np.ndarray,
    gyro_yaw_rad: np.ndarray,
    *,
    part: int = 0,
    interval_s: float = 1.0,
    block_s: float = 15.0,
    max_gap_s: float = 0.5,
) -> HeadingIntervals:
    """Consecutive intervals of ``interval_s`` over the time both series cover (on one clock),
    the odometry's and the gyro's heading changes over each (linear between samples); intervals
    in which either series has a hole longer than ``max_gap_s`` are left out."""
    t_o, yaw_o = np.asarray(odo_time_s, float), np.asarray(odo_yaw_rad, float)
    t_g, yaw_g = np.asarray(gyro_time_s, float), np.asarray(gyro_yaw_rad, float)
    lo, hi = max(t_o[0], t_g[0]), min(t_o[-1], t_g[-1])
    if hi - lo < 2 * interval_s:
        raise CalibrationError(
            f"the gyro and the wheels overlap for {max(hi - lo, 0.0):.1f} s: too little to compare"
        )
    a = np.arange(lo, hi - interval_s, interval_s)
    b = a + interval_s
    ok = np.ones(len(a), dtype=bool)
    for t in (t_o, t_g):
        gaps = np.flatnonzero(np.diff(t) > max_gap_s)
        for k in gaps:  # an interval overlapping a hole
            ok &= ~((a < t[k + 1]) & (b > t[k]))
    u = np.interp(b, t_o, yaw_o) - np.interp(a, t_o, yaw_o)
    y = np.interp(b, t_g, yaw_g) - np.interp(a, t_g, yaw_g)
    block = np.floor((a - lo) / block_s).astype(int)
    n = int(ok.sum())
    return HeadingIntervals(
        u[ok], y[ok], np.full(n, interval_s), a[ok], block[ok], np.full(n, part, dtype=int)
    )


def rate_knots(
    intervals: HeadingIntervals,
    ladder: Sequence[float] = RATE_LADDER,
    min_turn_rad: float = MIN_KNOT_TURN_RAD,
) -> tuple[float, ...]:
    """The knots of ``ladder`` the intervals support: those within a factor sqrt(2) of which the
    wheels turn by ``min_turn_rad`` or more; CalibrationError when fewer than two are."""
    rate, turn = intervals.rate, np.abs(intervals.u)
    kept = [
        float(k) for k in sorted(ladder)
        if float(turn[(rate >= k / math.sqrt(2)) & (rate < k * math.sqrt(2))].sum())
        >= min_turn_rad
    ]  # fmt: skip
    if len(kept) < 2:
        raise CalibrationError(
            f"the turn rate's effect needs turning at two rates or more: {len(kept)} of the "
            f"knots {', '.join(f'{k:g}' for k in ladder)} rad/s have a full turn near them"
        )
    return tuple(kept)


def _hat(rate: np.ndarray, knots: Sequence[float]) -> np.ndarray:
    """Piecewise-linear basis (hat functions at ``knots``, flat beyond the ends): shape
    (n, len(knots))."""
    k = np.asarray(knots, dtype=float)
    x = np.clip(rate, k[0], k[-1])
    basis = np.zeros((len(x), len(k)))
    j = np.clip(np.searchsorted(k, x, side="right") - 1, 0, len(k) - 2)
    w = (x - k[j]) / (k[j + 1] - k[j])
    basis[np.arange(len(x)), j] = 1 - w
    basis[np.arange(len(x)), j + 1] = w
    return basis


def _design(intervals: HeadingIntervals, knots: Sequence[float]) -> np.ndarray:
    """Columns: the gain (one, or one per knot) times ``u``, then the bias times ``dt``."""
    u = intervals.u[:, None]
    gain = u if not knots else _hat(intervals.rate, knots) * u
    return np.column_stack([gain, intervals.dt])


@dataclass(frozen=True)
class GyroGainFit:
    """The gain ``g`` (one, or one per knot), the residual bias, their covariance.

    ``gain``: shape (1,) or (len(knots),); ``covariance`` over (gain..., bias); ``clusters``
    the time blocks behind it; ``used``/``rejected`` the intervals kept and dropped."""

    knots: tuple[float, ...]
    gain: np.ndarray
    bias_rad_s: float
    covariance: np.ndarray
    clusters: int
    used: int
    rejected: int
    turned_rad: float

    @property
    def gain_stderr(self) -> np.ndarray:
        """The gains' standard errors."""
        return np.sqrt(np.diag(self.covariance)[: len(self.gain)])

    def predict(self, intervals: HeadingIntervals) -> np.ndarray:
        """The gyro heading change over each interval this model predicts (rad)."""
        return _design(intervals, self.knots) @ np.r_[self.gain, self.bias_rad_s]


def fit_gyro_gain(intervals: HeadingIntervals, knots: Sequence[float] = ()) -> GyroGainFit:
    """The gain and the residual bias (module docstring): least squares, one pass of rejection
    beyond 6 robust standard deviations, the delete-one-block jackknife covariance over the
    blocks (each part's blocks its own)."""
    if len(intervals) < 10:
        raise CalibrationError(f"{len(intervals)} gyro intervals: too few to fit")
    turned = float(np.abs(intervals.u).sum())
    if turned < MIN_KNOT_TURN_RAD:
        raise CalibrationError(
            f"the wheels turn {math.degrees(turned):.0f} deg in all: the gyro cannot see the "
            "effective track without turning; drive spins and arcs in both directions"
        )
    a = _design(intervals, knots)
    x, *_ = np.linalg.lstsq(a, intervals.y, rcond=None)
    r = intervals.y - a @ x
    sigma = 1.4826 * float(np.median(np.abs(r - np.median(r))))
    keep = np.abs(r) <= _OUTLIER_SIGMAS * max(sigma, 1e-12)
    a, y = a[keep], intervals.y[keep]
    x, *_ = np.linalg.lstsq(a, y, rcond=None)
    clusters = intervals.part[keep] * 1_000_000 + intervals.block[keep]
    if len(np.unique(clusters)) < 2:
        raise CalibrationError(
            "the driving fills one time block (blocks of 15 s, the units of the standard error): "
            "too short to say how sure the gain is; record at least 30 s of turning"
        )
    cov = cluster_jackknife_covariance(a, y - a @ x, clusters)
    p = a.shape[1] - 1
    return GyroGainFit(
        tuple(float(k) for k in knots), x[:p], float(x[p]), cov.covariance, cov.clusters,
        int(keep.sum()), int((~keep).sum()), turned,
    )  # fmt: skip


@dataclass(frozen=True)
class HeldOutHeading:
    """Held-out heading errors: per model label, the rms (deg) of the heading error accumulated
    over ``window_s`` on the parts it was not fitted to, pooled over the folds, and the windows
    behind it."""

    window_s: float
    rms_deg: dict[str, float]
    windows: int

    @property
    def best(self) -> str:
        """The label with the smallest held-out error."""
        return min(self.rms_deg, key=lambda k: self.rms_deg[k])


def _window_errors(
    intervals: HeadingIntervals, predicted: np.ndarray, window_s: float
) -> np.ndarray:
    """Heading errors (rad) accumulated over consecutive windows of ``window_s`` within each
    block-contiguous stretch of one part."""
    e = intervals.y - predicted
    idx = np.floor((intervals.start_s - intervals.start_s.min()) / window_s).astype(int)
    key = intervals.part * 10_000_000 + idx
    _, inv = np.unique(key, return_inverse=True)
    return np.bincount(inv, weights=e)


def held_out_heading(
    folds: Sequence[tuple[HeadingIntervals, HeadingIntervals]],
    *,
    window_s: float = 10.0,
    fixed: dict[str, float] | None = None,
) -> HeldOutHeading:
    """Three models fitted on each fold's first part and scored on its second (module
    docstring): 'nominal' (the wheels as they are, g = 1, only the bias fitted), 'effective
    track' (one gain) and 'turn-rate' (a gain per knot the training part supports; left out of
    a fold whose training part turns at fewer than two rates); and each of ``fixed`` (label ->
    a gain held, e.g. the one the controller ran with; only the bias fitted)."""
    gains = {"nominal": 1.0} | dict(fixed or {})
    errors: dict[str, list[np.ndarray]] = {k: [] for k in gains}
    errors |= {"effective track": [], "turn-rate": []}
    for train, test in folds:
        for label, g in gains.items():
            bias = float(np.sum(train.y - g * train.u) / np.sum(train.dt))
            errors[label].append(_window_errors(test, g * test.u + bias * test.dt, window_s))
        one = fit_gyro_gain(train).predict(test)
        errors["effective track"].append(_window_errors(test, one, window_s))
        try:
            knots = rate_knots(train)
        except CalibrationError:
            continue
        table = fit_gyro_gain(train, knots).predict(test)
        errors["turn-rate"].append(_window_errors(test, table, window_s))
    rms = {
        k: math.degrees(float(np.sqrt(np.mean(np.concatenate(v) ** 2))))
        for k, v in errors.items() if v
    }  # fmt: skip
    windows = sum(len(x) for x in errors["nominal"])
    return HeldOutHeading(window_s, rms, windows)
