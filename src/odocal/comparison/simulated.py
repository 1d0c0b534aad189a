"""The simulated comparison: every method on one simulated robot, over seeded Monte-Carlo trials.

See :mod:`odocal.comparison.methods` for the registry and the budget. Validation: with each trial's
calibrated parameters, the robot drives the validation track (the 4 m square CCW by default) once,
with noise; we report its final position error, and the same run without noise (the systematic
residual the calibration left).
"""

from __future__ import annotations

import zlib
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..core.model import NonSystematicError, Robot, WheelGeometry
from ..core.simulate import (
    commanded_wheel_angles,
    drive,
    measure,
    measure_track,
    odometric_pose,
    simulate,
)
from ..core.tracks import Track, polygon
from ..errors import CalibrationError
from .methods import METHOD_REGISTRY, Budget, GroupData, MethodEntry, RunGroup

__all__ = [
    "ErrorStats",
    "Distribution",
    "MethodStats",
    "SimulatedComparison",
    "compare_simulated",
    "simulate_group",
]


@dataclass(frozen=True)
class ErrorStats:
    """Bias (mean) and spread (std, ddof = 1) of a relative error over the finite trials; None
    where there are too few."""

    bias: float | None
    std: float | None

    @classmethod
    def of(cls, values: np.ndarray) -> ErrorStats:
        """The bias and spread of the finite entries of ``values``."""
        v = values[np.isfinite(values)]
        if len(v) == 0:
            return cls(None, None)
        return cls(float(v.mean()), float(v.std(ddof=1)) if len(v) > 1 else None)

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {"bias": self.bias, "std": self.std}


@dataclass(frozen=True)
class Distribution:
    """Mean, std (ddof = 1) and 95th percentile of a sample (None where there are too few)."""

    mean: float | None
    std: float | None
    p95: float | None

    @classmethod
    def of(cls, values: np.ndarray, finite_only: bool = True) -> Distribution:
        """The distribution of ``values`` (of their finite entries with ``finite_only``)."""
        v = values[np.isfinite(values)] if finite_only else values
        if len(v) == 0:
            return cls(None, None, None)
        return cls(
            float(v.mean()),
            float(v.std(ddof=1)) if len(v) > 1 else None,
            float(np.quantile(v, 0.95)),
        )

    def as_dict(self) -> dict:
        """JSON-ready."""
        return {"mean": self.mean, "std": self.std, "p95": self.p95}


@dataclass(frozen=True)
class MethodStats:
    """One method's numbers over the trials (errors relative to the TRUE geometry).

    E_b_error = b_cal / b_true - 1; E_d_error = (D_R/D_L)_cal / (D_R/D_L)_true - 1;
    E_s_error = mean D_cal / mean D_true - 1 (dimensionless). final_error_m: validation final
    position error (m) per trial; systematic_error_m: the same run without noise.
    """

    name: str
    drives: str
    sizes: dict[str, float]
    runs: int
    travel_m: float
    footprint_m: float
    failed: int
    E_b_error: np.ndarray
    E_d_error: np.ndarray
    E_s_error: np.ndarray
    final_error_m: np.ndarray
    systematic_error_m: np.ndarray

    @property
    def E_b_stats(self) -> ErrorStats:
        """Bias and spread of E_b_error over the trials (dimensionless)."""
        return ErrorStats.of(self.E_b_error)

    @property
    def E_d_stats(self) -> ErrorStats:
        """Bias and spread of E_d_error over the trials (dimensionless)."""
        return ErrorStats.of(self.E_d_error)

    @property
    def E_s_stats(self) -> ErrorStats:
        """Bias and spread of E_s_error over the trials (dimensionless)."""
        return ErrorStats.of(self.E_s_error)

    @property
    def final_error(self) -> Distribution:
        """The validation final position error over the trials (m)."""
        return Distribution.of(self.final_error_m)

    @property
    def systematic_error(self) -> Distribution:
        """The same without noise: the systematic residual of the calibration (m)."""
        return Distribution.of(self.systematic_error_m)

    def summary(self) -> dict:
        """JSON-ready (one entry of ``methods`` in ``odocal compare --json``): what the method
        drives and costs (m), its trials' failures, errors and final position errors (m)."""
        return {
            "name": self.name,
            "drives": self.drives,
            "sizes": {k: float(v) for k, v in self.sizes.items()},
            "runs": self.runs,
            "travel_m": self.travel_m,
            "footprint_m": self.footprint_m,
            "failed_trials": self.failed,
            "E_b_error": self.E_b_stats.as_dict(),
            "E_d_error": self.E_d_stats.as_dict(),
            "E_s_error": self.E_s_stats.as_dict(),
            "final_error_m": self.final_error.as_dict(),
            "systematic_final_error_m": self.systematic_error.as_dict(),
        }


@dataclass(frozen=True)
class SimulatedComparison:
    """Every method on one simulated robot: the trials and seed, the budget (runs, wheel travel
    in m), the validation track's name, the uncalibrated (nominal) validation errors per trial
    and without noise (m), and each method's :class:`MethodStats`."""

    robot: Robot
    trials: int
    seed: int
    budget_runs: int
    budget_travel_m: float
    validation: str
    nominal_final_error_m: np.ndarray
    nominal_systematic_error_m: float
    methods: tuple[MethodStats, ...]

    @property
    def nominal_final_error(self) -> Distribution:
        """The uncalibrated robot's validation final position error over the trials (m)."""
        return Distribution.of(self.nominal_final_error_m, finite_only=False)


def _method_rng(seed: int, name: str) -> np.random.Generator:
    # One stream per (seed, method name): adding a method to the registry changes no other's draws.
    return np.random.default_rng([seed, zlib.crc32(name.encode())])


def simulate_group(
    group: RunGroup, robot: Robot, trials: int, rng: np.random.Generator, max_step_m: float
) -> GroupData:
    """Simulated measurements of ``group`` over ``trials`` trials (see :class:`GroupData`)."""
    n = trials * group.runs
    if not group.points:
        res = simulate(group.track, robot, n, rng, max_step_m=max_step_m)
        errors = measure(res.errors, robot, rng).reshape(trials, group.runs, 3)
        return GroupData(group, errors + np.asarray(odometric_pose(group.track)), errors)
    # Fixed increments per segment, so that the encoder readings are known at every sample;
    # the poses are kept at about 200 tracker samples only (the last one included).
    steps, angles = commanded_wheel_angles(group.track, robot.believed_geometry, max_step_m)
    k = len(angles)
    idx = np.unique(np.r_[np.arange(0, k, max(1, k // 200)), k - 1])
    res = simulate(group.track, robot, n, rng, steps_per_segment=steps, trajectory=idx)
    errors = measure(res.errors, robot, rng).reshape(trials, group.runs, 3)
    final = errors + np.asarray(odometric_pose(group.track))
    assert res.trajectory is not None  # asked for with ``trajectory=idx``
    traj = measure_track(res.trajectory, robot, rng)
    traj = traj.reshape(trials, group.runs, len(idx), 3)
    return GroupData(group, final, errors, traj[..., :2], traj, angles[idx])


def _validate(robot: Robot, geometry: WheelGeometry, track: Track, rng, max_step_m: float):
    m = np.size(geometry.wheelbase_m)
    noisy = simulate(track, robot.with_believed(geometry), m, rng, max_step_m=max_step_m)
    clean = drive(
        track, robot.true_geometry, geometry, NonSystematicError(), m, None, max_step_m=max_step_m
    )
    return np.hypot(*noisy.errors[:, :2].T), np.hypot(*clean.errors[:, :2].T)


def compare_simulated(
    robot: Robot,
    trials: int = 200,
    seed: int = 0,
    budget: Budget | None = None,
    validation: Track | None = None,
    methods: list[MethodEntry] | None = None,
    max_step_m: float = 0.01,
    progress: Callable[[int, int, str], None] | None = None,
) -> SimulatedComparison:
    """Run every method in ``methods`` (default :data:`METHOD_REGISTRY`) on ``robot`` over
    ``trials`` Monte-Carlo trials (vectorised) and validate each trial's calibration on
    ``validation`` (default: the 4 m square CCW). Seeded: the same arguments give the same
    numbers. ``progress(done, total, method)`` is called after each method."""
    if trials < 2:
        raise CalibrationError(f"trials must be >= 2, got {trials}")
    budget = budget or Budget()
    validation = validation or polygon(4, 4.0, "ccw")
    methods = METHOD_REGISTRY if methods is None else methods
    ran_with = robot.believed_geometry
    true = robot.true_geometry
    b_hat = float(np.mean(ran_with.wheelbase_m))
    stats = []
    for k, entry in enumerate(methods):
        rng = _method_rng(seed, entry.name)
        groups = entry.plan(budget, robot)
        data = {g.label: simulate_group(g, robot, trials, rng, max_step_m) for g in groups}
        est = entry.estimate(data, ran_with)
        d_r, d_l, b = (np.broadcast_to(np.asarray(v, float), (trials,)) for v in est)
        ok = np.isfinite(d_r) & np.isfinite(d_l) & np.isfinite(b) & (d_r > 0) & (d_l > 0) & (b > 0)
        fin = np.full(trials, np.nan)
        sysf = np.full(trials, np.nan)
        if ok.any():
            geom = WheelGeometry(d_r[ok], d_l[ok], b[ok])
            fin[ok], sysf[ok] = _validate(robot, geom, validation, rng, max_step_m)
        with np.errstate(invalid="ignore", divide="ignore"):
            e_b = np.where(ok, b / true.wheelbase_m - 1.0, np.nan)
            e_d = np.where(ok, (d_r / d_l) / true.diameter_ratio - 1.0, np.nan)
            e_s = np.where(ok, 0.5 * (d_r + d_l) / true.mean_diameter_m - 1.0, np.nan)
        sizes = {}
        for g in groups:
            sizes.update(g.size)
        stats.append(
            MethodStats(
                entry.name,
                entry.drives,
                sizes,
                sum(g.runs for g in groups),
                sum(g.runs * g.track.mean_wheel_travel_m(b_hat) for g in groups),
                max(g.track.footprint_m() for g in groups),
                int((~ok).sum()),
                e_b,
                e_d,
                e_s,
                fin,
                sysf,
            )
        )
        if progress is not None:
            progress(k + 1, len(methods), entry.name)
    rng = _method_rng(seed, "nominal")
    nominal = WheelGeometry(
        *(
            np.full(trials, float(np.mean(v)))
            for v in (ran_with.diameter_right_m, ran_with.diameter_left_m, ran_with.wheelbase_m)
        )
    )
    nom, nom_sys = _validate(robot, nominal, validation, rng, max_step_m)
    return SimulatedComparison(
        robot,
        trials,
        seed,
        budget.runs,
        budget.total_travel_m(robot),
        validation.name,
        nom,
        float(nom_sys[0]),
        tuple(stats),
    )
