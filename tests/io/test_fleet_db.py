"""The fleet database: schema and migrations, one writer and concurrent readers, and the
failures that must end in one line with nothing lost (newer schema, not a database, read-only,
disk full)."""

from __future__ import annotations

import sqlite3
from pathlib import Path

import pytest

from odocal.errors import InputError
from odocal.io.fleet_db import MIGRATIONS, SCHEMA_VERSION, open_db
from tests.support.fleet import fake_result, fill_db

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
        assert [b.status for b in h] == ["done"] * 3 and h[0].result["parameters"]
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
        assert db.con.execute("SELECT version FROM schema_version").fetchone()[0] == 2
        assert db.robots() == [("r1", {})]
        db.remember_file("/a.bag", 1, 2, "h")  # the table of migration 2
        assert db.known_file("/a.bag", 1, 2) == "h" and db.known_file("/a.bag", 1, 3) is None


def test_a_newer_schema_is_refused_and_left_as_it_is(tmp_path):
    path = tmp_path / "f.db"
    with open_db(path, write=True) as db, db.transaction() as c:
        c.execute("UPDATE schema_version SET version = 99")
    before = path.read_bytes()
    for write in (True, False):
        with pytest.raises(InputError, match=r"newer odocal \(schema 99; this one knows up to 2"):
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
            assert reader.count("done") == 2 and reader.history("r1")[0].result is not None
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
                         result=big)  # fmt: skip
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
