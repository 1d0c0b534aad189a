"""The fleet database (``odocal fleet``): SQLite from the standard library, one file.

Schema (version :data:`SCHEMA_VERSION`, built by the ordered :data:`MIGRATIONS`; docs/fleet.md):

- ``schema_version(version)``: one row, the last migration applied;
- ``robots(robot_id, nominal_json, folder, first_seen, last_seen)``;
- ``bags(content_hash, robot_id, path, size_bytes, start_s, end_s, status, reason,
  odocal_version, ingested_at, attempts)``: one row per distinct bag content (sha256 of its
  bytes; a ROS 2 folder: of its files in sorted order, names excluded), so a copied or renamed
  bag is one bag. ``status``: ``done`` (calibrated; its result in ``calibrations``), ``failed``
  (cannot be calibrated; ``reason`` says why; not tried again), ``retry`` (being written, or
  claimed by two robots: tried again at the next ingest);
- ``calibrations(content_hash, route, enough, d_right_m, d_right_se_m, d_left_m, d_left_se_m,
  wheelbase_m, wheelbase_se_m, result_json)``: the bag route's whole answer (``result_json`` is
  ``odocal fit BAG --method auto --json``) and its parameters as columns;
- ``files(path, size_bytes, mtime_ns, content_hash)`` (version 2): the last hash of each path,
  so a nightly run hashes only new or changed files;
- ``alarms(robot_id, parameter, content_hash, start_s, size, z, raised_at)``: the change
  detector's alarms (replaced for a robot each time its history grows).

One writer (the ingest's parent process; each bag is one transaction), any number of readers
(WAL mode). A new database appears whole (built beside it, then linked into place: two ingests
creating it at once both use the first one's); migrations run under SQLite's write lock (a
second ingest waits). A database written by a newer odocal is refused with one line; so is a
file that is not one (an empty file too), and a database to be written that cannot be, before
SQLite opens it (nothing left beside it). Every sqlite3 failure (read-only file, disk full,
locked by another ingest for longer than :data:`LOCK_TIMEOUT_S`) becomes one
:class:`InputError` line.
"""

from __future__ import annotations

import json
import os
import sqlite3
import stat
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError

__all__ = [
    "SCHEMA_VERSION",
    "MIGRATIONS",
    "FleetDb",
    "BagRow",
    "open_db",
    "db_errors",
]

MIGRATIONS: tuple[str, ...] = (
    # 1: robots, bags, calibrations, alarms
    """
    CREATE TABLE robots (
        robot_id TEXT PRIMARY KEY, nominal_json TEXT NOT NULL, folder TEXT NOT NULL,
        first_seen TEXT NOT NULL, last_seen TEXT NOT NULL);
    CREATE TABLE bags (
        content_hash TEXT PRIMARY KEY, robot_id TEXT NOT NULL REFERENCES robots(robot_id),
        path TEXT NOT NULL, size_bytes INTEGER NOT NULL, start_s REAL, end_s REAL,
        status TEXT NOT NULL CHECK (status IN ('done', 'failed', 'retry')), reason TEXT,
        odocal_version TEXT NOT NULL, ingested_at TEXT NOT NULL,
        attempts INTEGER NOT NULL DEFAULT 1);
    CREATE TABLE calibrations (
        content_hash TEXT PRIMARY KEY REFERENCES bags(content_hash), route TEXT,
        enough INTEGER NOT NULL, d_right_m REAL, d_right_se_m REAL, d_left_m REAL,
        d_left_se_m REAL, wheelbase_m REAL, wheelbase_se_m REAL, result_json TEXT NOT NULL);
    CREATE TABLE alarms (
        robot_id TEXT NOT NULL REFERENCES robots(robot_id), parameter TEXT NOT NULL,
        content_hash TEXT NOT NULL, start_s REAL, size REAL NOT NULL, z REAL NOT NULL,
        raised_at TEXT NOT NULL, PRIMARY KEY (robot_id, parameter, content_hash));
    """,
    # 2: the hash cache of each path, and the history's index
    """
    CREATE TABLE files (
        path TEXT PRIMARY KEY, size_bytes INTEGER NOT NULL, mtime_ns INTEGER NOT NULL,
        content_hash TEXT NOT NULL);
    CREATE INDEX bags_by_robot ON bags(robot_id, start_s);
    """,
)
SCHEMA_VERSION = len(MIGRATIONS)


#: How long a writer waits for another one's write lock (s): an ingest storing a bag holds it
#: for milliseconds; one creating or migrating the database, for about as long.
LOCK_TIMEOUT_S = 30.0

_HINTS = {
    "readonly": " (the file or its folder is read-only: ingest needs to write it)",
    "full": " (the disk is full: free space and run the ingest again; every bag "
    "stored so far is kept)",
    "not a database": " (not an odocal fleet database)",
    "locked": " (another odocal fleet ingest is writing it: try again when it is done)",
    "unable to open": " (its folder must be writable: SQLite keeps files beside it)",
}


@contextmanager
def db_errors(path: Path) -> Iterator[None]:
    """sqlite3's failures as one line naming the database (read-only, full disk, not a
    database, locked too long)."""
    try:
        yield
    except sqlite3.Error as exc:
        msg = str(exc)
        extra = next((h for k, h in _HINTS.items() if k in msg), "")
        raise InputError(f"fleet database: {msg}{extra}", path) from None


@dataclass(frozen=True)
class BagRow:
    """One bag of the database with its calibration (None unless done)."""

    content_hash: str
    robot_id: str
    path: str
    start_s: float | None
    end_s: float | None
    status: str
    reason: str | None
    ingested_at: str
    result: dict[str, Any] | None
    enough: bool


class FleetDb:
    """An open fleet database (:func:`open_db`)."""

    def __init__(self, con: sqlite3.Connection, path: Path, writable: bool) -> None:
        self.con, self.path, self.writable = con, path, writable

    def close(self) -> None:
        """Close the connection."""
        self.con.close()

    def __enter__(self) -> FleetDb:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    @contextmanager
    def transaction(self) -> Iterator[sqlite3.Connection]:
        """One atomic write (all of it or nothing, also on a crash)."""
        with db_errors(self.path), self.con:
            yield self.con

    # ---- writes (the ingest's parent only) ----
    def upsert_robot(self, robot_id: str, nominal: dict, folder: str, now: str) -> None:
        """Record a robot (its nominal geometry is the latest robot.yaml's)."""
        with self.transaction() as c:
            c.execute(
                "INSERT INTO robots VALUES (?, ?, ?, ?, ?) ON CONFLICT(robot_id) DO UPDATE SET "
                "nominal_json = excluded.nominal_json, folder = excluded.folder, "
                "last_seen = excluded.last_seen",
                (robot_id, json.dumps(nominal), folder, now, now),
            )

    def remember_file(self, path: str, size: int, mtime_ns: int, content_hash: str) -> None:
        """Cache a path's hash at its size and modification time."""
        with self.transaction() as c:
            c.execute(
                "INSERT OR REPLACE INTO files VALUES (?, ?, ?, ?)",
                (path, size, mtime_ns, content_hash),
            )

    def store_bag(
        self,
        *,
        content_hash: str,
        robot_id: str,
        path: str,
        size_bytes: int,
        span_s: tuple[float, float] | None,
        status: str,
        reason: str | None,
        version: str,
        now: str,
        result: dict[str, Any] | None = None,
    ) -> None:
        """Store one bag's outcome (and its calibration when done) in one transaction."""
        start, end = span_s if span_s is not None else (None, None)
        with self.transaction() as c:
            c.execute(
                "INSERT INTO bags VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, 1) "
                "ON CONFLICT(content_hash) DO UPDATE SET robot_id = excluded.robot_id, "
                "path = excluded.path, size_bytes = excluded.size_bytes, "
                "start_s = excluded.start_s, end_s = excluded.end_s, status = excluded.status, "
                "reason = excluded.reason, odocal_version = excluded.odocal_version, "
                "ingested_at = excluded.ingested_at, attempts = bags.attempts + 1",
                (
                    content_hash,
                    robot_id,
                    path,
                    size_bytes,
                    start,
                    end,
                    status,
                    reason,
                    version,
                    now,
                ),
            )
            if result is not None:
                c.execute(
                    "INSERT OR REPLACE INTO calibrations VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (
                        content_hash,
                        result.get("answer_route"),
                        int(bool(result["verdict"]["enough"])),
                        *_columns(result),
                        json.dumps(result, sort_keys=True),
                    ),
                )

    def replace_alarms(self, robot_id: str, alarms: list[tuple], now: str) -> None:
        """The robot's alarms, (parameter, content_hash, start_s, size, z) each; an alarm
        already stored keeps its first ``raised_at``."""
        with self.transaction() as c:
            old = {
                (p, h): t
                for p, h, t in c.execute(
                    "SELECT parameter, content_hash, raised_at FROM alarms WHERE robot_id = ?",
                    (robot_id,),
                )
            }
            c.execute("DELETE FROM alarms WHERE robot_id = ?", (robot_id,))
            c.executemany(
                "INSERT INTO alarms VALUES (?, ?, ?, ?, ?, ?, ?)",
                [(robot_id, p, h, s, size, z, old.get((p, h), now)) for p, h, s, size, z in alarms],
            )

    def forget_stale_retries(self, present: set[str]) -> None:
        """Drop the ``retry`` bags whose content is no longer on disk (a bag that was being
        written has another hash once finished)."""
        with self.transaction() as c:
            stale = [
                (h,)
                for (h,) in c.execute("SELECT content_hash FROM bags WHERE status = 'retry'")
                if h not in present
            ]
            c.executemany("DELETE FROM bags WHERE content_hash = ?", stale)

    # ---- reads ----
    def known_file(self, path: str, size: int, mtime_ns: int) -> str | None:
        """The cached hash of ``path`` if it has not changed since."""
        with db_errors(self.path):
            row = self.con.execute(
                "SELECT content_hash FROM files WHERE path = ? AND size_bytes = ? AND mtime_ns = ?",
                (path, size, mtime_ns),
            ).fetchone()
        return None if row is None else str(row[0])

    def bag_status(self, content_hash: str) -> tuple[str, str] | None:
        """(status, robot_id) of a stored bag."""
        with db_errors(self.path):
            row = self.con.execute(
                "SELECT status, robot_id FROM bags WHERE content_hash = ?", (content_hash,)
            ).fetchone()
        return None if row is None else (str(row[0]), str(row[1]))

    def robots(self) -> list[tuple[str, dict]]:
        """(robot_id, nominal geometry) of every robot, by id."""
        with db_errors(self.path):
            rows = self.con.execute(
                "SELECT robot_id, nominal_json FROM robots ORDER BY robot_id"
            ).fetchall()
        return [(str(r), json.loads(n)) for r, n in rows]

    def history(self, robot_id: str) -> list[BagRow]:
        """The robot's bags in time order (bag start, then path)."""
        with db_errors(self.path):
            rows = self.con.execute(
                "SELECT b.content_hash, b.robot_id, b.path, b.start_s, b.end_s, b.status, "
                "b.reason, b.ingested_at, c.result_json, c.enough FROM bags b LEFT JOIN "
                "calibrations c USING (content_hash) WHERE b.robot_id = ? "
                "ORDER BY b.start_s, b.path",
                (robot_id,),
            ).fetchall()
        return [
            BagRow(h, r, p, s, e, st, why, at, None if j is None else json.loads(j), bool(ok))
            for h, r, p, s, e, st, why, at, j, ok in rows
        ]

    def alarms(self, robot_id: str) -> list[tuple[str, str, float | None, float, float, str]]:
        """(parameter, content_hash, start_s, size, z, raised_at) of the robot's alarms."""
        with db_errors(self.path):
            return [
                tuple(r)
                for r in self.con.execute(
                    "SELECT parameter, content_hash, start_s, size, z, raised_at FROM alarms "
                    "WHERE robot_id = ? ORDER BY start_s, parameter",
                    (robot_id,),
                )
            ]

    def count(self, status: str | None = None) -> int:
        """How many bags (of one status)."""
        sql, args = "SELECT COUNT(*) FROM bags", ()
        if status is not None:
            sql, args = sql + " WHERE status = ?", (status,)  # type: ignore[assignment]
        with db_errors(self.path):
            return int(self.con.execute(sql, args).fetchone()[0])


def _columns(result: dict[str, Any]) -> tuple[float | None, ...]:
    """(D_R, se, D_L, se, b, se) of the bag route's answer (None without one)."""
    p = result.get("parameters") or {}
    out: list[float | None] = []
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        v = p.get(key) or {}
        out += [v.get("value"), v.get("std_error")]
    return tuple(out)


def _version(con: sqlite3.Connection) -> int:
    """The schema version of an open fleet database; a database without the ``schema_version``
    table (an SQLite file of something else, or of nothing) is not one."""
    tables = {r[0] for r in con.execute("SELECT name FROM sqlite_master WHERE type = 'table'")}
    if "schema_version" not in tables:
        what = "no schema_version table" if tables else "an SQLite database without tables"
        raise sqlite3.DatabaseError(f"not a database odocal wrote ({what})")
    row = con.execute("SELECT MAX(version) FROM schema_version").fetchone()
    return int(row[0] or 0)


def _statements(sql: str) -> list[str]:
    """The SQL statements of a migration, one by one (:meth:`sqlite3.Connection.executescript`
    would commit the transaction they must run in)."""
    out, buf = [], ""
    for part in sql.split(";"):
        buf += part + ";"
        if sqlite3.complete_statement(buf):
            if buf.strip().strip(";").strip():
                out.append(buf.strip())
            buf = ""
    return out


def _migrate(con: sqlite3.Connection, path: Path, *, new: bool = False) -> None:
    """Apply the migrations the database lacks, all in one transaction under SQLite's write
    lock: a second ingest doing the same waits for the lock (:data:`LOCK_TIMEOUT_S`), then
    finds the work done. ``new``: an empty database, made here (:func:`_create`)."""
    con.execute("BEGIN IMMEDIATE")
    try:
        if new:
            con.execute("CREATE TABLE schema_version (version INTEGER NOT NULL)")
            current = 0
        else:
            current = _version(con)
            _refuse_newer(current, path)
        for version, sql in enumerate(MIGRATIONS[current:], start=current + 1):
            for statement in _statements(sql):
                con.execute(statement)
            con.execute("DELETE FROM schema_version")
            con.execute("INSERT INTO schema_version VALUES (?)", (version,))
        con.execute("COMMIT")
    except BaseException:
        if con.in_transaction:  # (SQLite may have rolled it back itself: a full disk)
            con.execute("ROLLBACK")
        raise


def _refuse_newer(current: int, path: Path) -> None:
    if current > SCHEMA_VERSION:
        raise InputError(
            f"written by a newer odocal (schema {current}; this one knows up to "
            f"{SCHEMA_VERSION}): upgrade odocal to read it",
            path,
        )


def _create(p: Path) -> None:
    """Make the database ``p`` whole or not at all: built beside it under a hidden temporary
    name (WAL mode, every migration), closed, then linked into place. Two ingests creating it at
    once: the second link fails and that ingest opens the first one's. Nothing is left beside
    it: SQLite removes the temporary's -wal and -shm when it closes it; the temporary goes."""
    try:
        fd, name = tempfile.mkstemp(prefix=f".{p.name}.", suffix=".new", dir=p.parent)
    except OSError as exc:
        raise InputError(f"cannot create the fleet database ({exc.strerror})", p) from None
    os.close(fd)  # (an empty file: SQLite makes it a database)
    tmp = Path(name)
    companions = [tmp.with_name(tmp.name + s) for s in ("-wal", "-shm", "-journal")]
    try:
        with db_errors(p):
            con = sqlite3.connect(tmp, timeout=LOCK_TIMEOUT_S, isolation_level=None)
            try:
                if con.execute("PRAGMA journal_mode = WAL").fetchone()[0] != "wal":
                    raise InputError("cannot switch the database to WAL mode", p)
                _migrate(con, p, new=True)
            finally:
                con.close()
        try:
            os.link(tmp, p)
        except FileExistsError:
            pass  # another ingest made it meanwhile: that one is the database
        except OSError:  # a file system without hard links: a rename, unless one is there now
            if not p.exists():
                os.replace(tmp, p)
    except OSError as exc:
        raise InputError(f"cannot create the fleet database ({exc.strerror})", p) from None
    finally:
        for f in (tmp, *companions):
            f.unlink(missing_ok=True)


def _check_file(p: Path, write: bool) -> None:
    """Refuse, before SQLite touches it (and leaves -wal and -shm files beside it), what cannot
    be a fleet database or cannot be written when it must be."""
    try:
        st = p.stat()
    except OSError as exc:
        raise InputError(f"cannot open the fleet database ({exc.strerror})", p) from None
    if not stat.S_ISREG(st.st_mode):
        raise InputError("not a regular file, not an odocal fleet database", p)
    if st.st_size == 0:
        raise InputError("an empty file, not an odocal fleet database", p)
    if write and not (os.access(p, os.W_OK) and os.access(p.parent, os.W_OK | os.X_OK)):
        raise InputError(f"fleet database: read-only{_HINTS['readonly']}", p)


def open_db(path: str | Path, *, write: bool) -> FleetDb:
    """Open the fleet database ``path``: ``write`` creates it (and its folder must exist) and
    migrates it to :data:`SCHEMA_VERSION`; otherwise it is opened read-only (it must exist; a
    database of an older schema is read as far as it goes only after an ingest migrates it).

    A new database appears whole (:func:`_create`), so an empty file is never one (refused, as
    a file of anything else is); a file that must be written and cannot be is refused before
    it is opened. Either way nothing is left beside it."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder, not a fleet database file", p)
    if not write and not p.exists():
        raise InputError("no fleet database here (run 'odocal fleet ingest ROOT --db' first)", p)
    if write and not p.parent.is_dir():
        raise InputError("its folder does not exist", p)
    if write and not p.exists():
        _create(p)
    _check_file(p, write)
    with db_errors(p):
        if write:  # (mode=rw: never SQLite's silent fallback to read-only)
            uri = f"{p.resolve().as_uri()}?mode=rw"
            con = sqlite3.connect(uri, uri=True, timeout=LOCK_TIMEOUT_S, isolation_level=None)
        else:
            uri = f"{p.resolve().as_uri()}?mode=ro"
            con = sqlite3.connect(uri, uri=True, timeout=LOCK_TIMEOUT_S)
        try:
            con.execute("PRAGMA foreign_keys = ON")
            current = _version(con)
            _refuse_newer(current, p)
            if write:
                if con.execute("PRAGMA journal_mode = WAL").fetchone()[0] != "wal":
                    raise InputError("cannot switch the database to WAL mode", p)
                con.execute("PRAGMA synchronous = NORMAL")
                if current < SCHEMA_VERSION:
                    _migrate(con, p)
                con.isolation_level = "DEFERRED"
            elif current < SCHEMA_VERSION:
                raise InputError(
                    f"an older fleet database (schema {current}; this odocal uses "
                    f"{SCHEMA_VERSION}): run 'odocal fleet ingest' once to migrate it",
                    p,
                )
        except BaseException:
            con.close()
            raise
    return FleetDb(con, p, write)
