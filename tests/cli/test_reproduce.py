"""``odocal reproduce``: bad inputs, the message without matplotlib, --out or --json required."""

from __future__ import annotations

import sys


def test_cli_reproduce_bad_inputs(cli, tmp_path):
    cli("reproduce", "--out", tmp_path, "--trials", "1").expect_error("--trials")
    cli("reproduce").expect_error("--out")
    f = tmp_path / "file"
    f.write_text("x")
    cli("reproduce", "--out", f, "--trials", "5").expect_error("file")


def test_cli_reproduce_without_matplotlib(cli, tmp_path, monkeypatch):
    # a None entry in sys.modules makes the import fail as if matplotlib were not installed
    for mod in ("matplotlib.figure", "matplotlib.backends.backend_agg"):
        monkeypatch.setitem(sys.modules, mod, None)
    cli("reproduce", "--out", tmp_path / "r", "--trials", "5").expect_error("pip install")
    assert not (tmp_path / "r").exists()


def test_reproduce_needs_out_or_json(cli):
    cli("reproduce").expect_error("--out DIR")
