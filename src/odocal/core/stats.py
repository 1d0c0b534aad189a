"""Independent-samples t-tests (Student and Welch), from samples or from summary statistics.

Textbook formulas (methods-notes section 7; model.md check value). With sample means m_a, m_b,
unbiased standard deviations s_a, s_b (ddof = 1) and sizes n_a, n_b:

    Student: s_p^2 = ((n_a-1) s_a^2 + (n_b-1) s_b^2) / (n_a + n_b - 2),
             t = (m_a - m_b) / sqrt(s_p^2 (1/n_a + 1/n_b)),  df = n_a + n_b - 2
    Welch:   t = (m_a - m_b) / sqrt(s_a^2/n_a + s_b^2/n_b),
             df = (s_a^2/n_a + s_b^2/n_b)^2 / ((s_a^2/n_a)^2/(n_a-1) + (s_b^2/n_b)^2/(n_b-1))

p-values: two-sided 2 sf(|t|), one-sided ``p_less`` (H1: mean_a < mean_b) = cdf(t) and
``p_greater`` (H1: mean_a > mean_b) = sf(t). They agree with ``scipy.stats.ttest_ind``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.special import stdtr

from ..errors import ModelError

__all__ = ["TTest", "ttest_from_stats", "ttest_samples", "ttest_paired"]


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
    va, vb = std_a**2 / n_a, std_b**2 / n_b
    if equal_var:
        df = float(n_a + n_b - 2)
        sp2 = ((n_a - 1) * std_a**2 + (n_b - 1) * std_b**2) / df
        se = math.sqrt(sp2 * (1.0 / n_a + 1.0 / n_b))
    else:
        se = math.sqrt(va + vb)
        denom = va**2 / (n_a - 1) + vb**2 / (n_b - 1)
        df = (va + vb) ** 2 / denom if denom > 0 else float(n_a + n_b - 2)
    diff = mean_a - mean_b
    if se > 0:
        t = diff / se
        # stdtr(df, t) is the Student-t CDF (what scipy.stats.t.cdf calls, without its overhead)
        p_less = float(stdtr(df, t))
        p_greater = float(stdtr(df, -t))
        p_two = float(min(1.0, 2.0 * stdtr(df, -abs(t))))
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


def ttest_samples(a, b, equal_var: bool = False) -> TTest:
    """t-test of sample ``a`` against sample ``b`` (1-D arrays of finite values)."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    for name, x in (("a", a), ("b", b)):
        if x.size < 2:
            raise ModelError(f"a t-test needs at least 2 values per group; {name} has {x.size}")
        if not np.all(np.isfinite(x)):
            raise ModelError(f"group {name} holds non-finite values")
    return ttest_from_stats(
        float(a.mean()),
        float(a.std(ddof=1)),
        a.size,
        float(b.mean()),
        float(b.std(ddof=1)),
        b.size,
        equal_var=equal_var,
    )


def ttest_paired(a, b) -> TTest:
    """Paired t-test of ``a`` against ``b`` (the same units measured twice, e.g. the same runs
    dead-reckoned with two parameter sets): t = mean(d) / (std(d) / sqrt(n)), d = a - b,
    df = n - 1 (kind 'paired'; ``std_a``, ``std_b`` are the groups' own deviations)."""
    a = np.asarray(a, dtype=float).ravel()
    b = np.asarray(b, dtype=float).ravel()
    if a.size != b.size:
        raise ModelError(f"a paired t-test needs pairs: {a.size} values against {b.size}")
    if a.size < 2:
        raise ModelError(f"a paired t-test needs at least 2 pairs, got {a.size}")
    if not (np.all(np.isfinite(a)) and np.all(np.isfinite(b))):
        raise ModelError("a paired t-test needs finite values")
    d = a - b
    n = d.size
    sd = float(d.std(ddof=1))
    diff = float(d.mean())
    df = float(n - 1)
    if sd > 0:
        t = diff / (sd / math.sqrt(n))
        p_less, p_greater = float(stdtr(df, t)), float(stdtr(df, -t))
        p_two = float(min(1.0, 2.0 * stdtr(df, -abs(t))))
    elif diff == 0:
        t = p_less = p_greater = p_two = math.nan
    else:
        t = math.copysign(math.inf, diff)
        p_less, p_greater = (0.0, 1.0) if diff < 0 else (1.0, 0.0)
        p_two = 0.0
    return TTest(
        "paired",
        float(t),
        df,
        p_two,
        p_less,
        p_greater,
        float(a.mean()),
        float(b.mean()),
        float(a.std(ddof=1)),
        float(b.std(ddof=1)),
        n,
        n,
    )


def circular_mean(angles_rad, axis=-1):
    """Circular mean of unwrapped angles that keeps their unwrapped scale.

    The mean direction is taken relative to the first sample, so a set of errors near -2 pi stays
    near -2 pi (and small errors stay small) instead of being wrapped into (-pi, pi].
    """
    a = np.asarray(angles_rad, dtype=float)
    ref = np.take(a, [0], axis=axis)
    d = a - ref
    return np.squeeze(ref, axis=axis) + np.arctan2(
        np.mean(np.sin(d), axis=axis), np.mean(np.cos(d), axis=axis)
    )
