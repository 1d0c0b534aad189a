"""``odocal.app.ttest.ttest`` on its typed result: the TV6 check values of two CSV columns, the
column it chooses, non-finite statistics as None."""

from __future__ import annotations

import pytest

from odocal.app.ttest import TTestStatistics, ttest
from odocal.core.stats import ttest_samples

# the TV6 samples of model.md / methods-notes (tests/core/test_stats.py checks the statistics)
A = [12.1, 15.3, 9.8, 14.2, 11.0]
B = [18.4, 21.0, 16.7, 25.3, 19.9]


@pytest.fixture
def samples(tmp_path):
    a = tmp_path / "a.csv"
    b = tmp_path / "b.csv"
    a.write_text("run,label,error_mm\n" + "".join(f"{i},x,{v}\n" for i, v in enumerate(A)))
    b.write_text("# second method\nerror_mm,note\n" + "".join(f"{v},y\n" for v in B))
    return a, b


def test_student_and_welch_of_one_column(samples):
    res = ttest(*samples, column="error_mm")
    assert res.student.t == pytest.approx(-4.396112, abs=1e-6)
    assert res.student.p_two_sided == pytest.approx(0.00229867, abs=1e-8)
    assert res.student.p_less == pytest.approx(0.00114934, abs=1e-8)
    assert res.welch.df == pytest.approx(7.136864, abs=1e-6)
    assert res.welch.p_two_sided == pytest.approx(0.00302735, abs=1e-8)
    assert res.student.mean_difference == pytest.approx(-7.78)
    assert (res.a.column, res.b.column) == ("error_mm", "error_mm")
    assert res.a.values.tolist() == A and res.b.values.tolist() == B
    assert res.warnings == ()
    d = res.as_dict()
    assert d["a"]["n"] == 5 and d["b"]["column"] == "error_mm"
    assert d["student"] == TTestStatistics.of(res.student).as_dict()


def test_the_default_column_is_each_file_s_first_numeric_one(samples):
    res = ttest(*samples)
    # A's first numeric column is 'run'; B has no 'run' and uses its own first numeric column
    assert (res.a.column, res.b.column) == ("run", "error_mm")
    assert res.a.values.tolist() == [0.0, 1.0, 2.0, 3.0, 4.0]


def test_samples_without_spread_warn_and_give_none(tmp_path):
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("v\n1\n1\n1\n")
    b.write_text("v\n1\n1\n")
    res = ttest(a, b)
    assert res.student.t != res.student.t  # nan: equal means, no spread
    assert any("zero spread" in w and "undefined" in w for w in res.warnings)
    stats = TTestStatistics.of(res.student)
    assert stats.t is None and stats.p_two_sided is None
    assert ttest_samples([1, 1, 1], [1, 1], True).df == stats.df == 3
