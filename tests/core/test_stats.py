"""t-tests: the model.md / methods-notes TV6 check values, scipy agreement, and ``odocal ttest``."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from odocal.core.stats import ttest_from_stats, ttest_samples
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


# --- odocal ttest -------------------------------------------------------------------------


@pytest.fixture
def samples(tmp_path):
    a = tmp_path / "a.csv"
    b = tmp_path / "b.csv"
    a.write_text("run,label,error_mm\n" + "".join(f"{i},x,{v}\n" for i, v in enumerate(A)))
    b.write_text("# second method\nerror_mm,note\n" + "".join(f"{v},y\n" for v in B))
    return a, b


def test_cli_ttest_check_value(cli, samples):
    a, b = samples
    status, out, err = cli("ttest", a, b, "--column", "error_mm")
    assert status == 0, err
    assert "-4.396112" in out and "0.00229867" in out and "0.00114934" in out
    assert "7.1369" in out and "0.00302735" in out


def test_cli_ttest_json(cli, samples):
    a, b = samples
    status, out, _ = cli("ttest", a, b, "--column", "error_mm", "--json")
    assert status == 0
    d = json.loads(out)
    assert d["student"]["t"] == pytest.approx(-4.396112, abs=1e-6)
    assert d["welch"]["df"] == pytest.approx(7.136864, abs=1e-6)
    assert d["mean_difference"] == pytest.approx(-7.78)
    assert d["a"]["n"] == 5 and d["b"]["column"] == "error_mm"


def test_cli_ttest_default_column_is_first_numeric_and_is_named(cli, samples):
    a, b = samples
    status, out, _ = cli("ttest", a, b)
    assert status == 0
    # A's first numeric column is 'run'; B has no 'run' and uses its own first numeric column
    assert "column 'run'" in out and "column 'error_mm'" in out
    assert "first numeric column" in out


def test_cli_ttest_bad_inputs(cli, tmp_path, samples):
    a, _ = samples
    cli("ttest", a, tmp_path / "missing.csv").expect_error("missing.csv", "no such file")
    cli("ttest", a, a, "--column", "nope").expect_error("no column 'nope'")
    bad = tmp_path / "bad.csv"
    bad.write_text("error_mm\n1.0\nabc\n")
    cli("ttest", a, bad, "--column", "error_mm").expect_error("bad.csv", "line 3", "error_mm")
    one = tmp_path / "one.csv"
    one.write_text("error_mm\n1.0\n")
    cli("ttest", one, a, "--column", "error_mm").expect_error("one.csv", "at least 2")
    empty = tmp_path / "empty.csv"
    empty.write_text("")
    cli("ttest", empty, a).expect_error("empty.csv", "empty file")
    text = tmp_path / "text.csv"
    text.write_text("name\nfoo\nbar\n")
    cli("ttest", text, a).expect_error("text.csv", "no numeric column")
    ragged = tmp_path / "ragged.csv"
    ragged.write_text("a,b\n1,2\n3\n")
    cli("ttest", ragged, a).expect_error("ragged.csv", "line 3")


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
