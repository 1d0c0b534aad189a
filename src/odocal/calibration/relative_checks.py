"""The checks of a relative-motion calibration from a bag (the SLAM and scan routes): the
held-out check against the nominal geometry (:func:`~odocal.calibration.heldout.heldout_check`),
the one-log noise estimate (:func:`~odocal.calibration.interval_noise.estimate_interval_noise`),
the timing check (:func:`~odocal.calibration.time_offset.timing_consistency`), and the clock
offset's own uncertainty added to the fit's covariance.

The inputs are relative motions on the wheels' clock (:class:`~odocal.calibration.
relative_motions.RelativeMotions`), whatever measured them; the verdicts (refuse without
``--force``) are the caller's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, replace

import numpy as np

from ..core.model import WheelGeometry
from ..core.transforms import se2_compose, se2_inverse
from ..errors import CalibrationError
from .censi import PARAMETERS, SensorOdometryFit, fit_censi
from .heldout import HeldOut, heldout_check
from .interval_noise import IntervalNoise, estimate_interval_noise
from .relative_motions import RelativeMotions, stack_motions, wheel_increments
from .time_offset import TimeOffset, TimingCheck, offset_covariance, time_blocks, timing_consistency

__all__ = [
    "PreferredAnswer",
    "RelativeChecks",
    "check_relative_fit",
    "interval_blocks",
    "preferred_answer",
    "slam_chains",
    "with_offset_error",
]


@dataclass(frozen=True)
class RelativeChecks:
    """The checks of a relative-motion fit from a bag.

    Attributes
    ----------
    heldout : HeldOut or None
        The blocked cross-validation against the nominal geometry (None: not made, a note says
        why).
    noise : IntervalNoise or None
        The wheels' random error and the truth's, from the residuals.
    timing : TimingCheck or None
        Whether the wheels' turning against the source's depends on the interval length.
    notes : tuple of str
        What was not checked, and why.
    heldout_problem : str or None
        Why the held-out check could not be made on this log (too short), when a nominal
        geometry was given: the caller refuses the fit without ``--force``.
    """

    heldout: HeldOut | None = None
    noise: IntervalNoise | None = None
    timing: TimingCheck | None = None
    notes: tuple[str, ...] = ()
    heldout_problem: str | None = None


@dataclass(frozen=True)
class PreferredAnswer:
    """The answer of a relative-motion fit checked on held-out data: its model ('full', or the
    restricted model the held-out check preferred), its geometry and the standard errors of its
    (D_R, D_L, b) (m; None where not estimated), and their covariance (m^2) when known."""

    model: str
    geometry: WheelGeometry
    stderr: tuple[float | None, float | None, float | None]
    covariance: np.ndarray | None = None


def preferred_answer(fit: SensorOdometryFit, heldout: HeldOut | None) -> PreferredAnswer:
    """The full fit, or the restricted model the held-out check preferred when the full one did
    not beat the nominal geometry (:class:`~odocal.calibration.heldout.HeldOut`)."""
    if heldout is None or heldout.preferred in (None, "full"):
        se = fit.stderr
        return PreferredAnswer("full", fit.geometry, (se.get("wheel_diameter_right_m"),
                               se.get("wheel_diameter_left_m"), se.get("wheelbase_m")),
                               np.asarray(fit.covariance)[:3, :3])  # fmt: skip
    score = next(m for m in heldout.models if m.model == heldout.preferred)
    err = None if score.fit is None else score.fit.stderr
    stderr = (None, None, None) if err is None else (float(err[0]), float(err[1]), float(err[2]))
    cov = None if score.fit is None else score.fit.covariance
    return PreferredAnswer(heldout.preferred, score.geometry, stderr, cov)


def interval_blocks(m: RelativeMotions) -> np.ndarray:
    """The independent groups of the intervals for the cluster-robust standard errors:
    contiguous time blocks (:func:`~odocal.calibration.time_offset.time_blocks`); intervals
    without times (tuple files, in the order recorded) in blocks of consecutive intervals."""
    if m.start_s is not None:
        return time_blocks(np.asarray(m.start_s, dtype=float))
    return time_blocks(np.arange(len(m.phi_right_rad), dtype=float), min_block_s=0.0)


def slam_chains(
    parts: Sequence[tuple[RelativeMotions, np.ndarray]], dropped: Sequence[int]
) -> tuple[RelativeMotions, np.ndarray]:
    """Every interval between SLAM updates of every bag (dropped ones included: they carry the
    held-out chains) and which of them the fit used (not a jump, not an outlier).

    ``parts``: per bag, every interval between its updates (on the wheels' clock) and which of
    them were given to the fit (``every_used``); ``dropped``: the fit's outliers, indices into
    the given intervals of all bags stacked."""
    motions, usable, k = [], [], 0
    drop = set(dropped)
    for m, every_used in parts:
        used = np.array(every_used, dtype=bool)
        keep = used.copy()
        pos = np.flatnonzero(used)
        for j, i in enumerate(pos):
            if k + j in drop:
                keep[i] = False
        k += len(pos)
        motions.append(m)
        usable.append(keep)
    return stack_motions(motions), np.concatenate(usable)


def _refit(
    motions: RelativeMotions, result: SensorOdometryFit
) -> Callable[[np.ndarray], WheelGeometry]:
    """The route's own estimator on some of the intervals (for the held-out folds): the
    relative-motion fit, the sensor's mounting fixed if it was."""
    assert motions.increments is not None
    inc_r, inc_l = motions.increments
    sm = np.asarray(motions.sensor_motion, dtype=float)
    pose = result.sensor_pose if result.sensor_pose_fixed else None

    def fit(idx: np.ndarray) -> WheelGeometry:
        return fit_censi(
            inc_r[idx].sum(axis=1), inc_l[idx].sum(axis=1), sm[idx], sensor_pose=pose,
            wheel_increments=(inc_r[idx], inc_l[idx]),
        ).geometry  # fmt: skip

    return fit


def with_offset_error(
    result: SensorOdometryFit,
    offset: TimeOffset,
    t: np.ndarray,
    right: np.ndarray,
    left: np.ndarray,
    start_s: np.ndarray,
    end_s: np.ndarray,
    motion: np.ndarray,
) -> SensorOdometryFit:
    """``result`` with the clock offset's uncertainty added to its covariance
    (:func:`~odocal.calibration.time_offset.offset_covariance`): the same intervals (their
    stamps, before the offset) refitted with the wheels taken one standard error earlier and
    later, the outliers the fit dropped left out."""
    keep = np.setdiff1d(np.arange(len(start_s)), result.dropped_indices)
    # the derivative needs no more than a sample of them (both refits on the same ones)
    keep = keep[np.unique(np.linspace(0, len(keep) - 1, min(len(keep), 1000)).round().astype(int))]
    pose = result.sensor_pose if result.sensor_pose_fixed else None

    def fit_at(d: float) -> np.ndarray:
        inc_r, inc_l = wheel_increments(t, right, left, start_s[keep] - d, end_s[keep] - d)
        f = fit_censi(inc_r.sum(axis=1), inc_l.sum(axis=1), motion[keep], sensor_pose=pose,
                      wheel_increments=(inc_r, inc_l), outlier_iterations=0)  # fmt: skip
        return f.parameters

    try:
        added = offset_covariance(fit_at, offset)
    except CalibrationError:
        return result
    if added is None:
        return result
    cov = np.array(result.covariance, dtype=float)
    free = np.isfinite(np.diag(cov))
    cov[np.ix_(free, free)] += added[np.ix_(free, free)]
    se = {k: (float(np.sqrt(cov[i, i])) if free[i] else None) for i, k in enumerate(PARAMETERS)}
    return replace(
        result, covariance=cov, stderr=se,
        uncertainty=f"{result.uncertainty}, and the clock offset's own uncertainty",
    )  # fmt: skip


def _base_motion(sensor_motion: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """The base's motion over each interval, from the motion of a sensor mounted at ``mount``
    (x_m, y_m, yaw_rad) on the base."""
    if not np.any(mount != 0):
        return sensor_motion
    mnt = np.broadcast_to(mount, sensor_motion.shape)
    return se2_compose(se2_compose(mnt, sensor_motion), se2_inverse(mnt))


def _heldout(
    motions: RelativeMotions,
    times: tuple[np.ndarray, np.ndarray],
    usable: np.ndarray,
    base: np.ndarray,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
) -> tuple[HeldOut | None, str | None, tuple[str, ...]]:
    """The held-out check (``times``: the intervals' starts and ends), why it could not be made
    on this log (or None), and the notes."""
    if nominal is None:
        return None, None, ("no held-out check: it needs the nominal geometry (--robot)",)
    assert motions.increments is not None
    inc_r, inc_l = motions.increments
    try:
        heldout = heldout_check(
            times[0], times[1], inc_r, inc_l, base, nominal, result.geometry,
            fit_mask=usable, fit_full=_refit(motions, result),
        )  # fmt: skip
    except CalibrationError as exc:
        return None, str(exc), (f"no held-out check: {exc}",)
    return heldout, None, ()


def _noise(
    inc: tuple[np.ndarray, np.ndarray],
    base: np.ndarray,
    geometry: WheelGeometry,
    start_s: np.ndarray,
    end_s: np.ndarray,
) -> tuple[IntervalNoise | None, tuple[str, ...]]:
    """The one-log noise estimate over the intervals given (the fit's), or a note why not."""
    try:
        noise = estimate_interval_noise(inc[0], inc[1], base, geometry, start_s, end_s=end_s)
    except CalibrationError as exc:
        return None, (f"no noise estimate: {exc}",)
    return noise, ()


def check_relative_fit(
    motions: RelativeMotions,
    usable: np.ndarray,
    mount: np.ndarray,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
    *,
    source: str,
    noise: bool = True,
) -> RelativeChecks:
    """The held-out check, the timing check and (``noise``) the one-log noise estimate of a bag
    route:
    ``motions`` every interval in time order (the sensor's motion, seen from a sensor mounted
    at ``mount`` on the base), ``usable`` those the fit used, ``result`` the fit, ``source`` the
    truth source's name (for the timing check's words). Without a nominal geometry there is
    nothing to hold the calibration against (a note says so); a log too short for the check
    leaves ``heldout_problem``."""
    start_s, end_s = motions.start_s, motions.end_s
    if motions.increments is None or start_s is None or end_s is None:
        return RelativeChecks(notes=("no held-out check: the intervals carry no times",))
    inc_r, inc_l = motions.increments
    sm = np.asarray(motions.sensor_motion, dtype=float)
    base = _base_motion(sm, mount)
    heldout, problem, notes = _heldout(motions, (start_s, end_s), usable, base, result, nominal)
    timing = timing_consistency(
        motions.phi_right_rad, motions.phi_left_rad, sm[:, 2], start_s, end_s, source=source
    )
    if not noise:
        return RelativeChecks(heldout, None, timing, notes, problem)
    found, more = _noise(
        (inc_r[usable], inc_l[usable]), base[usable], result.geometry, start_s[usable],
        end_s[usable],
    )  # fmt: skip
    return RelativeChecks(heldout, found, timing, notes + more, problem)
