"""The paper's experiment on a real robot, from recordings (``odocal reproduce --realdata``).

Jung et al. (2014) design the test track by simulation (steps 4-5), then check the design with a
real experiment: calibrate on squares of several sizes with the heading method, validate every
calibration on other runs, and compare with t-tests (Tables 1-3). This module does the same for a
robot with recorded runs (the OptiOdom robot: squares of 0.75 m and 1.7 m, held-out circles and
free paths), and asks whether the design predicted what the real calibrations did.

Real part (no randomness except the bootstrap intervals):

- Each square run's final error is actual - odometric: its ground-truth final pose minus the pose
  dead-reckoned from its wheel rotations with the ``reference`` geometry (the robot's nominal one;
  the heading method's E_b and E_d are relative to it). CW/CCW come from the data.
- Per side length, the runs of all data sets are pooled and calibrated once with the heading
  method (and UMBmark, mean form); every data set is also calibrated on its own, relative to the
  reference and, as a check, relative to the firmware values it ran with
  (:func:`odocal.calibration.squares.fit_recorded_squares`).
- Every calibration dead-reckons the held-out runs; the metric is their mean final position
  error. Intervals: a bootstrap over the calibration runs (resampled within each direction).
- Tables 2-3: the two sizes' calibrations compared on the same held-out runs, by a paired t-test
  (the same runs replayed with two parameter sets; the paper's Student test of independent
  validation drives is given beside it).

Predicted part (Monte Carlo): the robot model (nominal, systematic errors, wheel noise k and the
instrument, measured from the runs) runs the paper's procedure: n CW + n CCW runs on each
candidate square, heading calibration, validation by replaying the held-out runs' recorded wheel
rotations through the model (:mod:`odocal.core.replay`), which is exactly what the real validation
does with the real robot. Candidates: a sweep of sizes (equal runs per direction; the design's
preference) and the two real configurations (their real run counts; the predicted errors).

The verdict compares the predicted ordering and difference with the real ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..calibration.heading import calibrate_heading, heading_factors
from ..calibration.squares import direction_from_data, fit_recorded_squares
from ..calibration.turning import EffectiveWheelbase, effective_wheelbase
from ..calibration.umbmark import calibrate_umbmark, umbmark_factors
from ..core.model import Robot, WheelGeometry
from ..core.odometry import dead_reckon
from ..core.replay import chunk_rotations, replay_final_errors
from ..core.runs import EndPoseRuns
from ..core.stats import TTest, circular_mean, ttest_paired, ttest_samples
from ..errors import CalibrationError
from .metrics import leg_heading_noise_rad, leg_heading_systematic_rad, systematic_share
from .recommend import Recommendation, recommend
from .result import Candidate, ErrorSummary, rounded
from .sweep import FAST, SimulationSettings, calibrate_trials

__all__ = [
    "SquareCalibration",
    "Prediction",
    "GainPoint",
    "RealExperiment",
    "run_real_experiment",
    "square_end_errors",
    "motion_profile",
]

#: Wheel travel of one replay chunk (m): the deterministic part is exact at any size, the noise
#: covariance off by O(1/K^2).
REPLAY_CHUNK_M = 0.05
BOOTSTRAP = 300


def square_end_errors(recordings, geometry: WheelGeometry) -> EndPoseRuns:
    """Final errors (actual - odometric with ``geometry``) of recorded square runs, CW/CCW from
    the data (:func:`odocal.calibration.squares.direction_from_data`)."""
    dirs, errs = [], []
    for r in recordings:
        gt = np.asarray(r.ground_truth, dtype=float)
        d = direction_from_data(float(gt[-1, 2] - gt[0, 2]))
        if d is None:
            raise CalibrationError(f"{r.name}: not a closed square run")
        odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, geometry)
        errs.append(gt[-1] - odo[-1])
        dirs.append(d)
    return EndPoseRuns(tuple(dirs), np.array(errs))


def _final_positions(recording, d_r, d_l, b) -> np.ndarray:
    """Dead-reckoned final positions for geometries given as arrays of shape (B,): (B, 2)."""
    dpr = np.diff(recording.wheel_angle_right_rad)
    dpl = np.diff(recording.wheel_angle_left_rad)
    dr = np.outer(0.5 * np.asarray(d_r), dpr)
    dl = np.outer(0.5 * np.asarray(d_l), dpl)
    ds = 0.5 * (dr + dl)
    dth = (dr - dl) / np.asarray(b)[:, None]
    mid = np.cumsum(dth, axis=1) - 0.5 * dth
    return np.column_stack([(ds * np.cos(mid)).sum(axis=1), (ds * np.sin(mid)).sum(axis=1)])


def heldout_errors(heldout, geometry: WheelGeometry) -> np.ndarray:
    """Final position error (m) of every held-out run dead-reckoned with ``geometry`` (scalar
    or batched of shape (B,)); shape (runs,) or (runs, B)."""
    batched = np.ndim(geometry.wheelbase_m) > 0
    d_r = np.atleast_1d(np.asarray(geometry.diameter_right_m, dtype=float))
    d_l = np.atleast_1d(np.asarray(geometry.diameter_left_m, dtype=float))
    b = np.atleast_1d(np.asarray(geometry.wheelbase_m, dtype=float))
    d_r, d_l, b = np.broadcast_arrays(d_r, d_l, b)
    out = []
    for r in heldout:
        p = _final_positions(r, d_r, d_l, b)
        out.append(np.hypot(r.ground_truth[-1, 0] - p[:, 0], r.ground_truth[-1, 1] - p[:, 1]))
    arr = np.array(out)
    return arr if batched else arr[:, 0]


@dataclass(frozen=True)
class SquareCalibration:
    """One calibration from recorded squares and its held-out validation.

    Attributes
    ----------
    side_m : float
    method : str
        'heading' or 'umbmark' (mean form).
    scope : str
        'pooled' (all data sets of this side) or a data set id.
    runs_cw, runs_ccw : int
    E_b, E_d : float
        Relative to the reference geometry (the nominal one).
    E_b_ci95, E_d_ci95 : tuple or None
        Bootstrap 95 % intervals (pooled calibrations only).
    geometry : WheelGeometry
        reference.corrected(E_b, E_d).
    heldout_errors_m : ndarray, shape (runs,)
        Final position error of each held-out run.
    heldout_ci95_m : tuple or None
        Bootstrap 95 % interval of the mean held-out error (calibration uncertainty).
    ran_with : WheelGeometry or None
        Firmware values the data set ran with (per data set only).
    ran_with_geometry : WheelGeometry or None
        The same method relative to the firmware values, composed with them (the check).
    """

    side_m: float
    method: str
    scope: str
    runs_cw: int
    runs_ccw: int
    E_b: float
    E_d: float
    geometry: WheelGeometry
    heldout_errors_m: np.ndarray
    E_b_ci95: tuple[float, float] | None = None
    E_d_ci95: tuple[float, float] | None = None
    heldout_ci95_m: tuple[float, float] | None = None
    ran_with: WheelGeometry | None = None
    ran_with_geometry: WheelGeometry | None = None

    @property
    def heldout_error_m(self) -> float:
        return float(np.mean(self.heldout_errors_m))

    @property
    def turning_gain(self) -> float:
        return float(self.geometry.mean_diameter_m / self.geometry.wheelbase_m)

    def as_dict(self) -> dict:
        out = {
            "side_m": self.side_m,
            "method": self.method,
            "scope": self.scope,
            "runs_cw": self.runs_cw,
            "runs_ccw": self.runs_ccw,
            "E_b": rounded(self.E_b),
            "E_d": rounded(self.E_d),
            "E_b_ci95": None if self.E_b_ci95 is None else [rounded(v) for v in self.E_b_ci95],
            "E_d_ci95": None if self.E_d_ci95 is None else [rounded(v) for v in self.E_d_ci95],
            **{k: rounded(v) for k, v in self.geometry.as_dict().items()},
            "turning_gain": rounded(self.turning_gain),
            "heldout_error_m": rounded(self.heldout_error_m),
            "heldout_ci95_m": None
            if self.heldout_ci95_m is None
            else [rounded(v) for v in self.heldout_ci95_m],
            "heldout_errors_m": [rounded(v) for v in self.heldout_errors_m],
        }
        if self.ran_with is not None and self.ran_with_geometry is not None:
            g = self.ran_with_geometry
            out["ran_with"] = {k: rounded(v) for k, v in self.ran_with.as_dict().items()}
            out["relative_to_ran_with"] = {
                **{k: rounded(v) for k, v in g.as_dict().items()},
                "turning_gain": rounded(float(g.mean_diameter_m / g.wheelbase_m)),
                "turning_gain_difference": rounded(
                    float(g.mean_diameter_m / g.wheelbase_m) - self.turning_gain
                ),
            }
        return out


def _linear_heldout_errors(heldout, center: WheelGeometry, geos: WheelGeometry) -> np.ndarray:
    """Held-out final position errors (runs, B) for the batch ``geos``, with each run's final
    dead-reckoned position linearised about ``center`` (central differences). Bootstrap
    geometries lie within a few 0.1 % of the centre, where the quadratic term is below 1e-5 m."""
    c = np.array([center.diameter_right_m, center.diameter_left_m, center.wheelbase_m], float)
    g = np.stack(
        [
            np.asarray(geos.diameter_right_m, float),
            np.asarray(geos.diameter_left_m, float),
            np.asarray(geos.wheelbase_m, float),
        ],
        axis=1,
    )
    h = 1e-6 * c
    probes = np.vstack([c, c + np.diag(h), c - np.diag(h)])  # (7, 3)
    out = []
    for r in heldout:
        p = _final_positions(r, probes[:, 0], probes[:, 1], probes[:, 2])
        jac = (p[1:4] - p[4:7]) / (2 * h[:, None])  # (3, 2): d position / d parameter
        pos = p[0] + (g - c) @ jac
        out.append(np.hypot(r.ground_truth[-1, 0] - pos[:, 0], r.ground_truth[-1, 1] - pos[:, 1]))
    return np.array(out)


def _calibrate(method, ends: EndPoseRuns, side_m, reference):
    if method == "heading":
        return calibrate_heading(ends, 4, side_m, reference)
    return calibrate_umbmark(ends, side_m, reference, "mean")


def _bootstrap(method, ends: EndPoseRuns, side_m, reference, heldout, rng, n_boot):
    """Bootstrap over the runs of each direction: 95 % intervals of E_b, E_d and of the mean
    held-out error."""
    cw = ends.select("cw")
    ccw = ends.select("ccw")
    i_cw = rng.integers(0, len(cw), size=(n_boot, len(cw)))
    i_ccw = rng.integers(0, len(ccw), size=(n_boot, len(ccw)))
    b_ref = float(reference.wheelbase_m)
    if method == "heading":
        th_cw = circular_mean(cw[i_cw, 2], axis=-1)
        th_ccw = circular_mean(ccw[i_ccw, 2], axis=-1)
        E_b, E_d = heading_factors(th_cw, th_ccw, 4, side_m, b_ref)
    else:
        E_b, E_d = umbmark_factors(
            cw[i_cw, :2].mean(axis=1), ccw[i_ccw, :2].mean(axis=1), side_m, b_ref, "mean"
        )
    ok = np.isfinite(E_b) & np.isfinite(E_d)
    E_b, E_d = np.asarray(E_b)[ok], np.asarray(E_d)[ok]
    geos = reference.corrected(E_b, E_d)
    center = reference.corrected(float(np.median(E_b)), float(np.median(E_d)))
    mean_err = _linear_heldout_errors(heldout, center, geos).mean(axis=0)

    def ci(x):
        lo, hi = np.percentile(x, [2.5, 97.5])
        return (float(lo), float(hi))

    return ci(E_b), ci(E_d), ci(mean_err)


def _group(recordings):
    out: dict[str, list] = {}
    for r in recordings:
        out.setdefault(r.dataset, []).append(r)
    return out


def calibrate_squares(
    squares_by_side: dict[float, list],
    heldout,
    reference: WheelGeometry,
    rng: np.random.Generator,
    n_boot: int = BOOTSTRAP,
) -> list[SquareCalibration]:
    """Every real calibration (module docstring): per side, pooled and per data set, heading
    and UMBmark."""
    out = []
    for side in sorted(squares_by_side):
        runs = squares_by_side[side]
        ends = square_end_errors(runs, reference)
        for method in ("heading", "umbmark"):
            res = _calibrate(method, ends, side, reference)
            eb, ed, herr = _bootstrap(method, ends, side, reference, heldout, rng, n_boot)
            out.append(
                SquareCalibration(
                    side,
                    method,
                    "pooled",
                    ends.count("cw"),
                    ends.count("ccw"),
                    float(res.E_b),
                    float(res.E_d),
                    res.corrected,
                    heldout_errors(heldout, res.corrected),
                    eb,
                    ed,
                    herr,
                )
            )
        for name, group in _group(runs).items():
            g_ends = square_end_errors(group, reference)
            for method in ("heading", "umbmark"):
                try:
                    res = _calibrate(method, g_ends, side, reference)
                    rw = fit_recorded_squares(group, method, nominal=group[0].ran_with)
                except CalibrationError:
                    continue
                out.append(
                    SquareCalibration(
                        side,
                        method,
                        name,
                        g_ends.count("cw"),
                        g_ends.count("ccw"),
                        float(res.E_b),
                        float(res.E_d),
                        res.corrected,
                        heldout_errors(heldout, res.corrected),
                        ran_with=group[0].ran_with,
                        ran_with_geometry=rw.geometry,
                    )
                )
    return out


@dataclass(frozen=True)
class Prediction:
    """What the design (the model with the measured robot) predicts.

    Attributes
    ----------
    robot : Robot
        The model robot (nominal, systematic errors, k, instrument), running with ``reference``.
    sweep : tuple of Candidate
        Candidate squares with ``runs_per_direction`` runs each; validation error = mean
        held-out error of a replay (module docstring).
    recommendation : Recommendation
        The design's rule over ``sweep``.
    real : dict
        Side (m) -> Candidate with the real run counts.
    floor, uncalibrated : ErrorSummary
        Mean held-out error with the TRUE geometry, and with the reference (uncalibrated).
    ttest : dict
        Predicted paired t-test of the two real configurations (first side minus second):
        median t and p, share of experiments with p < 0.05, mean difference (m) and its central
        95 % range over the experiments.
    trials, runs_per_direction : int
    """

    robot: Robot
    sweep: tuple[Candidate, ...]
    recommendation: Recommendation
    real: dict
    floor: ErrorSummary
    uncalibrated: ErrorSummary
    ttest: dict
    trials: int
    runs_per_direction: int

    @property
    def preferred(self) -> Candidate:
        return self.sweep[self.recommendation.index]


def _candidates(robot, sides_m, n, trials, rng, chunks, settings) -> tuple[list, np.ndarray]:
    """Simulated calibrations on squares of ``sides_m`` (n runs per direction) validated by
    replaying the held-out chunks; returns candidates and per-run errors (C, runs, T)."""
    sides_m = np.asarray(sides_m, dtype=float)
    E_b, E_d = calibrate_trials(robot, 4, sides_m, n, trials, "heading", rng, settings)
    ok = np.isfinite(E_b) & np.isfinite(E_d)
    geos = robot.believed_geometry.corrected(np.where(ok, E_b, 1.0), np.where(ok, E_d, 1.0))
    per_run = np.stack(
        [
            replay_final_errors(c, robot.true_geometry, robot.nonsystematic, geos, rng)
            for c in chunks
        ],
        axis=1,
    )  # (C, runs, T)
    per_run[np.broadcast_to(~ok[:, None, :], per_run.shape)] = np.nan
    mean = per_run.mean(axis=1)  # (C, T)
    beta = np.abs(leg_heading_systematic_rad(robot, sides_m))
    sigma = leg_heading_noise_rad(robot, sides_m)
    share = systematic_share(beta, sigma, n)
    out = []
    for i, L in enumerate(sides_m):
        s = ErrorSummary.from_samples(mean[i])
        eb, ed = E_b[i][ok[i]], E_d[i][ok[i]]
        out.append(
            Candidate(
                sides=4,
                side_m=float(L),
                travel_m=float(4 * L),
                systematic_share=float(share[i]),
                post_error_mean_m=s.mean_m,
                post_error_std_m=s.std_m,
                post_error_ci95_m=s.ci95_m,
                E_b_mean=float(eb.mean()),
                E_b_std=float(eb.std(ddof=1)),
                E_d_mean=float(ed.mean()),
                E_d_std=float(ed.std(ddof=1)),
                trials=s.n,
                leg_heading_systematic_rad=float(beta[i]),
                leg_heading_noise_rad=float(sigma[i]),
                failed_trials=int(trials - s.n),
                post_errors_m=mean[i].copy(),
            )
        )
    return out, per_run


def predict(
    robot: Robot,
    heldout,
    real_runs_per_direction: dict[float, int],
    sweep_sides_m,
    runs_per_direction: int,
    trials: int,
    rng: np.random.Generator,
    settings: SimulationSettings = FAST,
    alpha: float = 0.05,
    tolerance: float = 0.05,
) -> Prediction:
    """The design's prediction (module docstring). ``real_runs_per_direction``: side (m) ->
    runs per direction of the real configuration (two sides, compared in that order)."""
    chunk_rad = REPLAY_CHUNK_M / (0.5 * float(robot.nominal.mean_diameter_m))
    chunks = [
        chunk_rotations(r.wheel_angle_right_rad, r.wheel_angle_left_rad, chunk_rad) for r in heldout
    ]

    def replayed(geometry):
        """Mean over the held-out runs of their replayed final errors with ``geometry``."""
        batch = _batch(geometry, trials)
        return np.mean(
            [
                replay_final_errors(c, robot.true_geometry, robot.nonsystematic, batch, rng)[0]
                for c in chunks
            ],
            axis=0,
        )

    floor = replayed(robot.true_geometry)  # in this order: they share the stream
    uncal = replayed(robot.believed_geometry)
    sweep, _ = _candidates(robot, sweep_sides_m, runs_per_direction, trials, rng, chunks, settings)
    rec = recommend(sweep, alpha, tolerance, "error")
    real = {}
    per_run = {}
    for side, n in real_runs_per_direction.items():
        cands, pr = _candidates(robot, [side], n, trials, rng, chunks, settings)
        real[side] = cands[0]
        per_run[side] = pr[0]  # (runs, T)
    (a, b) = list(real_runs_per_direction)[:2]
    d = per_run[a] - per_run[b]  # (runs, T)
    n_runs = d.shape[0]
    with np.errstate(invalid="ignore", divide="ignore"):
        t = d.mean(axis=0) / (d.std(axis=0, ddof=1) / math.sqrt(n_runs))
    from scipy.special import stdtr

    p = 2.0 * stdtr(n_runs - 1, -np.abs(t))
    diff = d.mean(axis=0)
    fin = np.isfinite(t)
    ttest = {
        "first_side_m": a,
        "second_side_m": b,
        "kind": "paired",
        "median_t": float(np.median(t[fin])),
        "median_p": float(np.median(p[fin])),
        "fraction_significant": float(np.mean(p[fin] < 0.05)),
        "fraction_first_significantly_better": float(np.mean((p[fin] < 0.05) & (diff[fin] < 0))),
        "fraction_second_significantly_better": float(np.mean((p[fin] < 0.05) & (diff[fin] > 0))),
        "fraction_first_worse": float(np.mean(diff[fin] > 0)),
        "mean_difference_m": float(np.mean(diff[fin])),
        "difference_ci95_m": [float(v) for v in np.percentile(diff[fin], [2.5, 97.5])],
    }
    return Prediction(
        robot,
        tuple(sweep),
        rec,
        real,
        ErrorSummary.from_samples(floor),
        ErrorSummary.from_samples(uncal),
        ttest,
        trials,
        runs_per_direction,
    )


def _batch(g: WheelGeometry, n: int) -> WheelGeometry:
    return WheelGeometry.unchecked(
        np.full((1, n), float(g.diameter_right_m)),
        np.full((1, n), float(g.diameter_left_m)),
        np.full((1, n), float(g.wheelbase_m)),
    )


def motion_profile(recordings, geometry: WheelGeometry) -> dict:
    """How the runs drive: 90th percentiles of the forward speed on straight stretches (m/s)
    and of the turn rate in spot turns (rad/s), from the wheel rotations."""
    v_straight, w_spot = [], []
    for r in recordings:
        dt = np.diff(np.asarray(r.time_s, dtype=float))
        vr = np.diff(r.wheel_angle_right_rad) * (0.5 * geometry.diameter_right_m) / dt
        vl = np.diff(r.wheel_angle_left_rad) * (0.5 * geometry.diameter_left_m) / dt
        k = np.ones(9) / 9
        sr, sl = np.convolve(vr, k, "same"), np.convolve(vl, k, "same")
        tot = np.abs(sr) + np.abs(sl)
        moving = tot > 0.01
        with np.errstate(invalid="ignore", divide="ignore"):
            s = np.abs(sr - sl) / tot
        v_straight.append(np.abs(0.5 * (sr + sl))[moving & (s < 0.04)])
        w_spot.append(np.abs((sr - sl) / geometry.wheelbase_m)[moving & (s >= 0.8)])

    def p90(parts):
        a = np.concatenate(parts) if parts else np.zeros(0)
        return float(np.percentile(a, 90)) if a.size >= 20 else None

    return {"straight_speed_m_s": p90(v_straight), "spot_turn_rate_rad_s": p90(w_spot)}


def closing_heading_split(recordings, reference: WheelGeometry) -> dict:
    """Where a square's closing heading error comes from: per direction, the mean odometric
    rotation (rad) and the mean heading error actual - odometric (rad) of the samples in spot
    turns and of all the others (legs, and the arcs that start or finish a turn); bands from
    :func:`odocal.calibration.turning.band_of_increments` with the reference's diameters."""
    from ..calibration.turning import band_of_increments

    acc: dict[str, list] = {"cw": [], "ccw": []}
    for r in recordings:
        gt = np.asarray(r.ground_truth, dtype=float)
        d = direction_from_data(float(gt[-1, 2] - gt[0, 2]))
        if d is None:
            continue
        band = band_of_increments(
            r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.time_s, reference
        )
        dr = np.diff(r.wheel_angle_right_rad) * (0.5 * reference.diameter_right_m)
        dl = np.diff(r.wheel_angle_left_rad) * (0.5 * reference.diameter_left_m)
        dth = (dr - dl) / reference.wheelbase_m
        err = np.diff(gt[:, 2]) - dth
        spot = band == 0
        acc[d].append([dth[spot].sum(), err[spot].sum(), dth[~spot].sum(), err[~spot].sum()])
    out = {}
    for d, rows in acc.items():
        if rows:
            m = np.mean(rows, axis=0)
            out[d] = {
                "spot_rotation_rad": float(m[0]),
                "spot_error_rad": float(m[1]),
                "other_rotation_rad": float(m[2]),
                "other_error_rad": float(m[3]),
            }
    return out


@dataclass(frozen=True)
class GainPoint:
    """One parameter set on the held-out error curve: its turning gain mean(D)/b and its mean
    held-out final error (m)."""

    label: str
    geometry: WheelGeometry
    heldout_error_m: float
    held_out: bool  # False: fitted on runs that include the held-out ones (not a validation)

    @property
    def turning_gain(self) -> float:
        return float(self.geometry.mean_diameter_m / self.geometry.wheelbase_m)

    def as_dict(self) -> dict:
        return {
            "label": self.label,
            **{k: rounded(v) for k, v in self.geometry.as_dict().items()},
            "turning_gain": rounded(self.turning_gain),
            "heldout_error_m": rounded(self.heldout_error_m),
            "held_out": self.held_out,
        }


def gain_curve(heldout, reference: WheelGeometry, gains) -> np.ndarray:
    """Mean held-out error (m) for every turning gain in ``gains``: the reference's diameters,
    wheelbase mean(D_ref) / gain."""
    gains = np.asarray(gains, dtype=float)
    geos = WheelGeometry.unchecked(
        np.full(gains.shape, float(reference.diameter_right_m)),
        np.full(gains.shape, float(reference.diameter_left_m)),
        float(reference.mean_diameter_m) / gains,
    )
    return heldout_errors(heldout, geos).mean(axis=0)


@dataclass(frozen=True)
class RealExperiment:
    """Everything ``odocal reproduce --realdata`` computes about the real robot.

    Attributes
    ----------
    reference : WheelGeometry
        The nominal geometry the final errors are dead-reckoned with.
    sides_m : tuple of float
        The square sizes, in the order compared (first minus second).
    calibrations : tuple of SquareCalibration
    ttests : dict
        Method -> {'paired': TTest, 'student': TTest, 'welch': TTest} of the pooled
        calibrations of the two sizes on the held-out runs (first minus second).
    prediction : Prediction
    heldout_names : tuple of str
    heldout_split : str
        Which runs are held out, in words.
    profiles : dict
        Side -> motion profile of its squares; 'heldout' -> of the held-out runs.
    closing : dict
        Side -> :func:`closing_heading_split` of its squares.
    gains : tuple of GainPoint
        Parameter sets on the held-out error curve (the default fit among them).
    gain_grid, gain_curve_m : ndarray
        The curve: turning gain -> mean held-out error (m), at the reference diameter ratio of
        the best square calibration.
    turning : dict
        Name -> EffectiveWheelbase (squares per side, held-out runs), all relative to
        ``turning_reference``.
    turning_reference : WheelGeometry
    """

    reference: WheelGeometry
    sides_m: tuple[float, float]
    calibrations: tuple[SquareCalibration, ...]
    ttests: dict
    prediction: Prediction
    heldout_names: tuple[str, ...]
    heldout_split: str
    profiles: dict
    closing: dict
    gains: tuple[GainPoint, ...]
    gain_grid: np.ndarray
    gain_curve_m: np.ndarray
    turning: dict
    turning_reference: WheelGeometry
    notes: tuple[str, ...] = field(default_factory=tuple)

    def calibration(self, side_m: float, method: str = "heading", scope: str = "pooled"):
        for c in self.calibrations:
            if math.isclose(c.side_m, side_m) and c.method == method and c.scope == scope:
                return c
        raise KeyError((side_m, method, scope))

    @property
    def verdict(self) -> dict:
        return verdict(self)


def _ttests(a: SquareCalibration, b: SquareCalibration) -> dict[str, TTest]:
    return {
        "paired": ttest_paired(a.heldout_errors_m, b.heldout_errors_m),
        "student": ttest_samples(a.heldout_errors_m, b.heldout_errors_m, equal_var=True),
        "welch": ttest_samples(a.heldout_errors_m, b.heldout_errors_m),
    }


def run_real_experiment(
    squares_by_side: dict[float, list],
    heldout,
    reference: WheelGeometry,
    robot: Robot,
    rng: np.random.Generator,
    *,
    trials: int = 800,
    sweep_sides_m=None,
    runs_per_direction: int | None = None,
    heldout_split: str = "",
    default_fit: WheelGeometry | None = None,
    extra_points: tuple[GainPoint, ...] = (),
    settings: SimulationSettings = FAST,
    n_boot: int = BOOTSTRAP,
) -> RealExperiment:
    """The real experiment and its prediction (module docstring).

    Parameters
    ----------
    squares_by_side : dict
        Side length (m) -> recorded square runs (all data sets); exactly two sides.
    heldout : list of Recording
        The validation runs (never used to calibrate).
    reference : WheelGeometry
        The nominal geometry (the heading method's E_b, E_d are relative to it).
    robot : Robot
        The model robot for the prediction (measured from the runs; running with ``reference``).
    sweep_sides_m : array_like, optional
        Candidate sides of the design (default 0.25 ... 3 m in 0.25 m steps plus the real sides).
    runs_per_direction : int, optional
        Runs per direction of the sweep (default the smaller real count).
    default_fit : WheelGeometry, optional
        odocal's default calibration of the same robot (for the gain curve).
    extra_points : tuple of GainPoint
        More parameter sets to place on the gain curve (e.g. published ones).
    """
    if len(squares_by_side) != 2:
        raise CalibrationError(
            f"the real experiment compares two square sizes, got {len(squares_by_side)}"
        )
    streams = rng.spawn(2)
    sides: tuple[float, float] = tuple(sorted(squares_by_side))  # type: ignore[assignment]
    cals = calibrate_squares(squares_by_side, heldout, reference, streams[0], n_boot)
    by = {(c.side_m, c.method): c for c in cals if c.scope == "pooled"}
    ttests = {m: _ttests(by[(sides[0], m)], by[(sides[1], m)]) for m in ("heading", "umbmark")}
    counts = {}
    for s in sides:
        ends = square_end_errors(squares_by_side[s], reference)
        counts[s] = min(ends.count("cw"), ends.count("ccw"))
    if sweep_sides_m is None:
        sweep_sides_m = np.unique(np.r_[np.arange(1, 13) * 0.25, list(sides)])
    n = runs_per_direction or min(counts.values())
    pred = predict(robot, heldout, counts, sweep_sides_m, n, trials, streams[1], settings)
    profiles: dict = {s: motion_profile(squares_by_side[s], reference) for s in sides}
    profiles["heldout"] = motion_profile(heldout, reference)
    closing = {s: closing_heading_split(squares_by_side[s], reference) for s in sides}
    points = [
        GainPoint(
            f"heading, {s:g} m squares",
            by[(s, "heading")].geometry,
            by[(s, "heading")].heldout_error_m,
            True,
        )
        for s in sides
    ] + [
        GainPoint(
            f"UMBmark, {s:g} m squares",
            by[(s, "umbmark")].geometry,
            by[(s, "umbmark")].heldout_error_m,
            True,
        )
        for s in sides
    ]
    if default_fit is not None:
        points.append(
            GainPoint(
                "odocal fit default (trajectory)",
                default_fit,
                float(heldout_errors(heldout, default_fit).mean()),
                True,
            )
        )
    points += list(extra_points)
    best = min((by[(s, "heading")] for s in sides), key=lambda c: c.heldout_error_m)
    g0 = best.turning_gain
    grid = np.linspace(g0 * 0.99, g0 * 1.01, 81)
    curve = gain_curve(heldout, best.geometry, grid)
    turn_ref = default_fit or best.geometry
    turning: dict[str, EffectiveWheelbase] = {}
    for s in sides:
        turning[f"{s:g} m squares"] = effective_wheelbase(squares_by_side[s], turn_ref)
    turning["held-out runs"] = effective_wheelbase(heldout, turn_ref)
    return RealExperiment(
        reference,
        sides,
        tuple(cals),
        ttests,
        pred,
        tuple(r.name for r in heldout),
        heldout_split,
        profiles,
        closing,
        tuple(points),
        grid,
        curve,
        turning,
        turn_ref,
    )


def verdict(exp: RealExperiment) -> dict:
    """Did the design predict the real ordering and the size of the difference? Numbers and the
    plain-words answer (the report's text is built from these)."""
    a, b = exp.sides_m
    ca, cb = exp.calibration(a), exp.calibration(b)
    pred = exp.prediction
    pa, pb = pred.real[a], pred.real[b]
    real_diff = ca.heldout_error_m - cb.heldout_error_m
    pred_diff = pred.ttest["mean_difference_m"]
    lo, hi = pred.ttest["difference_ci95_m"]
    paired = exp.ttests["heading"]["paired"]
    real_better = a if real_diff < 0 else b
    # what one experiment like the real one shows: a significant ordering (paired t, 5 %) or none;
    # the model predicts an ordering when most of its simulated experiments show it
    real_outcome = real_better if paired.p_two_sided < 0.05 else None
    t = pred.ttest
    pred_outcome = (
        a
        if t["fraction_first_significantly_better"] > 0.5
        else b
        if t["fraction_second_significantly_better"] > 0.5
        else None
    )
    pred_better = a if pred_diff < 0 else b
    ordering_predicted = real_outcome == pred_outcome
    within = lo <= real_diff <= hi
    preferred = pred.preferred.side_m
    return {
        "preferred_side_m": preferred,
        "predicted_error_m": {f"{a:g}": pa.post_error_mean_m, f"{b:g}": pb.post_error_mean_m},
        "real_error_m": {f"{a:g}": ca.heldout_error_m, f"{b:g}": cb.heldout_error_m},
        "predicted_difference_m": pred_diff,
        "predicted_difference_ci95_m": [lo, hi],
        "real_difference_m": real_diff,
        "real_paired_t": paired.t,
        "real_paired_p": paired.p_two_sided,
        "predicted_better_side_m": pred_better,
        "predicted_outcome": (
            "no significant difference" if pred_outcome is None else f"{pred_outcome:g} m better"
        ),
        "real_better_side_m": real_better,
        "real_outcome": (
            "no significant difference" if real_outcome is None else f"{real_outcome:g} m better"
        ),
        "ordering_predicted": ordering_predicted,
        "difference_within_prediction": within,
        "real_below_predicted_floor": min(ca.heldout_error_m, cb.heldout_error_m)
        < pred.floor.mean_m,
    }


def _ttest_dict(t: TTest) -> dict:
    return {
        "kind": t.kind,
        "t": rounded(t.t),
        "df": rounded(t.df),
        "p_two_sided": rounded(t.p_two_sided),
        "mean_difference_m": rounded(t.mean_difference),
        "mean_a_m": rounded(t.mean_a),
        "mean_b_m": rounded(t.mean_b),
        "n": t.n_a,
    }


def verdict_text(exp: RealExperiment) -> str:
    """The verdict in plain words, from the numbers (:func:`verdict`)."""
    v = verdict(exp)
    a, b = exp.sides_m
    pred = exp.prediction
    pa, pb = pred.real[a], pred.real[b]
    lo, hi = v["predicted_difference_ci95_m"]
    mm = 1000.0
    better, worse = (b, a) if v["real_better_side_m"] == b else (a, b)
    answer = (
        "Yes"
        if v["ordering_predicted"] and v["difference_within_prediction"]
        else "Partly"
        if v["ordering_predicted"] or v["difference_within_prediction"]
        else "No"
    )
    pa_, pb_ = exp.profiles[a], exp.profiles[b]
    ca, cb = exp.closing.get(a, {}), exp.closing.get(b, {})

    def spot_rot(c):
        vals = [abs(x["spot_rotation_rad"]) for x in c.values()]
        return sum(vals) / len(vals) if vals else math.nan

    differ = any(
        x is not None and y is not None and abs(x / y - 1) > 0.2
        for x, y in (
            (pa_["straight_speed_m_s"], pb_["straight_speed_m_s"]),
            (pa_["spot_turn_rate_rad_s"], pb_["spot_turn_rate_rad_s"]),
        )
    )
    gain_gap = 100 * abs(exp.calibration(a).turning_gain / exp.calibration(b).turning_gain - 1)
    eb_gap = abs(exp.calibration(a).E_b - exp.calibration(b).E_b) / max(pa.E_b_std, pb.E_b_std)
    ta = exp.turning.get(f"{a:g} m squares")
    tb = exp.turning.get(f"{b:g} m squares")
    th = exp.turning.get("held-out runs")
    spot = [
        x.band("spot").wheelbase_m for x in (ta, tb) if x is not None and x.band("spot").excited
    ]
    arcs = [
        e.wheelbase_m
        for e in (th.bands if th is not None else ())
        if e.band in ("tight", "wide") and e.excited and e.wheelbase_m is not None
    ]
    best = min(exp.gains, key=lambda g: g.heldout_error_m) if exp.gains else None
    text = [
        f"{answer}. The design (the model with the robot measured from its runs) prefers "
        f"{pred.preferred.side_m:g} m squares and predicts a mean held-out error of "
        f"{pa.post_error_mean_m * mm:.1f} mm after calibrating on the {a:g} m squares "
        f"({pa.trials} simulated experiments, {exp.calibration(a).runs_cw} + "
        f"{exp.calibration(a).runs_ccw} runs) and {pb.post_error_mean_m * mm:.1f} mm after the "
        f"{b:g} m squares ({exp.calibration(b).runs_cw} + {exp.calibration(b).runs_ccw} runs): "
        f"a difference of {v['predicted_difference_m'] * mm:+.1f} mm ({a:g} m minus {b:g} m; 95 % "
        f"of simulated experiments between {lo * mm:+.1f} and {hi * mm:+.1f} mm, significant in "
        f"{100 * pred.ttest['fraction_significant']:.0f} %). The real calibrations gave "
        f"{v['real_error_m'][f'{a:g}'] * mm:.1f} mm and {v['real_error_m'][f'{b:g}'] * mm:.1f} mm: "
        f"the {better:g} m squares were better by {abs(v['real_difference_m']) * mm:.1f} mm "
        f"(paired t = {v['real_paired_t']:.2f}, p = {v['real_paired_p']:.2g}). The model "
        + (
            f"predicts that outcome ({v['predicted_outcome']} in most simulated experiments)"
            if v["ordering_predicted"]
            else f"predicts {v['predicted_outcome']} for an experiment like this one, the real "
            f"one shows {v['real_outcome']}"
        )
        + (
            ", and the real difference lies within its range."
            if v["difference_within_prediction"]
            else ", and the real difference lies far outside its range."
        ),
        f"Why: the two sizes were {'not ' if differ else ''}driven alike. The {a:g} m squares "
        f"were driven at {_num(pa_['straight_speed_m_s'], '.3f')} m/s with spot turns at "
        f"{_num(pa_['spot_turn_rate_rad_s'], '.2f')} rad/s, the {b:g} m squares at "
        f"{_num(pb_['straight_speed_m_s'], '.3f')} m/s and "
        f"{_num(pb_['spot_turn_rate_rad_s'], '.2f')} rad/s. Each square's closing heading, which "
        "the heading method reads, includes how the controller ends a turn: per run the "
        f"{a:g} m squares {_turn_ending(spot_rot(ca))}, the {b:g} m squares "
        f"{_turn_ending(spot_rot(cb))} (2 pi = 6.28 rad). The calibrated turning gain "
        f"mean(D)/b differs by {gain_gap:.2f} % between the sizes, {eb_gap:.0f} "
        "times the calibration scatter the model predicts.",
    ]

    def span(vals):
        lo_, hi_ = min(vals) * mm, max(vals) * mm
        return f"{lo_:.1f}" if f"{lo_:.1f}" == f"{hi_:.1f}" else f"{lo_:.1f}-{hi_:.1f}"

    if spot and arcs:
        text.append(
            f"The robot turns differently on arcs than on the spot: its effective wheelbase (at "
            f"the diameters of odocal's fit) is {span(spot)} mm in "
            f"the squares' spot turns and {span(arcs)} mm on the "
            "held-out runs' arcs, which are most of what the held-out runs turn. The model has "
            "one wheelbase for every motion and every session, so it cannot predict which "
            "square size measures the turning the held-out runs need."
        )
    if v["real_below_predicted_floor"]:
        text.append(
            f"The model also overstates the noise: its floor (the held-out error with the TRUE "
            f"parameters) is {pred.floor.mean_m * mm:.1f} mm, above the best real result. Its k "
            "comes from the squares' run-to-run scatter, much of which is spot-turn scatter; the "
            "held-out runs mostly drive arcs, whose scatter is smaller."
        )
    if best is not None:
        text.append(
            "What decides the held-out error is one number, the turning gain: with the diameter "
            f"ratio fixed, the held-out error is smallest, {np.nanmin(exp.gain_curve_m) * mm:.1f} "
            f"mm, at mean(D)/b = {exp.gain_grid[int(np.nanargmin(exp.gain_curve_m))]:.5f}; every "
            "calibration's error follows from its distance to it (figure)."
        )
    return "\n\n".join(text)


def _turn_ending(spot_rotation_rad: float) -> str:
    """How a square's turns end, from its odometric rotation on the spot per run."""
    if not math.isfinite(spot_rotation_rad):
        return "(turn endings unknown)"
    full = 2 * math.pi
    if spot_rotation_rad > 1.005 * full:
        return (
            f"turned {spot_rotation_rad:.2f} rad on the spot, more than a full turn, and turned "
            "back on the legs"
        )
    if spot_rotation_rad < 0.995 * full:
        return (
            f"turned {spot_rotation_rad:.2f} rad on the spot and finished the turns on the legs' "
            "arcs"
        )
    return f"turned {spot_rotation_rad:.2f} rad on the spot, about a full turn"


def _num(v, fmt):
    return "-" if v is None else format(v, fmt)


def experiment_dict(exp: RealExperiment) -> dict:
    """The ``real_experiment`` object of ``odocal reproduce --realdata --json``."""
    a, b = exp.sides_m
    pred = exp.prediction
    v = verdict(exp)
    heading = exp.ttests["heading"]
    return {
        "reference": {k: rounded(x) for k, x in exp.reference.as_dict().items()},
        "relative_to": "final errors dead-reckoned with the reference (nominal) geometry; E_b "
        "and E_d are relative to it",
        "heldout": {
            "split": exp.heldout_split,
            "runs": list(exp.heldout_names),
            "count": len(exp.heldout_names),
        },
        "squares": [exp.calibration(s).as_dict() for s in exp.sides_m],
        "umbmark": [exp.calibration(s, "umbmark").as_dict() for s in exp.sides_m],
        "per_data_set": [c.as_dict() for c in exp.calibrations if c.scope != "pooled"],
        "design": {
            "preferred_side_m": pred.preferred.side_m,
            "predicted_error_m": {
                f"{s:g}": rounded(pred.real[s].post_error_mean_m) for s in exp.sides_m
            },
            "predicted_error_std_m": {
                f"{s:g}": rounded(pred.real[s].post_error_std_m) for s in exp.sides_m
            },
            "predicted_E_b": {
                f"{s:g}": [rounded(pred.real[s].E_b_mean), rounded(pred.real[s].E_b_std)]
                for s in exp.sides_m
            },
            "runs_per_direction": {
                f"{s:g}": min(exp.calibration(s).runs_cw, exp.calibration(s).runs_ccw)
                for s in exp.sides_m
            },
            "sweep_runs_per_direction": pred.runs_per_direction,
            "trials": pred.trials,
            "floor_m": rounded(pred.floor.mean_m),
            "uncalibrated_m": rounded(pred.uncalibrated.mean_m),
            "sweep": [
                {
                    "side_m": c.side_m,
                    "post_error_mean_m": rounded(c.post_error_mean_m),
                    "post_error_std_m": rounded(c.post_error_std_m),
                    "E_b_mean": rounded(c.E_b_mean),
                    "E_b_std": rounded(c.E_b_std),
                    "E_d_std": rounded(c.E_d_std),
                }
                for c in pred.sweep
            ],
            "predicted_ttest": {
                k: (rounded(x) if isinstance(x, float) else x) for k, x in pred.ttest.items()
            },
            "robot": {
                "systematic": dataclass_dict(pred.robot.systematic),
                "nonsystematic": dataclass_dict(pred.robot.nonsystematic),
                "measurement": {
                    "sigma_xy_m": rounded(pred.robot.measurement.sigma_xy_m),
                    "sigma_theta_deg": rounded(
                        math.degrees(pred.robot.measurement.sigma_theta_rad)
                    ),
                },
            },
        },
        "ttest": {
            **_ttest_dict(heading["paired"]),
            "first_side_m": a,
            "second_side_m": b,
            "method": "heading",
            "student": _ttest_dict(heading["student"]),
            "welch": _ttest_dict(heading["welch"]),
        },
        "ttest_umbmark": {
            **_ttest_dict(exp.ttests["umbmark"]["paired"]),
            "student": _ttest_dict(exp.ttests["umbmark"]["student"]),
        },
        "verdict": {
            **{k: (rounded(x) if isinstance(x, float) else x) for k, x in v.items()},
            "text": verdict_text(exp),
        },
        "motion": {
            (f"{k:g}" if isinstance(k, float) else k): val for k, val in exp.profiles.items()
        },
        "closing_heading": {f"{k:g}": val for k, val in exp.closing.items()},
        "turning_gain": {
            "points": [g.as_dict() for g in exp.gains],
            "curve_gain": [rounded(x) for x in exp.gain_grid],
            "curve_heldout_error_m": [rounded(x) for x in exp.gain_curve_m],
        },
        "effective_wheelbase": {k: e.as_dict() for k, e in exp.turning.items()},
    }


def dataclass_dict(obj) -> dict:
    from dataclasses import asdict

    return {k: rounded(x) for k, x in asdict(obj).items()}
