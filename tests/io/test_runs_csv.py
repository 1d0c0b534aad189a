"""``odocal.io.runs_csv``: the run-sheet reader's vectorised pass and its line-by-line twin."""

from __future__ import annotations

import numpy as np
import pytest

import odocal.io.runs_csv as runs_csv
from odocal.io.runs_csv import read_run_sheet


def _sheet(n: int, seed: int = 0) -> str:
    rng = np.random.default_rng(seed)
    v = rng.normal(0.0, [0.01, 0.02, 1.5], size=(n, 3))
    rows = [
        f"{'cw' if i % 2 else 'ccw'},{v[i, 0]:.6f},{v[i, 1]:.6f},{v[i, 2]:.4f},{i + 1}"
        for i in range(n)
    ]
    return "# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg,run\n" + "\n".join(rows) + "\n"


def test_a_clean_sheet_is_parsed_without_per_row_python(tmp_path, monkeypatch):
    # issue 20, performance: per-row Python made a 5-million-row sheet take 85 s and 4.5 GB
    calls = []

    def counted(*args, **kwargs):
        calls.append(args[1:3])
        return parse(*args, **kwargs)

    parse = runs_csv.parse_number
    monkeypatch.setattr(runs_csv, "parse_number", counted)
    p = tmp_path / "runs.csv"
    p.write_text(_sheet(3000))
    sheet = read_run_sheet(p, warnings=[])
    assert len(sheet.runs.directions) == 3000
    assert len(calls) <= 2  # the '# sides:' and '# side_m:' settings only


def test_vectorised_and_line_by_line_reads_agree(tmp_path):
    text = _sheet(400, seed=1)
    lines = text.splitlines()
    # the same runs the slow way: upper case, spaces, quotes, comments, blank lines, empty x, y
    slow, rows = list(lines[:3]), []
    for k, line in enumerate(lines[3:]):
        d, *rest = line.split(",")
        if k % 7 == 0:
            rest[0] = rest[1] = ""
        rows.append(",".join([f'"{d.upper()}"' if k % 2 else f" {d.upper()} ", *rest]))
        slow.append(rows[-1])
        if k % 50 == 0:
            slow += ["", "# a note"]
    fast = [ln if (k - 3) % 7 or k < 3 else ",".join([ln.split(",")[0], "", "", *ln.split(",")[3:]])
            for k, ln in enumerate(lines)]  # fmt: skip
    fast += [fast[10], fast[11]]  # two repeated runs
    slow += [rows[7], rows[8]]
    a, b = tmp_path / "fast.csv", tmp_path / "slow.csv"
    a.write_text("\n".join(fast) + "\n")
    b.write_text("\n".join(slow) + "\n")
    wa, wb = [], []
    heading = ("theta_deg",)
    ra = read_run_sheet(a, required=heading, warnings=wa)
    rb = read_run_sheet(b, required=heading, warnings=wb)
    assert ra.runs.directions == rb.runs.directions
    np.testing.assert_array_equal(ra.runs.errors, rb.runs.errors)  # NaN where empty, both
    assert np.isnan(ra.runs.errors[0, 0]) and not np.isnan(ra.runs.errors[1, 0])
    assert ra.lines[:3].tolist() == [4, 5, 6]
    assert len(wa) == len(wb) == 2
    assert wa[0].endswith("line 404 repeats line 11 exactly: the same run entered twice? Each "
                          "row counts as a run")  # fmt: skip
    assert "repeats line" in wb[0] and (ra.sides, ra.side_m) == (rb.sides, rb.side_m) == (4, 1.0)


@pytest.mark.parametrize(
    "row, needles",
    [
        ("up,0.1,0.1,1,9", ["line 1004", "field 'direction'", "unknown direction 'up'"]),
        ("cw,0.1,abc,1,9", ["line 1004", "field 'y_m'", "not a number: 'abc'"]),
        ("cw,0.1,0.1,,9", ["line 1004", "field 'theta_deg'", "not filled in"]),
        ("cw,0.1,0.1,nan,9", ["line 1004", "field 'theta_deg'", "must be finite"]),
        ("cw,0.1,1e9,1,9", ["line 1004", "field 'y_m'", "implausibly large"]),
        ("cw,0.1,0.1,1", ["line 1004", "expected 5 fields as in the header, got 4"]),
    ],
)
def test_a_bad_row_among_many_is_named(tmp_path, row, needles):
    p = tmp_path / "runs.csv"
    p.write_text(_sheet(1000) + row + "\n" + _sheet(5).splitlines()[-1] + "\n")
    with pytest.raises(runs_csv.InputError) as info:
        read_run_sheet(p)
    for n in needles:
        assert n in str(info.value)
