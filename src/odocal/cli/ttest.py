"""``odocal ttest``: independent-samples t-tests (Student and Welch) of one column of two CSVs."""

from __future__ import annotations

from .common import print_json, print_table, print_warnings


def add_parser(sub) -> None:
    """Add ``odocal ttest``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "ttest",
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


def run(args) -> int:
    """Run ``odocal ttest`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..app.ttest import ttest

    res = ttest(args.a_csv, args.b_csv, args.column)
    a, b = res.a, res.b
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
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
