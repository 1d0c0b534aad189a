"""Do the measured headings of polygon runs agree with their measured positions?

A heading read with the wrong sign (a protractor held the other way) passes every check of its
own and gives the inverse correction. When the run sheet also has the end positions, they tell:
the heading-error method's answer from ``theta_deg`` as written, and from ``theta_deg`` with the
opposite sign, each predict the mean end position of the CW and CCW runs (the noise-free drive
of the corrected geometry, the model of the method). The positions decide between the two.

The statistic uses the runs' own scatter. Let ``m`` be the four measured means (x, y of CW and
CCW), ``p`` and ``q`` the predictions of the written and the flipped headings, ``S`` the
covariance of ``m - p`` (each mean's squared standard error from the scatter of its runs, plus
what the headings' own scatter does to ``p``), ``d = q - p`` and ``D = sqrt(d' S^-1 d)`` (how
many standard errors the two predictions lie apart). The positions' standardised step towards
the flipped prediction is ``t = (m - p)' S^-1 d / D``: about 0 (unit spread) when the headings
are right, about ``D`` when their sign is wrong. The check fails when

- ``t > T``: far beyond the written headings' noise (``T`` the Student t quantile at
  ``ALPHA`` with the Welch-Satterthwaite degrees of freedom of the scatter behind ``S``: honest
  sheets essentially never reach it), and
- ``t > D / 2``: the positions lie nearer the flipped prediction than the written one (a
  model error smaller than half the effect cannot make them so).

When the headings are so small that flipping them changes the answer by less than the noise
(``D`` small), no check can tell the signs apart, and none is needed: the two answers agree.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.model import NonSystematicError, WheelGeometry
from ..core.runs import EndPoseRuns
from ..core.simulate import drive
from ..core.stats import student_t_quantile
from ..core.tracks import Track, polygon
from ..errors import InputError
from .heading import calibrate_heading

__all__ = [
    "HeadingCheck",
    "check_heading_sign",
    "refuse_flipped_headings",
    "ALPHA",
    "MIN_RUNS",
]

#: One-sided false-alarm probability of the check on an honest sheet (before the t > D/2 rule).
ALPHA = 1e-5
#: Runs per direction with x, y and theta all measured that the check needs (a scatter).
MIN_RUNS = 2


@dataclass(frozen=True)
class HeadingCheck:
    """The headings of a run sheet held against its positions (module docstring).

    Attributes
    ----------
    t : float
        The positions' standardised step from the written headings' prediction towards the
        flipped headings' prediction.
    separation : float
        ``D``: the two predictions' distance in standard errors.
    threshold : float
        ``T``.
    E_b_written, E_d_written, E_b_flipped, E_d_flipped : float
        The heading-error method's answers from theta as written and with the opposite sign.
    runs : int
        Runs with x, y and theta all measured.
    """

    t: float
    separation: float
    threshold: float
    E_b_written: float
    E_d_written: float
    E_b_flipped: float
    E_d_flipped: float
    runs: int

    @property
    def contradicted(self) -> bool:
        """Whether the positions say the headings have the wrong sign."""
        return self.t > self.threshold and self.t > self.separation / 2.0


def _mean_ends(
    track_for: Callable[[str], Track], geometries: list[WheelGeometry], ran_with: WheelGeometry
) -> np.ndarray:
    """Noise-free mean end positions (x, y of CW then CCW), shape (len(geometries), 4)."""
    true = WheelGeometry(
        np.array([float(g.diameter_right_m) for g in geometries]),
        np.array([float(g.diameter_left_m) for g in geometries]),
        np.array([float(g.wheelbase_m) for g in geometries]),
    )
    out = []
    for d in ("cw", "ccw"):
        res = drive(
            track_for(d),
            true,
            ran_with,
            NonSystematicError(0.0, 0.0),
            len(geometries),
            None,
            steps_per_segment=1,
            integration="exact",
        )
        out.append(res.errors[:, :2])
    return np.hstack(out)


def check_heading_sign(
    runs: EndPoseRuns, sides: int, side_m: float, ran_with: WheelGeometry
) -> HeadingCheck | None:
    """Hold the headings of ``runs`` (regular ``sides``-gon of side ``side_m`` m, driven with
    ``ran_with``) against their positions; None when fewer than :data:`MIN_RUNS` runs per
    direction have x, y and theta all measured, or they have no scatter to judge by."""
    err = np.asarray(runs.errors, dtype=float)
    complete = np.all(np.isfinite(err), axis=1)
    labels = np.asarray(runs.directions, dtype=object)
    counts = [int(np.count_nonzero(complete & (labels == d))) for d in ("cw", "ccw")]
    if min(counts) < MIN_RUNS:
        return None
    sub = EndPoseRuns(tuple(labels[complete].tolist()), err[complete])
    written = calibrate_heading(sub, sides, side_m, ran_with)
    flipped_err = err[complete] * np.array([1.0, 1.0, -1.0])
    flipped = calibrate_heading(EndPoseRuns(sub.directions, flipped_err), sides, side_m, ran_with)
    if written.uncertainty is None:
        return None

    def track_for(d: str) -> Track:
        return polygon(sides, side_m, d)

    h = 1e-6
    E_b, E_d = written.E_b, written.E_d
    geometries = [
        written.corrected,
        flipped.corrected,
        ran_with.corrected(E_b + h, E_d),
        ran_with.corrected(E_b, E_d + h),
    ]
    ends = _mean_ends(track_for, geometries, ran_with)
    p, q = ends[0], ends[1]
    jac = np.column_stack([(ends[2] - p) / h, (ends[3] - p) / h])
    cov_e = written.uncertainty.covariance[:2, :2]
    # each measured mean's squared standard error from the scatter of its runs
    var, dofs = [], []
    for d in ("cw", "ccw"):
        xy = sub.select(d)[:, :2]
        var += list(xy.var(axis=0, ddof=1) / len(xy))
        dofs += [len(xy) - 1] * 2
    from_headings = jac @ cov_e @ jac.T
    s = np.diag(var) + from_headings
    m = np.concatenate([sub.mean("cw")[:2], sub.mean("ccw")[:2]])
    d_vec = q - p
    try:
        s_inv_d = np.linalg.solve(s, d_vec)
    except np.linalg.LinAlgError:
        return None
    separation_sq = float(d_vec @ s_inv_d)
    if not (math.isfinite(separation_sq) and separation_sq > 0.0):
        return None
    separation = math.sqrt(separation_sq)
    t = float((m - p) @ s_inv_d) / separation
    # Welch-Satterthwaite degrees of freedom of t's variance (D^2 = sum of these parts)
    parts = np.append(s_inv_d**2 * np.array(var), s_inv_d @ from_headings @ s_inv_d)
    nus = np.append(np.array(dofs, dtype=float), float(np.min(written.uncertainty.dof[:2])))
    dof = separation_sq**2 / float(np.sum(parts**2 / nus))
    return HeadingCheck(
        t=t,
        separation=separation,
        threshold=student_t_quantile(1.0 - ALPHA, dof),
        E_b_written=float(written.E_b),
        E_d_written=float(written.E_d),
        E_b_flipped=float(flipped.E_b),
        E_d_flipped=float(flipped.E_d),
        runs=sum(counts),
    )


def refuse_flipped_headings(
    runs: EndPoseRuns,
    sides: int,
    side_m: float,
    ran_with: WheelGeometry,
    force: bool,
    where: str | Path | None = None,
) -> list[str]:
    """Where a sheet (``where``) has both headings and positions, the positions must not say
    that the headings have the wrong sign (:func:`check_heading_sign`): InputError, or with
    ``force`` a warning (returned)."""
    check = check_heading_sign(runs, sides, side_m, ran_with)
    if check is None or not check.contradicted:
        return []
    problem = (
        f"the headings contradict the positions: theta_deg as written gives E_b "
        f"{check.E_b_written:.4f}, E_d {check.E_d_written:.4f}, but the x_m, y_m of the same "
        f"{check.runs} runs lie {check.t:.1f} standard errors towards theta_deg with the "
        f"opposite sign (E_b {check.E_b_flipped:.4f}, E_d {check.E_d_flipped:.4f}; the two are "
        f"{check.separation:.1f} standard errors apart). Was the protractor read the other way? "
        "theta is counter-clockwise positive (seen from above), the final heading ERROR actual "
        "- odometric (docs/conventions.md); correct the sign in the sheet"
    )
    if not force:
        raise InputError(f"{problem} (--force calibrates the sheet as written)", where)
    return [f"{where}: {problem}; calibrated as written (--force)"]
