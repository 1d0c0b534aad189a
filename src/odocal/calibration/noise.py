"""Non-systematic error parameters k_r, k_l from repeated straight runs (methods-notes 3.5).

k is in METRES (the paper's and Siegwart's form: a wheel's travel ds gets noise of variance
k |ds|). Chong & Kleeman's own k, in m^0.5, is the square root: k_here = k_CK^2.

Two protocols, both driven ``N`` times with the direction ``fwd`` in RUNS.csv:

- out-and-back d: forward d, then backward d without turning. The robot retraces its own arc, so
  systematic errors cancel exactly and the spread is purely random::

      k_r + k_l = b^2 s_theta^2 / (2 d),   k_r - k_l = b s_xtheta / d

- straight d: forward d only (systematic curvature only shifts the mean)::

      k_r + k_l = b^2 s_theta^2 / d,       k_r - k_l = 2 b s_xtheta / d

with unbiased (ddof = 1) sample (co)variances over the runs. (N - 1) s^2 / sigma^2 is chi-square
with N - 1 degrees of freedom, which gives the 95 % interval. The instrument's heading variance
(ROBOT.yaml ``measurement``) is subtracted from s_theta^2 when it is known.

The k_r - k_l formulas above hold for a straight mean path only: a systematic curvature (E_d != 1)
couples the along-track error x to the heading, and already E_d = 1.004 over 10 m flips the sign
of s_xtheta. So k_r - k_l is solved from cov(x, theta) = k_r a_r + k_l a_l with the coefficients
a propagated (eqs. (8)-(10)) along the mean path: its curvature is the mean heading / d for
straight runs, and must be given (from the robot's systematic errors) for out-and-back runs,
whose end poses cannot show it. s_xtheta is small and noisy, so k_r and k_l are reported only when
the standard error of k_r - k_l is below a quarter of k_r + k_l (otherwise None, with the reason).
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable
from dataclasses import dataclass, field

import numpy as np

from ..core.covariance import propagate, propagate_increments
from ..core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from ..core.odometry import wheel_travel
from ..core.recording import Recording
from ..core.runs import EndPoseRuns
from ..core.tracks import out_and_back, straight_line
from ..errors import CalibrationError

__all__ = [
    "NoiseEstimate",
    "estimate_k",
    "RecordedNoise",
    "estimate_k_from_recordings",
    "refuse_without_repeats",
    "tracker_noise",
    "NOISE_TRACKS",
    "MIN_RUNS",
    "RECOMMENDED_RUNS",
]

NOISE_TRACKS = ("out-and-back", "straight")
NO_REPEATS = (
    "no group of repeated runs (two or more runs of one track in one data set or folder): k "
    "needs the spread of repeats"
)
MIN_RUNS = 3
RECOMMENDED_RUNS = 10
# A check whose statistic exceeds this many standard errors is "obvious" (an error unless forced).
_OBVIOUS_SE = 5.0
# The lateral-spread consistency check warns beyond this many (approximate) standard errors.
_LATERAL_SE = 4.0


@dataclass(frozen=True)
class NoiseEstimate:
    """k_r + k_l (and k_r, k_l where identifiable) from repeated runs.

    Attributes
    ----------
    track : str
        'out-and-back' or 'straight'.
    distance_m, wheelbase_m : float
        Run length d and wheelbase b used in the estimators (m).
    runs : int
    k_sum_m : float
        k_r + k_l (m).
    k_sum_ci95_m : tuple of float
        95 % chi-square interval of k_r + k_l (m).
    k_diff_m, k_diff_se_m : float
        k_r - k_l (m) and its approximate standard error (m).
    k_r_m, k_l_m : float or None
        Separate values, None when not identifiable (``split_note`` says why).
    theta_mean_rad, theta_std_rad : float
        Mean and sample std (ddof = 1) of the final heading errors (rad).
    measurement_var_theta_rad2 : float
        Instrument heading variance subtracted from s_theta^2 (rad^2).
    warnings : tuple of str
        Everything a user should know before trusting the numbers.
    """

    track: str
    distance_m: float
    wheelbase_m: float
    runs: int
    k_sum_m: float
    k_sum_ci95_m: tuple[float, float]
    k_diff_m: float
    k_diff_se_m: float
    k_r_m: float | None
    k_l_m: float | None
    split_note: str
    theta_mean_rad: float
    theta_std_rad: float
    measurement_var_theta_rad2: float
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def as_dict(self) -> dict:
        """The JSON contract of ``odocal noise --json`` (plus extra keys)."""
        return {
            "k_sum_m": self.k_sum_m,
            "k_sum_ci95": list(self.k_sum_ci95_m),
            "k_r_m": self.k_r_m,
            "k_l_m": self.k_l_m,
            "runs": self.runs,
            "track": self.track,
            "distance_m": self.distance_m,
            "wheelbase_m": self.wheelbase_m,
            "k_diff_m": self.k_diff_m,
            "k_diff_se_m": self.k_diff_se_m,
            "k_split_note": self.split_note,
            "k_each_m": self.k_sum_m / 2,
            "k_each_chong_kleeman_m05": math.sqrt(self.k_sum_m / 2),
            "theta_mean_deg": math.degrees(self.theta_mean_rad),
            "theta_std_deg": math.degrees(self.theta_std_rad),
            "measurement_var_theta_rad2": self.measurement_var_theta_rad2,
            "warnings": list(self.warnings),
        }


def _interval_width(ci: tuple[float, float]) -> str:
    """How wide the 95 % interval of k is, in words: the factor between its ends, or, when its
    lower end is 0 (the spread not told apart from the instrument's noise) or a factor beyond
    1000, its two ends."""
    lo, hi = ci
    if lo > 0 and hi / lo <= 1e3:
        return f"spans a factor {hi / lo:.3g} ({lo:.3g} to {hi:.3g} m)"
    if lo > 0:
        return f"runs from {lo:.3g} to {hi:.3g} m (more than a factor 1000)"
    return (
        f"runs from 0 to {hi:.3g} m (its lower end cannot be told apart from the instrument's "
        "noise)"
    )


@functools.lru_cache(maxsize=16)
def _coefficients(
    track: str, d: float, b: float, curvature_rad_per_m: float
) -> tuple[np.ndarray, ...]:
    """Final-pose covariance per unit k_r and per unit k_l, ((3, 3), (3, 3)), on the mean path
    (read-only arrays: kept for the next estimate of the same track, as a coverage study over
    many sets of runs makes; the propagation is most of an estimate's time)."""
    half = 0.5 * curvature_rad_per_m * b  # (f_r - f_l) / 2 for a path of this curvature
    believed = WheelGeometry.symmetric(1.0, b)
    true = WheelGeometry(1.0 + half, 1.0 - half, b)
    tr = out_and_back(d) if track == "out-and-back" else straight_line(d)
    out = []
    for k in ((1.0, 0.0), (0.0, 1.0)):
        cov = propagate(tr, true, believed, NonSystematicError(*k), steps_per_segment=400)
        cov.covariance.setflags(write=False)
        out.append(cov.covariance)
    return tuple(out)


def _trend(values: np.ndarray) -> tuple[float, float, float]:
    """Least-squares slope of ``values`` against run order, its t statistic and R^2 (what
    ``scipy.stats.linregress`` gives, without importing scipy.stats: 0.6 s)."""
    y = np.asarray(values, dtype=float)
    x = np.arange(len(y), dtype=float)
    xc, yc = x - x.mean(), y - y.mean()
    sxx, syy, sxy = float(xc @ xc), float(yc @ yc), float(xc @ yc)
    slope = sxy / sxx
    r2 = min(sxy * sxy / (sxx * syy), 1.0) if syy > 0 else 0.0
    residual = yc - slope * xc  # (linregress's (1 - r^2) syy loses digits for a near-exact line)
    stderr = math.sqrt(float(residual @ residual) / sxx / (len(y) - 2))
    t = slope / stderr if stderr > 0 else (math.inf if slope else 0.0)
    return slope, t, r2


def _chi2_quantiles(dof: int) -> np.ndarray:
    """The 97.5 % and 2.5 % quantiles of chi^2 with ``dof`` degrees of freedom: 2 P^-1(dof/2, q)
    (the inverse regularised gamma function), the numbers ``scipy.stats.chi2.ppf`` gives bit for
    bit, without importing scipy.stats (0.6 s)."""
    from scipy.special import gammaincinv

    return 2.0 * gammaincinv(dof / 2, np.array([0.975, 0.025]))


def estimate_k(
    runs: EndPoseRuns,
    track: str,
    distance_m: float,
    wheelbase_m: float,
    measurement: MeasurementNoise | None = None,
    *,
    curvature_rad_per_m: float = 0.0,
    strict: bool = True,
) -> NoiseEstimate:
    """Estimate k_r + k_l (and k_r, k_l) from the final pose errors of repeated runs.

    Parameters
    ----------
    runs : EndPoseRuns
        Final pose errors (actual - odometric, start frame), one row per run; all runs are used
        whatever their direction label.
    track : {'out-and-back', 'straight'}
    distance_m : float
        d, the length of the (outward) straight (m).
    wheelbase_m : float
        b (m); the best known value (a calibrated one if available).
    measurement : MeasurementNoise, optional
        Instrument noise; its heading variance is subtracted from the heading spread.
    curvature_rad_per_m : float
        Systematic curvature of the forward path (rad/m, CCW +), needed for k_r - k_l from
        out-and-back runs (their end poses cannot show it); straight runs measure it themselves
        (mean heading / d) and ignore this.
    strict : bool
        If True, an obviously systematic spread (see below) raises CalibrationError; if False it
        becomes a warning.

    Checks: fewer than MIN_RUNS runs is an error; fewer than RECOMMENDED_RUNS a warning. Obvious
    (more than 5 standard errors): out-and-back runs whose mean heading error is far from zero
    (systematic errors did not cancel), and heading errors that drift with run order (a
    systematic part changes between runs). A lateral spread inconsistent with the heading spread
    (misaligned start, not a straight path) is a warning.
    """
    if track not in NOISE_TRACKS:
        raise CalibrationError(f"track must be one of {', '.join(NOISE_TRACKS)}, got {track!r}")
    d, b = float(distance_m), float(wheelbase_m)
    err = np.asarray(runs.errors, dtype=float)
    n = len(err)
    if n < MIN_RUNS:
        raise CalibrationError(
            f"{n} run(s): at least {MIN_RUNS} are needed to estimate k (and "
            f"{RECOMMENDED_RUNS} or more for a useful interval)"
        )
    var_m_theta = measurement.sigma_theta_rad**2 if measurement else 0.0
    var_m_xy = measurement.sigma_xy_m**2 if measurement else 0.0
    spread = _Spread.of(err)
    k_sum, ci = _k_sum(track, d, b, spread, var_m_theta)
    warnings: list[str] = []
    if n < RECOMMENDED_RUNS:
        warnings.append(
            f"only {n} runs: the 95 % interval {_interval_width(ci)}; "
            f"{RECOMMENDED_RUNS} to 20 runs are recommended"
        )
    if track == "straight":
        curvature_rad_per_m = spread.mean_th / d  # the runs show the path's curvature directly
    coef = _coefficients(track, d, b, curvature_rad_per_m)
    k_diff, k_diff_se, k_r, k_l, note = _split_k(k_sum, coef, spread, var_m_theta)
    if track == "out-and-back":
        note += (
            f"; the split assumes a path curvature of {curvature_rad_per_m:.3g} rad/m "
            "(from the robot's systematic errors; out-and-back runs cannot show it)"
        )
    severe = _systematic_spread(track, err[:, 2], spread)
    warnings += _lateral_mismatch(err[:, 1], k_sum, coef, var_m_xy)
    warnings = _severe_first(severe, warnings, strict)
    return NoiseEstimate(
        track=track,
        distance_m=d,
        wheelbase_m=b,
        runs=n,
        k_sum_m=float(k_sum),
        k_sum_ci95_m=(float(ci[0]), float(ci[1])),
        k_diff_m=float(k_diff),
        k_diff_se_m=float(k_diff_se),
        k_r_m=None if k_r is None else float(k_r),
        k_l_m=None if k_l is None else float(k_l),
        split_note=note,
        theta_mean_rad=spread.mean_th,
        theta_std_rad=math.sqrt(spread.s2_th),
        measurement_var_theta_rad2=var_m_theta,
        warnings=tuple(warnings),
    )


@dataclass(frozen=True)
class _Spread:
    """Sample moments (ddof = 1) of the final errors of repeated runs: variances of x and
    theta, their covariance, the mean heading error and the number of runs."""

    s2_x: float
    s2_th: float
    c_xth: float
    mean_th: float
    runs: int

    @classmethod
    def of(cls, err: np.ndarray) -> _Spread:
        x, th = err[:, 0], err[:, 2]
        return cls(
            s2_x=float(np.var(x, ddof=1)),
            s2_th=float(np.var(th, ddof=1)),
            c_xth=float(np.cov(x, th, ddof=1)[0, 1]),
            mean_th=float(np.mean(th)),
            runs=len(err),
        )


def _k_sum(
    track: str, d: float, b: float, spread: _Spread, var_m_theta: float
) -> tuple[float, tuple[float, float]]:
    """k_r + k_l (m) from the heading spread and its 95 % chi-square interval."""
    s2_th = spread.s2_th
    dof = spread.runs - 1
    lo_q, hi_q = _chi2_quantiles(dof)
    var_lo, var_hi = dof * s2_th / lo_q, dof * s2_th / hi_q
    if s2_th <= var_m_theta:
        raise CalibrationError(
            f"the heading spread (std {math.degrees(math.sqrt(s2_th)):.4g} deg) is not larger "
            f"than the instrument's (sigma_theta {math.degrees(math.sqrt(var_m_theta)):.4g} deg): "
            "k cannot be resolved; drive longer runs or measure the heading more precisely"
        )
    factor = b * b / (2.0 * d if track == "out-and-back" else d)
    k_sum = factor * (s2_th - var_m_theta)
    ci = (factor * max(var_lo - var_m_theta, 0.0), factor * max(var_hi - var_m_theta, 0.0))
    return k_sum, ci


def _split_k(
    k_sum: float, coef: tuple[np.ndarray, ...], spread: _Spread, var_m_theta: float
) -> tuple[float, float, float | None, float | None, str]:
    """k_r - k_l from the x-theta covariance, its standard error, k_r and k_l (None where not
    identifiable) and a note saying which.

    The coefficients depend on the mean path (a curving path couples x to the heading), so they
    come from the propagation of eqs. (8)-(10) along it: cov(x, theta) = k_r a_r + k_l a_l,
    var(theta) = (k_r + k_l) t."""
    s2_th, c_xth, s2_x = spread.s2_th, spread.c_xth, spread.s2_x
    dof = spread.runs - 1
    a_mean, a_half = 0.5 * (coef[0][0, 2] + coef[1][0, 2]), 0.5 * (coef[0][0, 2] - coef[1][0, 2])
    w = a_mean / coef[0][2, 2]
    k_diff = (c_xth - w * (s2_th - var_m_theta)) / a_half
    # normal-theory variance of s_xtheta - w s_theta^2 (sample moments in place of the true ones)
    var_stat = (s2_x * s2_th + c_xth**2 - 4 * w * c_xth * s2_th + 2 * w**2 * s2_th**2) / dof
    k_diff_se = math.sqrt(max(var_stat, 0.0)) / abs(a_half)
    k_r, k_l = 0.5 * (k_sum + k_diff), 0.5 * (k_sum - k_diff)
    if k_diff_se > 0.25 * k_sum:
        note = (
            f"k_r and k_l are not identifiable from these runs: k_r - k_l = {k_diff:.3g} m has a "
            f"standard error of {k_diff_se:.3g} m, more than a quarter of k_r + k_l; use more "
            "runs, a more precise along-track measurement, or pivot turns about one wheel "
            "(docs/nonsystematic-errors.md); k_r = k_l = (k_r + k_l)/2 is the usual assumption"
        )
        return k_diff, k_diff_se, None, None, note
    if k_r < 0 or k_l < 0:
        note = f"k_r - k_l = {k_diff:.3g} m exceeds k_r + k_l: a negative k is not physical"
        return k_diff, k_diff_se, None, None, note
    note = f"k_r - k_l = {k_diff:.3g} m (standard error {k_diff_se:.3g} m)"
    return k_diff, k_diff_se, k_r, k_l, note


def _systematic_spread(track: str, th: np.ndarray, spread: _Spread) -> list[str]:
    """Obvious signs (more than 5 standard errors) that the spread is not purely random."""
    severe = []
    n, mean_th = spread.runs, spread.mean_th
    if track == "out-and-back":
        t = mean_th / (math.sqrt(spread.s2_th) / math.sqrt(n))
        if abs(t) > _OBVIOUS_SE:
            severe.append(
                f"the mean heading error ({math.degrees(mean_th):+.4g} deg) is {abs(t):.1f} "
                "standard errors from zero, but out-and-back runs cancel systematic errors: the "
                "robot turned between the legs, or the backward leg is not the reverse of the "
                "forward one (slip, castor flip); the spread is not purely random"
            )
    if n >= 5:
        slope, t, r2 = _trend(th)
        if abs(t) > _OBVIOUS_SE and r2 > 0.5:
            severe.append(
                f"the heading errors drift with run order ({math.degrees(slope):+.3g} deg per run, "
                f"{100 * r2:.0f} % of their variance): a systematic part changed during the "
                "session (battery, tyre temperature, floor); the spread overstates k"
            )
    return severe


def _lateral_mismatch(
    y: np.ndarray, k_sum: float, coef: tuple[np.ndarray, ...], var_m_xy: float
) -> list[str]:
    """A warning when the lateral spread disagrees with the one k_sum (plus the instrument)
    predicts."""
    pred_y = k_sum * 0.5 * (coef[0][1, 1] + coef[1][1, 1]) + var_m_xy
    s2_y = float(np.var(y, ddof=1))
    if not (pred_y > 0 and s2_y > 0):
        return []
    # log of a ratio of two sample variances with correlation ~0.87 under the model:
    # var(log ratio) ~ 4 (1 - rho^2) / (N - 1) = 1 / (N - 1)
    z = math.log(s2_y / pred_y) * math.sqrt(len(y) - 1)
    if abs(z) <= _LATERAL_SE:
        return []
    return [
        f"the lateral spread (std {math.sqrt(s2_y):.3g} m) is "
        f"{math.sqrt(s2_y / pred_y):.2g} times what the heading spread predicts "
        f"({math.sqrt(pred_y):.3g} m): "
        + (
            "the start heading varies between runs (mark the start pose better), or the "
            "path is not a straight line"
            if s2_y > pred_y
            else "check the sign and frame of y and theta (start frame, +y left)"
        )
    ]


def _severe_first(severe: list[str], warnings: list[str], strict: bool) -> list[str]:
    """Raise for obvious problems when ``strict``; else they lead the warnings."""
    if severe and strict:
        raise CalibrationError("; and ".join(severe) + " (use --force to estimate k anyway)")
    return severe + warnings


# --------------------------------------------------------------------------- recorded runs

#: Repeated runs of one track: their travel may differ by at most this fraction of the mean,
#: their total rotation by at most this many radians (else they are not repeats).
_REPEAT_TRAVEL = 0.1
_REPEAT_ROTATION_RAD = math.radians(30.0)


def _kind_of_run(rec: Recording, total_rotation_rad: float) -> str:
    """What a run is, for grouping repeats: its label, else its direction from the data."""
    if rec.label:
        return str(rec.label)
    if total_rotation_rad > math.pi / 4:
        return "ccw"
    if total_rotation_rad < -math.pi / 4:
        return "cw"
    return "straight"


@dataclass(frozen=True)
class RecordedNoise:
    """k_r + k_l (and k_r, k_l where identifiable) from repeated recorded runs.

    The runs are grouped into repeats of one track (same data set or folder, same kind of run:
    label, else CW/CCW/straight from the data, with similar travel and rotation). Within a group
    the mean final error is the systematic part; what is left is random. Under the model
    (docs/conventions.md) the final heading of any run has the variance

        var(theta_N) = (k_r T_R + k_l T_L) / b^2 + 2 sigma_theta^2,

    T_R, T_L the total |wheel travel| of the run and sigma_theta the tracker's heading noise
    (start and end are both measured), whatever the path. With k_r = k_l the pooled estimate is

        k_r + k_l = b^2 (SS - 2 sigma_theta^2 dof) / sum_g (n_g - 1) T_g,

    SS the sum of squared deviations from the group means, dof = sum_g (n_g - 1), T_g the mean
    (T_R + T_L) / 2 of group g; the 95 % interval is chi-square with dof degrees of freedom
    (exact when every group has the same travel, approximate otherwise). k_r - k_l comes from the
    position-heading covariances, whose coefficients are propagated along each run's recorded
    path (first order, eqs. (8)-(10)); its standard error is a delete-one-group jackknife, and
    k_r, k_l are reported only when it is below a quarter of k_r + k_l.

    Attributes
    ----------
    k_sum_m : float
        k_r + k_l (m).
    k_sum_ci95_m : tuple of float
    k_r_m, k_l_m : float or None
    k_diff_m, k_diff_se_m : float or None
    split_note : str
    runs, dof : int
        Runs used and degrees of freedom of the heading spread.
    wheelbase_m : float
        b used in the estimator (m).
    groups : tuple of dict
        Per group: key, runs, mean travel (m), heading std (deg), its own k_r + k_l and 95 %
        interval (a check of the model: k should not depend on the track).
    skipped : tuple of str
        Runs or groups left out, with the reason.
    warnings : tuple of str
    """

    k_sum_m: float
    k_sum_ci95_m: tuple[float, float]
    k_r_m: float | None
    k_l_m: float | None
    k_diff_m: float | None
    k_diff_se_m: float | None
    split_note: str
    runs: int
    dof: int
    wheelbase_m: float
    measurement_var_theta_rad2: float
    groups: tuple[dict, ...]
    skipped: tuple[str, ...] = ()
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal noise RUN_OR_DIR... --json``."""
        return {
            "k_sum_m": self.k_sum_m,
            "k_sum_ci95": list(self.k_sum_ci95_m),
            "k_r_m": self.k_r_m,
            "k_l_m": self.k_l_m,
            "k_diff_m": self.k_diff_m,
            "k_diff_se_m": self.k_diff_se_m,
            "k_split_note": self.split_note,
            "k_each_m": self.k_sum_m / 2,
            "k_each_chong_kleeman_m05": math.sqrt(max(self.k_sum_m, 0.0) / 2),
            "runs": self.runs,
            "dof": self.dof,
            "wheelbase_m": self.wheelbase_m,
            "measurement_var_theta_rad2": self.measurement_var_theta_rad2,
            "groups": [dict(g) for g in self.groups],
            "skipped": list(self.skipped),
            "warnings": list(self.warnings),
        }


def _chi2_interval(ss_scaled: float, dof: int) -> tuple[float, float]:
    lo_q, hi_q = _chi2_quantiles(dof)
    return ss_scaled / lo_q, ss_scaled / hi_q


def estimate_k_from_recordings(
    recordings: Iterable[Recording],
    geometry: WheelGeometry,
    measurement: MeasurementNoise | None = None,
    *,
    strict: bool = True,
) -> RecordedNoise:
    """k from the run-to-run spread of repeated recorded runs (see :class:`RecordedNoise`).

    Parameters
    ----------
    recordings : sequence of Recording
        Runs with ground truth; ``meta['dataset']`` (else the folder) and the kind of run group
        them into repeats.
    geometry : WheelGeometry
        Best known geometry (a calibration of the same robot): it turns wheel rotations into
        travel and its wheelbase is the b of the estimator.
    measurement : MeasurementNoise, optional
        The tracker's noise; its heading variance (twice: start and end) is subtracted.
    strict : bool
        A group whose heading errors drift with run order (more than 5 standard errors) is an
        error if True, a warning if False.
    """
    b = float(geometry.wheelbase_m)
    var_m = (measurement.sigma_theta_rad**2) if measurement else 0.0
    skipped: list[str] = []
    groups = _group_runs(recordings, geometry, skipped)
    used = _repeats(groups, skipped)
    pooled = _pool(used, b, var_m)
    k_sum = b * b * (pooled.ss - 2 * var_m * pooled.dof) / pooled.denom
    if k_sum <= 0:
        raise CalibrationError(
            "the heading spread of the repeats is not larger than the tracker's heading noise: "
            "k cannot be resolved"
        )
    # chi-square interval of the pooled heading variance per unit travel, minus the tracker's
    lo_ss, hi_ss = _chi2_interval(pooled.ss, pooled.dof)  # interval of the variance
    scale = b * b * pooled.dof / pooled.denom
    ci = (max(scale * (lo_ss - 2 * var_m), 0.0), max(scale * (hi_ss - 2 * var_m), 0.0))
    warnings: list[str] = []
    if pooled.dof < RECOMMENDED_RUNS - 1:
        warnings.append(
            f"only {pooled.dof} degrees of freedom: the 95 % interval {_interval_width(ci)}; "
            "more repeats narrow it"
        )
    warnings += _groups_off_the_pool(pooled.rows, k_sum)
    # k_r - k_l from the x-theta and y-theta covariances (coefficients along each recorded path)
    k_diff, k_diff_se, k_r, k_l, note = _split_recorded(used, k_sum)
    warnings = _severe_first(pooled.severe, warnings, strict)
    return RecordedNoise(
        k_sum_m=float(k_sum),
        k_sum_ci95_m=(float(ci[0]), float(ci[1])),
        k_r_m=None if k_r is None else float(k_r),
        k_l_m=None if k_l is None else float(k_l),
        k_diff_m=None if k_diff is None else float(k_diff),
        k_diff_se_m=None if k_diff_se is None else float(k_diff_se),
        split_note=note,
        runs=sum(len(rows) for _, rows in used),
        dof=int(pooled.dof),
        wheelbase_m=b,
        measurement_var_theta_rad2=float(var_m),
        groups=tuple(pooled.rows),
        skipped=tuple(skipped),
        warnings=tuple(warnings),
    )


@dataclass(frozen=True)
class _RecordedRun:
    """One recorded run: its final error (actual - odometric, start frame), total wheel travel
    (m), heading change (rad) and final-pose covariance per unit k_r and per unit k_l."""

    name: str
    err: np.ndarray
    travel: float
    rotation: float
    coef_r: np.ndarray
    coef_l: np.ndarray


_Group = tuple[tuple[str, str], list[_RecordedRun]]


def _group_runs(
    recordings: Iterable[Recording], geometry: WheelGeometry, skipped: list[str]
) -> dict[tuple[str, str], list[_RecordedRun]]:
    """The runs by (data set, kind of run), with the coefficients along each recorded path;
    runs too short to use are listed in ``skipped``."""
    from pathlib import Path

    b = float(geometry.wheelbase_m)
    scalar = WheelGeometry.unchecked(
        float(geometry.diameter_right_m), float(geometry.diameter_left_m), b
    )
    groups: dict[tuple[str, str], list[_RecordedRun]] = {}
    for r in recordings:
        if r.ground_truth is None:
            raise CalibrationError(f"{r.name}: estimating k from recorded runs needs ground truth")
        dr, dl = wheel_travel(
            np.diff(np.asarray(r.wheel_angle_right_rad, dtype=float)),
            np.diff(np.asarray(r.wheel_angle_left_rad, dtype=float)),
            scalar,
        )
        if len(dr) < 1:
            skipped.append(f"{Path(r.name).name}: too short")
            continue
        mean, coef_r = propagate_increments(dr, dl, b, NonSystematicError(1.0, 0.0))
        _, coef_l = propagate_increments(dr, dl, b, NonSystematicError(0.0, 1.0))
        gt = np.asarray(r.ground_truth, dtype=float)
        key = (r.dataset, _kind_of_run(r, float(gt[-1, 2] - gt[0, 2])))
        travel = 0.5 * float(np.abs(dr).sum() + np.abs(dl).sum())
        run = _RecordedRun(r.name, gt[-1] - mean, travel, float(mean[2]), coef_r, coef_l)
        groups.setdefault(key, []).append(run)
    return groups


def _repeats(groups: dict[tuple[str, str], list[_RecordedRun]], skipped: list[str]) -> list[_Group]:
    """The groups that are repeats of one track (two or more runs of similar travel and
    rotation); the others are listed in ``skipped``. None is an error."""
    used: list[_Group] = []
    for key, rows in groups.items():
        label = f"{key[0]} {key[1]}"
        if len(rows) < 2:
            skipped.append(f"{label}: a single run (repeats are needed)")
            continue
        travel = np.array([x.travel for x in rows])
        rot = np.array([x.rotation for x in rows])
        if np.ptp(travel) > _REPEAT_TRAVEL * travel.mean() or np.ptp(rot) > _REPEAT_ROTATION_RAD:
            skipped.append(
                f"{label}: not repeats of one track (travel {travel.min():.3g}-{travel.max():.3g}"
                f" m, rotation {math.degrees(rot.min()):+.0f} to {math.degrees(rot.max()):+.0f} "
                "deg)"
            )
            continue
        used.append((key, rows))
    if not used:
        raise CalibrationError(NO_REPEATS + (f" ({'; '.join(skipped[:3])})" if skipped else ""))
    return used


def refuse_without_repeats(recordings: Iterable[Recording]) -> None:
    """CalibrationError before any work when no two runs with ground truth share a data set and
    a kind of run: :func:`estimate_k_from_recordings` would find no repeats (it also compares
    their travel, which needs a geometry; this needs none)."""
    kinds: dict[tuple[str, str], int] = {}
    for r in recordings:
        if r.ground_truth is not None and len(r.ground_truth):
            gt = np.asarray(r.ground_truth, dtype=float)
            key = (r.dataset, _kind_of_run(r, float(gt[-1, 2] - gt[0, 2])))
            kinds[key] = kinds.get(key, 0) + 1
    if kinds and max(kinds.values()) < 2:
        shown = "; ".join(f"{d} {k}: a single run" for d, k in list(kinds)[:3])
        raise CalibrationError(f"{NO_REPEATS} ({shown})")


@dataclass(frozen=True)
class _Pooled:
    """The pooled heading spread of the groups: the sum of squared deviations from the group
    means (rad^2), its degrees of freedom, sum_g (n_g - 1) T_g (m), each group's own estimate
    (the rows of ``RecordedNoise.groups``) and the groups whose headings drift."""

    ss: float
    dof: int
    denom: float
    rows: list[dict]
    severe: list[str]


def _pool(used: list[_Group], b: float, var_m: float) -> _Pooled:
    """:class:`_Pooled` of the groups of repeats (``var_m``: the tracker's heading variance)."""
    ss = 0.0
    dof = 0
    denom = 0.0
    group_rows: list[dict] = []
    severe: list[str] = []
    for key, rows in used:
        th = np.array([x.err[2] for x in rows])
        n = len(th)
        t_mean = float(np.mean([x.travel for x in rows]))
        ss_g = float(np.sum((th - th.mean()) ** 2))
        ss += ss_g
        dof += n - 1
        denom += (n - 1) * t_mean
        # the group's own estimate (clipped at 0: its spread may be below the tracker's)
        k_g = max(b * b * (ss_g / (n - 1) - 2 * var_m) / t_mean, 0.0)
        lo, hi = _chi2_interval(b * b * ss_g / t_mean, n - 1)
        tracker = b * b * 2 * var_m / t_mean
        group_rows.append(
            {
                "group": f"{key[0]} {key[1]}",
                "runs": n,
                "travel_m": t_mean,
                "theta_std_deg": math.degrees(math.sqrt(ss_g / (n - 1))),
                "k_sum_m": k_g,
                "k_sum_ci95": [max(lo - tracker, 0.0), max(hi - tracker, 0.0)],
            }
        )
        if n >= 5:
            slope, t, r2 = _trend(th)
            if abs(t) > _OBVIOUS_SE and r2 > 0.5:
                severe.append(
                    f"{key[0]} {key[1]}: the heading errors drift with run order "
                    f"({math.degrees(slope):+.3g} deg per run): a systematic part changed during "
                    "the session; the spread overstates k"
                )
    return _Pooled(ss, dof, denom, group_rows, severe)


def _groups_off_the_pool(group_rows: list[dict], k_sum: float) -> list[str]:
    """Does k depend on the track? A warning naming the groups whose own 95 % intervals
    exclude the pooled value."""
    off = [g["group"] for g in group_rows if not g["k_sum_ci95"][0] <= k_sum <= g["k_sum_ci95"][1]]
    if not off:
        return []
    return [
        f"{len(off)} of {len(group_rows)} groups disagree with the pooled k at 95 % ("
        + ", ".join(off[:4])
        + (", ..." if len(off) > 4 else "")
        + "): the random error does not grow with the travel as the model says (e.g. spot "
        "turns or a floor that add their own scatter); the pooled k is an average"
    ]


def _split_recorded(
    used: list[_Group], k_sum: float
) -> tuple[float | None, float | None, float | None, float | None, str]:
    """k_r - k_l, its jackknife standard error, k_r and k_l (None where not identifiable) and
    a note saying which."""
    k_diff, k_diff_se, note = _k_diff_recorded(used, k_sum)
    if k_diff is None:
        return None, k_diff_se, None, None, note
    if k_diff_se is None or k_diff_se > 0.25 * k_sum:
        note = (
            f"k_r and k_l are not identifiable from these runs: k_r - k_l = {k_diff:.3g} m"
            + (f" has a standard error of {k_diff_se:.3g} m" if k_diff_se is not None else "")
            + ", more than a quarter of k_r + k_l; k_r = k_l = (k_r + k_l)/2 is the usual "
            "assumption"
        )
        return k_diff, k_diff_se, None, None, note
    if abs(k_diff) > k_sum:
        note = f"k_r - k_l = {k_diff:.3g} m exceeds k_r + k_l: a negative k is not physical"
        return k_diff, k_diff_se, None, None, note
    note = f"k_r - k_l = {k_diff:.3g} m (jackknife standard error {k_diff_se:.3g} m)"
    return k_diff, k_diff_se, 0.5 * (k_sum + k_diff), 0.5 * (k_sum - k_diff), note


def _k_diff_recorded(used: list[_Group], k_sum: float) -> tuple[float | None, float | None, str]:
    """k_r - k_l by least squares on the x-theta and y-theta sample covariances of every group,
    given k_sum; jackknife standard error over groups. Returns (k_diff, se, note)."""

    def solve(parts: list[list[_RecordedRun]]) -> float | None:
        num = den = 0.0
        for rows in parts:
            e = np.array([x.err for x in rows])
            n = len(e)
            if n < 2:
                continue
            c = np.cov(e.T, ddof=1)
            ar = np.mean([x.coef_r for x in rows], axis=0)
            al = np.mean([x.coef_l for x in rows], axis=0)
            mid, half = 0.5 * (ar + al), 0.5 * (ar - al)
            for i in (0, 1):
                resid = c[i, 2] - k_sum * mid[i, 2]
                num += (n - 1) * resid * half[i, 2]
                den += (n - 1) * half[i, 2] ** 2
        return num / den if den > 0 else None

    parts = [rows for _, rows in used]
    k_diff = solve(parts)
    if k_diff is None:
        return None, None, "k_r - k_l: these runs give no position-heading coupling to split k"
    if len(parts) < 3:
        return k_diff, None, "k_r - k_l: too few groups for a standard error"
    values = [solve(parts[:i] + parts[i + 1 :]) for i in range(len(parts))]
    jack = np.array([v for v in values if v is not None])
    g = len(jack)
    se = math.sqrt((g - 1) / g * float(np.sum((jack - jack.mean()) ** 2))) if g >= 3 else None
    return k_diff, se, ""


def tracker_noise(recordings: Iterable[Recording]) -> MeasurementNoise:
    """The tracker's noise per sample, from the jitter of its poses: second differences of the
    ground truth, x_(i+1) - 2 x_i + x_(i-1), have variance 6 sigma^2 for white noise on a smooth
    path; sigma = 1.4826 MAD / sqrt(6) over every sample of every run (robust to the robot's
    own accelerations and to the odd jump). An upper bound: what the robot really does between
    samples counts as noise. A pose error measured relative to the start pose carries it twice
    (start and end).
    """
    d_xy, d_th = [], []
    for r in recordings:
        if r.ground_truth is None or len(r.ground_truth) < 3:
            continue
        g = np.asarray(r.ground_truth, dtype=float)
        d2 = g[2:] - 2 * g[1:-1] + g[:-2]
        d_xy.append(d2[:, :2].ravel())
        d_th.append(d2[:, 2])
    if not d_xy:
        raise CalibrationError(
            "the tracker noise needs runs with ground truth of 3 samples or more"
        )

    def robust_sigma(parts: list[np.ndarray]) -> float:
        a = np.concatenate(parts)
        return float(1.4826 * np.median(np.abs(a - np.median(a))) / math.sqrt(6.0))

    return MeasurementNoise(robust_sigma(d_xy), robust_sigma(d_th))
