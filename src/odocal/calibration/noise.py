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

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.covariance import propagate
from ..core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from ..core.runs import EndPoseRuns
from ..core.tracks import out_and_back, straight_line
from ..errors import CalibrationError

__all__ = ["NoiseEstimate", "estimate_k", "NOISE_TRACKS", "MIN_RUNS", "RECOMMENDED_RUNS"]

NOISE_TRACKS = ("out-and-back", "straight")
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


def _coefficients(track: str, d: float, b: float, curvature_rad_per_m: float):
    """Final-pose covariance per unit k_r and per unit k_l, ((3, 3), (3, 3)), on the mean path."""
    half = 0.5 * curvature_rad_per_m * b  # (f_r - f_l) / 2 for a path of this curvature
    believed = WheelGeometry.symmetric(1.0, b)
    true = WheelGeometry(1.0 + half, 1.0 - half, b)
    tr = out_and_back(d) if track == "out-and-back" else straight_line(d)
    return tuple(
        propagate(tr, true, believed, NonSystematicError(*k), steps_per_segment=400).covariance
        for k in ((1.0, 0.0), (0.0, 1.0))
    )


def _trend(values: np.ndarray) -> tuple[float, float, float]:
    """Least-squares slope of ``values`` against run order, its t statistic and R^2."""
    from scipy import stats

    res = stats.linregress(np.arange(len(values), dtype=float), values)
    t = res.slope / res.stderr if res.stderr > 0 else (math.inf if res.slope else 0.0)
    return float(res.slope), float(t), float(res.rvalue**2)


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
    from scipy import stats

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
    warnings: list[str] = []
    severe: list[str] = []
    var_m_theta = measurement.sigma_theta_rad**2 if measurement else 0.0
    var_m_xy = measurement.sigma_xy_m**2 if measurement else 0.0
    x, y, th = err[:, 0], err[:, 1], err[:, 2]
    s2_th = float(np.var(th, ddof=1))
    c_xth = float(np.cov(x, th, ddof=1)[0, 1])
    s2_x = float(np.var(x, ddof=1))
    dof = n - 1
    lo_q, hi_q = stats.chi2.ppf([0.975, 0.025], dof)
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
    if n < RECOMMENDED_RUNS:
        warnings.append(
            f"only {n} runs: the 95 % interval spans a factor {ci[1] / max(ci[0], 1e-300):.3g}; "
            f"{RECOMMENDED_RUNS} to 20 runs are recommended"
        )

    # k_r - k_l from the x-theta covariance. Its coefficients depend on the mean path (a
    # curving path couples x to the heading), so they come from the propagation of eqs. (8)-(10)
    # along the mean path: cov(x, theta) = k_r a_r + k_l a_l, var(theta) = (k_r + k_l) t.
    mean_th = float(np.mean(th))
    if track == "straight":
        curvature_rad_per_m = mean_th / d  # the runs show the path's curvature directly
    coef = _coefficients(track, d, b, curvature_rad_per_m)
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
        k_r = k_l = None
    elif k_r < 0 or k_l < 0:
        note = f"k_r - k_l = {k_diff:.3g} m exceeds k_r + k_l: a negative k is not physical"
        k_r = k_l = None
    else:
        note = f"k_r - k_l = {k_diff:.3g} m (standard error {k_diff_se:.3g} m)"
    if track == "out-and-back":
        note += (
            f"; the split assumes a path curvature of {curvature_rad_per_m:.3g} rad/m "
            "(from the robot's systematic errors; out-and-back runs cannot show it)"
        )

    sd_th = math.sqrt(s2_th)
    if track == "out-and-back":
        t = mean_th / (sd_th / math.sqrt(n))
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
    # lateral spread predicted from k_sum (plus the instrument) vs observed
    pred_y = k_sum * 0.5 * (coef[0][1, 1] + coef[1][1, 1]) + var_m_xy
    s2_y = float(np.var(y, ddof=1))
    if pred_y > 0 and s2_y > 0:
        # log of a ratio of two sample variances with correlation ~0.87 under the model:
        # var(log ratio) ~ 4 (1 - rho^2) / (N - 1) = 1 / (N - 1)
        z = math.log(s2_y / pred_y) * math.sqrt(dof)
        if abs(z) > _LATERAL_SE:
            warnings.append(
                f"the lateral spread (std {math.sqrt(s2_y):.3g} m) is "
                f"{math.sqrt(s2_y / pred_y):.2g} times what the heading spread predicts "
                f"({math.sqrt(pred_y):.3g} m): "
                + (
                    "the start heading varies between runs (mark the start pose better), or the "
                    "path is not a straight line"
                    if s2_y > pred_y
                    else "check the sign and frame of y and theta (start frame, +y left)"
                )
            )
    if severe:
        if strict:
            raise CalibrationError(
                severe[0] + " (use --force to estimate k anyway)"
                if len(severe) == 1
                else "; and ".join(severe) + " (use --force to estimate k anyway)"
            )
        warnings = severe + warnings
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
        theta_mean_rad=mean_th,
        theta_std_rad=sd_th,
        measurement_var_theta_rad2=var_m_theta,
        warnings=tuple(warnings),
    )
