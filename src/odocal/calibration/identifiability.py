"""Is this log enough? What the recorded motion lets a trajectory fit see (docs/check.md).

From the wheel-angle series of recorded runs (ground truth optional) and a geometry to linearise
at, :func:`check_recordings` computes for the fitted parameters D_R, D_L, b (m), and optionally
the mounting (x_m, y_m, yaw_rad) of the ground-truth frame on the robot:

- the Fisher information ``F = sum_runs J^T Sigma^-1 J`` of the residual model of
  :func:`odocal.calibration.trajectory.fit_trajectory` (the same residual kind, samples, segments
  and run weights), with ``Sigma`` the covariance of those residuals under a STATED noise model
  (:class:`NoiseModel`): the wheel-travel noise k (variance k |ds| per increment, k in METRES,
  docs/conventions.md) and an optional extra heading noise per radian turned, propagated along
  the recorded motion, plus the ground-truth instrument's sigma_xy, sigma_theta on every pose
  used (the start pose included: it defines the start frame); ``residual_scale='empirical'``
  scales that noise to the residuals of the recordings' own ground truth;
- the predicted covariance of the fit AS IMPLEMENTED (its weights are not ``Sigma^-1``: heading
  rows times ``heading_weight_m``, run blocks by travel), the sandwich
  ``H^-1 (sum J^T A Sigma A J) H^-1`` with ``H = sum J^T A J``; its square-rooted diagonal is the
  predicted standard error; ``F^-1`` is the best any estimator of these residuals could do;
- the condition number of ``F`` in the RELATIVE parametrisation (each length as a fraction of its
  value, the mounting offsets in wheelbases, the mounting yaw in rad) and its weakest direction in
  words;
- the degenerate motions present, from the wheel motion alone (:class:`CheckThresholds`), and
  what to drive to fix them.

The wheel-noise covariance is first order along the noise-free dead-reckoned trajectory at
``geometry`` (as ``odocal.core.covariance`` does for a track); every recorded sample step is one
increment. Under this model segment residuals of different segments are independent in their
wheel part; pose residuals of one run are strongly correlated (a random walk), which the fit's
own ``s^2 (J^T J)^-1`` ignores and this prediction does not. How well the prediction matches
real data depends on how well the stated noise describes the robot (docs/check.md).
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from numpy.typing import ArrayLike

from ..core.jsonable import jsonable
from ..core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from ..core.odometry import body_increments, dead_reckon, wheel_jacobian, wheel_travel
from ..core.recording import Recording
from ..core.transforms import se2_conjugate
from ..errors import CalibrationError
from .fit_methods import Residual, RunWeight
from .trajectory import RESIDUALS, RUN_WEIGHTS, RunResiduals, relative_poses

# The fit's residual layout (sample indices, segment marks, run weights), its relative-pose
# helper and its unchecked geometry are private to trajectory.py; they are imported, not copied,
# so that this check always describes exactly the residuals the fit uses (docs/check.md, "Open
# points": they should become public).
from .turning import BAND_EDGES

__all__ = [
    "with_prediction",
    "NoiseModel",
    "CheckThresholds",
    "MotionSummary",
    "Degeneracy",
    "LogCheck",
    "check_recordings",
    "summarize_motion",
    "GEOMETRY_PARAMETERS",
    "MOUNT_PARAMETERS",
    "describe_direction",
    "LogInformation",
    "log_information",
    "judge",
    "DEGENERATE_MOTIONS",
    "degenerate_motions",
]

# Residual blocks of one run at most (its dense covariance is 3 x 3 per block pair).
MAX_BLOCKS_PER_RUN = 2000

# Above this condition number the Fisher information is treated as singular (no inverse).
_SINGULAR = 1e12

GEOMETRY_PARAMETERS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
MOUNT_PARAMETERS = ("mount_x_m", "mount_y_m", "mount_yaw_rad")


@dataclass(frozen=True)
class NoiseModel:
    """The stated noise of the residuals.

    Attributes
    ----------
    wheel : NonSystematicError
        Wheel-travel noise, variance k |ds| per increment, k_r_m and k_l_m in METRES. Default
        1e-6 m per wheel (the order of the paper's robots, odocal.presets).
    measurement : MeasurementNoise
        Ground-truth instrument noise on every measured pose: sigma_xy_m (m, per coordinate),
        sigma_theta_rad. Default 1 mm and 0.2 deg (a motion-capture rigid body).
    turn_rad : float
        Extra heading noise while turning: variance ``turn_rad * |dtheta|`` per increment (rad^2
        per rad turned, so in rad), independent of the wheels. Wheel noise alone ties the heading
        noise of a turn to that of a straight line of the same wheel travel; real spot turns
        scrub and slip more (docs/check.md). Default 0.
    """

    wheel: NonSystematicError = field(default_factory=lambda: NonSystematicError(1e-6, 1e-6))
    measurement: MeasurementNoise = field(
        default_factory=lambda: MeasurementNoise(1e-3, math.radians(0.2))
    )
    turn_rad: float = 0.0

    def __post_init__(self) -> None:
        if not (self.turn_rad >= 0 and math.isfinite(self.turn_rad)):
            raise CalibrationError(f"turn_rad must be finite and >= 0, got {self.turn_rad!r}")

    def as_dict(self) -> dict:
        """JSON-ready (k in m, the tracker noise in m and degrees)."""
        return {
            "k_r_m": float(self.wheel.k_r_m),
            "k_l_m": float(self.wheel.k_l_m),
            "turn_rad": float(self.turn_rad),
            "sigma_xy_m": float(self.measurement.sigma_xy_m),
            "sigma_theta_deg": math.degrees(self.measurement.sigma_theta_rad),
        }


@dataclass(frozen=True)
class CheckThresholds:
    """Thresholds of the motion classes and degeneracy flags (docs/check.md).

    Curvature bands are judged on windows of ``window_m`` of mean absolute wheel travel (so that
    encoder quantisation does not make a straight line wiggle); a window is STRAIGHT when its
    turning radius is at least ``straight_radius_b`` wheelbases, a SPOT turn when at most
    ``spot_radius_b`` wheelbases, an ARC otherwise. The edges are those of the bands of motion
    of ``fit`` (:mod:`odocal.calibration.turning`: spot up to 0.625 b, straight beyond 12.5 b),
    so that both call the same driving the same thing. Shares are of wheel travel.

    ``max_condition``: directions whose Fisher information is below 1/max_condition of the best
    determined one are reported as not determined (a factor 100 in relative standard error).
    ``max_relative_stderr``: a predicted standard error of D_R, D_L or b above this fraction of
    its value is reported as imprecise (0.5 % of b turns a full turn 1.8 deg wrong).
    """

    window_m: float = 0.05
    straight_radius_b: float = 0.5 / BAND_EDGES[-2]  # 12.5: the straight band's edge
    spot_radius_b: float = 0.5 / BAND_EDGES[0]  # 0.625: the spot band's edge
    only_share: float = 0.95
    min_travel_m: float = 2.0
    min_rotation_rad: float = 2.0 * math.pi
    min_turn_each_way_rad: float = 0.5 * math.pi
    min_turn_balance: float = 0.25
    constant_ratio: float = 0.99
    max_condition: float = 1e4
    max_relative_stderr: float = 5e-3


@dataclass(frozen=True)
class MotionSummary:
    """What one recording (or a whole log) drove, from its wheel angles alone.

    travel_m : path length of the axle centre (m). wheel_travel_m : mean absolute wheel travel
    (m; spot turns count). rotation_rad : total absolute heading change (rad); rotation_left_rad
    and rotation_right_rad: CCW and CW turning in spot and arc windows. share_* : share of wheel
    travel in straight / spot / arc windows (0..1). turning : 'both', 'left', 'right' or 'none'
    (a direction counts from ``min_turn_each_way_rad`` and from ``min_turn_balance`` times the
    other direction's turning). ratio_concentration : 1 when the wheels
    keep one speed ratio all the time (a line, a spot turn or a circle: only two of D_R, D_L, b
    visible), lower with more different ratios (0 for equal straight and spot-turn travel).
    """

    name: str
    label: str | None
    travel_m: float
    wheel_travel_m: float
    rotation_rad: float
    rotation_left_rad: float
    rotation_right_rad: float
    share_straight: float
    share_spot: float
    share_arc: float
    turning: str
    ratio_concentration: float

    def as_dict(self) -> dict:
        """JSON-ready."""
        d = {k: jsonable(v) for k, v in self.__dict__.items()}
        for k in ("rotation_rad", "rotation_left_rad", "rotation_right_rad"):
            d[k.replace("_rad", "_deg")] = jsonable(math.degrees(getattr(self, k)))
            del d[k]
        return d


@dataclass(frozen=True)
class Degeneracy:
    """A motion (or conditioning) problem of the log.

    code : short id ('straight-only', ...). severity : 'blind' (the model cannot see a parameter
    combination from this motion) or 'weak' (visible, but poorly or not robustly). cannot_see :
    the combination concerned, in words. message : one line for people.
    """

    code: str
    severity: str
    cannot_see: str
    message: str

    def as_dict(self) -> dict:
        """JSON-ready."""
        return dict(self.__dict__)


@dataclass(frozen=True)
class LogCheck:
    """Result of :func:`check_recordings`.

    Attributes
    ----------
    parameters : tuple of str
        Parameter names, GEOMETRY_PARAMETERS (+ MOUNT_PARAMETERS with ``mounting=True``).
    values : ndarray, shape (n,)
        The linearisation point (m, m, m [, m, m, rad]).
    fisher_information : ndarray, shape (n, n)
        J^T Sigma^-1 J in SI units (1/m^2 ...), of the stated noise times ``residual_scale^2``.
    covariance : ndarray, shape (n, n)
        Predicted covariance of the fit with its own weights (the sandwich); SI units.
    stderr, stderr_best : dict
        Predicted standard error per parameter (m or rad) of the fit as implemented, and the
        Cramer-Rao bound sqrt(diag F^-1); inf where not identifiable.
    condition_number : float
        cond(F) in the relative parametrisation (module docstring).
    weakest_direction : str
        The least-determined parameter combination, in words.
    blind_directions : tuple of str
        The parameter combinations (one per dimension) whose information is below
        1 / ``max_condition`` of the best determined one: what this log cannot see.
    weakest_vector : tuple of float
        Its unit vector in the relative parametrisation (ln D_R, ln D_L, ln b [, x/b, y/b, yaw]).
    weakest_relative_stderr : float
        Predicted (Cramer-Rao) standard error along that direction, as a fraction (0.001 = 0.1 %).
    degeneracies : tuple of Degeneracy
    suggestions : tuple of str
    motion : MotionSummary
        The whole log.
    per_recording : tuple of MotionSummary
    noise : NoiseModel
        The stated noise model.
    residual_scale : float
        Factor applied to the stated noise's standard deviations (1 for 'stated'; the residuals'
        rms in units of the stated noise for 'empirical').
    settings : dict
        Residual kind, segment length, heading weight, run weight, samples per run, scale source.
    """

    parameters: tuple
    values: np.ndarray
    fisher_information: np.ndarray
    covariance: np.ndarray
    stderr: dict
    stderr_best: dict
    condition_number: float
    weakest_direction: str
    blind_directions: tuple
    weakest_vector: tuple
    weakest_relative_stderr: float
    degeneracies: tuple
    suggestions: tuple
    motion: MotionSummary
    per_recording: tuple
    noise: NoiseModel
    residual_scale: float
    settings: dict

    @property
    def ok(self) -> bool:
        """True when no 'blind' degeneracy was found."""
        return not any(d.severity == "blind" for d in self.degeneracies)

    def flagged(self, code: str) -> bool:
        """True when the degeneracy ``code`` was found."""
        return any(d.code == code for d in self.degeneracies)

    def as_dict(self) -> dict:
        """JSON-safe dictionary (non-finite numbers as None)."""
        return {
            "ok": self.ok,
            "parameters": list(self.parameters),
            "values": jsonable(self.values),
            "stderr": {k: jsonable(v) for k, v in self.stderr.items()},
            "stderr_best": {k: jsonable(v) for k, v in self.stderr_best.items()},
            "covariance": jsonable(self.covariance),
            "fisher_information": jsonable(self.fisher_information),
            "condition_number": jsonable(self.condition_number),
            "weakest_direction": self.weakest_direction,
            "blind_directions": list(self.blind_directions),
            "weakest_vector": jsonable(self.weakest_vector),
            "weakest_relative_stderr": jsonable(self.weakest_relative_stderr),
            "degeneracies": [d.as_dict() for d in self.degeneracies],
            "degenerate_motions": degenerate_motions(self),
            "suggestions": list(self.suggestions),
            "motion": self.motion.as_dict(),
            "per_recording": [m.as_dict() for m in self.per_recording],
            "noise": self.noise.as_dict(),
            "residual_scale": jsonable(self.residual_scale),
            "settings": {k: jsonable(v) for k, v in self.settings.items()},
        }


# --------------------------------------------------------------------------------------------
# Motion summary (wheel angles only)


def _windows(
    ds_r: np.ndarray, ds_l: np.ndarray, b: float, window_m: float
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Net wheel travel and absolute wheel travel per window of ``window_m`` travel."""
    w = 0.5 * (np.abs(ds_r) + np.abs(ds_l))
    c = np.concatenate([[0.0], np.cumsum(w)])
    if c[-1] <= 0:
        return np.zeros(0), np.zeros(0), np.zeros(0)
    marks = np.unique(np.append(np.searchsorted(c, np.arange(0.0, c[-1], window_m)), len(c) - 1))
    cr = np.concatenate([[0.0], np.cumsum(ds_r)])
    cl = np.concatenate([[0.0], np.cumsum(ds_l)])
    s_r, s_l, travel = np.diff(cr[marks]), np.diff(cl[marks]), np.diff(c[marks])
    keep = travel > 0
    return s_r[keep], s_l[keep], travel[keep]


def _summary(
    name: str,
    label: str | None,
    s_r: np.ndarray,
    s_l: np.ndarray,
    travel: np.ndarray,
    path_m: float,
    b: float,
    th: CheckThresholds,
) -> MotionSummary:
    a, dth = body_increments(s_r, s_l, b)  # centre travel and heading change per window
    straight = np.abs(a) >= th.straight_radius_b * b * np.abs(dth)
    spot = np.abs(a) <= th.spot_radius_b * b * np.abs(dth)
    arc = ~straight & ~spot
    total = float(travel.sum())
    turning_windows = ~straight
    left = float(dth[turning_windows & (dth > 0)].sum())
    right = float(-dth[turning_windows & (dth < 0)].sum())
    # a direction counts from min_turn_each_way_rad and from min_turn_balance of the other one
    # (the wiggles of a controller on straight legs turn both ways a little)
    need = {
        "left": max(th.min_turn_each_way_rad, th.min_turn_balance * right),
        "right": max(th.min_turn_each_way_rad, th.min_turn_balance * left),
    }
    directions = [n for n, v in (("left", left), ("right", right)) if v >= need[n]]
    turning = "both" if len(directions) == 2 else (directions[0] if directions else "none")
    if total > 0:
        # axis of the wheel-travel vector (s_R, s_L), taken modulo pi (forward and backward are the
        # same ratio): doubled-angle mean resultant length, weighted by travel
        ang = 2.0 * np.arctan2(s_l, s_r)
        conc = float(abs(np.sum(travel * np.exp(1j * ang))) / total)
        shares = [float(travel[m].sum() / total) for m in (straight, spot, arc)]
    else:
        conc = float("nan")
        shares = [float("nan")] * 3
    return MotionSummary(
        name=name,
        label=label,
        travel_m=float(path_m),
        wheel_travel_m=total,
        rotation_rad=float(np.abs(dth).sum()),
        rotation_left_rad=left,
        rotation_right_rad=right,
        share_straight=shares[0],
        share_spot=shares[1],
        share_arc=shares[2],
        turning=turning,
        ratio_concentration=conc,
    )


def summarize_motion(
    recordings: Iterable[Recording],
    geometry: WheelGeometry,
    thresholds: CheckThresholds | None = None,
) -> tuple[MotionSummary, tuple[MotionSummary, ...]]:
    """(whole log, per recording) motion summaries from the wheel angles (no ground truth)."""
    th = thresholds or CheckThresholds()
    b = float(geometry.wheelbase_m)
    per, parts = [], []
    for rec in recordings:
        ds_r, ds_l = wheel_travel(
            np.diff(rec.wheel_angle_right_rad), np.diff(rec.wheel_angle_left_rad), geometry
        )
        win = _windows(ds_r, ds_l, b, th.window_m)
        path = float(np.abs(0.5 * (ds_r + ds_l)).sum())
        per.append(_summary(rec.name, rec.label, win[0], win[1], win[2], path, b, th))
        parts.append((win, path))
    s_r = np.concatenate([w[0] for w, _ in parts])
    s_l = np.concatenate([w[1] for w, _ in parts])
    tr = np.concatenate([w[2] for w, _ in parts])
    whole = _summary("all", None, s_r, s_l, tr, sum(p for _, p in parts), b, th)
    return whole, tuple(per)


# --------------------------------------------------------------------------------------------
# Residual model: Jacobian and noise covariance per run


def _mounted(poses: np.ndarray, mount: np.ndarray) -> np.ndarray:
    """Poses of a frame mounted at (x, y, yaw) on the robot, in that frame's start frame."""
    if mount[0] == 0 and mount[1] == 0 and mount[2] == 0:
        return poses
    return se2_conjugate(poses, np.asarray(mount, dtype=float))


def _blocks(run: RunResiduals, kind: str) -> tuple[np.ndarray, np.ndarray]:
    """(start, end) sample index of every residual block of ``run``."""
    if kind == "pose":
        return np.zeros(len(run.idx), dtype=int), np.asarray(run.idx)
    return np.asarray(run.i0), np.asarray(run.i1)


def _predict(run: RunResiduals, kind: str, params: np.ndarray) -> np.ndarray:
    """Residual rows (x, y, theta per block, unweighted) predicted by ``params``."""
    odo = dead_reckon(run.phi_r, run.phi_l, WheelGeometry.unchecked(*params[:3]))
    if len(params) > 3:
        odo = _mounted(odo, params[3:])
    if kind == "pose":
        return odo[run.idx].ravel()
    return relative_poses(odo, run.i0, run.i1).ravel()


def _jacobian(run: RunResiduals, kind: str, params: np.ndarray, steps: np.ndarray) -> np.ndarray:
    """d(predicted rows)/d(params) by central differences, shape (3 blocks, n)."""
    cols = []
    for i, h in enumerate(steps):
        up, dn = np.array(params, float), np.array(params, float)
        up[i] += h
        dn[i] -= h
        cols.append((_predict(run, kind, up) - _predict(run, kind, dn)) / (2.0 * h))
    return np.column_stack(cols)


def _cumulative_increment_covariance(
    run: RunResiduals, geometry: WheelGeometry, noise: NoiseModel, pose: np.ndarray, a: np.ndarray
) -> np.ndarray | None:
    """Qc[t] = sum over the increments before sample t of H_i diag(q_i) H_i^T, shape (K, 4, 4),
    or None without wheel or turn noise (see _noise_covariance)."""
    k_r, k_l, k_t = noise.wheel.k_r_m, noise.wheel.k_l_m, noise.turn_rad
    if not (k_r > 0 or k_l > 0 or k_t > 0):
        return None
    b = float(geometry.wheelbase_m)
    ds_r, ds_l = wheel_travel(np.diff(run.phi_r), np.diff(run.phi_l), geometry)
    ds, dth = body_increments(ds_r, ds_l, b)
    mid = pose[:-1, 2] + 0.5 * dth  # pose: the midpoint poses of these increments
    c, s = np.cos(mid), np.sin(mid)
    # columns: right wheel, left wheel, extra heading noise of the increment
    B = np.empty((len(ds), 3, 3))
    B[:, :, :2] = wheel_jacobian(ds, c, s, b)
    B[:, 0, 2], B[:, 1, 2], B[:, 2, 2] = -0.5 * ds * s, 0.5 * ds * c, 1.0
    H = np.empty((len(ds), 4, 3))
    H[:, :3, :] = B - a[1:, :, None] * B[:, 2:3, :]
    H[:, 3, :] = B[:, 2, :]
    q = np.stack([k_r * np.abs(ds_r), k_l * np.abs(ds_l), k_t * np.abs(dth)], axis=-1)
    Hq = H * np.sqrt(q)[:, None, :]
    Q = Hq @ np.swapaxes(Hq, 1, 2)
    return np.concatenate([np.zeros((1, 4, 4)), np.cumsum(Q, axis=0)])


def _pose_forms(
    run: RunResiduals, geometry: WheelGeometry, noise: NoiseModel, X: np.ndarray, V: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """Pose residuals without dense matrices: (X^T Sigma^-1 X, V^T Sigma V) for X, V of shape
    (3 B, k). The rows are a linear Gaussian state-space model: block j is C_j Z_j + v_j with
    C_j = [I | a_j], Z_j = Z_j-1 + w_j (the wheel and turn noise of the increments up to sample
    j, plus the start pose's instrument noise in Z_0) and v_j the sample's instrument noise, so
    Sigma^-1 forms come from the innovations of a Kalman filter and Sigma forms from cumulative
    sums, in O(B) (the same numbers as the dense covariance, tested)."""
    pose = dead_reckon(run.phi_r, run.phi_l, geometry)
    s1 = np.asarray(run.idx)
    nb = len(s1)
    a = np.column_stack([-pose[:, 1], pose[:, 0], np.zeros(len(pose))])
    C = np.concatenate([np.broadcast_to(np.eye(3), (nb, 3, 3)), a[s1][:, :, None]], axis=2)
    Qc = _cumulative_increment_covariance(run, geometry, noise, pose, a)
    W = np.zeros((nb, 4, 4)) if Qc is None else np.diff(Qc[np.r_[0, s1]], axis=0)
    m = noise.measurement
    d = np.array([m.sigma_xy_m**2, m.sigma_xy_m**2, m.sigma_theta_rad**2])
    D = np.diag(d)
    G = np.zeros((4, 4))  # the start pose's noise (d0, dtheta0) enters every block as C_j g
    G[:3, :3] = D
    G[:3, 3] = G[3, :3] = D[:, 2]
    G[3, 3] = d[2]
    Xb = np.asarray(X, dtype=float).reshape(nb, 3, -1)
    Vb = np.asarray(V, dtype=float).reshape(nb, 3, -1)
    # V^T Sigma V = U_1^T G U_1 + sum_q U_q^T W_q U_q + sum_j V_j^T D V_j,
    # U_q = sum_{j >= q} C_j^T V_j
    U = np.cumsum((np.swapaxes(C, 1, 2) @ Vb)[::-1], axis=0)[::-1]
    vsv = U[0].T @ G @ U[0] + np.sum(np.swapaxes(U, 1, 2) @ W @ U, axis=0)
    vsv += np.sum(np.swapaxes(Vb, 1, 2) @ (Vb * d[None, :, None]), axis=0)
    P = G.copy()
    xh = np.zeros((4, Xb.shape[2]))
    acc = np.zeros((Xb.shape[2], Xb.shape[2]))
    for j in range(nb):
        P = P + W[j]
        Cj = C[j]
        PCt = P @ Cj.T
        S = Cj @ PCt + D
        Si = np.linalg.pinv(S, hermitian=True, rcond=1e-12) if d.min() <= 0 else np.linalg.inv(S)
        nu = Xb[j] - Cj @ xh
        acc += nu.T @ Si @ nu
        K = PCt @ Si
        xh = xh + K @ nu
        P = P - K @ PCt.T
        P = 0.5 * (P + P.T)
    return 0.5 * (acc + acc.T), 0.5 * (vsv + vsv.T)


def _noise_covariance(
    run: RunResiduals,
    kind: str,
    geometry: WheelGeometry,
    noise: NoiseModel,
    max_blocks: int = MAX_BLOCKS_PER_RUN,
) -> np.ndarray:
    """Covariance of the residual rows of ``run`` under ``noise``, shape (3 B, 3 B).

    Wheel part: the error of the pose at the end of block (s0, s1] from the increments inside
    it is [I | a_s1] z with z = sum_i H_i n_i, a = (-y, x, 0) and H_i = [B_i - a_i e_th^T B_i;
    e_th^T B_i], B_i the midpoint update's wheel Jacobian (covariance.py); two blocks share the
    increments in the overlap of their intervals. Instrument part: each block is the relative
    pose between the measured poses at s0 and s1, so it is linear in their noise.
    """
    pose = dead_reckon(run.phi_r, run.phi_l, geometry)
    s0, s1 = _blocks(run, kind)
    nb = len(s0)
    if nb > max_blocks:
        raise CalibrationError(
            f"check: {run.name} has {nb} residual blocks (at most {max_blocks}: the "
            "noise covariance is dense); use a longer segment_m or fewer samples_per_run"
        )
    # block rotation into the frame of its start pose (identity for pose residuals)
    rot = np.zeros((nb, 3, 3))
    c0, sn0 = np.cos(pose[s0, 2]), np.sin(pose[s0, 2])
    rot[:, 0, 0], rot[:, 0, 1], rot[:, 1, 0], rot[:, 1, 1] = c0, sn0, -sn0, c0
    rot[:, 2, 2] = 1.0
    a = np.column_stack([-pose[:, 1], pose[:, 0], np.zeros(len(pose))])  # a after each sample
    cov = np.zeros((3 * nb, 3 * nb))

    Qc = _cumulative_increment_covariance(run, geometry, noise, pose, a)
    if Qc is not None:
        lo = np.maximum.outer(s0, s0)
        hi = np.minimum.outer(s1, s1)
        P = np.where((hi > lo)[..., None, None], Qc[hi] - Qc[np.minimum(lo, hi)], 0.0)
        E = np.concatenate([np.broadcast_to(np.eye(3), (nb, 3, 3)), a[s1][:, :, None]], axis=2)
        RE = rot @ E  # (nb, 3, 4)
        blocks = RE[:, None] @ P @ np.swapaxes(RE, 1, 2)[None, :]  # (nb, nb, 3, 3)
        cov += blocks.transpose(0, 2, 1, 3).reshape(3 * nb, 3 * nb)

    m = noise.measurement
    if not m.is_zero:
        # block a = rot_a (d_s1 - T_a d_s0), T_a = [I | a_s1 - a_s0]: two 3x3 blocks per row of
        # the map from the instrument noise d at every sample; blocks meet where samples agree
        d = np.array([m.sigma_xy_m**2, m.sigma_xy_m**2, m.sigma_theta_rad**2])
        T = np.broadcast_to(np.eye(3), (nb, 3, 3)).copy()
        T[:, :, 2] += a[s1] - a[s0]
        maps = ((s1, rot, 1.0), (s0, rot @ T, -1.0))
        total = np.zeros((nb, nb, 3, 3))
        for ia, Ma, sa in maps:
            for ib, Mb, sb in maps:
                hit = np.equal.outer(ia, ib)
                if hit.any():
                    r, c = np.nonzero(hit)
                    total[r, c] += sa * sb * (Ma[r] * d) @ np.swapaxes(Mb[c], 1, 2)
        cov += total.transpose(0, 2, 1, 3).reshape(3 * nb, 3 * nb)
    return 0.5 * (cov + cov.T)


def _solve_psd(S: np.ndarray, X: np.ndarray) -> np.ndarray:
    """S^-1 X for a covariance S (pseudo-inverse when singular, e.g. no noise at all)."""
    from scipy.linalg import cho_factor, cho_solve  # here: scipy.linalg takes long to import

    try:
        return cho_solve(cho_factor(S, lower=True, check_finite=False), X, check_finite=False)
    except np.linalg.LinAlgError:
        return np.linalg.pinv(S, hermitian=True, rcond=1e-12) @ X


# --------------------------------------------------------------------------------------------
# Directions in words


_BASIS_NAMES = (
    "the common wheel scale",
    "the diameter ratio D_R/D_L",
    "the wheelbase b",
    "the sensor's x offset",
    "the sensor's y offset",
    "the sensor's yaw offset",
)


def _basis(n: int) -> np.ndarray:
    """Orthonormal basis of the relative parametrisation, rows as _BASIS_NAMES: wheel scale
    (ln D_R + ln D_L)/sqrt 2, ratio (ln D_R - ln D_L)/sqrt 2, ln b, then the mounting axes."""
    B = np.eye(n)
    B[0, :2] = B[1, :2] = np.sqrt(0.5)
    B[1, 1] = -np.sqrt(0.5)
    return B


def _named_directions(n: int) -> list[tuple[str, np.ndarray]]:
    """Directions with their own name, unit vectors of the relative parametrisation."""

    def v(*x: float) -> np.ndarray:
        u = np.zeros(n)
        u[: len(x)] = x
        return u / np.linalg.norm(u)

    return [
        ("the common scale of D_R, D_L and b together", v(1, 1, 1)),
        ("the right wheel diameter D_R alone", v(1, 0, 0)),
        ("the left wheel diameter D_L alone", v(0, 1, 0)),
    ] + [(name, row) for name, row in zip(_BASIS_NAMES, _basis(n), strict=False)]


def describe_direction(vec: ArrayLike) -> str:
    """A unit vector of the relative parametrisation (ln D_R, ln D_L, ln b [, x/b, y/b, yaw]) in
    words. A change of the parameters along it is what the data cannot see (or see worst).

    A named direction when one matches (|cos| >= 0.95); else, in the orthonormal basis (wheel
    scale, diameter ratio, b [, sensor x, y, yaw]), the two largest components when they carry at
    least 90 % of it: "A together with B" (same sign: both growing together is invisible) or
    "A traded against B" (opposite signs); else all components.
    """
    vec = np.asarray(vec, dtype=float)
    n = len(vec)
    for name, u in _named_directions(n):
        if abs(float(u @ vec)) >= 0.95:
            return name
    c = _basis(n) @ vec
    order = np.argsort(-np.abs(c))
    i, j = order[0], order[1]
    if c[i] ** 2 + c[j] ** 2 >= 0.9:
        how = "together with" if c[i] * c[j] > 0 else "traded against"
        return f"{_BASIS_NAMES[i]} {how} {_BASIS_NAMES[j]}"
    short = ("wheel scale", "ratio", "b", "x", "y", "yaw")
    return "the combination " + ", ".join(
        f"{c[k]:+.2f} {short[k]}" for k in order if abs(c[k]) > 0.1
    )


def _describe_subspace(N: np.ndarray) -> list[str]:
    """Words for every dimension of the subspace spanned by the orthonormal columns of ``N``:
    first the named directions lying in it (projection >= 0.95), then the rest."""
    k = N.shape[1]
    if k == 0:
        return []
    if k == 1:
        return [describe_direction(N[:, 0])]
    out: list[str] = []
    found: list[np.ndarray] = []
    for name, u in _named_directions(N.shape[0]):
        p = N @ (N.T @ u)
        for f in found:
            p = p - f * (f @ p)
        if np.linalg.norm(p) >= 0.95 and len(found) < k:
            found.append(p / np.linalg.norm(p))
            out.append(name)
    rest = N - (np.column_stack(found) @ (np.column_stack(found).T @ N) if found else 0.0)
    u, sv, _ = np.linalg.svd(rest, full_matrices=False)
    for i in range(k - len(found)):
        w = u[:, i] * np.sign(u[np.argmax(np.abs(u[:, i])), i])
        out.append(describe_direction(w))
    return out


# --------------------------------------------------------------------------------------------
# Degeneracies and suggestions


def _radius_hint(b: float) -> str:
    return f"{2.5 * b:.2g}-{10 * b:.2g} m (2.5-10 wheelbases)"


# A degeneracy and the advice that cures it.
_Finding = tuple[Degeneracy, list[str]]


#: The degenerate motions of wheel calibration named after Lee, Eckenhoff, Yang, Geneva & Huang,
#: "Visual-Inertial-Wheel Odometry with Online Calibration", IROS 2020, whose abstract states that
#: its observability analysis "identifies five commonly-seen degenerate motions for wheel
#: calibration parameters". The list itself was NOT read (docs/check.md: RECONSTRUCTED): the five
#: names below are the motion classes that make the information of D_R, D_L, b singular (or, the
#: last, hide direction-dependent effects) in the wheel model, each with the check's flag that
#: detects it. Stable code -> (name, flag of this check, what it hides for D_R, D_L, b).
DEGENERATE_MOTIONS: dict[str, tuple[str, str, str]] = {
    "no-motion": ("no motion", "no-motion", "everything"),
    "pure-translation": (
        "pure translation (straight lines only)",
        "straight-only",
        "the wheelbase b",
    ),
    "pure-rotation": (
        "pure rotation (spot turns only)",
        "spot-turns-only",
        "the common scale of D_R, D_L and b",
    ),
    "constant-velocity": (
        "constant angular and linear velocity (one circle)",
        "constant-curvature",
        "one combination of D_R, D_L and b",
    ),
    "one-axis-rotation": (
        "rotation about one axis in one sense only",
        "one-turning-direction",
        "direction-dependent effects, absorbed into b and D_R/D_L",
    ),
}


def degenerate_motions(check: LogCheck) -> list[dict]:
    """The named degenerate motions (:data:`DEGENERATE_MOTIONS`) that ``check`` flags: code,
    name, the check's flag and what it hides."""
    return [
        {"code": code, "name": name, "flag": flag, "hides": hides}
        for code, (name, flag, hides) in DEGENERATE_MOTIONS.items()
        if check.flagged(flag)
    ]


def _degeneracies(
    motion: MotionSummary,
    cond: float,
    weakest_se: float,
    blind: Sequence[str],
    stderr: Sequence[float],
    values: np.ndarray,
    b: float,
    th: CheckThresholds,
) -> tuple[list[Degeneracy], list[str]]:
    """The log's degeneracies and what to drive about them: first what the motion lacks, then
    the conditioning (advice from it only when the motion gave none)."""
    if not motion.wheel_travel_m > 0:
        nothing = Degeneracy("no-motion", "blind", "everything", "the wheels did not turn at all")
        return [nothing], ["drive the robot: this log has no wheel motion"]
    motion_findings = [
        _kind_of_motion(motion, b, th),
        _one_turning_direction(motion, th),
        _too_little_travel(motion, th),
        _too_little_rotation(motion, th),
    ]
    found = [f for f in motion_findings if f is not None]
    out = [d for d, _ in found]
    tips = [t for _, advice in found for t in advice]
    fit = _ill_conditioned(cond, weakest_se, blind, b, th) or _imprecise(stderr, values, b, th)
    if fit is not None:
        out.append(fit[0])
        if not tips:
            tips += fit[1]
    return out, tips


def _kind_of_motion(motion: MotionSummary, b: float, th: CheckThresholds) -> _Finding | None:
    """Only straight lines, only spot turns, or one curvature all the time."""
    if motion.share_straight >= th.only_share:
        return Degeneracy(
            "straight-only",
            "blind",
            "the wheelbase b",
            f"only straight lines ({100 * motion.share_straight:.0f} % of the wheel travel): "
            "they see the wheel scale and, from their heading drift, (D_R - D_L)/b, never b",
        ), [
            "add turns in both directions: spot turns, or arcs of radius "
            f"{_radius_hint(b)}, at least half a turn each way (straight lines cannot separate "
            "b from the diameters)"
        ]
    if motion.share_spot >= th.only_share:
        return Degeneracy(
            "spot-turns-only",
            "blind",
            "the common scale of D_R, D_L and b (and, robustly, the diameter ratio)",
            f"only spot turns ({100 * motion.share_spot:.0f} % of the wheel travel): they see "
            "mean(D)/b, and D_R - D_L only through the small drift of the axle centre, "
            "which a tracker off the axle imitates",
        ), [
            "add straight runs of a known (tracked) length, 2 m or more, forward (and back): "
            "spot turns never see the common scale, and a closed track seen only at its end "
            "cannot see it either"
        ]
    if motion.ratio_concentration >= th.constant_ratio:
        return Degeneracy(
            "constant-curvature",
            "blind",
            "one combination of D_R, D_L and b",
            "the wheels keep one speed ratio (one curvature) all the time "
            f"(concentration {motion.ratio_concentration:.3f}): the path is one circle whose "
            "radius and length per wheel turn fix only two of D_R, D_L, b",
        ), [
            "add motion with a different wheel-speed ratio: straight runs and spot turns, or "
            f"arcs of another radius in {_radius_hint(b)}, in both directions"
        ]
    return None


def _one_turning_direction(motion: MotionSummary, th: CheckThresholds) -> _Finding | None:
    """Enough turning, but (almost) all of it one way."""
    if not (motion.rotation_rad >= th.min_rotation_rad and motion.turning in ("left", "right")):
        return None
    other = "right (CW)" if motion.turning == "left" else "left (CCW)"
    main, turned = motion.rotation_left_rad, motion.rotation_right_rad
    if motion.turning == "right":
        main, turned = turned, main
    return Degeneracy(
        "one-turning-direction",
        "weak",
        "direction-dependent effects against b and D_R/D_L",
        f"turns only {motion.turning}: {math.degrees(turned):.0f} deg to the "
        f"{other.split()[0]} against {math.degrees(main):.0f} deg (less than "
        f"{math.degrees(th.min_turn_each_way_rad):.0f} deg or "
        f"{100 * th.min_turn_balance:.0f} %)",
    ), [
        f"drive the same motions turning {other} as well, about as much: with one direction "
        "only, any direction-dependent effect (slip, caster drag, a tilted tracker) is "
        "absorbed into b and D_R/D_L"
    ]


def _too_little_travel(motion: MotionSummary, th: CheckThresholds) -> _Finding | None:
    if not motion.travel_m < th.min_travel_m - 1e-9:  # a float sum of exactly the minimum passes
        return None
    return Degeneracy(
        "too-little-travel",
        "weak",
        "the wheel scale",
        f"the axle centre travelled {motion.travel_m:.2f} m (< {th.min_travel_m:g} m)",
    ), [f"drive at least {th.min_travel_m:g} m in total (straight runs of 2 m or more)"]


def _too_little_rotation(motion: MotionSummary, th: CheckThresholds) -> _Finding | None:
    if not motion.rotation_rad < th.min_rotation_rad or motion.share_straight >= th.only_share:
        return None
    return Degeneracy(
        "too-little-rotation",
        "weak",
        "the wheelbase b",
        f"the robot turned {math.degrees(motion.rotation_rad):.0f} deg in total "
        f"(< {math.degrees(th.min_rotation_rad):.0f} deg)",
    ), [f"turn at least {math.degrees(th.min_rotation_rad):.0f} deg in total, both ways"]


def _ill_conditioned(
    cond: float, weakest_se: float, blind: Sequence[str], b: float, th: CheckThresholds
) -> _Finding | None:
    """Directions the Fisher information does not determine: far weaker than the best one and
    not known to ``max_relative_stderr`` (a long log that pins the diameter ratio to a millionth
    is not blind to a scale it knows to a thousandth)."""
    if cond < th.max_condition or weakest_se <= th.max_relative_stderr:  # NaN: ill-conditioned
        return None
    what = "; ".join(blind)
    return Degeneracy(
        "ill-conditioned",
        "blind",
        what,
        f"condition number {cond:.3g} of the (relative) Fisher information "
        f"(>= {th.max_condition:.0e}); not determined: {what}",
    ), [_tip_for(w, b) for w in blind]


def _imprecise(
    stderr: Sequence[float], values: np.ndarray, b: float, th: CheckThresholds
) -> _Finding | None:
    """Geometry parameters determined (not ill-conditioned), but with a predicted standard error
    above the threshold."""
    rel = {k: v / p for k, v, p in zip(GEOMETRY_PARAMETERS, stderr, values, strict=False)}
    loose = {k: v for k, v in rel.items() if v > th.max_relative_stderr}
    if not loose:
        return None
    words = {
        "wheel_diameter_right_m": "D_R",
        "wheel_diameter_left_m": "D_L",
        "wheelbase_m": "b",
    }
    what = ", ".join(words[k] for k in loose)
    direction = "the wheelbase b" if "wheelbase_m" in loose else "the common wheel scale"
    return Degeneracy(
        "imprecise",
        "weak",
        what,
        "predicted standard error "
        + ", ".join(f"{words[k]} {100 * v:.2g} %" for k, v in loose.items())
        + f" (> {100 * th.max_relative_stderr:.2g} % of the value) with the noise below",
    ), [_tip_for(direction, b) + ", or simply more of the same runs"]


def with_prediction(check: LogCheck, covariance: np.ndarray, what: str) -> LogCheck:
    """``check`` with the predicted covariance of another estimator (e.g. the relative-motion fit
    of a SLAM truth, whose residuals are not the trajectory fit's): its standard errors, and the
    'imprecise' finding judged again on them; ``what`` names it (in ``settings['prediction']``).
    The motion, the blind directions and the other findings stay the trajectory fit's."""
    th = CheckThresholds()
    cov = np.asarray(covariance, dtype=float)
    se = np.sqrt(np.abs(np.diag(cov)))
    values = np.asarray(check.values, dtype=float)[: len(se)]
    keys = GEOMETRY_PARAMETERS[: len(se)]
    stderr = dict(check.stderr) | {k: float(v) for k, v in zip(keys, se, strict=True)}
    kept = tuple(d for d in check.degeneracies if d.code != "imprecise")
    blind = any(d.code == "ill-conditioned" for d in check.degeneracies)
    finding = None if blind else _imprecise(list(se), values, float(values[-1]), th)
    before = [check.stderr[k] for k in keys]
    old = None if blind else _imprecise(before, values, float(values[-1]), th)
    stale = set(old[1]) if old is not None else set()  # the trajectory fit's advice
    suggestions = tuple(t for t in check.suggestions if t not in stale)
    if finding is not None:
        kept = (*kept, finding[0])
        suggestions = tuple(dict.fromkeys((*suggestions, *finding[1])))
    return replace(
        check, stderr=stderr, degeneracies=kept, suggestions=suggestions,
        settings=dict(check.settings) | {"prediction": what},
    )  # fmt: skip


def _tip_for(weakest: str, b: float) -> str:
    if "scale" in weakest:
        return "add straight runs of a known (tracked) length, 2 m or more"
    if "ratio" in weakest:
        return "add long straight runs: their heading drift measures D_R/D_L"
    if "wheelbase" in weakest or "turning" in weakest:
        return "add spot turns or arcs in both directions, at least half a turn each way"
    if "sensor" in weakest:
        return (
            f"add arcs of radius {_radius_hint(b)} and spot turns in both directions: turning "
            "about different centres separates the sensor offset from the geometry"
        )
    return f"add straight runs, spot turns and arcs of radius {_radius_hint(b)}, both directions"


# --------------------------------------------------------------------------------------------
# The check


def check_recordings(
    recordings: Iterable[Recording],
    geometry: WheelGeometry,
    *,
    noise: NoiseModel | None = None,
    residual: Residual = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    samples_per_run: int = 200,
    run_weight: RunWeight = "travel",
    mounting: bool = False,
    residual_scale: str = "stated",
    thresholds: CheckThresholds | None = None,
    max_blocks_per_run: int = MAX_BLOCKS_PER_RUN,
) -> LogCheck:
    """Is this log enough to fit ``geometry``'s D_R, D_L, b? (module docstring)

    Parameters
    ----------
    recordings : list of Recording
        Wheel angles are required, ground truth only for ``residual_scale='empirical'``.
    geometry : WheelGeometry
        Linearisation point (a fit result, or the nominal geometry), m.
    noise : NoiseModel
        Stated noise (default: NoiseModel()).
    residual, segment_m, heading_weight_m, samples_per_run, run_weight
        The trajectory fit's settings (``fit_trajectory``), so that the prediction is for the fit
        that will be run.
    mounting : bool
        Also the mounting (x_m, y_m, yaw_rad) of the ground-truth frame on the robot, linearised
        at zero offset (a relative-motion fit that estimates it).
    residual_scale : {'stated', 'empirical'}
        'empirical' scales the stated noise by s = sqrt(r^T Sigma^-1 r / (m - n)), r the
        residuals of the recordings' ground truth at ``geometry`` (pass the fitted geometry).
    thresholds : CheckThresholds
    """
    fit = _Settings(
        residual, segment_m, heading_weight_m, samples_per_run, run_weight, mounting, residual_scale
    )
    fit.check()
    recordings = _checked_recordings(recordings, fit.empirical)
    noise = noise or NoiseModel()
    info = _log_information(recordings, geometry, noise, fit, max_blocks_per_run)
    return judge(info, recordings, thresholds)


@dataclass(frozen=True)
class LogInformation:
    """What :func:`check_recordings` sums over the runs of a log, at one linearisation point,
    noise and fit setting: the Fisher information ``fisher`` (J^T Sigma^-1 J, scaled), the fit's
    ``hessian`` (J^T W J) and ``meat`` (J^T W Sigma W J), all additive over runs (the runs'
    residuals are independent), so the information of a log and of a motion added to it is the
    sum (``+``). ``residual_scale`` is 1 for the stated noise."""

    parameters: tuple
    values: np.ndarray
    geometry: WheelGeometry
    noise: NoiseModel
    settings: _Settings
    fisher: np.ndarray
    hessian: np.ndarray
    meat: np.ndarray
    residual_scale: float = 1.0

    def __add__(self, other: LogInformation) -> LogInformation:
        if (other.parameters, other.settings, other.residual_scale) != (
            self.parameters,
            self.settings,
            self.residual_scale,
        ):
            raise CalibrationError("check: information of different parameters or settings")
        return replace(
            self,
            fisher=self.fisher + other.fisher,
            hessian=self.hessian + other.hessian,
            meat=self.meat + other.meat,
        )

    def times(self, runs: int) -> LogInformation:
        """The information of ``runs`` independent repeats of this log."""
        return replace(
            self, fisher=runs * self.fisher, hessian=runs * self.hessian, meat=runs * self.meat
        )

    def stderr(self) -> dict:
        """Predicted standard error of the fit as implemented (the sandwich), per parameter."""
        return _stderr(self.parameters, _sandwich(self.hessian, self.meat))


def log_information(
    recordings: Iterable[Recording],
    geometry: WheelGeometry,
    *,
    noise: NoiseModel | None = None,
    residual: Residual = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    samples_per_run: int = 200,
    run_weight: RunWeight = "travel",
    mounting: bool = False,
    max_blocks_per_run: int = MAX_BLOCKS_PER_RUN,
) -> LogInformation:
    """The additive information of ``recordings`` under the STATED noise (arguments as
    :func:`check_recordings`); ground truth is not needed (a synthetic motion has none)."""
    fit = _Settings(
        residual, segment_m, heading_weight_m, samples_per_run, run_weight, mounting, "stated"
    )
    fit.check()
    return _log_information(
        _checked_recordings(recordings, False), geometry, noise or NoiseModel(), fit,
        max_blocks_per_run,
    )  # fmt: skip


def _log_information(
    recordings: Sequence[Recording],
    geometry: WheelGeometry,
    noise: NoiseModel,
    fit: _Settings,
    max_blocks_per_run: int,
) -> LogInformation:
    b = float(geometry.wheelbase_m)
    p0 = np.array([geometry.diameter_right_m, geometry.diameter_left_m, b], dtype=float)
    names = GEOMETRY_PARAMETERS + (MOUNT_PARAMETERS if fit.mounting else ())
    params = np.concatenate([p0, np.zeros(3)]) if fit.mounting else p0
    rel = _relative_units(params, b)
    steps = 1e-6 * rel
    info = _Information(len(params))
    for rec in recordings:
        info.add_run(rec, geometry, noise, params, steps, fit, max_blocks_per_run)
    F, Mw, scale = info.scaled(fit.empirical)
    return LogInformation(names, params, geometry, noise, fit, F, info.hessian, Mw, scale)


def _relative_units(params: np.ndarray, b: float) -> np.ndarray:
    """Units of the relative parametrisation: lengths as fractions, mounting offsets in
    wheelbases, yaw in rad."""
    return np.concatenate([params[:3], [b, b, 1.0]]) if len(params) > 3 else params[:3]


def judge(
    info: LogInformation,
    recordings: Sequence[Recording],
    thresholds: CheckThresholds | None = None,
) -> LogCheck:
    """The check of a log from its information (:func:`log_information`, possibly a sum) and
    its recordings' motion: what :func:`check_recordings` returns."""
    th = thresholds or CheckThresholds()
    geometry, params, names = info.geometry, info.values, info.parameters
    b = float(geometry.wheelbase_m)
    F = info.fisher
    cov = _sandwich(info.hessian, info.meat)
    d = _Directions.of(F, _relative_units(params, b), th)
    if d.cond < _SINGULAR:
        cov_best = np.linalg.inv(F)
    else:
        cov_best = np.full(F.shape, np.inf)
        cov = np.full(F.shape, np.inf)
    motion, per = summarize_motion(recordings, geometry, th)
    stderr = _stderr(names, cov)
    degeneracies, tips = _degeneracies(
        motion,
        d.cond,
        d.weakest_relative_stderr,
        d.blind or (d.weakest,),
        list(stderr.values()),
        params,
        b,
        th,
    )
    return LogCheck(
        parameters=names,
        values=params,
        fisher_information=F,
        covariance=cov,
        stderr=stderr,
        stderr_best=_stderr(names, cov_best),
        condition_number=d.cond,
        weakest_direction=d.weakest,
        blind_directions=tuple(d.blind),
        weakest_vector=tuple(float(x) for x in d.weakest_vector),
        weakest_relative_stderr=d.weakest_relative_stderr,
        degeneracies=tuple(degeneracies),
        suggestions=tuple(tips),
        motion=motion,
        per_recording=per,
        noise=info.noise,
        residual_scale=info.residual_scale,
        settings=info.settings.as_dict(),
    )


@dataclass(frozen=True)
class _Settings:
    """The check's settings: the trajectory fit's it predicts for (``fit_trajectory``), the
    mounting and the source of the noise scale."""

    residual: Residual
    segment_m: float
    heading_weight_m: float
    samples_per_run: int
    run_weight: RunWeight
    mounting: bool
    residual_scale: str

    @property
    def empirical(self) -> bool:
        return self.residual_scale == "empirical"

    def check(self) -> None:
        if self.residual not in RESIDUALS:
            raise CalibrationError(
                f"residual must be one of {', '.join(RESIDUALS)}, got {self.residual!r}"
            )
        if self.run_weight not in RUN_WEIGHTS:
            raise CalibrationError(
                f"run_weight must be one of {', '.join(RUN_WEIGHTS)}, got {self.run_weight!r}"
            )
        if self.residual_scale not in ("stated", "empirical"):
            raise CalibrationError(
                f"residual_scale must be 'stated' or 'empirical', got {self.residual_scale!r}"
            )
        if not (self.segment_m > 0 and math.isfinite(self.segment_m)):
            raise CalibrationError(f"segment_m must be finite and > 0, got {self.segment_m!r}")
        if not (self.heading_weight_m >= 0 and math.isfinite(self.heading_weight_m)):
            raise CalibrationError(
                f"heading_weight_m must be finite and >= 0, got {self.heading_weight_m!r}"
            )

    def as_dict(self) -> dict:
        """``LogCheck.settings``."""
        return {
            "residual": self.residual,
            "segment_m": self.segment_m if self.residual == "segment" else None,
            "heading_weight_m": self.heading_weight_m,
            "samples_per_run": self.samples_per_run,
            "run_weight": self.run_weight,
            "mounting": self.mounting,
            "residual_scale": self.residual_scale,
        }


def _checked_recordings(recordings: Iterable[Recording], need_truth: bool) -> list[Recording]:
    recordings = list(recordings)
    if not recordings:
        raise CalibrationError("check: no recordings")
    for r in recordings:
        if len(r.time_s) < 2:
            raise CalibrationError(f"check: {r.name} has fewer than two samples")
        if need_truth and r.ground_truth is None:
            raise CalibrationError(
                f"check: residual_scale='empirical' needs ground truth; {r.name} has none"
            )
    return recordings


class _Information:
    """Sums over the runs: the Fisher information F = J^T Sigma^-1 J of the stated noise, the
    fit's own J^T W J (``hessian``) and J^T W Sigma W J (``meat``), and for an empirical scale
    the residuals' r^T Sigma^-1 r and their count."""

    def __init__(self, n: int) -> None:
        self.n = n
        self.fisher = np.zeros((n, n))
        self.hessian = np.zeros((n, n))
        self.meat = np.zeros((n, n))
        self.chi2 = 0.0
        self.rows = 0

    def add_run(
        self,
        rec: Recording,
        geometry: WheelGeometry,
        noise: NoiseModel,
        params: np.ndarray,
        steps: np.ndarray,
        fit: _Settings,
        max_blocks: int,
    ) -> None:
        n, residual = self.n, fit.residual
        odo = dead_reckon(rec.wheel_angle_right_rad, rec.wheel_angle_left_rad, geometry)
        gt = odo if rec.ground_truth is None else rec.ground_truth
        run = RunResiduals(
            replace(rec, ground_truth=gt),
            residual,
            fit.samples_per_run,
            fit.segment_m,
            geometry,
            fit.run_weight,
        )
        J = _jacobian(run, residual, params, steps)
        w = np.tile([1.0, 1.0, fit.heading_weight_m], len(J) // 3) * run.weight
        AJ = J * (w**2)[:, None]
        self.hessian += J.T @ AJ
        r = np.zeros(len(J))
        if fit.empirical:
            r = np.asarray(
                run.gt[run.idx] if residual == "pose" else run.gt_rel, dtype=float
            ).ravel() - _predict(run, residual, params)
            self.rows += len(r)
        Jr = np.column_stack([J, r])
        if residual == "pose":
            inv_form, Mrun = _pose_forms(run, geometry, noise, Jr, AJ)
        else:
            S = _noise_covariance(run, residual, geometry, noise, max_blocks)
            inv_form, Mrun = Jr.T @ _solve_psd(S, Jr), AJ.T @ S @ AJ
        self.fisher += inv_form[:n, :n]
        self.meat += Mrun
        self.chi2 += float(inv_form[n, n])

    def scaled(self, empirical: bool) -> tuple[np.ndarray, np.ndarray, float]:
        """F and the meat with the noise scaled by s (1, or sqrt(chi2 / (rows - n)) for an
        empirical scale), and s."""
        scale = 1.0
        if empirical:
            if self.rows <= self.n:
                raise CalibrationError("check: too few residuals for an empirical scale")
            scale = math.sqrt(self.chi2 / (self.rows - self.n))
        return self.fisher / scale**2, self.meat * scale**2, scale


@dataclass(frozen=True)
class _Directions:
    """The eigen-directions of F in the relative parametrisation: its condition number, the
    weakest direction (unit vector and words), its Cramer-Rao relative standard error, and the
    directions not determined (below 1 / ``max_condition`` of the best one), in words."""

    cond: float
    weakest_vector: np.ndarray
    weakest: str
    weakest_relative_stderr: float
    blind: Sequence[str]

    @classmethod
    def of(cls, F: np.ndarray, rel: np.ndarray, th: CheckThresholds) -> _Directions:
        F_rel = F * np.outer(rel, rel)
        lam, vec = np.linalg.eigh(0.5 * (F_rel + F_rel.T))
        lam_max = float(lam[-1])
        cond = lam_max / float(lam[0]) if lam[0] > 0 else math.inf
        weakest_se = 1.0 / math.sqrt(float(lam[0])) if cond < _SINGULAR else math.inf
        v = vec[:, 0]
        v = v * np.sign(v[np.argmax(np.abs(v))])
        blind = _describe_subspace(vec[:, lam <= lam_max / th.max_condition]) if lam_max > 0 else ()
        return cls(cond, v, describe_direction(v), weakest_se, blind)


def _sandwich(H: np.ndarray, M: np.ndarray) -> np.ndarray:
    """H^-1 M H^-1, or inf where H is singular."""
    n = len(H)
    d = np.sqrt(np.clip(np.diag(H), 1e-300, None))
    Hn = H / np.outer(d, d)
    if np.linalg.cond(Hn) > 1e14:
        return np.full((n, n), np.inf)
    Hi = np.linalg.inv(Hn) / np.outer(d, d)
    cov = Hi @ M @ Hi
    return 0.5 * (cov + cov.T)


def _stderr(names: Sequence[str], cov: np.ndarray) -> dict:
    d = np.diag(cov)
    return {
        k: (math.sqrt(v) if math.isfinite(v) and v >= 0 else math.inf)
        for k, v in zip(names, d, strict=True)
    }
