"""``odocal ttest``: independent-samples t-tests (Student and Welch) of one column of two CSVs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..core.stats import TTest, ttest_samples
from ..io.table import ColumnSample, read_column, read_table

__all__ = ["TTestResult", "ttest"]


@dataclass(frozen=True)
class TTestResult:
    """Both t-tests of sample a (first file) against sample b (second file), and warnings."""

    a: ColumnSample
    b: ColumnSample
    student: TTest
    welch: TTest
    warnings: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal ttest --json`` (non-finite statistics as null)."""
        s = self.student
        return {
            "a": {"path": self.a.path, "column": self.a.column, "n": int(self.a.values.size)},
            "b": {"path": self.b.path, "column": self.b.column, "n": int(self.b.values.size)},
            "mean_a": s.mean_a,
            "mean_b": s.mean_b,
            "std_a": s.std_a,
            "std_b": s.std_b,
            "mean_difference": s.mean_difference,
            "student": _test_dict(self.student),
            "welch": _test_dict(self.welch),
        }


def _finite(v):
    return v if v is not None and v == v and abs(v) != float("inf") else None


def _test_dict(t: TTest) -> dict:
    return {
        k: _finite(v)
        for k, v in {
            "t": t.t,
            "df": t.df,
            "p_two_sided": t.p_two_sided,
            "p_less": t.p_less,
            "p_greater": t.p_greater,
        }.items()
    }


def ttest(a_csv: str | Path, b_csv: str | Path, column: str | None = None) -> TTestResult:
    """Student and Welch t-tests of ``column`` of ``a_csv`` against the same column of
    ``b_csv`` (default: each file's first numeric column; B uses A's column when it has one of
    that name)."""
    a = read_column(a_csv, column)
    table_b = read_table(b_csv, what="a header row and values")
    b = read_column(
        b_csv, column or (a.column if a.column in table_b.header else None), table=table_b
    )
    student = ttest_samples(a.values, b.values, True)
    welch = ttest_samples(a.values, b.values, False)
    warnings = []
    if student.std_a == 0 and student.std_b == 0:
        warnings.append(
            "both samples have zero spread: t is "
            + ("undefined (equal means)" if student.mean_difference == 0 else "infinite")
            + " and the test says nothing beyond the means"
        )
    return TTestResult(a, b, student, welch, tuple(warnings))
