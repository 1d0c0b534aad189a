"""Bi-directional circular path test (BCPT; after Abbas, Arif & Ahmed 2006). RECONSTRUCTED.

The BCPT paper was not available: the equations below reconstruct the method's idea from the
project's model (docs/conventions.md; methods-notes.md section 4) and are verified numerically,
but are not known to match the paper's own equations.

Procedure: steered by its own odometry with the parameters it RAN WITH (wheelbase b_n), the robot
drives a circle of commanded axle-centre radius R_c counter-clockwise and clockwise; an external
tracker measures the actual radii R_ccw and R_cw (least-squares circle fit to tracked points).
With h = b_true / 2 and g = (R_c + b_n/2) / (R_c - b_n/2) the commanded wheel-travel ratio:

    CCW:  (R_ccw + h) / (R_ccw - h) = E_d g
    CW:   (R_cw  + h) / (R_cw  - h) = g / E_d

Their product eliminates E_d and leaves a quadratic in h (k = g^2):

    (1 - k) h^2 + (1 + k)(R_ccw + R_cw) h + (1 - k) R_ccw R_cw = 0   -> smallest positive root
    E_b = 2 h / b_n,   E_d = sqrt((R_ccw + h)(R_cw - h) / ((R_ccw - h)(R_cw + h)))

This is exact under the model (no small-angle shortcut). To first order in the radius changes:

    E_b ~ (R_cw + R_ccw) / (2 R_c),   E_d ~ 1 + b_n (R_cw - R_ccw) / (2 R_c^2)

Signs: E_d > 1 (right wheel larger) pulls the robot left, so the CCW circle tightens and the CW
circle widens; E_b > 1 widens both. A common scale error E_s cancels (it changes how fast, not
where, the robot drives). E_b, E_d are relative to the parameters the robot ran with.
"""

from __future__ import annotations

import math
from collections.abc import Iterable
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry, check_positive
from ..core.odometry import dead_reckon
from ..core.recording import Recording
from ..core.runs import CircleRuns
from ..errors import CalibrationError
from .circle_fit import fit_circle
from .result import CalibrationResult
from .uncertainty import spread_uncertainty

__all__ = [
    "bcpt_factors",
    "bcpt_first_order",
    "calibrate_bcpt",
    "circle_arcs_from_recording",
    "circle_runs_from_recordings",
    "calibrate_bcpt_recordings",
]


def _ratio(radius: float | np.ndarray, half_wheelbase: float | np.ndarray) -> float | np.ndarray:
    return (radius + half_wheelbase) / (radius - half_wheelbase)


def bcpt_factors(
    radius_cw_m: ArrayLike,
    radius_ccw_m: ArrayLike,
    commanded_radius_m: ArrayLike,
    wheelbase_m: ArrayLike,
    commanded_ccw_m: ArrayLike | None = None,
) -> tuple[np.ndarray, np.ndarray]:
    """Exact E_b, E_d from the measured CW and CCW radii (m); arrays broadcast.

    Parameters
    ----------
    radius_cw_m, radius_ccw_m : float or ndarray
        Measured axle-centre radii of the CW and CCW circles (m).
    commanded_radius_m : float or ndarray
        Commanded radius R_c (m) in the robot's belief (of the CW circle, and of the CCW circle
        too unless ``commanded_ccw_m`` is given).
    wheelbase_m : float or ndarray
        Wheelbase the robot ran with, b_n (m).
    commanded_ccw_m : float or ndarray, optional
        Commanded radius of the CCW circle when it differs from the CW one (recorded arcs).

    Returns NaN where the equations have no physical solution (e.g. a radius below b/2).
    """
    r_cw = np.asarray(radius_cw_m, dtype=float)
    r_ccw = np.asarray(radius_ccw_m, dtype=float)
    rc_cw = np.asarray(commanded_radius_m, dtype=float)
    rc_ccw = rc_cw if commanded_ccw_m is None else np.asarray(commanded_ccw_m, dtype=float)
    half = 0.5 * np.asarray(wheelbase_m, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        g_cw = _ratio(rc_cw, half)
        g_ccw = _ratio(rc_ccw, half)
        k = g_cw * g_ccw
        qa = 1.0 - k
        qb = (1.0 + k) * (r_ccw + r_cw)
        qc = (1.0 - k) * r_ccw * r_cw
        disc = qb * qb - 4.0 * qa * qc
        # Stable smallest positive root: 2 c / (-b - sqrt(disc)) = 2 (k-1) R R' / (b + sqrt(disc)).
        h = np.where(disc >= 0, -2.0 * qc / (qb + np.sqrt(np.maximum(disc, 0.0))), np.nan)
        ok = (h > 0) & (h < r_cw) & (h < r_ccw) & (g_cw > 0) & (g_ccw > 0)
        E_b = np.where(ok, h / half, np.nan)
        rho_ccw = _ratio(r_ccw, h)
        rho_cw = _ratio(r_cw, h)
        E_d = np.where(ok, np.sqrt(rho_ccw * g_cw / (rho_cw * g_ccw)), np.nan)
    return E_b, E_d


def bcpt_first_order(
    radius_cw_m: float | np.ndarray,
    radius_ccw_m: float | np.ndarray,
    commanded_radius_m: float | np.ndarray,
    wheelbase_m: float | np.ndarray,
) -> tuple[float | np.ndarray, float | np.ndarray]:
    """First-order (linearised) E_b, E_d, for intuition and sanity checks only:
    E_b ~ (R_cw + R_ccw)/(2 R_c), E_d ~ 1 + b_n (R_cw - R_ccw)/(2 R_c^2)."""
    rc = np.asarray(commanded_radius_m, dtype=float)
    with np.errstate(over="ignore", under="ignore"):  # absurd radii: inf/0, rejected downstream
        E_b = (np.asarray(radius_cw_m) + radius_ccw_m) / (2.0 * rc)
        E_d = 1.0 + wheelbase_m * (np.asarray(radius_cw_m) - radius_ccw_m) / (2.0 * rc * rc)
    return E_b, E_d


def calibrate_bcpt(
    runs: CircleRuns, commanded_radius_m: float, ran_with: WheelGeometry, **inputs: Any
) -> CalibrationResult:
    """BCPT from measured circle radii (the mean radius per direction); see module docstring.

    ``commanded_radius_m`` (m) is the radius the robot was told to drive; ``ran_with`` the
    parameters it ran with. Extra keyword ``inputs`` are recorded in the result.
    """
    check_positive("commanded radius", commanded_radius_m)
    r_cw = runs.mean("cw")
    r_ccw = runs.mean("ccw")
    if commanded_radius_m <= 0.5 * float(ran_with.wheelbase_m):
        raise CalibrationError(
            f"bcpt: the commanded radius {commanded_radius_m:g} m must exceed half the wheelbase"
        )
    E_b, E_d = bcpt_factors(r_cw, r_ccw, commanded_radius_m, ran_with.wheelbase_m)
    lin_b, lin_d = bcpt_first_order(r_cw, r_ccw, commanded_radius_m, ran_with.wheelbase_m)
    unc = spread_uncertainty(
        lambda z: bcpt_factors(z[0], z[1], commanded_radius_m, ran_with.wheelbase_m),
        [(d, runs.select(d)[:, None]) for d in ("cw", "ccw")],
        ran_with,
    )
    return CalibrationResult.from_factors(
        "bcpt",
        float(E_b),
        float(E_d),
        ran_with,
        unc,
        commanded_radius_m=float(commanded_radius_m),
        runs_cw=runs.count("cw"),
        runs_ccw=runs.count("ccw"),
        mean_radius_cw_m=r_cw,
        mean_radius_ccw_m=r_ccw,
        first_order_E_b=float(lin_b),
        first_order_E_d=float(lin_d),
        **inputs,
    )


# --- recorded runs ---------------------------------------------------------------------------


def circle_arcs_from_recording(
    recording: Recording, arc_rad: float | None = None, geometry: WheelGeometry | None = None
) -> list[dict]:
    """Fit circles to a recorded circle run, whole or split into arcs.

    The commanded radius is taken from the run itself: the circle fitted to the DEAD-RECKONED
    trajectory (wheel rotations with ``geometry``, default the parameters the robot ran with) is
    the path the robot believed it drove; the circle fitted to the ground truth over the same
    samples is the path it really drove.

    Parameters
    ----------
    recording : Recording
        Needs ground truth.
    arc_rad : float, optional
        Split the run into consecutive arcs of this much odometric rotation (rad), e.g. pi for the
        OptiOdom ``circular/`` runs (four 180-degree arcs of decreasing radius); the last partial
        arc is dropped if shorter than half of ``arc_rad``. Default: the whole run is one circle.

    Returns
    -------
    list of dict
        Per arc: ``commanded_radius_m``, ``radius_m`` (ground truth), ``rms_residual_m``,
        ``direction`` ('cw'/'ccw', from the sign of the odometric rotation), ``samples``.
    """
    if recording.ground_truth is None:
        raise CalibrationError(f"{recording.name}: BCPT needs ground truth (tracked points)")
    geometry = geometry or recording.ran_with
    if geometry is None:
        raise CalibrationError(f"{recording.name}: no parameters to dead-reckon with")
    odo = dead_reckon(recording.wheel_angle_right_rad, recording.wheel_angle_left_rad, geometry)
    gt = np.asarray(recording.ground_truth, dtype=float)
    turn = odo[-1, 2]
    direction = "ccw" if turn > 0 else "cw"
    if arc_rad is None:
        pieces = [np.arange(len(odo))]
    else:
        a = np.abs(odo[:, 2])
        n_arcs = int(math.floor(a[-1] / arc_rad + 0.5))
        pieces = [
            np.nonzero((a >= k * arc_rad) & (a < (k + 1) * arc_rad))[0] for k in range(n_arcs)
        ]
        pieces = [p for p in pieces if len(p) >= 10]
    out = []
    for idx in pieces:
        fo = fit_circle(odo[idx, :2])
        fg = fit_circle(gt[idx, :2])
        out.append(
            {
                "direction": direction,
                "commanded_radius_m": fo.radius_m,
                "radius_m": fg.radius_m,
                "rms_residual_m": fg.rms_residual_m,
                "samples": int(len(idx)),
            }
        )
    return out


def circle_runs_from_recordings(
    recordings: Iterable[Recording], arc_rad: float | None = None
) -> list[list[dict]]:
    """Per-arc fits of several recorded circle runs; returns (list of arc dicts per run)."""
    return [circle_arcs_from_recording(r, arc_rad) for r in recordings]


def calibrate_bcpt_recordings(
    recordings: Iterable[Recording],
    arc_rad: float | None = None,
    commanded_radius_m: float | None = None,
) -> CalibrationResult:
    """BCPT from recorded CW and CCW circle runs with ground truth.

    Every run is fitted (whole, or per arc of ``arc_rad``); arc k of the CW runs is paired with
    arc k of the CCW runs (mean radius per direction), solved exactly, and the per-arc E_b, E_d are
    averaged. The commanded radius of each arc is fitted to the dead-reckoned path unless
    ``commanded_radius_m`` (m) is given (whole runs only). All runs must share ``ran_with``.
    """
    recordings = list(recordings)
    if not recordings:
        raise CalibrationError("bcpt: no runs")
    ran_with = recordings[0].ran_with
    if ran_with is None:
        raise CalibrationError(f"{recordings[0].name}: the parameters it ran with are unknown")
    for r in recordings[1:]:
        if r.ran_with != ran_with:
            raise CalibrationError(
                f"bcpt: {r.name} ran with other parameters than {recordings[0].name}"
            )
    fits = circle_runs_from_recordings(recordings, arc_rad)
    by_dir: dict[str, list[list[dict]]] = {"cw": [], "ccw": []}
    for f in fits:
        if f:
            by_dir[f[0]["direction"]].append(f)
    for d in ("cw", "ccw"):
        if not by_dir[d]:
            raise CalibrationError(f"bcpt: there are no {d.upper()} circle runs")
    n_arcs = min(len(f) for d in by_dir for f in by_dir[d])
    per_arc = []
    for k in range(n_arcs):
        radius = {d: float(np.mean([f[k]["radius_m"] for f in by_dir[d]])) for d in by_dir}
        rc = {d: float(np.mean([f[k]["commanded_radius_m"] for f in by_dir[d]])) for d in by_dir}
        if commanded_radius_m is not None:
            rc = {"cw": commanded_radius_m, "ccw": commanded_radius_m}
        e_b, e_d = bcpt_factors(
            radius["cw"], radius["ccw"], rc["cw"], ran_with.wheelbase_m, rc["ccw"]
        )
        per_arc.append(
            {
                "commanded_radius_cw_m": rc["cw"],
                "commanded_radius_ccw_m": rc["ccw"],
                "radius_cw_m": radius["cw"],
                "radius_ccw_m": radius["ccw"],
                "E_b": float(e_b),
                "E_d": float(e_d),
            }
        )
    E_b = float(np.mean([a["E_b"] for a in per_arc]))
    E_d = float(np.mean([a["E_d"] for a in per_arc]))
    return CalibrationResult.from_factors(
        "bcpt",
        E_b,
        E_d,
        ran_with,
        runs_cw=len(by_dir["cw"]),
        runs_ccw=len(by_dir["ccw"]),
        arcs=per_arc,
        runs=[r.name for r in recordings],
    )
