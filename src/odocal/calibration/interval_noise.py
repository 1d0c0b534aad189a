"""The wheels' random error from one log: relative-motion residuals against a truth source.

``odocal noise`` measures the non-systematic error k from repeated runs with a position truth.
A robot with one bag and a SLAM, laser or motion-capture truth has something as good: many
intervals, each with the wheels' rotations and the truth's measured motion. Once the systematic
part is calibrated, the residual of interval i (measured minus dead-reckoned motion, in the base
frame at its start) is the wheels' random error over that interval plus the truth's own noise:

    Cov(e_i) = k C_i + R,      R = diag(r_xy, r_xy, r_theta)

where C_i is the first-order covariance of the interval's dead reckoning per unit of
k = k_r + k_l (model.md: each wheel's travel variance grows as k_w |s_w|, here with
k_r = k_l = k / 2; ``core.covariance.propagate_increments``) and R the truth's noise on a
relative motion (for a SLAM pose, about twice its per-pose variance). Longer intervals carry
more wheel noise and the same truth noise, which separates the two. A log's intervals are often
all of about one length (a SLAM updating once a second), so consecutive intervals are also
composed into stretches of 2, 4, 8 and 16 (the measured motions composed, the wheel increments
strung together): k, r_xy and r_theta are the Gaussian maximum-likelihood values over all of
them (in log space, so that each stays positive). The stretches share data, so the likelihood
is not a proper one; the interval below does not rely on it.

The 95 % interval of k is a block bootstrap (contiguous time blocks of intervals resampled, the
likelihood maximised again; the interval is the estimate times exp(+-1.96 bootstrap standard
deviations of log k)): residuals come in runs (a wheel slipping for a second, a SLAM that
is off for a stretch), which a likelihood interval would ignore. Model mismatch that the
calibration leaves in the residuals (an effective wheelbase that changes with the motion, a
synchro drive seen as a differential one) is counted as wheel noise: the k found is what the
odometry's error looks like to a filter, which is what a covariance is for.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core.covariance import propagate_increments
from ..core.model import NonSystematicError, WheelGeometry
from ..core.odometry import dead_reckon_rows
from ..core.transforms import se2_compose
from ..errors import CalibrationError
from .time_offset import time_blocks

__all__ = ["IntervalNoise", "estimate_interval_noise", "predicted_covariance"]

#: Fewest intervals for a noise estimate.
MIN_INTERVALS = 30
#: At most this many intervals enter the estimate: contiguous chunks of
#: :data:`CHUNK_INTERVALS`, spread evenly over the log (an hour's 7000 SLAM intervals would
#: cost a minute and gigabytes for three numbers).
MAX_INTERVALS = 320
CHUNK_INTERVALS = 16
_BOOTSTRAP = 30


@dataclass(frozen=True)
class IntervalNoise:
    """The random error of the odometry and of the truth, from one log's intervals.

    Attributes
    ----------
    k_sum_m : float
        k_r + k_l (m): each wheel's travel variance per metre travelled, summed.
    k_ci95_m : tuple of float
        Block-bootstrap 95 % interval of ``k_sum_m``.
    truth_sigma_xy_m, truth_sigma_theta_rad : float
        The truth source's noise on one interval's relative motion (m, rad).
    intervals : int
    blocks : int
        Time blocks behind the interval.
    """

    k_sum_m: float
    k_ci95_m: tuple[float, float]
    truth_sigma_xy_m: float
    truth_sigma_theta_rad: float
    intervals: int
    blocks: int

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {
            "k_sum_m": self.k_sum_m,
            "k_ci95_m": list(self.k_ci95_m),
            "truth_sigma_xy_m": self.truth_sigma_xy_m,
            "truth_sigma_theta_rad": self.truth_sigma_theta_rad,
            "intervals": self.intervals,
            "blocks": self.blocks,
            "method": "Gaussian maximum likelihood of relative-motion residuals; "
            "block-bootstrap interval",
        }


def _nll_and_gradient(
    log_params: np.ndarray, e: np.ndarray, c: np.ndarray
) -> tuple[float, np.ndarray]:
    """The negative log-likelihood (up to a constant) of residuals e (n, 3) with covariances
    k c_i + diag(r_xy, r_xy, r_theta), and its gradient in the log parameters: for each j,
    sum_i tr(S_i^-1 dS_i) - e_i^T S_i^-1 dS_i S_i^-1 e_i, with dS_i = k C_i, or r_xy on the
    two position entries, or r_theta on the heading entry."""
    k, r_xy, r_th = np.exp(log_params)
    s = k * c + np.diag([r_xy, r_xy, r_th])[None, :, :]
    sign, logdet = np.linalg.slogdet(s)
    if np.any(sign <= 0):
        return 1e300, np.zeros(3)
    inv = np.linalg.inv(s)
    u = np.einsum("nij,nj->ni", inv, e)  # S^-1 e
    value = float(np.sum(logdet) + np.sum(e * u))
    grad = np.empty(3)
    # d/d log k: k C
    grad[0] = k * float(np.einsum("nij,nji->", inv, c) - np.einsum("ni,nij,nj->", u, c, u))
    grad[1] = r_xy * float(
        np.sum(inv[:, 0, 0] + inv[:, 1, 1]) - np.sum(u[:, 0] ** 2 + u[:, 1] ** 2)
    )
    grad[2] = r_th * float(np.sum(inv[:, 2, 2]) - np.sum(u[:, 2] ** 2))
    return value, grad


LOG_VARIANCE_BOUNDS = (math.log(1e-40), math.log(1e6))


def _maximise(e: np.ndarray, c: np.ndarray, start: np.ndarray, xatol: float) -> np.ndarray:
    """The maximum-likelihood log parameters (quasi-Newton with the analytic gradient; ``xatol``
    the tolerance in log parameters)."""
    from scipy.optimize import minimize  # here: a slow import

    # the variances between 1e-40 and 1e6: a log without noise drives them to zero, and exp
    # must stay finite on the way there
    sol = minimize(_nll_and_gradient, np.clip(start, *LOG_VARIANCE_BOUNDS), args=(e, c),
                   jac=True, method="L-BFGS-B", bounds=[LOG_VARIANCE_BOUNDS] * 3,
                   options={"ftol": 1e-12, "gtol": xatol * 1e-3, "maxiter": 500})  # fmt: skip
    return np.asarray(sol.x, dtype=float)


def _stretches(
    inc_r: np.ndarray,
    inc_l: np.ndarray,
    motion: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray | None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The intervals and the stretches of 2, 4, ... 16 consecutive ones (consecutive: one
    starts where the last ended): increments (M, L) each, measured motions (M, 3), start times
    (M,)."""
    n, k = inc_r.shape
    rows_r, rows_l, motions, starts = [inc_r], [inc_l], [motion], [start_s]
    if end_s is not None and n > 1:
        gap = np.abs(start_s[1:] - end_s[:-1]) > 1e-6 + 1e-3 * float(np.median(end_s - start_s))
        chains = np.split(np.arange(n), np.flatnonzero(gap) + 1)
        for size in (2, 4, 8, 16):
            groups = [c[i : i + size] for c in chains for i in range(0, len(c) - size + 1, size)]
            if not groups:
                break
            idx = np.array(groups)  # (G, size)
            r = inc_r[idx].reshape(len(idx), size * k)
            lft = inc_l[idx].reshape(len(idx), size * k)
            m = motion[idx[:, 0]]
            for j in range(1, size):
                m = se2_compose(m, motion[idx[:, j]])
            rows_r.append(r)
            rows_l.append(lft)
            motions.append(m)
            starts.append(start_s[idx[:, 0]])
    width = max(x.shape[1] for x in rows_r)

    def pad(a: np.ndarray) -> np.ndarray:
        return np.pad(a, ((0, 0), (0, width - a.shape[1])))

    return (
        np.concatenate([pad(x) for x in rows_r]),
        np.concatenate([pad(x) for x in rows_l]),
        np.concatenate(motions),
        np.concatenate(starts),
    )


def _chunks(n: int) -> np.ndarray:
    """The intervals that enter the estimate: all, or :data:`MAX_INTERVALS` in contiguous
    chunks spread evenly over the log."""
    if n <= MAX_INTERVALS:
        return np.arange(n)
    count = MAX_INTERVALS // CHUNK_INTERVALS
    starts = np.linspace(0, n - CHUNK_INTERVALS, count).round().astype(int)
    return np.unique((starts[:, None] + np.arange(CHUNK_INTERVALS)[None, :]).ravel())


def estimate_interval_noise(
    inc_r: ArrayLike,
    inc_l: ArrayLike,
    motion: ArrayLike,
    geometry: WheelGeometry,
    start_s: ArrayLike,
    *,
    end_s: ArrayLike | None = None,
    rng: np.random.Generator | None = None,
) -> IntervalNoise:
    """k and the truth's noise (module docstring) from intervals a calibration used.

    Parameters
    ----------
    inc_r, inc_l : ndarray, shape (n, K)
        Wheel rotations within each interval as sampled (rad; rows zero padded).
    motion : ndarray, shape (n, 3)
        Measured base motion over each interval (m, m, rad), base frame at its start.
    geometry : WheelGeometry
        The calibrated geometry.
    start_s : ndarray, shape (n,)
        Interval starts (s), for the time blocks.
    end_s : ndarray, shape (n,), optional
        Interval ends (s): with them consecutive intervals are composed into stretches.
    rng : numpy.random.Generator, optional
        For the bootstrap (default seeded 0).
    """
    r = np.asarray(inc_r, dtype=float)
    lft = np.asarray(inc_l, dtype=float)
    m = np.asarray(motion, dtype=float)
    n = len(m)
    if n < MIN_INTERVALS:
        raise CalibrationError(
            f"too few intervals for a noise estimate: {n} (need {MIN_INTERVALS})"
        )
    start = np.asarray(start_s, dtype=float)
    end = None if end_s is None else np.asarray(end_s, dtype=float)
    pick = _chunks(n)
    r, lft, m, start = r[pick], lft[pick], m[pick], start[pick]
    end = None if end is None else end[pick]
    r, lft, m, t0 = _stretches(r, lft, m, start, end)  # fmt: skip
    pred = dead_reckon_rows(r, lft, geometry)[:, :, -1].T
    e = m - pred
    e[:, 2] = np.angle(np.exp(1j * e[:, 2]))
    dr, dl = 0.5 * geometry.diameter_right_m * r, 0.5 * geometry.diameter_left_m * lft
    _, c = propagate_increments(dr, dl, geometry.wheelbase_m, NonSystematicError(0.5, 0.5))
    # start: k from the translation spread per metre, truth from the shortest intervals
    travel = np.sum(0.5 * (np.abs(dr) + np.abs(dl)), axis=1)
    k0 = max(float(np.median(e[:, 0] ** 2 / np.maximum(travel, 1e-6))), 1e-12)
    start = np.log([k0, max(float(np.median(e[:, 1] ** 2)), 1e-12),
                    max(float(np.median(e[:, 2] ** 2)), 1e-12)])  # fmt: skip
    best = _maximise(e, c, start, 1e-4)
    gen = rng if rng is not None else np.random.default_rng(0)
    blk = time_blocks(t0)
    nb = int(blk.max()) + 1
    members = [np.flatnonzero(blk == b) for b in range(nb)]
    logs = []
    for _ in range(_BOOTSTRAP if nb >= 2 else 0):
        idx = np.concatenate([members[j] for j in gen.integers(0, nb, nb)])
        logs.append(_maximise(e[idx], c[idx], best, 1e-2)[0])
    k, r_xy, r_th = np.exp(best)
    # the interval in log k (k > 0; its estimate is about log-normal): the estimate +- 1.96
    # bootstrap standard deviations, so that it always holds the estimate and behaves near 0
    spread = float(np.std(logs, ddof=1)) if len(logs) > 1 else math.inf
    lo, hi = float(k) * math.exp(-1.96 * spread), float(k) * math.exp(1.96 * spread)
    return IntervalNoise(
        float(k), (lo, hi), float(math.sqrt(r_xy)), float(math.sqrt(r_th)), len(pick), nb
    )


def predicted_covariance(
    inc_r: ArrayLike,
    inc_l: ArrayLike,
    geometry: WheelGeometry,
    noise: IntervalNoise,
) -> np.ndarray:
    """The covariance (3, 3) of (D_R, D_L, b) a relative-motion fit of these intervals would
    have under ``noise`` (the wheels' k and the truth's noise per interval): the inverse of
    sum_i J_i^T S_i^-1 J_i, with J_i the derivative of interval i's dead-reckoned motion and
    S_i = k C_i + R its covariance (module docstring). NaN where singular."""
    r = np.asarray(inc_r, dtype=float)
    lft = np.asarray(inc_l, dtype=float)
    p0 = np.array([geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m])
    jac = np.empty((len(r), 3, 3))
    for j in range(3):
        h = 1e-6 * p0[j]
        up, down = p0.copy(), p0.copy()
        up[j] += h
        down[j] -= h
        plus = dead_reckon_rows(r, lft, WheelGeometry.unchecked(*up))[:, :, -1].T
        minus = dead_reckon_rows(r, lft, WheelGeometry.unchecked(*down))[:, :, -1].T
        jac[:, :, j] = (plus - minus) / (2 * h)
    dr, dl = 0.5 * geometry.diameter_right_m * r, 0.5 * geometry.diameter_left_m * lft
    _, c = propagate_increments(dr, dl, geometry.wheelbase_m, NonSystematicError(0.5, 0.5))
    s = (
        noise.k_sum_m * c
        + np.diag(
            [noise.truth_sigma_xy_m**2, noise.truth_sigma_xy_m**2, noise.truth_sigma_theta_rad**2]
        )[None, :, :]
    )
    info = np.einsum("nij,njk,nkl->il", jac.transpose(0, 2, 1), np.linalg.inv(s), jac)
    try:
        return np.linalg.inv(info)
    except np.linalg.LinAlgError:
        return np.full((3, 3), np.nan)
