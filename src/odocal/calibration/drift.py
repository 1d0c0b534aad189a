"""Drift of one robot's parameter over its bags: a filtered level and a change detector that
use each estimate's stated standard error (``odocal fleet``, docs/fleet.md).

Model: the bag estimates ``y_k = x_k + e_k``, ``e_k ~ N(0, se_k^2)`` (the bag route's standard
error, as given), of a level ``x_k`` that walks slowly: ``x_k = x_{k-1} + w_k``,
``w_k ~ N(0, (q se_k)^2)`` (``q`` = :data:`PROCESS_NOISE`, a small fraction of the per-bag error
per bag: slow wear is followed, a sudden change is not).

1. **Kalman filter** of the level; its innovation ``v_k = y_k - x_{k|k-1}`` has variance
   ``S_k = P_{k|k-1} + se_k^2``; ``z_k = v_k / sqrt(S_k)`` is N(0, 1) and independent from bag
   to bag while the model holds.
2. **Two-sided CUSUM** on ``z``: ``g+ = max(0, g+ + z - k)``, ``g- = max(0, g- - z - k)``; an
   alarm when either exceeds ``h``. ``k`` is half the step to detect (in standard errors),
   ``h`` sets the false-alarm rate (:data:`DEFAULT_K`, :data:`DEFAULT_H`, chosen by simulation
   in benchmarks/bench_fleet.py for the targets of docs/fleet.md).
   While either CUSUM is above zero (a change may be under way) the bags are held out of the
   level, so that the level does not follow a step before it is detected; when both return
   to zero the bags held are filtered in.
   The CUSUM starts once the level rests on :data:`WARMUP` bags.
3. **After an alarm** the filter restarts at the alarm's bag (the CUSUM's change point): the
   level then describes the robot as it is now, and a second change can be detected.

Pure numpy; no I/O.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ModelError

__all__ = [
    "DriftAlarm",
    "DriftTrack",
    "track_parameter",
    "DEFAULT_K",
    "DEFAULT_H",
    "PROCESS_NOISE",
    "WARMUP",
]

#: the CUSUM's allowance (standard deviations of the innovation): half of a 3-se step
DEFAULT_K = 1.5
#: the CUSUM's threshold (benchmarks/bench_fleet.py, docs/fleet.md: 0.04 false alarm per 100
#: robot-months at 20 bags a month and three parameters; a 3-se step found after 3.5 bags on
#: average, 92 % of them within 5 bags)
DEFAULT_H = 4.0
#: bags that make a level before the CUSUM watches it (at the start, and after a change):
#: against a level of one bag, the innovations share its error and a CUSUM would add it up
WARMUP = 4
#: the level's random walk per bag, as a fraction of the bag's standard error
PROCESS_NOISE = 0.05


@dataclass(frozen=True)
class DriftAlarm:
    """A change found at bag ``index`` (the CUSUM's crossing) that began at ``start_index``
    (where the CUSUM last left zero); ``size``: the level after it minus the level before
    (estimated from the bags from ``start_index`` to ``index``), ``z``: that in combined
    standard errors."""

    index: int
    start_index: int
    size: float
    z: float


@dataclass(frozen=True)
class DriftTrack:
    """One parameter's history: the filtered level and its standard error after each bag, the
    standardised innovations, the CUSUMs and the alarms."""

    level: np.ndarray
    level_se: np.ndarray
    z: np.ndarray
    cusum_up: np.ndarray
    cusum_down: np.ndarray
    alarms: tuple[DriftAlarm, ...]


def _weighted_mean(y: np.ndarray, se: np.ndarray) -> tuple[float, float]:
    w = 1.0 / se**2
    return float(np.sum(w * y) / np.sum(w)), float(np.sqrt(1.0 / np.sum(w)))


def _update(x: float, p: float, y: float, se: float, q: float) -> tuple[float, float]:
    """One Kalman step of the level (x, its variance p) with the estimate y (se)."""
    p_pred = p + (q * se) ** 2
    gain = p_pred / (p_pred + se**2)
    return x + gain * (y - x), (1.0 - gain) * p_pred


def track_parameter(
    values: np.ndarray,
    std_errors: np.ndarray,
    *,
    k: float = DEFAULT_K,
    h: float = DEFAULT_H,
    q: float = PROCESS_NOISE,
    warmup: int = WARMUP,
) -> DriftTrack:
    """Filter and watch one parameter's estimates (in time order) with their standard errors
    (module docstring). Every standard error must be finite and positive."""
    y = np.asarray(values, float)
    se = np.asarray(std_errors, float)
    if y.shape != se.shape or y.ndim != 1:
        raise ModelError("values and std_errors must be 1-D arrays of one length")
    if not (np.all(np.isfinite(y)) and np.all(np.isfinite(se)) and np.all(se > 0)):
        raise ModelError("every value must be finite and every standard error positive")
    if k < 0 or h <= 0 or q < 0 or warmup < 1:
        raise ModelError(f"need k >= 0, h > 0, q >= 0, warmup >= 1; got {k}, {h}, {q}, {warmup}")
    n = len(y)
    level, level_se, z = np.empty(n), np.empty(n), np.zeros(n)
    up, down = np.zeros(n), np.zeros(n)
    alarms: list[DriftAlarm] = []
    x, p = float(y[0]), float(se[0] ** 2)
    level[0], level_se[0] = x, se[0]
    g_up = g_down = 0.0
    pending: list[int] = []  # bags held out of the level while a CUSUM is above zero
    began_up = began_down = 0  # where each CUSUM last left zero
    in_level = 1  # bags in the current level (since the start or the last change)
    for i in range(1, n):
        # the level's prediction over the bags held (it walks on meanwhile)
        walk = sum((q * se[j]) ** 2 for j in (*pending, i))
        z[i] = (y[i] - x) / np.sqrt(p + walk + se[i] ** 2)
        if in_level < warmup:
            x, p = _update(x, p, y[i], se[i], q)
            in_level += 1
            level[i], level_se[i] = x, np.sqrt(p)
            continue
        began_up = i if g_up == 0.0 else began_up
        began_down = i if g_down == 0.0 else began_down
        g_up = max(0.0, g_up + z[i] - k)
        g_down = max(0.0, g_down - z[i] - k)
        pending.append(i)
        if g_up > h or g_down > h:
            c = began_up if g_up > h else began_down
            after, after_se = _weighted_mean(y[c : i + 1], se[c : i + 1])
            size = after - x
            alarms.append(DriftAlarm(i, c, size, size / np.sqrt(after_se**2 + p)))
            # restart at the change: the level of the bags since it
            x, p = after, after_se**2
            in_level = i + 1 - c
            g_up = g_down = 0.0
            pending = []
        elif g_up == 0.0 and g_down == 0.0:
            # no change under way: the bags held go into the level, one Kalman update each
            for j in pending:
                x, p = _update(x, p, y[j], se[j], q)
            in_level += len(pending)
            pending = []
        level[i], level_se[i], up[i], down[i] = x, np.sqrt(p), g_up, g_down
    return DriftTrack(level, level_se, z, up, down, tuple(alarms))
