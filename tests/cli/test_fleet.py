"""`odocal fleet`: parsing, printing and exit codes (the work is tested in tests/app)."""

from __future__ import annotations

import json

import numpy as np

from odocal.io.fleet_db import open_db
from tests.support.fleet import fill_db, robot_yaml

SE = (5e-5, 5e-5, 2.5e-4)


def _db(path, n=6):
    rng = np.random.default_rng(1)
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": [(tuple(np.array([0.05, 0.05, 0.25]) + np.array(SE) *
                                   rng.standard_normal(3)), SE) for _ in range(n)]})  # fmt: skip
    return path


def test_status_text_and_json(cli, tmp_path):
    db = _db(tmp_path / "f.db")
    status, out, err = cli("fleet", "status", "--db", db)
    assert status == 0 and err == ""
    header, row = out.splitlines()
    assert header.split() == ["robot", "bags", "failed", "D_R", "mm", "D_L", "mm", "b", "mm",
                              "drift"]  # fmt: skip
    assert row.split()[:3] == ["r1", "6", "0"] and row.split()[-1] == "-"
    status, out, _ = cli("fleet", "status", "--db", db, "--json")
    (r,) = json.loads(out)["robots"]
    assert r["drift_alarm"] is False and set(r["parameters"]) == {
        "wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"}  # fmt: skip


def test_export(cli, tmp_path):
    db = _db(tmp_path / "f.db")
    status, out, _ = cli("fleet", "export", "r1", "--db", db, "--ros2", tmp_path / "r1.yaml")
    assert status == 0 and "filtered level of 6 bags" in out
    assert "diff_drive_controller:" in (tmp_path / "r1.yaml").read_text()
    status, out, _ = cli("fleet", "export", "r1", "--db", db, "--ros2", tmp_path / "2.yaml",
                         "--json")  # fmt: skip
    assert status == 0 and json.loads(out)["bags"] == 6


def test_ingest_text(cli, tmp_path):
    robot_yaml(tmp_path / "root" / "r1")
    (tmp_path / "root" / "r1" / "x.bag").write_bytes(b"junk")
    status, out, err = cli("fleet", "ingest", tmp_path / "root", "--db", tmp_path / "f.db")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("1 bags under") and "0 new, 1 failed (0 to retry)" in lines[0]
    assert lines[1].startswith("  failed: ") and lines[1].count("x.bag") == 1


def _one_line(status, out, err, *needles):
    assert status == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith("odocal: error: ")
    for n in needles:
        assert n in err, err


def test_bad_inputs_are_one_line(cli, tmp_path):
    root = tmp_path / "root"
    (root / "r1").mkdir(parents=True)
    _one_line(*cli("fleet", "ingest", root, "--db", tmp_path / "f.db"),
              "r1: robot folder without robot.yaml")  # fmt: skip
    assert not (tmp_path / "f.db").exists()
    db = _db(tmp_path / "new.db")
    with open_db(db, write=True) as fdb, fdb.transaction() as c:
        c.execute("UPDATE schema_version SET version = 7")
    robot_yaml(root / "r1")
    for argv in (("ingest", root), ("status",), ("report", "--html", tmp_path / "h")):
        _one_line(*cli("fleet", *argv, "--db", db), "newer odocal (schema 7")
    _one_line(*cli("fleet", "status", "--db", tmp_path / "missing.db"), "no fleet database")
    _one_line(*cli("fleet", "ingest", root, "--db", tmp_path / "f.db", "--workers", "0"))
    _one_line(*cli("fleet", "export", "r1", "--db", db, "--ros2", db), "overwrite an input")
    _one_line(*cli("fleet", "status"), "--db")


def test_ingest_names_a_robot_it_could_not_ingest_and_goes_on(cli, tmp_path):
    robot_yaml(tmp_path / "root" / "r1")
    (tmp_path / "root" / "r1" / "x.bag").write_bytes(b"junk")
    (tmp_path / "root" / "r2").mkdir()
    status, out, err = cli("fleet", "ingest", tmp_path / "root", "--db", tmp_path / "f.db")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("1 bags under") and "(1 robots)" in lines[0]
    assert lines[-1] == (f"  robot not ingested: {tmp_path / 'root' / 'r2'}: robot folder without "
                         "robot.yaml (each robot's folder holds its nominal geometry: "
                         "wheel_diameter_m, wheelbase_m; docs/fleet.md)")  # fmt: skip
