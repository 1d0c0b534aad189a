"""Monte-Carlo execution of a track (model.md, "Executing a track").

The robot drives each segment open loop on its encoders: it turns the segment into wheel
rotations with the parameters it BELIEVES; the true wheel travel is that rotation times the TRUE
radius, plus Gaussian noise of variance k |ds| per increment; the true pose follows the midpoint
update (Siegwart eq. 5.6) over increments of at most ``max_step_m`` of wheel travel.

Everything is vectorised over a batch of runs (axis 0) and, within a segment, over its increments
(axis 1, through cumulative sums), so there is no Python loop per increment. Geometry values and
segment values may be arrays of shape (runs,): one robot or one track size per run.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .model import ModelError, NonSystematicError, Robot, WheelGeometry
from .pose import compose
from .tracks import Track

__all__ = [
    "SimulationResult",
    "simulate",
    "drive",
    "odometric_pose",
    "measure",
    "measure_track",
    "commanded_wheel_angles",
    "increments_per_segment",
]

# Work arrays are at most about this many elements (chunks of runs); 2e6 doubles = 16 MB each.
_MAX_ELEMENTS = 2_000_000


@dataclass(frozen=True)
class SimulationResult:
    """Outcome of ``runs`` simulated runs of one track.

    Attributes
    ----------
    true_final : ndarray, shape (runs, 3)
        True final pose (x_m, y_m, theta_rad) in the start frame; theta unwrapped.
    odometric_final : ndarray, shape (3,) or (runs, 3)
        The pose the robot believes it reached (the commanded one).
    trajectory : ndarray, shape (runs, K + 1, 3) or None
        True pose after every increment, starting with the start pose (only on request).
    """

    true_final: np.ndarray
    odometric_final: np.ndarray
    trajectory: np.ndarray | None = None

    @property
    def errors(self) -> np.ndarray:
        """Final pose error, actual - odometric, shape (runs, 3) (x_m, y_m, theta_rad)."""
        return self.true_final - self.odometric_final


def odometric_pose(track: Track) -> np.ndarray:
    """The believed (commanded) final pose of ``track`` from the origin, shape (3,) or (runs, 3)
    when segment values are arrays."""
    pose = np.zeros(3)
    for seg in track.segments:
        pose = compose(pose, seg.distance_m, seg.angle_rad)
    return pose


# Bounds on the work of one simulation call, so that absurd lengths, steps or run counts are a
# clear error instead of a memory blow-up: increments per segment (1e6 = 10 km at the default
# 1 cm), and runs x increments over the whole track (about a minute of numpy work at the most).
MAX_STEPS_PER_SEGMENT = 1_000_000
MAX_RUN_INCREMENTS = 2_000_000_000


def increments_per_segment(
    s_r, s_l, max_step_m: float | None, steps_per_segment: int | None = None
) -> int:
    """Increments a segment of wheel travel ``s_r``, ``s_l`` (m; scalars or arrays) is split into:
    ``steps_per_segment`` if given, else enough that no increment exceeds ``max_step_m`` (m)."""
    if steps_per_segment is not None:
        return int(steps_per_segment)
    if max_step_m is None or not max_step_m > 0:
        raise ModelError(f"max_step_m must be > 0, got {max_step_m!r}")
    longest = float(np.max(np.maximum(np.abs(s_r), np.abs(s_l))))
    ratio = longest / max_step_m
    if not ratio <= MAX_STEPS_PER_SEGMENT:  # also catches inf/NaN (an absurd length or step)
        raise ModelError(
            f"a segment of {longest:.3g} m of wheel travel in increments of at most "
            f"{max_step_m:.3g} m needs more than {MAX_STEPS_PER_SEGMENT} increments: "
            "use a shorter track or a larger maximum step"
        )
    return max(1, math.ceil(ratio - 1e-9))


def drive(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    runs: int,
    rng: np.random.Generator | None,
    *,
    max_step_m: float | None = 0.01,
    steps_per_segment: int | None = None,
    integration: str = "midpoint",
    trajectory: bool = False,
) -> SimulationResult:
    """Drive ``track`` ``runs`` times open loop; see the module docstring.

    Parameters
    ----------
    true, believed : WheelGeometry
        True and believed geometry; values are scalars or arrays of shape (runs,).
    noise : NonSystematicError
        Wheel-travel noise (k in metres). Zero noise needs no ``rng``.
    max_step_m : float
        Largest wheel travel (m) of one increment (default 1 cm, model.md).
    steps_per_segment : int, optional
        Fixed number of increments per segment (overrides ``max_step_m``).
    integration : {'midpoint', 'exact'}
        'midpoint' is eq. (8); 'exact' integrates each increment as an exact arc, which makes the
        deterministic part exact at any step size (used for fast design sweeps).
    trajectory : bool
        Also return the pose after every increment (memory: runs x increments x 3 doubles).
    """
    if runs < 1:
        raise ModelError(f"runs must be >= 1, got {runs}")
    if integration not in ("midpoint", "exact"):
        raise ModelError(f"integration must be 'midpoint' or 'exact', got {integration!r}")
    if steps_per_segment is None and not (max_step_m and max_step_m > 0):
        raise ModelError(f"max_step_m must be > 0, got {max_step_m!r}")
    if not noise.is_zero and rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate noise")

    if runs * len(track.segments) > MAX_RUN_INCREMENTS:  # every segment takes >= 1 increment
        raise ModelError(
            f"{runs} runs is too much work (at most {MAX_RUN_INCREMENTS:.0e} increments in one "
            "simulation): use fewer runs"
        )

    def batch(v):
        return np.broadcast_to(np.asarray(v, dtype=float), (runs,))

    # per-wheel travel factor true/believed and true wheelbase, shape (runs,)
    f_r = batch(true.diameter_right_m / believed.diameter_right_m)
    f_l = batch(true.diameter_left_m / believed.diameter_left_m)
    b_true = batch(true.wheelbase_m)
    b_hat = batch(believed.wheelbase_m)

    travel = []  # true wheel travel over each segment (m), shape (runs,), and its increments
    for seg in track.segments:
        s_hat_r, s_hat_l = seg.wheel_travel(b_hat)
        s_r, s_l = batch(s_hat_r * f_r), batch(s_hat_l * f_l)
        travel.append((s_r, s_l, increments_per_segment(s_r, s_l, max_step_m, steps_per_segment)))
    steps = [n for _, _, n in travel]
    if runs * sum(steps) > MAX_RUN_INCREMENTS:
        raise ModelError(
            f"{runs} runs x {sum(steps)} increments is too much work (at most "
            f"{MAX_RUN_INCREMENTS:.0e} increments in one simulation): use fewer runs, a shorter "
            "track or a larger maximum step"
        )
    pose = np.zeros((runs, 3))
    pieces: list[np.ndarray] = [pose[:, None, :].copy()]
    draw = rng.standard_normal if rng is not None else None
    for s_r, s_l, n in travel:
        chunk = max(1, _MAX_ELEMENTS // n)
        seg_traj = np.empty((runs, n, 3) if trajectory else (0, 0, 3))
        for lo in range(0, runs, chunk):
            hi = min(runs, lo + chunk)
            dr = np.repeat((s_r[lo:hi] / n)[:, None], n, axis=1)
            dl = np.repeat((s_l[lo:hi] / n)[:, None], n, axis=1)
            if noise.k_r_m > 0 and draw is not None:
                dr = dr + np.sqrt(noise.k_r_m * np.abs(dr)) * draw(dr.shape)
            if noise.k_l_m > 0 and draw is not None:
                dl = dl + np.sqrt(noise.k_l_m * np.abs(dl)) * draw(dl.shape)
            ds = 0.5 * (dr + dl)
            dth = (dr - dl) / b_true[lo:hi, None]
            theta_after = pose[lo:hi, 2:3] + np.cumsum(dth, axis=1)
            mid = theta_after - 0.5 * dth
            if integration == "exact":
                ds = ds * np.sinc(dth / (2.0 * math.pi))
            dx = ds * np.cos(mid)
            dy = ds * np.sin(mid)
            if trajectory:
                seg_traj[lo:hi, :, 0] = pose[lo:hi, 0:1] + np.cumsum(dx, axis=1)
                seg_traj[lo:hi, :, 1] = pose[lo:hi, 1:2] + np.cumsum(dy, axis=1)
                seg_traj[lo:hi, :, 2] = theta_after
            pose[lo:hi, 0] += dx.sum(axis=1)
            pose[lo:hi, 1] += dy.sum(axis=1)
            pose[lo:hi, 2] = theta_after[:, -1]
        if trajectory:
            pieces.append(seg_traj)
    traj = np.concatenate(pieces, axis=1) if trajectory else None  # noqa: the first piece
    return SimulationResult(pose, odometric_pose(track), traj)


def simulate(
    track: Track,
    robot: Robot,
    runs: int,
    rng: np.random.Generator | None,
    **options,
) -> SimulationResult:
    """Drive ``track`` ``runs`` times with ``robot`` (true geometry from its systematic errors,
    believed geometry from ``robot.believed`` or nominal). Options as in :func:`drive`.
    Measurement noise is NOT applied here; see :func:`measure`."""
    return drive(
        track,
        robot.true_geometry,
        robot.believed_geometry,
        robot.nonsystematic,
        runs,
        rng,
        **options,
    )


def measure(errors: np.ndarray, robot: Robot, rng: np.random.Generator | None) -> np.ndarray:
    """Add the ground-truth instrument's noise to final pose errors, shape (..., 3)."""
    m = robot.measurement
    if m.is_zero:
        return np.asarray(errors, dtype=float)
    if rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate measurement noise")
    z = rng.standard_normal(np.shape(errors))
    scale = np.array([m.sigma_xy_m, m.sigma_xy_m, m.sigma_theta_rad])
    return errors + z * scale


def measure_track(poses: np.ndarray, robot: Robot, rng: np.random.Generator | None) -> np.ndarray:
    """Tracked poses as an instrument sees them: ``poses`` (..., 3) (x_m, y_m, theta_rad) plus the
    instrument's noise (``robot.measurement``) on every sample, independently. A new array.

    Draws the position noise, then the heading noise (only the parts whose sigma is > 0)."""
    out = np.array(poses, dtype=float)
    m = robot.measurement
    if m.is_zero:
        return out
    if rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate measurement noise")
    if m.sigma_xy_m > 0:
        out[..., :2] += m.sigma_xy_m * rng.standard_normal(out[..., :2].shape)
    if m.sigma_theta_rad > 0:
        out[..., 2] += m.sigma_theta_rad * rng.standard_normal(out[..., 2].shape)
    return out


def commanded_wheel_angles(
    track: Track, believed: WheelGeometry, max_step_m: float
) -> tuple[int, np.ndarray]:
    """The encoder readings of an open-loop drive of ``track``, sampled after every increment.

    One increment count ``n`` for every segment (enough that no increment exceeds ``max_step_m``
    of wheel travel); returns ``(n, angles)`` with ``angles`` the cumulative commanded wheel
    rotations (right, left; rad), shape (n * segments + 1, 2), starting at 0. Use with
    ``drive(..., steps_per_segment=n, trajectory=True)`` to pair readings with true poses.
    """
    b_hat = float(np.mean(believed.wheelbase_m))
    travel = [seg.wheel_travel(b_hat) for seg in track.segments]
    longest = max(max(abs(float(r)), abs(float(lft))) for r, lft in travel)
    n = increments_per_segment(longest, longest, max_step_m)
    d_r = float(np.mean(believed.diameter_right_m))
    d_l = float(np.mean(believed.diameter_left_m))
    inc = np.concatenate(
        [
            np.repeat([[2.0 * float(r) / d_r / n, 2.0 * float(lft) / d_l / n]], n, axis=0)
            for r, lft in travel
        ]
    )
    return n, np.vstack([np.zeros((1, 2)), np.cumsum(inc, axis=0)])
