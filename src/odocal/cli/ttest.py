"""``odocal ttest``: independent-samples t-tests (Student and Welch) of one column of two CSVs."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass

import numpy as np

from ..core.stats import TTest, ttest_samples
from ..errors import InputError
from .common import print_json, print_table, print_warnings


@dataclass(frozen=True)
class ColumnSample:
    """The finite values of one CSV column (blank cells skipped)."""

    path: str
    column: str
    values: np.ndarray


@dataclass(frozen=True)
class TTestFiles:
    """Both t-tests of sample a (first file) against sample b (second file)."""

    a: ColumnSample
    b: ColumnSample
    student: TTest
    welch: TTest


def _rows(path) -> tuple[list[str], list[tuple[int, list[str]]]]:
    from ..io.textfile import read_text

    text = read_text(path)
    lines = [
        (i + 1, line)
        for i, line in enumerate(text.splitlines())
        if line.strip() and not line.lstrip().startswith("#")
    ]
    if not lines:
        raise InputError("empty file, expected a header row and values", path)
    header = [h.strip() for h in next(csv.reader([lines[0][1]]))]
    if any(h == "" for h in header) or len(set(header)) != len(header):
        raise InputError("the header row needs unique, non-empty column names", path, lines[0][0])
    rows = []
    for line_no, line in lines[1:]:
        fields = [f.strip() for f in next(csv.reader(io.StringIO(line)))]
        if len(fields) != len(header):
            raise InputError(
                f"expected {len(header)} fields as in the header, got {len(fields)}", path, line_no
            )
        rows.append((line_no, fields))
    return header, rows


def _number(text: str) -> float | None:
    try:
        v = float(text)
    except ValueError:
        return None
    return v if math.isfinite(v) else None


def read_column(path, column: str | None = None) -> ColumnSample:
    """The values of ``column`` (default: the first column whose every non-blank cell is a
    finite number). Raises InputError naming the file, line and field for anything else."""
    header, rows = _rows(path)
    if not rows:
        raise InputError("no data rows after the header", path)
    if column is None:
        for j, name in enumerate(header):
            cells = [f[j] for _, f in rows if f[j] != ""]
            if cells and all(_number(c) is not None for c in cells):
                column = name
                break
        else:
            raise InputError("no numeric column (every column holds text)", path)
    elif column not in header:
        raise InputError(f"no column '{column}'; the header has {', '.join(header)}", path)
    j = header.index(column)
    values = []
    for line_no, fields in rows:
        if fields[j] == "":
            continue
        v = _number(fields[j])
        if v is None:
            raise InputError(f"not a finite number: {fields[j]!r}", path, line_no, column)
        values.append(v)
    if len(values) < 2:
        raise InputError(f"a t-test needs at least 2 values, got {len(values)}", path, None, column)
    values = np.asarray(values)
    with np.errstate(over="ignore", invalid="ignore"):
        spread_ok = math.isfinite(float(np.mean(values))) and math.isfinite(
            float(np.std(values, ddof=1))
        )
    if not spread_ok:
        raise InputError(
            "values too large for a t-test (their mean or spread overflows)", path, None, column
        )
    return ColumnSample(str(path), column, values)


def ttest_files(path_a, path_b, column: str | None = None) -> TTestFiles:
    """Student and Welch t-tests of ``column`` of ``path_a`` against the same column of
    ``path_b`` (default: each file's first numeric column)."""
    a = read_column(path_a, column)
    # without --column, B uses A's column when it has one of that name
    if column is None:
        header_b, _ = _rows(path_b)
        if a.column in header_b:
            column = a.column
    b = read_column(path_b, column)
    return TTestFiles(
        a, b, ttest_samples(a.values, b.values, True), ttest_samples(a.values, b.values, False)
    )


def add_parser(sub) -> None:
    p = sub.add_parser(
        "ttest",
        help="Student and Welch t-tests of two samples (CSV columns)",
        description="Independent-samples t-tests of sample A against sample B (e.g. the final "
        "position errors after two calibrations, as in the paper's Tables 2 and 3): t, df, "
        "two-sided and one-sided p, mean difference A - B. Blank cells and lines starting with "
        "'#' are skipped.",
    )
    p.add_argument("a_csv", metavar="A.csv", help="sample A: a CSV with a header row")
    p.add_argument("b_csv", metavar="B.csv", help="sample B: a CSV with a header row")
    p.add_argument(
        "--column",
        metavar="NAME",
        help="column to compare (default: the first numeric column of each file)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def _finite(v):
    return v if v is not None and math.isfinite(v) else None


def run(args) -> int:
    res = ttest_files(args.a_csv, args.b_csv, args.column)
    a, b = res.a, res.b
    if res.student.std_a == 0 and res.student.std_b == 0:
        print_warnings(
            [
                "both samples have zero spread: t is "
                + ("undefined (equal means)" if res.student.mean_difference == 0 else "infinite")
                + " and the test says nothing beyond the means"
            ]
        )
    if args.json:
        print_json(
            {
                "a": {"path": a.path, "column": a.column, "n": int(a.values.size)},
                "b": {"path": b.path, "column": b.column, "n": int(b.values.size)},
                "mean_a": res.student.mean_a,
                "mean_b": res.student.mean_b,
                "std_a": res.student.std_a,
                "std_b": res.student.std_b,
                "mean_difference": res.student.mean_difference,
                "student": {k: _finite(v) for k, v in _test_dict(res.student).items()},
                "welch": {k: _finite(v) for k, v in _test_dict(res.welch).items()},
            }
        )
        return 0
    how = "" if args.column else " (first numeric column; choose with --column)"
    print(f"A: {a.path}, column '{a.column}', n = {a.values.size}{how}")
    print(f"B: {b.path}, column '{b.column}', n = {b.values.size}{how}")
    s = res.student
    print(
        f"mean A {s.mean_a:.6g} (std {s.std_a:.4g}), mean B {s.mean_b:.6g} (std {s.std_b:.4g}), "
        f"mean difference A - B {s.mean_difference:.6g}"
    )
    rows = [("test", "t", "df", "p two-sided", "p (A < B)", "p (A > B)")]
    for name, t in (("Student (equal variances)", res.student), ("Welch", res.welch)):
        rows.append(
            (
                name,
                f"{t.t:.6f}",
                f"{t.df:.4f}" if t.kind == "welch" else f"{t.df:.0f}",
                f"{t.p_two_sided:.6g}",
                f"{t.p_less:.6g}",
                f"{t.p_greater:.6g}",
            )
        )
    print_table(rows)
    return 0


def _test_dict(t: TTest) -> dict:
    return {
        "t": t.t,
        "df": t.df,
        "p_two_sided": t.p_two_sided,
        "p_less": t.p_less,
        "p_greater": t.p_greater,
    }
