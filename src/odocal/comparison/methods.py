"""The method registry of the comparison: what each method drives, sized from one budget, and how it
calibrates (from simulated measurements and from real data sets).

A fair comparison of calibration methods: same robot, same budget, same validation track.

Every method is an entry of a registry (:data:`METHOD_REGISTRY`): its name, what it drives (a
plan of run groups sized from a common :class:`Budget`), a function from the simulated runs to
calibrated geometries (vectorised over Monte-Carlo trials), and optionally a function that
calibrates from real recorded data sets. To add a method, append one :class:`MethodEntry`.

The budget (documented in docs/methods.md): every method gets the same number of runs (default
10) and the same total driven distance, counted as mean WHEEL travel (so spot turns count:
a spin of psi costs |psi| b / 2). The default total is what UMBmark's 5 CW + 5 CCW runs on the 4 m
square cost the robot. Track sizes follow from it:

- square (heading, UMBmark): 5 CW + 5 CCW squares of side L = 4 m;
- BCPT: 5 CW + 5 CCW single-turn circles of radius R = per-run travel / (2 pi);
- Ivanjko: 4 straight runs + 3 CW + 3 CCW 180-degree spins; the straights take what the spins
  leave (long: a corridor, not a lab floor; the footprint is reported).

Validation: with each trial's calibrated parameters, the robot drives the validation track (the
4 m square CCW by default) once, with noise; we report its final position error, and the same
run without noise (the systematic residual the calibration left).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from ..calibration.bcpt import bcpt_factors, calibrate_bcpt_recordings
from ..calibration.circle_fit import fit_circle
from ..calibration.heading import calibrate_heading, heading_factors
from ..calibration.ivanjko import calibrate_ivanjko_recordings, ivanjko_from_end_poses
from ..calibration.linear import fit_linear, linear_geometry_trials
from ..calibration.result import CalibrationResult
from ..calibration.trajectory import fit_trajectory, fit_trajectory_trials
from ..calibration.umbmark import calibrate_umbmark, umbmark_factors
from ..core.model import Robot, WheelGeometry, wheel_factors
from ..core.odometry import dead_reckon
from ..core.runs import EndPoseRuns
from ..core.stats import circular_mean
from ..core.tracks import Track, arc, circle, polygon, spot_turn, straight_line
from ..errors import CalibrationError

__all__ = [
    "Budget",
    "RunGroup",
    "GroupData",
    "GeometryBatch",
    "MethodEntry",
    "METHOD_REGISTRY",
    "square_end_pose_runs",
]


@dataclass(frozen=True)
class Budget:
    """Runs and total mean wheel travel (m) every method may spend.

    ``travel_m=None`` means: what 5 CW + 5 CCW runs on the 4 m square cost this robot
    (runs x (16 m + pi b_n)), scaled to ``runs``. ``straight_m`` caps the length of Ivanjko's
    straight runs (m), e.g. to the floor space a square needs; that method then spends less
    than the budget (its reported ``travel_m`` says how much).
    """

    runs: int = 10
    travel_m: float | None = None
    straight_m: float | None = None

    def total_travel_m(self, robot: Robot) -> float:
        """The travel (m) the budget allows ``robot`` in all: ``travel_m``, else ``runs`` runs of 16
        m + pi b (b the wheelbase the robot believes, m)."""
        if self.travel_m is not None:
            return float(self.travel_m)
        b = float(np.mean(robot.believed_geometry.wheelbase_m))
        return self.runs * (16.0 + math.pi * b)

    def per_run_m(self, robot: Robot) -> float:
        """The travel (m) the budget allows per run."""
        return self.total_travel_m(robot) / self.runs


@dataclass(frozen=True)
class RunGroup:
    """``runs`` runs of one track, e.g. the CW squares. ``points``: the method needs tracked
    positions along the run (not only the final pose)."""

    label: str
    track: Track
    runs: int
    points: bool = False
    size: dict = field(default_factory=dict)


class GroupData(NamedTuple):
    """Simulated measurements of one run group over M trials.

    final : ndarray, shape (M, runs, 3)
        Measured true final pose (x_m, y_m, theta_rad; start frame, theta unwrapped), with the
        instrument's measurement noise.
    errors : ndarray, shape (M, runs, 3)
        Measured final error, actual - odometric.
    points : ndarray, shape (M, runs, K, 2) or None
        Tracked positions (m) along each run (about 200 samples, the last one included), with
        the instrument's position noise. Only for groups with ``points=True``.
    trajectory : ndarray, shape (M, runs, K, 3) or None
        Tracked poses (x_m, y_m, theta_rad) at the same samples (``points`` plus the heading, with
        the instrument's heading noise).
    wheel_angles_rad : ndarray, shape (K, 2) or None
        Cumulative wheel rotations (right, left; rad) at the same samples: what the encoders
        read (the commanded rotations, the same in every run). With ``trajectory`` this is a
        recording, e.g. for a trajectory or linear least-squares fit.
    """

    group: RunGroup
    final: np.ndarray
    errors: np.ndarray
    points: np.ndarray | None = None
    trajectory: np.ndarray | None = None
    wheel_angles_rad: np.ndarray | None = None


class GeometryBatch(NamedTuple):
    """Calibrated geometry per trial: arrays of shape (M,) in m; NaN marks a failed trial."""

    diameter_right_m: np.ndarray
    diameter_left_m: np.ndarray
    wheelbase_m: np.ndarray


Estimator = Callable[[dict, WheelGeometry], GeometryBatch]
Planner = Callable[[Budget, Robot], tuple]


@dataclass(frozen=True)
class MethodEntry:
    """One method in the comparison.

    Attributes
    ----------
    name : str
    drives : str
        What the robot drives (for tables).
    plan : callable
        ``plan(budget, robot) -> tuple[RunGroup, ...]``.
    estimate : callable
        ``estimate(data: dict[label, GroupData], ran_with: WheelGeometry) -> GeometryBatch``.
    real : callable or None
        ``real(datasets: dict[kind, list[list[Recording]]]) -> list[(name, CalibrationResult)]``:
        calibrations from real OptiOdom data sets (one per usable data set).
    """

    name: str
    drives: str
    plan: Planner
    estimate: Estimator
    real: Callable | None = None


def _from_factors(ran_with: WheelGeometry, E_b, E_d) -> GeometryBatch:
    c_r, c_l = wheel_factors(E_d)
    return GeometryBatch(
        np.asarray(ran_with.diameter_right_m * c_r, dtype=float),
        np.asarray(ran_with.diameter_left_m * c_l, dtype=float),
        np.asarray(ran_with.wheelbase_m * E_b, dtype=float),
    )


def _square_plan(budget: Budget, robot: Robot) -> tuple:
    b = float(np.mean(robot.believed_geometry.wheelbase_m))
    side = (budget.per_run_m(robot) - math.pi * b) / 4.0
    n_cw = budget.runs // 2
    size = {"side_m": side}
    return (
        RunGroup("cw", polygon(4, side, "cw"), n_cw, size=size),
        RunGroup("ccw", polygon(4, side, "ccw"), budget.runs - n_cw, size=size),
    )


def _circle_plan(budget: Budget, robot: Robot) -> tuple:
    radius = budget.per_run_m(robot) / (2.0 * math.pi)
    n_cw = budget.runs // 2
    size = {"radius_m": radius}
    return (
        RunGroup("cw", circle(radius, "cw"), n_cw, points=True, size=size),
        RunGroup("ccw", circle(radius, "ccw"), budget.runs - n_cw, points=True, size=size),
    )


def _ivanjko_plan(budget: Budget, robot: Robot) -> tuple:
    b = float(np.mean(robot.believed_geometry.wheelbase_m))
    n_spin = budget.runs // 3
    n_straight = budget.runs - 2 * n_spin
    if n_spin < 1 or n_straight < 1:
        raise CalibrationError("ivanjko needs at least 3 runs (straight, CW spin, CCW spin)")
    spin_travel = math.pi * b / 2.0
    length = (budget.total_travel_m(robot) - 2 * n_spin * spin_travel) / n_straight
    if length <= 0:
        raise CalibrationError("the budget does not leave any travel for the straight runs")
    if budget.straight_m is not None:
        length = min(length, float(budget.straight_m))
    size = {"straight_m": length, "spin_deg": 180.0}
    return (
        RunGroup("straight", straight_line(length), n_straight, size=size),
        RunGroup("spin-cw", Track("spin cw", (spot_turn(-math.pi),)), n_spin, size=size),
        RunGroup("spin-ccw", Track("spin ccw", (spot_turn(math.pi),)), n_spin, size=size),
    )


def _mean_theta(g: GroupData) -> np.ndarray:
    return circular_mean(g.errors[..., 2], axis=1)


def _heading_estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
    side = data["cw"].group.size["side_m"]
    E_b, E_d = heading_factors(
        _mean_theta(data["cw"]), _mean_theta(data["ccw"]), 4, side, ran_with.wheelbase_m
    )
    return _from_factors(ran_with, E_b, E_d)


def _umbmark_estimate(form: str) -> Estimator:
    def estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
        side = data["cw"].group.size["side_m"]
        cw = data["cw"].errors[..., :2].mean(axis=1)
        ccw = data["ccw"].errors[..., :2].mean(axis=1)
        E_b, E_d = umbmark_factors(cw, ccw, side, ran_with.wheelbase_m, form)
        return _from_factors(ran_with, E_b, E_d)

    return estimate


def _bcpt_estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
    radius = data["cw"].group.size["radius_m"]
    # batched points (trials, runs, K, 2): the radii are an array (trials, runs)
    r = {d: np.asarray(fit_circle(data[d].points).radius_m).mean(axis=1) for d in ("cw", "ccw")}
    E_b, E_d = bcpt_factors(r["cw"], r["ccw"], radius, ran_with.wheelbase_m)
    return _from_factors(ran_with, E_b, E_d)


def _ivanjko_estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
    s = data["straight"]
    fit = ivanjko_from_end_poses(
        s.final,
        s.group.size["straight_m"],
        data["spin-cw"].final,
        data["spin-ccw"].final,
        math.pi,
        ran_with,
    )
    g = fit.geometry
    return GeometryBatch(
        np.asarray(g.diameter_right_m), np.asarray(g.diameter_left_m), np.asarray(g.wheelbase_m)
    )


def _tracked_square_plan(budget: Budget, robot: Robot) -> tuple:
    return tuple(
        RunGroup(g.label, g.track, g.runs, points=True, size=g.size)
        for g in _square_plan(budget, robot)
    )


def _open_arc_plan(budget: Budget, robot: Robot) -> tuple:
    """Open arcs of radius 1 m CW and CCW (about 2.7 turns for the default budget), tracked.

    Linear least squares needs runs that translate while the wheels turn at different speeds and
    that end away from their start: its position step separates the two wheels only through such
    motion (Antonelli et al.'s conditioning of the test motion); on closed squares it is singular.
    """
    radius = 1.0
    angle = budget.per_run_m(robot) / radius
    n_cw = budget.runs // 2
    size = {"radius_m": radius}
    return tuple(
        RunGroup(d, Track(f"open arc {d}", (arc(radius, sign * angle),)), n, True, size)
        for d, sign, n in (("cw", -1, n_cw), ("ccw", 1, budget.runs - n_cw))
    )


def _linear_fit(recs, nominal):
    return fit_linear(recs, nominal)


def _trajectory_fit(recs, nominal):
    return fit_trajectory(recs, nominal=nominal)


def _linear_estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
    """The linear least squares of every trial at once, from each run's wheel angles and its
    last tracked pose (calibration.linear.linear_geometry_trials)."""
    groups = list(data.values())
    angles = [g.wheel_angles_rad for g in groups for _ in range(g.trajectory.shape[1])]
    finals = np.concatenate([g.trajectory[:, :, -1, :] for g in groups], axis=1)
    return GeometryBatch(*linear_geometry_trials(angles, finals).T)


def _trajectory_estimate(data: dict, ran_with: WheelGeometry) -> GeometryBatch:
    """The trajectory fit of every trial at once, started from the parameters the robot ran
    with (calibration.trajectory.fit_trajectory_trials)."""
    groups = list(data.values())
    x = fit_trajectory_trials(
        [g.wheel_angles_rad for g in groups], [g.trajectory for g in groups], ran_with
    )
    return GeometryBatch(*x.T)


# --- real data (OptiOdom folders) ------------------------------------------------------------


def square_end_pose_runs(recordings) -> EndPoseRuns:
    """Final pose errors (ground truth - dead reckoning with the parameters each run ran with)
    of labelled ('cw'/'ccw') recorded square runs."""
    labels, errors = [], []
    for r in recordings:
        if r.label not in ("cw", "ccw") or r.ground_truth is None:
            continue
        odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ran_with)
        errors.append(np.asarray(r.ground_truth[-1], float) - odo[-1])
        labels.append(r.label)
    if not errors:
        raise CalibrationError("no labelled CW/CCW runs with ground truth")
    return EndPoseRuns(tuple(labels), np.array(errors))


def _dataset_name(recs) -> str:
    return recs[0].dataset


def _real_squares(fn: Callable) -> Callable:
    def real(datasets: dict) -> list:
        out = []
        for recs in datasets.get("square", []):
            side = recs[0].meta.get("side_m")
            if not side:
                continue
            out.append(
                (_dataset_name(recs), fn(square_end_pose_runs(recs), side, recs[0].ran_with))
            )
        return out

    return real


def _real_heading(runs, side, ran_with):
    return calibrate_heading(runs, 4, side, ran_with)


def _real_umbmark(form: str) -> Callable:
    return lambda runs, side, ran_with: calibrate_umbmark(runs, side, ran_with, form)


def _real_bcpt(datasets: dict) -> list:
    # Only the calibration circle data set (see REALDATA_SPLIT); OptiOdom's circular runs are four
    # 180-degree arcs of decreasing radius, so every arc is fitted on its own.
    out = []
    for recs in datasets.get("circular-calibration", []):
        out.append((_dataset_name(recs), calibrate_bcpt_recordings(recs, arc_rad=math.pi)))
    return out


def _real_ivanjko(datasets: dict) -> list:
    return [
        (_dataset_name(r), calibrate_ivanjko_recordings(r)) for r in datasets.get("ivanjko", [])
    ]


def _real_fit(fit, kinds: tuple[str, ...], pooled: bool = False) -> Callable:
    """A recording fit of tracked runs (scale included): one per data set of ``kinds``, or one
    over all of them pooled (each run dead-reckoned with the fitted geometry)."""

    def real(datasets: dict) -> list:
        sets = [recs for k in kinds for recs in datasets.get(k, [])]
        if pooled and sets:
            sets = [[r for recs in sets for r in recs]]
        out = []
        for recs in sets:
            ran = recs[0].ran_with
            g = fit(recs, ran).geometry
            E_b = g.wheelbase_m / ran.wheelbase_m
            E_d = g.diameter_ratio / ran.diameter_ratio
            out.append((_dataset_name(recs), CalibrationResult("fit", E_b, E_d, ran, g)))
        return out

    return real


METHOD_REGISTRY: list[MethodEntry] = [
    MethodEntry(
        "heading",
        "square CW+CCW (final heading)",
        _square_plan,
        _heading_estimate,
        _real_squares(_real_heading),
    ),
    *[
        MethodEntry(
            f"umbmark-{form}",
            f"square CW+CCW (final {'x and y' if form == 'mean' else form})",
            _square_plan,
            _umbmark_estimate(form),
            _real_squares(_real_umbmark(form)),
        )
        for form in ("x", "y", "mean")
    ],
    MethodEntry(
        "bcpt",
        "circles CW+CCW (tracked radius)",
        _circle_plan,
        _bcpt_estimate,
        _real_bcpt,
    ),
    MethodEntry(
        "ivanjko",
        "straight runs + 180 deg spins CW/CCW",
        _ivanjko_plan,
        _ivanjko_estimate,
        _real_ivanjko,
    ),
    MethodEntry(
        "linear",
        "open arcs r=1 m CW+CCW (tracked, Antonelli least squares)",
        _open_arc_plan,
        _linear_estimate,
        _real_fit(_linear_fit, ("square", "ivanjko"), pooled=True),
    ),
    MethodEntry(
        "trajectory",
        "square CW+CCW (tracked poses, trajectory fit)",
        _tracked_square_plan,
        _trajectory_estimate,
        _real_fit(_trajectory_fit, ("square",)),
    ),
]
