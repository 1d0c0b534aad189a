"""``odocal ttest``: the check values printed and as JSON, the column it chose, bad inputs."""

from __future__ import annotations

import json

import pytest

import odocal.app.ttest as app_ttest
from tests.support.printed import as_printed

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


def test_cli_ttest_check_value(cli, samples):
    a, b = samples
    status, out, err = cli("ttest", a, b, "--column", "error_mm")
    assert status == 0, err
    assert "-4.396112" in out and "0.00229867" in out and "0.00114934" in out
    assert "7.1369" in out and "0.00302735" in out


def test_cli_ttest_json(cli, samples, returned):
    results = returned(app_ttest, "ttest")
    a, b = samples
    status, out, _ = cli("ttest", a, b, "--column", "error_mm", "--json")
    assert status == 0
    d = json.loads(out)
    # the app's typed result, printed (its numbers: tests/app/test_ttest.py)
    assert d == as_printed(results[0].as_dict())
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


def test_cli_ttest_of_one_column_saved_with_decimal_commas(cli, tmp_path, samples):
    # issue 27 item 19: the README promises the European dialect; one column has no separator
    a, b = samples
    eu = tmp_path / "b_eu.csv"
    eu.write_text("error_mm\n" + "".join(f"{v}\n".replace(".", ",") for v in B))
    status, out, err = cli("ttest", a, eu, "--column", "error_mm")
    assert status == 0, err
    assert out == cli("ttest", a, b, "--column", "error_mm")[1].replace(str(b), str(eu))
