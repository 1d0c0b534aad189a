"""Independent-samples t-tests (Student and Welch), from samples or from summary statistics.

Textbook formulas (methods-notes section 7; model.md check value). With sample means m_a, m_b,
unbiased standard deviations s_a, s_b (ddof = 1) and sizes n_a, n_b:

    Student: s_p^2 = ((n_a-1) s_a^2 + (n_b-1) s_b^2) / (n_a + n_b - 2),
             t = (m_a - m_b) / sqrt(s_p^2 (1/n_a + 1/n_b)),  df = n_a + n_b - 2
    Welch:   t = (m_a - m_b) / sqrt(s_a^2/n_a + s_b^2/n_b),
             df = (s_a^2/n_a + s_b^2/n_b)^2 / ((s_a^2/n_a)^2/(n_a-1) + (s_b^2/n_b)^2/(n_b-1))

p-values: two-sided 2 sf(|t|), one-sided ``p_less`` (H1: mean_a < mean_b) = cdf(t) and
``p_greater`` (H1: mean_a > mean_b) = sf(t). They agree with ``scipy.stats.ttest_ind`` (to about
1e-13 relative): the Student-t tail is the regularized incomplete beta function, evaluated here
by its continued fraction (Numerical Recipes 6.4, modified Lentz), so that the t-tests of
``odocal design`` need no scipy import.

Paired (two samples of the same n units, e.g. candidates simulated with common random numbers):
d_i = a_i - b_i, t = mean(d) / (s_d / sqrt(n)), df = n - 1 (``scipy.stats.ttest_rel``).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..errors import ModelError

__all__ = [
    "TTest",
    "ttest_from_stats",
    "ttest_samples",
    "ttest_paired",
    "student_t_sf",
    "student_t_quantile",
    "circular_mean",
]


@dataclass(frozen=True)
class TTest:
    """Result of one independent-samples t-test of group a against group b.

    Attributes
    ----------
    kind : str
        'student' (pooled, equal variances) or 'welch'.
    t, df : float
        Test statistic and degrees of freedom (Welch df is fractional).
    p_two_sided, p_less, p_greater : float
        Two-sided p; one-sided p for H1 mean_a < mean_b; one-sided p for H1 mean_a > mean_b.
    mean_a, mean_b, std_a, std_b : float
        Group means and unbiased standard deviations (ddof = 1), in the data's unit.
    n_a, n_b : int
        Group sizes.
    """

    kind: str
    t: float
    df: float
    p_two_sided: float
    p_less: float
    p_greater: float
    mean_a: float
    mean_b: float
    std_a: float
    std_b: float
    n_a: int
    n_b: int

    @property
    def mean_difference(self) -> float:
        """mean_a - mean_b (the paper's "mean difference")."""
        return self.mean_a - self.mean_b

    def as_dict(self) -> dict:
        """JSON-ready: the statistic, its p-values, the mean difference and the groups' summaries
        (in the data's unit)."""
        return {
            "kind": self.kind,
            "t": self.t,
            "df": self.df,
            "p_two_sided": self.p_two_sided,
            "p_less": self.p_less,
            "p_greater": self.p_greater,
            "mean_difference": self.mean_difference,
            "mean_a": self.mean_a,
            "mean_b": self.mean_b,
            "std_a": self.std_a,
            "std_b": self.std_b,
            "n_a": self.n_a,
            "n_b": self.n_b,
        }


def _beta_fraction(a: float, b: float, x: float) -> float:
    """Continued fraction of the incomplete beta function (converges for x < (a+1)/(a+b+2))."""
    tiny = 1e-300
    qab, qap, qam = a + b, a + 1.0, a - 1.0
    c, d = 1.0, 1.0 - qab * x / qap
    d = 1.0 / (d if abs(d) > tiny else tiny)
    h = d
    for m in range(1, 10_000):
        m2 = 2 * m
        for num in (m * (b - m) * x / ((qam + m2) * (a + m2)),
                    -(a + m) * (qab + m) * x / ((a + m2) * (qap + m2))):  # fmt: skip
            d = 1.0 + num * d
            d = 1.0 / (d if abs(d) > tiny else tiny)
            c = 1.0 + num / c
            c = c if abs(c) > tiny else tiny
            h *= d * c
        if abs(d * c - 1.0) < 1e-16:
            break
    return h


def _beta_lower(a: float, b: float, x: float, y: float, log_front: float) -> float:
    """Regularized incomplete beta I_x(a, b), with ``y`` = 1 - x and ``log_front`` =
    ln(x^a y^b / B(a, b)) given exactly by the caller."""
    if x <= 0.0:
        return 0.0
    if y <= 0.0:
        return 1.0
    if x < (a + 1.0) / (a + b + 2.0):
        return math.exp(log_front) * _beta_fraction(a, b, x) / a
    return 1.0 - math.exp(log_front) * _beta_fraction(b, a, y) / b


def _log_gamma_ratio_half(h: float) -> float:
    """ln(Gamma(h + 1/2) / Gamma(h)); for large h by its asymptotic series (the difference of
    two large lgamma values would lose digits)."""
    if h < 20.0:
        return math.lgamma(h + 0.5) - math.lgamma(h)
    u = 1.0 / h
    u2 = u * u
    return 0.5 * math.log(h) - u / 8.0 + u * u2 * (1 / 192 - u2 * (1 / 640 - u2 * 17 / 14336))


def student_t_sf(t: float, df: float) -> float:
    """P(T > t) for Student's t with ``df`` degrees of freedom (df > 0, fractional allowed)."""
    if math.isnan(t) or math.isnan(df):
        return math.nan
    if math.isinf(t):
        return 0.0 if t > 0 else 1.0
    if t == 0.0:
        return 0.5
    t2 = t * t
    h = 0.5 * df
    # P(|T| > |t|) = I_x(df/2, 1/2) with x = df / (df + t^2)
    log_x, log_y = -math.log1p(t2 / df), -math.log1p(df / t2)
    log_front = _log_gamma_ratio_half(h) - 0.5 * math.log(math.pi) + h * log_x + 0.5 * log_y
    both = _beta_lower(h, 0.5, df / (df + t2), t2 / (df + t2), log_front)
    return 0.5 * both if t > 0 else 1.0 - 0.5 * both


def student_t_quantile(p: float, df: float) -> float:
    """The t with P(T <= t) = ``p`` (0 < p < 1) for Student's t with ``df`` > 0 degrees of
    freedom: :func:`student_t_sf` inverted by safeguarded Newton steps (what
    ``scipy.stats.t.ppf`` gives, to about 1e-13, without importing scipy.stats)."""
    if not (0.0 < p < 1.0) or not df > 0:
        return math.nan
    if p == 0.5:
        return 0.0
    tail = min(p, 1.0 - p)  # solve sf(t) = tail for t > 0
    lo, hi = 0.0, 1.0
    while student_t_sf(hi, df) > tail:
        lo, hi = hi, 2.0 * hi
        if hi > 1e300:
            return math.copysign(math.inf, p - 0.5)
    log_norm = math.lgamma(0.5 * (df + 1)) - math.lgamma(0.5 * df) - 0.5 * math.log(df * math.pi)
    t = 0.5 * (lo + hi)
    for _ in range(100):
        excess = student_t_sf(t, df) - tail  # > 0: t too small
        if excess > 0:
            lo = t
        else:
            hi = t
        pdf = math.exp(log_norm - 0.5 * (df + 1) * math.log1p(t * t / df))
        step = excess / pdf if pdf > 0 else math.inf
        new = t + step
        if not lo < new < hi:  # outside the bracket: bisect instead
            new = 0.5 * (lo + hi)
        if abs(new - t) <= 1e-15 * abs(new) or new in (lo, hi):
            t = new
            break
        t = new
    return t if p > 0.5 else -t


def _p_values(t: float, df: float) -> tuple[float, float, float]:
    """Two-sided, less and greater p-values of a finite t with ``df`` degrees of freedom, from
    one tail computed directly (the small one)."""
    tail = student_t_sf(abs(t), df)
    p_less, p_greater = (1.0 - tail, tail) if t >= 0 else (tail, 1.0 - tail)
    return min(1.0, 2.0 * tail), p_less, p_greater


def ttest_from_stats(
    mean_a: float,
    std_a: float,
    n_a: int,
    mean_b: float,
    std_b: float,
    n_b: int,
    equal_var: bool = False,
) -> TTest:
    """t-test of group a against group b from summary statistics (see module docstring).

    ``std_a``, ``std_b`` are unbiased sample standard deviations (ddof = 1). Both groups need at
    least 2 values. When both standard deviations are 0 the test degenerates: t is +-inf (or NaN
    for equal means) and the p-values are 0 or 1 accordingly (NaN for equal means).
    """
    for name, n in (("n_a", n_a), ("n_b", n_b)):
        if int(n) != n or n < 2:
            raise ModelError(f"a t-test needs at least 2 values per group, got {name}={n}")
    for name, v in (("mean_a", mean_a), ("mean_b", mean_b), ("std_a", std_a), ("std_b", std_b)):
        if not math.isfinite(v):
            raise ModelError(f"{name} must be finite, got {v!r}")
    if std_a < 0 or std_b < 0:
        raise ModelError(f"standard deviations must be >= 0, got {std_a!r} and {std_b!r}")
    n_a, n_b = int(n_a), int(n_b)
    # t and df do not depend on the unit: compute them on values scaled to about 1, so that a
    # variance of data on a 1e-300 (or 1e+200) scale neither underflows to 0 nor overflows
    scale = _scale(mean_a, mean_b, std_a, std_b)
    sa, sb = std_a / scale, std_b / scale
    va, vb = sa**2 / n_a, sb**2 / n_b
    if equal_var:
        df = float(n_a + n_b - 2)
        sp2 = ((n_a - 1) * sa**2 + (n_b - 1) * sb**2) / df
        se = math.sqrt(sp2 * (1.0 / n_a + 1.0 / n_b))
    else:
        se = math.sqrt(va + vb)
        denom = va**2 / (n_a - 1) + vb**2 / (n_b - 1)
        df = (va + vb) ** 2 / denom if denom > 0 else float(n_a + n_b - 2)
    diff = mean_a / scale - mean_b / scale
    if se > 0:
        t = diff / se
        p_two, p_less, p_greater = _p_values(t, df)
    elif diff == 0:
        t = p_less = p_greater = p_two = math.nan
    else:
        t = math.copysign(math.inf, diff)
        p_less, p_greater = (0.0, 1.0) if diff < 0 else (1.0, 0.0)
        p_two = 0.0
    return TTest(
        "student" if equal_var else "welch",
        float(t),
        float(df),
        p_two,
        p_less,
        p_greater,
        float(mean_a),
        float(mean_b),
        float(std_a),
        float(std_b),
        n_a,
        n_b,
    )


def _scale(*values: float) -> float:
    """The power of two just above the largest magnitude among ``values`` (1 when all are 0):
    what a statistic's inputs are divided by before squaring. A power of two divides exactly, so
    data of an ordinary scale give the same bits as unscaled arithmetic."""
    m = max(abs(float(v)) for v in values)
    return math.ldexp(1.0, math.frexp(m)[1]) if m > 0 else 1.0


def _mean_std(x: np.ndarray, scale: float) -> tuple[float, float]:
    """Mean and unbiased standard deviation of ``x``, computed on ``x / scale`` (no underflow of
    the squared deviations of tiny values, no overflow of huge ones) and given in x's unit."""
    y = x / scale
    return float(y.mean()) * scale, float(y.std(ddof=1)) * scale


def ttest_samples(a: ArrayLike, b: ArrayLike, equal_var: bool = False) -> TTest:
    """t-test of sample ``a`` against sample ``b`` (1-D arrays of finite values; any scale: the
    statistics are computed on the values divided by the largest magnitude)."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    for name, x in (("a", a), ("b", b)):
        if x.size < 2:
            raise ModelError(f"a t-test needs at least 2 values per group; {name} has {x.size}")
        if not np.all(np.isfinite(x)):
            raise ModelError(f"group {name} holds non-finite values")
    scale = _scale(np.max(np.abs(a)), np.max(np.abs(b)))
    (mean_a, std_a), (mean_b, std_b) = _mean_std(a, scale), _mean_std(b, scale)
    return ttest_from_stats(mean_a, std_a, a.size, mean_b, std_b, b.size, equal_var=equal_var)


def ttest_paired(a: ArrayLike, b: ArrayLike) -> TTest:
    """Paired t-test of ``a`` against ``b`` (1-D arrays of equal length; pairs with a non-finite
    member are left out). ``std_a``/``std_b`` are the groups' own spreads; the test uses the
    spread of the differences."""
    xa = np.asarray(a, dtype=float).ravel()
    xb = np.asarray(b, dtype=float).ravel()
    if xa.shape != xb.shape:
        raise ModelError(
            f"a paired t-test needs samples of equal length, got {xa.size} and {xb.size}"
        )
    ok = np.isfinite(xa) & np.isfinite(xb)
    xa, xb = xa[ok], xb[ok]
    n = int(xa.size)
    if n < 2:
        raise ModelError(f"a paired t-test needs at least 2 finite pairs, got {n}")
    scale = _scale(np.max(np.abs(xa)), np.max(np.abs(xb)))
    d = xa / scale - xb / scale  # on a scale of about 1: no under- or overflow
    diff, sd = float(d.mean()), float(d.std(ddof=1))
    df = float(n - 1)
    if sd > 0:
        t = diff / (sd / math.sqrt(n))
        p_two, p_less, p_greater = _p_values(t, df)
    elif diff == 0:
        t = p_less = p_greater = p_two = math.nan
    else:
        t = math.copysign(math.inf, diff)
        p_less, p_greater = (0.0, 1.0) if diff < 0 else (1.0, 0.0)
        p_two = 0.0
    (mean_a, std_a), (mean_b, std_b) = _mean_std(xa, scale), _mean_std(xb, scale)
    return TTest("paired", float(t), df, p_two, p_less, p_greater, mean_a, mean_b, std_a, std_b,
                 n, n)  # fmt: skip


def circular_mean(angles_rad: ArrayLike, axis: int = -1) -> np.ndarray:
    """Circular mean of unwrapped angles that keeps their unwrapped scale.

    The mean direction is taken relative to the arithmetic mean, so a set of errors near -2 pi
    stays near -2 pi (and small errors stay small) instead of being wrapped into (-pi, pi], and
    the result does not depend on the order of the samples.
    """
    a = np.asarray(angles_rad, dtype=float)
    ref = np.mean(a, axis=axis, keepdims=True)
    d = a - ref
    return np.squeeze(ref, axis=axis) + np.arctan2(
        np.mean(np.sin(d), axis=axis), np.mean(np.cos(d), axis=axis)
    )
