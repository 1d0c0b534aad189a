"""core.stats: the t-tests (the model.md / methods-notes TV6 check values, scipy agreement, paired
tests), the t distribution without scipy, the circular mean."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.stats import circular_mean, ttest_from_stats, ttest_paired, ttest_samples
from odocal.errors import ModelError

A = [12.1, 15.3, 9.8, 14.2, 11.0]
B = [18.4, 21.0, 16.7, 25.3, 19.9]


def test_student_check_value_tv6():
    r = ttest_samples(A, B, equal_var=True)
    assert r.t == pytest.approx(-4.396112, abs=1e-6)
    assert r.df == 8
    assert r.p_two_sided == pytest.approx(0.00229867, abs=1e-8)
    assert r.p_less == pytest.approx(0.00114934, abs=1e-8)
    assert r.p_greater == pytest.approx(1 - 0.00114934, abs=1e-8)
    assert r.mean_difference == pytest.approx(12.48 - 20.26, abs=1e-12)


def test_welch_check_value_tv6():
    r = ttest_samples(A, B, equal_var=False)
    assert r.df == pytest.approx(7.136864, abs=1e-6)
    assert r.p_two_sided == pytest.approx(0.00302735, abs=1e-8)


@pytest.mark.parametrize("equal_var", [True, False])
@pytest.mark.parametrize("alternative", ["two-sided", "less", "greater"])
def test_agrees_with_scipy(equal_var, alternative):
    from scipy import stats

    rng = np.random.default_rng(7)
    a = rng.normal(1.0, 0.3, 13)
    b = rng.normal(1.2, 0.7, 21)
    ours = ttest_samples(a, b, equal_var)
    ref = stats.ttest_ind(a, b, equal_var=equal_var, alternative=alternative)
    p = {"two-sided": ours.p_two_sided, "less": ours.p_less, "greater": ours.p_greater}
    assert ours.t == pytest.approx(ref.statistic, rel=1e-12)
    assert p[alternative] == pytest.approx(ref.pvalue, rel=1e-9)
    assert ours.df == pytest.approx(ref.df, rel=1e-12)


def test_from_stats_matches_scipy_from_stats():
    from scipy import stats

    ours = ttest_from_stats(0.3, 0.05, 800, 0.31, 0.07, 600)
    ref = stats.ttest_ind_from_stats(0.3, 0.05, 800, 0.31, 0.07, 600, equal_var=False)
    assert ours.t == pytest.approx(ref.statistic, rel=1e-12)
    assert ours.p_two_sided == pytest.approx(ref.pvalue, rel=1e-9)


def test_zero_variance_is_decided_by_the_means():
    r = ttest_from_stats(1.0, 0.0, 5, 2.0, 0.0, 5)
    assert r.t == -math.inf and r.p_less == 0.0 and r.p_greater == 1.0
    r = ttest_from_stats(1.0, 0.0, 5, 1.0, 0.0, 5)
    assert math.isnan(r.t) and math.isnan(r.p_two_sided)


@pytest.mark.parametrize(
    "args",
    [(1.0, 0.1, 1, 1.0, 0.1, 5), (1.0, -0.1, 5, 1.0, 0.1, 5), (math.nan, 0.1, 5, 1.0, 0.1, 5)],
)
def test_bad_summary_statistics(args):
    with pytest.raises(ModelError):
        ttest_from_stats(*args)


def test_bad_samples():
    with pytest.raises(ModelError, match="at least 2"):
        ttest_samples([1.0], [1.0, 2.0])
    with pytest.raises(ModelError, match="non-finite"):
        ttest_samples([1.0, math.inf], [1.0, 2.0])


@pytest.mark.parametrize("df", [0.7, 1, 2, 7.7, 30, 1598.2, 1e5])
def test_student_t_tail_and_quantile_without_scipy_agree_with_scipy(df):
    from scipy import stats

    from odocal.core.stats import student_t_quantile, student_t_sf

    def sf(t):  # df 1 is Cauchy: exact in closed form (scipy loses digits near t = 0 there)
        return 0.5 - math.atan(t) / math.pi if df == 1 else stats.t.sf(t, df)

    for t in (0.0, 1e-6, 0.3, 1.96, 4.0, 12.0):
        assert student_t_sf(t, df) == pytest.approx(sf(t), rel=1e-9, abs=1e-300)
        assert student_t_sf(-t, df) == pytest.approx(sf(-t), rel=1e-12)
    for p in (1e-6, 0.025, 0.5, 0.9, 0.975):
        assert student_t_quantile(p, df) == pytest.approx(stats.t.ppf(p, df), rel=1e-10, abs=1e-14)


def test_circular_mean_keeps_unwrapped_scale():
    a = np.array([-2 * math.pi + 0.01, -2 * math.pi - 0.01, -2 * math.pi + 0.03])
    assert circular_mean(a) == pytest.approx(-2 * math.pi + 0.01, abs=1e-4)
    # samples either side of the +-pi cut: the mean is pi, not 0
    assert circular_mean(np.array([3.1, -3.1])) == pytest.approx(math.pi, abs=1e-12)


def test_paired_ttest_matches_scipy():
    from scipy import stats

    rng = np.random.default_rng(4)
    a = rng.normal(0.03, 0.01, 19)
    b = a - rng.normal(0.02, 0.01, 19)
    t = ttest_paired(a, b)
    ref = stats.ttest_rel(a, b)
    assert t.t == pytest.approx(ref.statistic) and t.p_two_sided == pytest.approx(ref.pvalue)
    assert t.df == 18 and t.kind == "paired"


@pytest.mark.parametrize("scale", [1e-300, 1e-200, 1e200])
def test_the_t_tests_do_not_depend_on_the_data_s_scale(scale):
    """Data on a 1e-300 scale once gave variances that underflowed to 0 (t = -inf, p = 0, 'zero
    spread'); on a 1e200 scale they overflow. t, df and p are those of the same data in units of
    1, and an ordinary scale gives exactly the unscaled bits (a power-of-two rescaling)."""
    a, b = np.array([1.0, 2.0, 3.0]), np.array([2.0, 3.0, 4.5])
    for test in (ttest_samples, ttest_paired):
        one = test(a, b)
        far = test(a * scale, b * scale)
        assert far.t == pytest.approx(one.t, rel=1e-12) and math.isfinite(far.t)
        assert far.df == pytest.approx(one.df, rel=1e-12)
        assert far.p_two_sided == pytest.approx(one.p_two_sided, rel=1e-9)
        assert far.std_a == pytest.approx(scale * one.std_a, rel=1e-12) and far.std_a > 0
    student = ttest_samples(a * scale, b * scale, equal_var=True)
    assert student.t == pytest.approx(ttest_samples(a, b, equal_var=True).t, rel=1e-12)
    from_stats = ttest_from_stats(2e-300, 1e-300, 3, 3e-300, 1e-300, 3)
    assert from_stats.t == pytest.approx(ttest_from_stats(2.0, 1.0, 3, 3.0, 1.0, 3).t, rel=1e-12)
