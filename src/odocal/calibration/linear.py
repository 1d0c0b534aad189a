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

import numpy as np

from ..core.model import WheelGeometry
from ..errors import CalibrationError
from .result import GeometryFit, check_physical, stderr_dict

__all__ = ["fit_linear", "linear_coefficients"]


def _lstsq(A, y):
    """Solution and covariance (residual-variance scaled; None if no redundancy)."""
    x, *_ = np.linalg.lstsq(A, y, rcond=None)
    dof = len(y) - A.shape[1]
    cov = None
    if dof > 0:
        s2 = float(np.sum((y - A @ x) ** 2)) / dof
        cov = s2 * np.linalg.inv(A.T @ A)
    return x, cov


def linear_coefficients(recordings):
    """(c_R1, c_L1, c_R2, c_L2), their covariances (2x2 each or None) and cond(Phi^T Phi) of
    step 1. ``recordings`` need ground truth."""
    phi = np.array([[r.wheel_angle_right_rad[-1], r.wheel_angle_left_rad[-1]] for r in recordings])
    dtheta = np.array([r.ground_truth[-1, 2] for r in recordings])
    if len(recordings) < 2 or np.linalg.matrix_rank(phi) < 2:
        raise CalibrationError(
            "linear: the heading step needs at least two runs with independent wheel rotations "
            "(e.g. CW and CCW turns, or a turn and a straight line)"
        )
    cond = float(np.linalg.cond(phi.T @ phi))
    c2, cov2 = _lstsq(phi, dtheta)
    rows, rhs = [], []
    for r in recordings:
        dr = np.diff(r.wheel_angle_right_rad)
        dl = np.diff(r.wheel_angle_left_rad)
        dth = c2[0] * dr + c2[1] * dl
        theta = np.concatenate([[0.0], np.cumsum(dth)])
        m = theta[:-1] + 0.5 * dth
        cm, sm = np.cos(m), np.sin(m)
        rows += [[dr @ cm, dl @ cm], [dr @ sm, dl @ sm]]
        rhs += [r.ground_truth[-1, 0], r.ground_truth[-1, 1]]
    A = np.array(rows)
    if np.linalg.matrix_rank(A) < 2:
        raise CalibrationError(
            "linear: the position step needs runs that drive different wheel travels"
        )
    c1, cov1 = _lstsq(A, np.array(rhs))
    return c1, c2, cov1, cov2, cond


def _physical(c):
    c_r1, c_l1, c_r2, c_l2 = c
    d_r, d_l = 4 * c_r1, 4 * c_l1
    r_r, r_l = d_r / 2, d_l / 2
    inv_b = (r_r * c_r2 - r_l * c_l2) / (r_r**2 + r_l**2)
    return np.array([d_r, d_l, 1.0 / inv_b])


def fit_linear(recordings, nominal: WheelGeometry | None = None) -> GeometryFit:
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
        e = r.ground_truth[-1] - odo[-1]
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
        extras={
            "coefficients": {
                "c_R1": float(c[0]),
                "c_L1": float(c[1]),
                "c_R2": float(c[2]),
                "c_L2": float(c[3]),
            },
            "heading_step_condition_number": cond,
            "wheelbase_from_right_m": float(values[0] / 2 / c[2]),
            "wheelbase_from_left_m": float(-values[1] / 2 / c[3]),
        },
    )
