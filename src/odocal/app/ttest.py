"""``odocal ttest``: independent-samples t-tests (Student and Welch) of one column of two CSVs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..core.jsonable import finite_or_none
from ..core.stats import TTest, ttest_samples
from ..io.table import ColumnSample, read_column, read_table

__all__ = ["SampleInfo", "TTestStatistics", "TTestResult", "ttest"]


@dataclass(frozen=True)
class SampleInfo:
    """Where one sample came from: the file, the column and how many values it holds."""

    path: str
    column: str
    n: int

    @classmethod
    def of(cls, sample: ColumnSample) -> SampleInfo:
        """The summary of ``sample``."""
        return cls(sample.path, sample.column, int(sample.values.size))

    def as_dict(self) -> dict:
        """JSON-ready (the ``a`` and ``b`` objects of ``odocal ttest --json``)."""
        return {"path": self.path, "column": self.column, "n": self.n}


@dataclass(frozen=True)
class TTestStatistics:
    """One t-test's statistic, degrees of freedom and p-values (None where not finite, e.g. t of
    two samples without spread)."""

    t: float | None
    df: float | None
    p_two_sided: float | None
    p_less: float | None
    p_greater: float | None

    @classmethod
    def of(cls, test: TTest) -> TTestStatistics:
        """The statistics of ``test``, non-finite values as None."""
        return cls(
            finite_or_none(test.t),
            finite_or_none(test.df),
            finite_or_none(test.p_two_sided),
            finite_or_none(test.p_less),
            finite_or_none(test.p_greater),
        )

    def as_dict(self) -> dict:
        """JSON-ready (the ``student`` and ``welch`` objects of ``odocal ttest --json``)."""
        return {
            "t": self.t,
            "df": self.df,
            "p_two_sided": self.p_two_sided,
            "p_less": self.p_less,
            "p_greater": self.p_greater,
        }


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
            "a": SampleInfo.of(self.a).as_dict(),
            "b": SampleInfo.of(self.b).as_dict(),
            "mean_a": s.mean_a,
            "mean_b": s.mean_b,
            "std_a": s.std_a,
            "std_b": s.std_b,
            "mean_difference": s.mean_difference,
            "student": TTestStatistics.of(self.student).as_dict(),
            "welch": TTestStatistics.of(self.welch).as_dict(),
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
