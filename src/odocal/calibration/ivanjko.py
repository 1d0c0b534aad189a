"""Ivanjko et al., "Simple off-line odometry calibration of differential drive mobile robots".

Test runs: straight lines, and 180-degree spot turns clockwise and counter-clockwise. Following
the reference implementation in Sousa et al.'s OptiOdom repository (methods-notes.md section 6),
the procedure alternates two least-squares fits until both corrections are below 0.1 %:

1. wheel diameters: factors (K_R, K_L) on (D_R, D_L) that minimise the sum of squared final
   POSITION errors of the straight runs (dead reckoning with the current estimate against the
   measured final position);
2. wheelbase: a factor K_b on b minimising the squared final HEADING errors of the spins, fitted
   to the CW and the CCW spins separately and averaged (a spin's odometric rotation is
   (phi_R D_R - phi_L D_L) / (2 b), so this fit is closed-form in 1/K_b).

Unlike UMBmark and the heading method, the straight runs give the absolute wheel scale (E_s) too.
Everything here is vectorised over a leading batch axis (Monte-Carlo trials).
"""

from __future__ import annotations

from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import WheelGeometry
from ..core.odometry import arc_step, body_increments, dead_reckon, wheel_travel
from ..core.recording import Recording
from ..errors import CalibrationError
from .result import CalibrationResult

__all__ = [
    "IvanjkoFit",
    "ivanjko_fit",
    "ivanjko_from_end_poses",
    "calibrate_ivanjko_recordings",
    "ivanjko_result",
    "DEFAULT_TOLERANCE",
]

DEFAULT_TOLERANCE = 1e-3  # 0.1 %, as in Ivanjko et al. / OptiOdom


@dataclass(frozen=True)
class IvanjkoFit:
    """Result of the alternating fit, batched over trials.

    Attributes
    ----------
    geometry : WheelGeometry
        Calibrated D_R, D_L, b (m); arrays of shape (M,) (or floats for M = 1 via ``take(0)``).
    iterations : ndarray of int, shape (M,)
        Alternations until both corrections fell below the tolerance.
    converged : ndarray of bool, shape (M,)
    """

    geometry: WheelGeometry
    iterations: np.ndarray
    converged: np.ndarray


StraightPredictor = Callable[[np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def _fit_diameter_factors(
    predict: StraightPredictor,
    target: np.ndarray,
    d_r: np.ndarray,
    d_l: np.ndarray,
    b: np.ndarray,
    iterations: int = 30,
) -> np.ndarray:
    """Gauss-Newton on (K_R, K_L); ``predict(D_R, D_L, b)`` -> (M, n, 2); target (M, n, 2)."""
    m = d_r.shape[0]
    k = np.ones((m, 2))
    h = 1e-7
    for _ in range(iterations):
        base = predict(d_r * k[:, 0], d_l * k[:, 1], b)
        res = (base - target).reshape(m, -1)
        jr = (predict(d_r * (k[:, 0] + h), d_l * k[:, 1], b) - base).reshape(m, -1) / h
        jl = (predict(d_r * k[:, 0], d_l * (k[:, 1] + h), b) - base).reshape(m, -1) / h
        jac = np.stack([jr, jl], axis=-1)  # (M, 2n, 2)
        jtj = np.einsum("mki,mkj->mij", jac, jac)
        jtr = np.einsum("mki,mk->mi", jac, res)
        # 2 x 2 solve per trial; a (near-)singular system (straight runs too short to tell the
        # diameters apart) gives NaN for that trial, which callers report as a failed calibration
        det = jtj[:, 0, 0] * jtj[:, 1, 1] - jtj[:, 0, 1] * jtj[:, 1, 0]
        singular = ~(np.abs(det) > 1e-12 * (jtj[:, 0, 0] + jtj[:, 1, 1]) ** 2)
        with np.errstate(invalid="ignore", divide="ignore"):
            det = np.where(singular, np.nan, det)
            step = np.stack(
                [
                    -(jtj[:, 1, 1] * jtr[:, 0] - jtj[:, 0, 1] * jtr[:, 1]) / det,
                    -(jtj[:, 0, 0] * jtr[:, 1] - jtj[:, 1, 0] * jtr[:, 0]) / det,
                ],
                axis=-1,
            )
        k = k + step
        if np.max(np.abs(step)) < 1e-13:
            break
    return k


def _fit_wheelbase_factor(
    phi_r: np.ndarray,
    phi_l: np.ndarray,
    theta: np.ndarray,
    d_r: np.ndarray,
    d_l: np.ndarray,
    b: np.ndarray,
) -> np.ndarray:
    """Closed-form LS factor K_b for spins: theta_i ~ a_i / K_b, a_i = (phi_R D_R - phi_L D_L)/(2b).

    phi_r, phi_l, theta: (M, n). Returns (M,).
    """
    a = (phi_r * d_r[:, None] - phi_l * d_l[:, None]) / (2.0 * b[:, None])
    u = np.sum(theta * a, axis=1) / np.sum(a * a, axis=1)
    return 1.0 / u


def ivanjko_fit(
    start: WheelGeometry,
    predict_straight: StraightPredictor,
    straight_xy: ArrayLike,
    spins_cw: Sequence[ArrayLike],
    spins_ccw: Sequence[ArrayLike],
    tolerance: float = DEFAULT_TOLERANCE,
    max_iterations: int = 50,
) -> IvanjkoFit:
    """The alternating Ivanjko fit (see module docstring), vectorised over M trials.

    Parameters
    ----------
    start : WheelGeometry
        Parameters the robot ran with (scalars or arrays of shape (M,)); the first estimate.
    predict_straight : callable
        ``predict_straight(D_R, D_L, b)`` with arrays of shape (M,) returns the dead-reckoned final
        positions of the straight runs, shape (M, n_straight, 2) (m).
    straight_xy : ndarray, shape (M, n_straight, 2)
        Measured final positions of the straight runs (m), start frame.
    spins_cw, spins_ccw : tuple of three ndarrays, each shape (M, n)
        (phi_R, phi_L, theta): total wheel rotations (rad) and measured total rotation (rad,
        unwrapped) of the CW and CCW spins.
    tolerance : float
        Stop when |K_R - 1|, |K_L - 1| and |K_b - 1| are all below this (default 0.1 %).
    """
    straight_xy = np.asarray(straight_xy, dtype=float)
    m = straight_xy.shape[0]
    d_r = np.broadcast_to(np.asarray(start.diameter_right_m, float), (m,)).copy()
    d_l = np.broadcast_to(np.asarray(start.diameter_left_m, float), (m,)).copy()
    b = np.broadcast_to(np.asarray(start.wheelbase_m, float), (m,)).copy()
    spins = [tuple(np.asarray(v, dtype=float) for v in s) for s in (spins_cw, spins_ccw)]
    active = np.ones(m, dtype=bool)
    iterations = np.zeros(m, dtype=int)
    for _ in range(max_iterations):
        idx = np.nonzero(active)[0]
        if len(idx) == 0:
            break

        def pred(
            dr: np.ndarray, dl: np.ndarray, bb: np.ndarray, idx: np.ndarray = idx
        ) -> np.ndarray:
            return _predict_subset(predict_straight, idx, m, dr, dl, bb)

        k = _fit_diameter_factors(pred, straight_xy[idx], d_r[idx], d_l[idx], b[idx])
        d_r[idx] *= k[:, 0]
        d_l[idx] *= k[:, 1]
        kb = np.mean(
            [
                _fit_wheelbase_factor(s[0][idx], s[1][idx], s[2][idx], d_r[idx], d_l[idx], b[idx])
                for s in spins
            ],
            axis=0,
        )
        b[idx] *= kb
        iterations[idx] += 1
        done = (np.abs(k - 1.0).max(axis=1) < tolerance) & (np.abs(kb - 1.0) < tolerance)
        active[idx[done]] = False
    if not (np.all(np.isfinite(d_r)) and np.all(np.isfinite(d_l)) and np.all(np.isfinite(b))):
        raise CalibrationError(
            "ivanjko: the fit diverged or is undefined (check the run labels and units, and that "
            "the straight runs are long enough to tell the wheel diameters apart)"
        )
    bad = ~((d_r > 0) & (d_l > 0) & (b > 0))
    if bad.any():
        i = int(np.argmax(bad))
        raise CalibrationError(
            f"ivanjko: non-physical result in {int(bad.sum())} of {bad.size} fit(s) "
            f"(D_R={d_r[i]:.6g} m, D_L={d_l[i]:.6g} m, b={b[i]:.6g} m): the errors are too large "
            "for the method, or the left and right wheels are swapped"
        )
    return IvanjkoFit(WheelGeometry(d_r, d_l, b), iterations, ~active)


def _predict_subset(
    predict: StraightPredictor,
    idx: np.ndarray,
    m: int,
    dr: np.ndarray,
    dl: np.ndarray,
    bb: np.ndarray,
) -> np.ndarray:
    """Call a full-batch predictor for the trials ``idx`` only (others get the first values)."""
    if len(idx) == m:
        return predict(dr, dl, bb)
    full = [np.full(m, v[0]) for v in (dr, dl, bb)]
    for f, v in zip(full, (dr, dl, bb), strict=True):
        f[idx] = v
    return predict(*full)[idx]


def ivanjko_result(fit: IvanjkoFit, ran_with: WheelGeometry, **inputs: Any) -> CalibrationResult:
    """A (single-trial) fit as a CalibrationResult: E_b, E_d relative to ``ran_with``; the
    corrected geometry is the fitted one (absolute scale included, reported as ``E_s``)."""
    g = fit.geometry.take(0) if np.ndim(fit.geometry.wheelbase_m) else fit.geometry
    g = WheelGeometry(float(g.diameter_right_m), float(g.diameter_left_m), float(g.wheelbase_m))
    E_b = float(g.wheelbase_m) / float(ran_with.wheelbase_m)
    E_d = float(g.diameter_ratio) / float(ran_with.diameter_ratio)
    E_s = float(g.mean_diameter_m) / float(ran_with.mean_diameter_m)
    if not (E_b > 0 and E_d > 0 and E_s > 0):
        raise CalibrationError(f"ivanjko: non-physical result {g}")
    return CalibrationResult(
        "ivanjko",
        E_b,
        E_d,
        ran_with,
        g,
        {
            "E_s": E_s,
            "iterations": int(np.atleast_1d(fit.iterations)[0]),
            "converged": bool(np.atleast_1d(fit.converged)[0]),
            **inputs,
        },
    )


# --- simulated runs: one constant-curvature segment per run --------------------------------


def ivanjko_from_end_poses(
    straight_final: ArrayLike,
    straight_length_m: float,
    spin_cw_final: ArrayLike,
    spin_ccw_final: ArrayLike,
    spin_angle_rad: float,
    ran_with: WheelGeometry,
    tolerance: float = DEFAULT_TOLERANCE,
) -> IvanjkoFit:
    """Ivanjko on simulated open-loop runs, from measured TRUE final poses (start frame).

    The robot drove each straight run of ``straight_length_m`` (m) and each spot turn of
    ``spin_angle_rad`` (rad, magnitude; CW runs turned by -spin_angle_rad) with the parameters
    ``ran_with`` (scalars or shape (M,)), so its wheels rotated by phi = 2 d / D_hat (straight) and
    +-psi b_hat / D_hat (spin) (docs/conventions.md). Dead reckoning a single constant-ratio
    segment is an exact arc, used as the predictor.

    Parameters
    ----------
    straight_final : ndarray, shape (M, n_straight, 3)
    spin_cw_final, spin_ccw_final : ndarray, shape (M, n_spin, 3)
        Measured true final poses (x_m, y_m, theta_rad); theta unwrapped.
    """
    sf = np.asarray(straight_final, dtype=float)
    m = sf.shape[0]
    d_r_hat = np.broadcast_to(np.asarray(ran_with.diameter_right_m, float), (m,))
    d_l_hat = np.broadcast_to(np.asarray(ran_with.diameter_left_m, float), (m,))
    b_hat = np.broadcast_to(np.asarray(ran_with.wheelbase_m, float), (m,))
    phi_r_s = (2.0 * straight_length_m / d_r_hat)[:, None]
    phi_l_s = (2.0 * straight_length_m / d_l_hat)[:, None]

    def predict(d_r: np.ndarray, d_l: np.ndarray, b: np.ndarray) -> np.ndarray:
        batch = WheelGeometry.unchecked(d_r[:, None], d_l[:, None], b[:, None])
        ds, dth = body_increments(*wheel_travel(phi_r_s, phi_l_s, batch), batch.wheelbase_m)
        pose = arc_step(np.zeros(3), ds, dth)  # one wheel-speed ratio: an exact arc
        return pose[..., :2] * np.ones((1, sf.shape[1], 1))

    def spins(final: ArrayLike, sign: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        f = np.asarray(final, dtype=float)
        psi = sign * spin_angle_rad
        phi_r = np.broadcast_to((psi * b_hat / d_r_hat)[:, None], f.shape[:2])
        phi_l = np.broadcast_to((-psi * b_hat / d_l_hat)[:, None], f.shape[:2])
        return phi_r, phi_l, f[..., 2]

    return ivanjko_fit(
        WheelGeometry(d_r_hat, d_l_hat, b_hat),
        predict,
        sf[..., :2],
        spins(spin_cw_final, -1.0),
        spins(spin_ccw_final, +1.0),
        tolerance,
    )


# --- recorded runs ---------------------------------------------------------------------------


def _truth(r: Recording) -> np.ndarray:
    if r.ground_truth is None:
        raise CalibrationError(f"{r.name}: ivanjko needs ground truth")
    return r.ground_truth


def calibrate_ivanjko_recordings(
    recordings: Iterable[Recording],
    tolerance: float = DEFAULT_TOLERANCE,
    start: WheelGeometry | None = None,
) -> CalibrationResult:
    """Ivanjko on recorded runs with ground truth, labelled 'straight', 'spin-cw', 'spin-ccw'
    (``odocal.io.optiodom.load_optiodom_dataset`` labels the OptiOdom ``ivanjko/`` runs so).

    The first estimate is ``start`` (default: the parameters the first run ran with). Dead
    reckoning uses the recorded wheel rotations (``odocal.core.odometry.dead_reckon``).
    """
    recordings = list(recordings)
    groups: dict[str, list] = {"straight": [], "spin-cw": [], "spin-ccw": []}
    for r in recordings:
        if r.ground_truth is None:
            raise CalibrationError(f"{r.name}: ivanjko needs ground truth")
        if r.label in groups:
            groups[r.label].append(r)
    for label, runs in groups.items():
        if not runs:
            raise CalibrationError(
                f"ivanjko needs straight runs and CW and CCW spins; there are no '{label}' runs"
            )
    start = start or recordings[0].ran_with
    if start is None:
        raise CalibrationError("ivanjko: no starting parameters (ran_with unknown)")
    straight = groups["straight"]
    target = np.array([[_truth(r)[-1, :2] for r in straight]])

    def predict(d_r: np.ndarray, d_l: np.ndarray, b: np.ndarray) -> np.ndarray:
        g = WheelGeometry(float(d_r[0]), float(d_l[0]), float(b[0]))
        return np.array(
            [
                [
                    dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, g)[-1, :2]
                    for r in straight
                ]
            ]
        )

    def spins(runs: list[Recording]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        return (
            np.array([[r.wheel_angle_right_rad[-1] - r.wheel_angle_right_rad[0] for r in runs]]),
            np.array([[r.wheel_angle_left_rad[-1] - r.wheel_angle_left_rad[0] for r in runs]]),
            np.array([[_truth(r)[-1, 2] - _truth(r)[0, 2] for r in runs]]),
        )

    fit = ivanjko_fit(
        start, predict, target, spins(groups["spin-cw"]), spins(groups["spin-ccw"]), tolerance
    )
    straight_len = float(np.mean([np.hypot(*_truth(r)[-1, :2]) for r in straight]))
    return ivanjko_result(
        fit,
        start,
        runs_straight=len(straight),
        runs_spin_cw=len(groups["spin-cw"]),
        runs_spin_ccw=len(groups["spin-ccw"]),
        straight_length_m=straight_len,
        spin_deg=float(np.degrees(np.mean([abs(_truth(r)[-1, 2]) for r in groups["spin-ccw"]]))),
        tolerance=tolerance,
    )
