"""Linear-in-parameters least squares (Antonelli, Chiaverini & Fusco 2005).

RECONSTRUCTED formulation (methods-notes.md section 5; the structure follows the paper's
abstract, the notation and the wheelbase combination are ours, verified to be exact on noise-free
data). With cumulative wheel angles phi_R, phi_L (rad) and the discrete mid-point odometry of
``core.odometry.dead_reckon``::

    dtheta_k = c_R2 dphi_R,k + c_L2 dphi_L,k,        c_R2 = D_R / (2 b),  c_L2 = -D_L / (2 b)
    ds_k     = c_R1 dphi_R,k + c_L1 dphi_L,k,        c_R1 = D_R / 4,      c_L1 = D_L / 4

Step 1 (heading), one row per run: theta_N = c_R2 phi_R,N + c_L2 phi_L,N, with theta_N the
UNWRAPPED total true rotation. Exact in discrete time; needs runs with independent rows (e.g. CW
and CCW turns, or a turn and a straight line).
Step 2 (position), two rows per run: rebuild theta_k from (c_R2, c_L2), mid-points
m_k = theta_k-1 + dtheta_k / 2, then
x_N = c_R1 sum dphi_R cos m_k + c_L1 sum dphi_L cos m_k (likewise y with sin).
Physical parameters: D_R = 4 c_R1, D_L = 4 c_L1, and b from both wheels combined (least squares
in 1/b): 1/b = (r_R c_R2 - r_L c_L2) / (r_R^2 + r_L^2), r = D/2.

Only the final poses of the runs are used, so it is fast and closed-form; it is the starting
point of the trajectory fit.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.odometry import midpoint_headings
from ..core.recording import Recording
from ..errors import CalibrationError
from .result import GeometryFit, LinearDetails, check_physical, stderr_dict

__all__ = ["fit_linear", "linear_coefficients", "coefficients_trials", "linear_geometry_trials"]


def _rank_ok(A: np.ndarray) -> np.ndarray:
    """Full column rank per matrix of ``A`` (..., n, p), with numpy.linalg.matrix_rank's
    tolerance (largest singular value x max(n, p) x machine epsilon)."""
    sv = np.linalg.svd(A, compute_uv=False)
    tol = sv[..., :1] * max(A.shape[-2:]) * np.finfo(float).eps
    return np.all(sv > tol, axis=-1)


def _lstsq(A: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray | None]:
    """Least squares per trial: ``A`` (M, n, p), ``y`` (M, n) -> solution (M, p) and covariance
    (M, p, p; residual-variance scaled; None without redundancy). Full column rank assumed
    (rank-deficient trials give non-finite values)."""
    q, r = np.linalg.qr(A)
    x = np.linalg.solve(r, np.einsum("mnp,mn->mp", q, y)[..., None])[..., 0]
    dof = A.shape[1] - A.shape[2]
    cov = None
    if dof > 0:
        s2 = np.sum((y - np.einsum("mnp,mp->mn", A, x)) ** 2, axis=1) / dof
        r_inv = np.linalg.inv(r)
        cov = s2[:, None, None] * (r_inv @ np.swapaxes(r_inv, 1, 2))
    return x, cov


def coefficients_trials(angles: Sequence[np.ndarray], finals: ArrayLike) -> tuple[Any, ...]:
    """The two steps of the module docstring for many trials at once.

    ``angles``: per run, its cumulative wheel angles (right, left; rad), shape (K_j, 2),
    starting at 0 and the same in every trial; ``finals``: the runs' true final poses (x_m, y_m,
    theta_rad, unwrapped; start frame) per trial, shape (M, runs, 3).

    Returns (c1, c2, cov1, cov2, ok1, ok2, cond): c1 = (c_R1, c_L1) and c2 = (c_R2, c_L2) of shape
    (M, 2), their covariances (M, 2, 2) (None without redundancy), whether step 1 (the same
    matrix in every trial) and step 2 (per trial, shape (M,)) have full rank, and cond(Phi^T
    Phi) of step 1. Where a step is rank-deficient its values are not meaningful.
    """
    finals = np.asarray(finals, dtype=float)
    trials = finals.shape[0]
    phi = np.array([[a[-1, 0], a[-1, 1]] for a in angles], dtype=float)
    ok1 = len(angles) >= 2 and bool(_rank_ok(phi[None])[0])
    cond = float(np.linalg.cond(phi.T @ phi))
    if not ok1:
        nan = np.full((trials, 2), np.nan)
        return nan, nan, None, None, False, np.zeros(trials, bool), cond
    c2, cov2 = _lstsq(np.broadcast_to(phi, (trials, *phi.shape)), finals[:, :, 2])
    rows = np.empty((trials, 2 * len(angles), 2))
    done: dict[int, np.ndarray] = {}  # runs that share their wheel angles share their rows
    for j, a in enumerate(angles):
        if id(a) not in done:
            dr = np.diff(a[:, 0])
            dl = np.diff(a[:, 1])
            dth = c2[:, 0:1] * dr + c2[:, 1:2] * dl
            _, m = midpoint_headings(dth)  # the mid heading of each increment
            cm, sm = np.cos(m), np.sin(m)
            done[id(a)] = np.stack([cm @ dr, cm @ dl, sm @ dr, sm @ dl], axis=1).reshape(-1, 2, 2)
        rows[:, 2 * j : 2 * j + 2] = done[id(a)]
    ok2 = _rank_ok(rows)
    safe = np.where(ok2[:, None, None], rows, np.eye(2 * len(angles), 2))
    c1, cov1 = _lstsq(safe, finals[:, :, :2].reshape(trials, -1))
    return c1, c2, cov1, cov2, ok1, ok2, cond


def _final_truth(r: Recording) -> np.ndarray:
    """The last ground-truth pose of ``r`` (x_m, y_m, theta_rad)."""
    if r.ground_truth is None:
        raise CalibrationError(f"{r.name}: linear needs ground truth")
    return r.ground_truth[-1]


def linear_coefficients(recordings: Sequence[Recording]) -> tuple[Any, ...]:
    """(c_R1, c_L1, c_R2, c_L2), their covariances (2x2 each or None) and cond(Phi^T Phi) of
    step 1. ``recordings`` need ground truth."""
    angles = [
        np.column_stack([r.wheel_angle_right_rad, r.wheel_angle_left_rad]) for r in recordings
    ]
    finals = np.array([[_final_truth(r) for r in recordings]], dtype=float)
    c1, c2, cov1, cov2, ok1, ok2, cond = coefficients_trials(angles, finals)
    if not ok1:
        raise CalibrationError(
            "linear: the heading step needs at least two runs with independent wheel rotations "
            "(e.g. CW and CCW turns, or a turn and a straight line)"
        )
    if not ok2[0]:
        raise CalibrationError(
            "linear: the position step needs runs that drive different wheel travels"
        )
    first = (lambda c: None) if cov1 is None else (lambda c: c[0])
    return c1[0], c2[0], first(cov1), None if cov2 is None else cov2[0], cond


def _physical(c: ArrayLike) -> np.ndarray:
    """(D_R, D_L, b) (m) of the coefficients ``c`` = (c_R1, c_L1, c_R2, c_L2), shape (..., 4)."""
    c = np.asarray(c, dtype=float)
    c_r1, c_l1, c_r2, c_l2 = c[..., 0], c[..., 1], c[..., 2], c[..., 3]
    d_r, d_l = 4 * c_r1, 4 * c_l1
    r_r, r_l = d_r / 2, d_l / 2
    inv_b = (r_r * c_r2 - r_l * c_l2) / (r_r**2 + r_l**2)
    return np.stack([d_r, d_l, 1.0 / inv_b], axis=-1)


def linear_geometry_trials(angles: Sequence[np.ndarray], finals: ArrayLike) -> np.ndarray:
    """D_R, D_L, b (m) per trial, shape (M, 3), from the runs of :func:`coefficients_trials`;
    NaN rows where a step is rank-deficient."""
    c1, c2, _, _, ok1, ok2, _ = coefficients_trials(angles, finals)
    with np.errstate(all="ignore"):
        out = _physical(np.concatenate([c1, c2], axis=1))
    out[~(ok1 & ok2)] = np.nan
    return out


def fit_linear(
    recordings: Sequence[Recording], nominal: WheelGeometry | None = None
) -> GeometryFit:
    """Antonelli-style two-step linear least squares (module docstring) from runs with truth."""
    c1, c2, cov1, cov2, cond = linear_coefficients(recordings)
    c = np.concatenate([c1, c2])
    values = _physical(c)
    warnings = check_physical(values, nominal, "linear")
    geometry = WheelGeometry(*values)
    cov = None
    if cov1 is not None and cov2 is not None:
        # delta method, the two steps treated as independent (step 2 uses step 1's estimate)
        C = np.zeros((4, 4))
        C[:2, :2], C[2:, 2:] = cov1, cov2
        J = np.zeros((3, 4))
        for j in range(4):
            h = 1e-7 * max(abs(c[j]), 1e-12)
            cp, cm = c.copy(), c.copy()
            cp[j] += h
            cm[j] -= h
            J[:, j] = (_physical(cp) - _physical(cm)) / (2 * h)
        cov = J @ C @ J.T
    per_run = []
    from ..core.odometry import dead_reckon

    for r in recordings:
        odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, geometry)
        e = _final_truth(r) - odo[-1]
        per_run.append(
            {
                "name": r.name,
                "final_position_residual_m": float(np.hypot(e[0], e[1])),
                "final_heading_residual_rad": float(e[2]),
            }
        )
    return GeometryFit(
        method="linear",
        geometry=geometry,
        stderr=stderr_dict(cov),
        covariance=cov,
        runs=[r.name for r in recordings],
        per_run=per_run,
        warnings=warnings,
        linear=LinearDetails(
            coefficients=(float(c[0]), float(c[1]), float(c[2]), float(c[3])),
            heading_step_condition_number=cond,
            wheelbase_from_right_m=float(values[0] / 2 / c[2]),
            wheelbase_from_left_m=float(-values[1] / 2 / c[3]),
        ),
    )
