"""The fleet database: schema and migrations, one writer and concurrent readers, and the
failures that must end in one line with nothing lost (newer schema, not a database, read-only,
disk full)."""

from __future__ import annotations

import json
import sqlite3
from pathlib import Path

import numpy as np
import pytest

from odocal.errors import InputError
from odocal.io.fleet_db import MIGRATIONS, SCHEMA_VERSION, open_db
from tests.support.fleet import fake_record, fake_result, fill_db, first_format, old_database

NOW = "2026-01-01T00:00:00+00:00"


def _history(n=3):
    return [((0.05, 0.05, 0.25), (5e-5, 5e-5, 2.5e-4))] * n


def test_a_new_database_has_the_schema_in_wal_mode(tmp_path):
    with open_db(tmp_path / "f.db", write=True) as db:
        fill_db(db, {"r1": _history()})
        assert db.con.execute("PRAGMA journal_mode").fetchone()[0] == "wal"
        assert db.con.execute("SELECT version FROM schema_version").fetchall() == [
            (SCHEMA_VERSION,)
        ]
    with open_db(tmp_path / "f.db", write=False) as db:
        h = db.history("r1")
        assert [b.status for b in h] == ["done"] * 3 and h[0].record.parameters
        assert db.report(h[0].content_hash)["parameters"]
        assert db.count() == 3 and db.robots()[0][0] == "r1"


def test_an_older_schema_is_migrated_and_keeps_its_rows(tmp_path):
    path = tmp_path / "f.db"
    con = sqlite3.connect(path)
    con.executescript("CREATE TABLE schema_version (version INTEGER NOT NULL);"
                      f"{MIGRATIONS[0]} INSERT INTO schema_version VALUES (1);")  # fmt: skip
    con.execute("INSERT INTO robots VALUES ('r1', '{}', '/r1', ?, ?)", (NOW, NOW))
    con.commit()
    con.close()
    with pytest.raises(InputError, match="older fleet database.*ingest"):
        open_db(path, write=False)
    with open_db(path, write=True) as db:
        assert db.con.execute("SELECT version FROM schema_version").fetchone()[0] == 3
        assert db.robots() == [("r1", {})]
        db.remember_file("/a.bag", 1, 2, "h")  # the table of migration 2
        assert db.known_file("/a.bag", 1, 2) == "h" and db.known_file("/a.bag", 1, 3) is None


def test_a_newer_schema_is_refused_and_left_as_it_is(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db, db.transaction() as c:
        c.execute("UPDATE schema_version SET version = 99")
    before = path.read_bytes()
    for write in (True, False):
        with pytest.raises(InputError, match=r"newer odocal \(schema 99; this one knows up to 3"):
            open_db(path, write=write)
    assert path.read_bytes() == before


def test_not_a_database(tmp_path):
    (tmp_path / "x.db").write_text("hello, not sqlite\n" * 100)
    with pytest.raises(InputError, match="x.db.*not an odocal fleet database"):
        open_db(tmp_path / "x.db", write=True)
    other = tmp_path / "other.db"
    sqlite3.connect(other).execute("CREATE TABLE t (x)").connection.commit()
    with pytest.raises(InputError, match="no schema_version"):
        open_db(other, write=True)
    with pytest.raises(InputError, match="no fleet database here"):
        open_db(tmp_path / "missing.db", write=False)
    with pytest.raises(InputError, match="folder does not exist"):
        open_db(tmp_path / "nowhere" / "f.db", write=True)


def test_a_reader_reads_while_the_writer_is_in_a_transaction(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(2)})
        db.con.execute("BEGIN IMMEDIATE")  # the writer holds the write lock, uncommitted
        db.con.execute("DELETE FROM calibrations")
        with open_db(path, write=False) as reader:  # not blocked, sees the last commit
            assert reader.count("done") == 2 and reader.history("r1")[0].record is not None
        db.con.execute("ROLLBACK")


def test_a_read_only_database_is_one_line(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(1)})
    with open_db(path, write=False) as db:  # opened read-only: a write is refused
        with pytest.raises(InputError, match="readonly.*read-only"):
            db.upsert_robot("r2", {}, "/r2", NOW)
    with open_db(path, write=False) as db:
        assert db.count() == 1


def test_a_full_disk_loses_nothing_stored(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(2)})
        pages = db.con.execute("PRAGMA page_count").fetchone()[0]
        db.con.execute(f"PRAGMA max_page_count = {pages}")  # SQLite's own 'disk is full'
        big = fake_result("/big", (0.05, 0.05, 0.25), (1e-5, 1e-5, 1e-5))
        big["warnings"] = ["x" * 200_000]
        with pytest.raises(InputError, match="disk is full.*every bag stored so far is kept"):
            db.store_bag(content_hash="z" * 64, robot_id="r1", path="/big", size_bytes=1,
                         span_s=None, status="done", reason=None, version="t", now=NOW,
                         record=fake_record((0.05, 0.05, 0.25), (1e-5, 1e-5, 1e-5)),
                         report=big)  # fmt: skip
    with open_db(path, write=False) as db:
        assert db.count() == 2 and db.bag_status("z" * 64) is None


# ---- the fleet's edges (issue 27, item 15): two creators, an empty file, nothing left behind


def _create_and_count(path, barrier, results):
    """In a child process: wait for the other, then open (create) the database for writing."""
    try:
        barrier.wait(10)
        with open_db(path, write=True) as db:
            results.put(("ok", db.count()))
    except InputError as exc:
        results.put(("error", str(exc)))


def test_two_ingests_creating_one_new_database_both_succeed(tmp_path):
    """Both saw no database and made the schema: one failed ('table schema_version already
    exists', 'database is locked') in 2 of 3 tries. The database now appears whole or not at
    all (made beside it, then linked into place): the second uses the first's."""
    import multiprocessing as mp

    ctx = mp.get_context("fork")
    for i in range(8):
        path = tmp_path / f"f{i}.db"
        barrier, results = ctx.Barrier(2), ctx.Queue()
        procs = [ctx.Process(target=_create_and_count, args=(path, barrier, results))
                 for _ in range(2)]  # fmt: skip
        for p in procs:
            p.start()
        try:
            got = [results.get(timeout=60) for _ in procs]
        finally:
            for p in procs:
                p.join(10)
                if p.exitcode is None:
                    p.kill()
        assert got == [("ok", 0), ("ok", 0)], got
        with open_db(path, write=True) as db:
            assert db.con.execute("SELECT version FROM schema_version").fetchall() == [
                (SCHEMA_VERSION,)]  # fmt: skip
        # (two connections closing at the same instant may each leave the -wal and -shm files
        # to the other, as SQLite does: the next one to close alone removes them)
        assert [f.name for f in tmp_path.iterdir() if f.name.startswith(f"f{i}")] == [path.name]
    assert not [f for f in tmp_path.iterdir() if f.name.startswith(".")]  # no temporary left


def test_an_empty_file_is_not_a_fleet_database(tmp_path):
    """An empty file was 'an older fleet database (schema 0)' to a reader, and an ingest made it
    one (a database truncated to nothing would start again, its history gone unsaid)."""
    path = tmp_path / "f.db"
    path.touch()
    for write in (False, True):
        with pytest.raises(InputError, match=r"f.db: an empty file, not an odocal fleet database"):
            open_db(path, write=write)
    assert path.stat().st_size == 0 and [f.name for f in tmp_path.iterdir()] == ["f.db"]
    empty = tmp_path / "empty-sqlite.db"  # an SQLite database without a table
    sqlite3.connect(empty).execute("PRAGMA user_version = 1").connection.close()
    for write in (False, True):
        with pytest.raises(InputError, match="not an odocal fleet database"):
            open_db(empty, write=write)


def test_another_ingest_holding_the_database_is_one_line(tmp_path, monkeypatch):
    """Locked for longer than the wait: one line saying why."""
    import odocal.io.fleet_db as fleet_db

    path = tmp_path / "f.db"
    open_db(path, write=True).close()
    other = sqlite3.connect(path, isolation_level=None)
    other.execute("BEGIN IMMEDIATE")  # another ingest, storing a bag
    monkeypatch.setattr(fleet_db, "LOCK_TIMEOUT_S", 0.2)
    try:
        with open_db(path, write=True) as db:
            with pytest.raises(InputError, match="locked.*another odocal fleet ingest"):
                db.upsert_robot("r1", {}, "/r1", NOW)
    finally:
        other.execute("ROLLBACK")
        other.close()


def test_a_read_only_database_leaves_nothing_beside_it(tmp_path):
    """A read-only database in a folder one may write: SQLite opened it read-only without a word,
    the ingest failed at its first write, and -wal and -shm files stayed beside it. It is refused
    at once, one line, nothing created. (Opened in a forked child that becomes an unprivileged
    user when the tests run as root, who may write any file.)"""
    import os
    import select
    import shutil
    import signal
    import tempfile

    folder = Path(tempfile.mkdtemp(prefix="odocal-ro-"))  # (tmp_path's parents: root's alone)
    try:
        folder.chmod(0o777)
        path = folder / "f.db"
        with open_db(path, write=True) as db:
            fill_db(db, {"r1": _history(1)})
        path.chmod(0o444)
        r, w = os.pipe()
        pid = os.fork()
        if pid == 0:  # the child: report, then leave at once (no test machinery runs here)
            try:
                os.close(r)
                if os.geteuid() == 0:
                    os.setgroups([])
                    os.setgid(65534)
                    os.setuid(65534)
                try:
                    open_db(path, write=True).close()
                    msg = "opened"
                except InputError as exc:
                    msg = str(exc)
                os.write(w, f"{msg}\n{sorted(os.listdir(folder))}".encode())
            finally:
                os._exit(0)
        os.close(w)
        try:
            ready, _, _ = select.select([r], [], [], 60)
            if not ready:  # (never waited for: ended, then reaped)
                os.kill(pid, signal.SIGKILL)
            assert ready, "the child did not answer within 60 s"
            text = b""
            while chunk := os.read(r, 65536):
                text += chunk
        finally:
            os.close(r)
            os.waitpid(pid, 0)
        line, listing = text.decode().splitlines()
        assert "f.db: fleet database: read-only" in line and "ingest needs to write it" in line
        assert listing == "['f.db']"
    finally:
        shutil.rmtree(folder)


# ---- schema 3: the typed, versioned calibration record (issue 27, item 3)

KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def _old_drift_inputs(path, robot_id):
    """What the drift detector took from each bag before the record: fleet_status.robot_drift
    of the code before it (commit cddfbe2), reading result_json by its keys."""
    with sqlite3.connect(path) as con:
        rows = con.execute(
            "SELECT b.status, c.result_json, c.enough FROM bags b LEFT JOIN calibrations c "
            "USING (content_hash) WHERE b.robot_id = ? ORDER BY b.start_s, b.path",
            (robot_id,),
        ).fetchall()
    out = {}
    for key in KEYS:
        idx, vals, ses = [], [], []
        for i, (status, j, ok) in enumerate(rows):
            result = None if j is None else json.loads(j)
            p = ((result or {}).get("parameters") or {}).get(key) or {}
            v, se = p.get("value"), p.get("std_error")
            if status == "done" and bool(ok) and v is not None and se is not None and se > 0:
                idx.append(i)
                vals.append(v)
                ses.append(se)
        out[key] = (tuple(idx), vals, ses)
    return out


def _old_fleet():
    """Every kind of row the code before the record stored: both formats of result_json, a
    step in D_R, a first-version gyro answer (diameters without an error), a restricted model's
    held b (an error of 0), failed and untrusted bags, a bag no route could calibrate."""
    import numpy as np

    rng = np.random.default_rng(7)
    se = np.array([5e-5, 5e-5, 2.5e-4])
    true = np.array([0.0505, 0.0495, 0.25])
    worn, mixed = [], []
    for i in range(40):
        v = true * (1 + np.array([0.006 if i >= 25 else 0.0, 0, 0])) + se * rng.standard_normal(3)
        fit = fake_result(f"/fleet/worn/bag{i:03d}", v, se, enough=i % 9 != 4)
        worn.append(("done", first_format(fit) if i < 20 else fit))
    for i in range(12):
        v = true + se * rng.standard_normal(3)
        if i % 4 == 0:  # a restricted model of the first version: b held, reported as 0
            fit = first_format(fake_result("/b", v, (se[0], se[1], 0.0)))
        elif i % 4 == 1:  # the gyro of the first version: diameters without an error
            fit = first_format(fake_result("/b", (0.05, 0.05, v[2]), (None, None, se[2])))
            fit["answer_route"] = "gyro"
            fit["routes"] = [{"name": "gyro", "used": True, "reason": "x"}]
        elif i % 4 == 2:
            fit = fake_result("/b", v, se)
        else:
            mixed.append(("failed", None))
            continue
        mixed.append(("done", fit))
    none = fake_result("/b", (0, 0, 0), (None, None, None), enough=False)
    none.update(answer_route=None, answer_model=None, parameters=None)
    mixed.append(("done", none))
    return {"worn": worn, "mixed": mixed}


def test_a_database_of_the_code_before_the_record_is_migrated_with_its_drift_history(tmp_path):
    """Schema 2 stored the fit --json and read it by its keys; schema 3 reads every row into a
    record once. The drift history (which bags, their values and errors, the levels and the
    alarms) is the same, bit for bit."""
    from odocal.app.fleet_status import fleet_status, robot_drift
    from odocal.calibration.drift import track_parameter

    path = tmp_path / "old.db"
    old_database(path, _old_fleet())
    before = {r: _old_drift_inputs(path, r) for r in ("worn", "mixed")}
    with pytest.raises(InputError, match="older fleet database.*schema 2.*ingest"):
        open_db(path, write=False)
    open_db(path, write=True).close()  # what an ingest does first: migrate
    with open_db(path, write=False) as db:
        assert db.con.execute("SELECT version FROM schema_version").fetchone() == (3,)
        for robot_id, old in before.items():
            history = db.history(robot_id)
            assert all(b.record is not None for b in history if b.status == "done")
            for p in robot_drift(history).parameters:
                idx, vals, ses = old[p.key]
                assert p.bags == idx and p.values.tolist() == vals
                assert p.std_errors.tolist() == ses
                if vals:
                    t = track_parameter(np.asarray(vals), np.asarray(ses))
                    assert p.track.level.tolist() == t.level.tolist()
                    assert p.track.alarms == t.alarms
        # the columns are the record's: a held parameter has no standard error
        (row,) = db.con.execute(
            "SELECT d_right_se_m, wheelbase_m, wheelbase_se_m, route FROM calibrations "
            "WHERE content_hash LIKE 'mixed-0000%'"
        )
        assert row[0] == pytest.approx(5e-5, rel=0.5) and row[1] > 0.24 and row[2] is None
        assert row[3] == "slam"
        mixed = [b.record for b in db.history("mixed") if b.record is not None]
        assert [r.route for r in mixed[:2]] == ["slam", "gyro"] and mixed[-1].route is None
        assert [p.status for p in mixed[1].parameters] == ["held", "held", "estimated"]
    assert len(before["worn"]["wheel_diameter_right_m"][0]) == 36  # (4 untrusted bags)
    (worn,) = [r for r in fleet_status(path).robots if r.robot_id == "worn"]
    assert worn.drift_alarm and worn.alarms[0]["parameter"] == "wheel_diameter_right_m"


def test_a_row_the_migration_cannot_read_is_named_and_nothing_changes(tmp_path):
    """A stored result with a renamed key ('params' for 'parameters') dropped its bag from the
    drift history without a word; now the migration names the bag and changes nothing."""
    fleet = _old_fleet()
    status, fit = fleet["worn"][7]
    fit["params"] = fit.pop("parameters")
    path = tmp_path / "old.db"
    old_database(path, fleet)
    with sqlite3.connect(path) as con:
        rows = con.execute("SELECT * FROM calibrations ORDER BY content_hash").fetchall()
    with pytest.raises(InputError) as err:
        open_db(path, write=True)
    msg = str(err.value)
    assert "cannot migrate the fleet database to schema 3" in msg
    assert "bag /fleet/worn/bag007" in msg and "record.fit has no 'parameters'" in msg
    assert "nothing was changed" in msg and "\n" not in msg
    with sqlite3.connect(path) as con:
        assert con.execute("SELECT version FROM schema_version").fetchone() == (2,)
        assert con.execute("SELECT * FROM calibrations ORDER BY content_hash").fetchall() == rows
        assert "record_json" not in [c[1] for c in con.execute("PRAGMA table_info(calibrations)")]


def test_a_record_of_a_newer_odocal_is_one_line_naming_its_bag(tmp_path):
    from odocal.app.fleet_status import fleet_status

    path = tmp_path / "f.db"
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(2)})
        with db.transaction() as c:
            (text,) = c.execute("SELECT record_json FROM calibrations LIMIT 1").fetchone()
            d = json.loads(text)
            d["record_version"] = 2
            c.execute("UPDATE calibrations SET record_json = ? WHERE record_json = ?",
                      (json.dumps(d), text))  # fmt: skip
    with pytest.raises(InputError, match=r"record of bag /fleet/r1/bag00\d: record version 2 was "
                       "written by a newer odocal"):  # fmt: skip
        fleet_status(path)


def test_an_acknowledged_alarm_keeps_its_acknowledgement_when_the_alarms_are_replaced(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(3)})
        h = "r1-0002".ljust(64, "0")
        db.replace_alarms("r1", [("wheelbase_m", h, 1.7e9, 1e-3, 5.0)], NOW)
        db.acknowledge("r1", "wheelbase_m", h, "2026-02-01T00:00:00+00:00")
        db.replace_alarms("r1", [("wheelbase_m", h, 1.7e9, 1.1e-3, 5.5),
                                 ("wheel_diameter_left_m", h, 1.7e9, 1e-4, -4.5)],
                          "2026-03-01T00:00:00+00:00")  # fmt: skip
        got = {a.parameter: a for a in db.alarms("r1")}
        assert got["wheelbase_m"].acknowledged_at == "2026-02-01T00:00:00+00:00"
        assert got["wheelbase_m"].raised_at == NOW and got["wheelbase_m"].size == 1.1e-3
        assert not got["wheel_diameter_left_m"].acknowledged
        assert got["wheelbase_m"].bag == "/fleet/r1/bag002"
