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
  wheelbase_m, wheelbase_se_m, result_json, record_version, record_json)``: the bag's
  calibration record (``record_json``, version ``record_version``: a
  :class:`~odocal.io.fleet_record.CalibrationRecord`, what every reader reads), its route,
  verdict and parameters as columns (copied from the record, for SQL), and the bag's report
  (``result_json``: ``odocal fit BAG --method auto --json`` as the ingest got it, rendered on
  the bag's page; no fact is read from it);
- ``files(path, size_bytes, mtime_ns, content_hash)`` (version 2): the last hash of each path,
  so a nightly run hashes only new or changed files;
- ``alarms(robot_id, parameter, content_hash, start_s, size, z, raised_at, acknowledged_at)``:
  the change detector's alarms (replaced for a robot each time its history grows; an alarm
  found again keeps its ``raised_at`` and its acknowledgement, version 3).

Version 3 converted every stored ``result_json`` into a record (its migration reads each row
through :func:`~odocal.io.fleet_record.upgrade_fit_json` and refuses, naming the bag, a row it
cannot read: nothing is changed then).

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
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..errors import InputError, one_line
from .fleet_record import RECORD_VERSION, CalibrationRecord, RecordError

__all__ = [
    "SCHEMA_VERSION",
    "MIGRATIONS",
    "FleetDb",
    "BagRow",
    "AlarmRow",
    "open_db",
    "db_errors",
]


def _records(con: sqlite3.Connection, path: Path) -> None:
    """3: each calibration's typed, versioned record beside its report, and alarms that can be
    acknowledged. Every stored ``result_json`` (the ``fit --method auto --json`` of the odocal
    that stored it) is read into a record (:func:`~odocal.io.fleet_record.upgrade_fit_json`) and
    its columns are rewritten from it; a row that cannot be read stops the migration (nothing
    changed), naming its bag."""
    for statement in (
        "ALTER TABLE calibrations ADD COLUMN record_version INTEGER",
        "ALTER TABLE calibrations ADD COLUMN record_json TEXT",
        "ALTER TABLE alarms ADD COLUMN acknowledged_at TEXT",
    ):
        con.execute(statement)
    rows = con.execute(
        "SELECT c.content_hash, b.path, b.odocal_version, c.result_json FROM calibrations c "
        "LEFT JOIN bags b USING (content_hash) ORDER BY b.robot_id, b.start_s, b.path"
    ).fetchall()
    bad: list[str] = []
    for content_hash, bag, version, text in rows:
        try:
            old = {"record_version": 0, "odocal_version": version or "", "fit": json.loads(text)}
            record = CalibrationRecord.from_dict(old)
        except (ValueError, RecordError) as exc:
            bad.append(f"bag {bag} (sha256 {content_hash[:12]}): {one_line(str(exc))}")
            continue
        con.execute(
            "UPDATE calibrations SET route = ?, enough = ?, d_right_m = ?, d_right_se_m = ?, "
            "d_left_m = ?, d_left_se_m = ?, wheelbase_m = ?, wheelbase_se_m = ?, "
            "record_version = ?, record_json = ? WHERE content_hash = ?",
            (*_record_columns(record), content_hash),
        )
    if bad:
        more = f" (and {len(bad) - 1} more)" if len(bad) > 1 else ""
        raise InputError(
            f"cannot migrate the fleet database to schema 3: the stored result of {bad[0]}"
            f"{more}; nothing was changed (docs/fleet.md, 'The calibration record': remove "
            "that bag's rows and the next ingest calibrates it again)",
            path,
        )


#: A migration: SQL statements, or a function of the open connection (in the migrations'
#: transaction) for one that converts rows.
Migration = str | Callable[[sqlite3.Connection, Path], None]

MIGRATIONS: tuple[Migration, ...] = (
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
    # 3: the calibration record (converted from every result_json), alarms acknowledged
    _records,
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
    """One bag of the database with its calibration record (None unless done)."""

    content_hash: str
    robot_id: str
    path: str
    start_s: float | None
    end_s: float | None
    status: str
    reason: str | None
    ingested_at: str
    record: CalibrationRecord | None

    @property
    def enough(self) -> bool:
        """Calibrated with the verdict 'trustworthy'."""
        return self.record is not None and self.record.enough


@dataclass(frozen=True)
class AlarmRow:
    """One alarm of the change detector as stored: the robot, the parameter, the bag that
    raised it (its hash, path and start), the step's size (m) and its size in standard errors
    (z), when it was first raised and when it was acknowledged (None: not yet)."""

    robot_id: str
    parameter: str
    content_hash: str
    bag: str | None
    start_s: float | None
    size: float
    z: float
    raised_at: str
    acknowledged_at: str | None

    @property
    def acknowledged(self) -> bool:
        """Acknowledged by an operator (``odocal fleet ack``)."""
        return self.acknowledged_at is not None


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
        record: CalibrationRecord | None = None,
        report: dict[str, Any] | None = None,
    ) -> None:
        """Store one bag's outcome (and when done its calibration: ``record``, and ``report``,
        the ``fit --json`` its page renders) in one transaction."""
        if (record is None) != (report is None):
            raise ValueError("a calibration is stored with its record and its report")
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
            if record is not None:
                c.execute(
                    "INSERT OR REPLACE INTO calibrations (content_hash, route, enough, "
                    "d_right_m, d_right_se_m, d_left_m, d_left_se_m, wheelbase_m, "
                    "wheelbase_se_m, record_version, record_json, result_json) "
                    "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                    (content_hash, *_record_columns(record), json.dumps(report, sort_keys=True)),
                )

    def replace_alarms(self, robot_id: str, alarms: list[tuple], now: str) -> None:
        """The robot's alarms, (parameter, content_hash, start_s, size, z) each; an alarm
        already stored keeps its first ``raised_at`` and its acknowledgement."""
        with self.transaction() as c:
            old = {
                (p, h): (t, ack)
                for p, h, t, ack in c.execute(
                    "SELECT parameter, content_hash, raised_at, acknowledged_at FROM alarms "
                    "WHERE robot_id = ?",
                    (robot_id,),
                )
            }
            c.execute("DELETE FROM alarms WHERE robot_id = ?", (robot_id,))
            c.executemany(
                "INSERT INTO alarms (robot_id, parameter, content_hash, start_s, size, z, "
                "raised_at, acknowledged_at) VALUES (?, ?, ?, ?, ?, ?, ?, ?)",
                [
                    (robot_id, p, h, s, size, z, *old.get((p, h), (now, None)))
                    for p, h, s, size, z in alarms
                ],
            )

    def acknowledge(self, robot_id: str, parameter: str, content_hash: str, now: str) -> None:
        """Mark the alarm of ``robot_id``'s ``parameter`` raised by the bag ``content_hash`` as
        acknowledged at ``now`` (kept, no longer active)."""
        with self.transaction() as c:
            c.execute(
                "UPDATE alarms SET acknowledged_at = ? WHERE robot_id = ? AND parameter = ? AND "
                "content_hash = ? AND acknowledged_at IS NULL",
                (now, robot_id, parameter, content_hash),
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
        """The robot's bags in time order (bag start, then path), each with its calibration
        record read back (:class:`~odocal.io.fleet_record.RecordError` naming the bag when one
        cannot be read)."""
        with db_errors(self.path):
            rows = self.con.execute(
                "SELECT b.content_hash, b.robot_id, b.path, b.start_s, b.end_s, b.status, "
                "b.reason, b.ingested_at, c.content_hash IS NOT NULL, c.record_json "
                "FROM bags b LEFT JOIN calibrations c USING (content_hash) "
                "WHERE b.robot_id = ? ORDER BY b.start_s, b.path",
                (robot_id,),
            ).fetchall()
        return [
            BagRow(h, r, p, s, e, st, why, at, self._record(p, j) if has else None)
            for h, r, p, s, e, st, why, at, has, j in rows
        ]

    def _record(self, bag: str, text: str | None) -> CalibrationRecord:
        """A stored record, read back."""
        try:
            if text is None:
                raise RecordError("a calibration without its record")
            return CalibrationRecord.from_dict(json.loads(text))
        except (ValueError, RecordError) as exc:
            raise RecordError(
                f"fleet database: the calibration record of bag {bag}: {one_line(str(exc))}",
                self.path,
            ) from None

    def report(self, content_hash: str) -> dict[str, Any] | None:
        """The bag's report (the ``fit --method auto --json`` the ingest got; its page renders
        it), or None when the bag was not calibrated."""
        with db_errors(self.path):
            row = self.con.execute(
                "SELECT result_json FROM calibrations WHERE content_hash = ?", (content_hash,)
            ).fetchone()
        return None if row is None else json.loads(row[0])

    def alarms(self, robot_id: str | None = None) -> list[AlarmRow]:
        """The alarms of one robot (or of every robot), by robot, bag start and parameter."""
        sql = (
            "SELECT a.robot_id, a.parameter, a.content_hash, b.path, a.start_s, a.size, a.z, "
            "a.raised_at, a.acknowledged_at FROM alarms a LEFT JOIN bags b USING (content_hash)"
        )
        args: tuple[str, ...] = ()
        if robot_id is not None:
            sql, args = sql + " WHERE a.robot_id = ?", (robot_id,)
        with db_errors(self.path):
            rows = self.con.execute(
                sql + " ORDER BY a.robot_id, a.start_s, a.parameter", args
            ).fetchall()
        return [AlarmRow(*r) for r in rows]

    def latest_starts(self) -> dict[str, float]:
        """Robot id -> the start of its latest bag (s since the epoch)."""
        with db_errors(self.path):
            rows = self.con.execute(
                "SELECT robot_id, MAX(start_s) FROM bags WHERE start_s IS NOT NULL "
                "GROUP BY robot_id"
            ).fetchall()
        return {str(r): float(t) for r, t in rows}

    def count(self, status: str | None = None) -> int:
        """How many bags (of one status)."""
        sql, args = "SELECT COUNT(*) FROM bags", ()
        if status is not None:
            sql, args = sql + " WHERE status = ?", (status,)  # type: ignore[assignment]
        with db_errors(self.path):
            return int(self.con.execute(sql, args).fetchone()[0])


def _record_columns(record: CalibrationRecord) -> tuple[Any, ...]:
    """The calibrations row's columns from its record: route, enough, (D_R, se, D_L, se, b, se)
    (None without an answer; a held parameter has no standard error), record_version and
    record_json."""
    out: list[Any] = [record.route, int(record.enough)]
    for p in record.parameters or ():
        out += [p.value, p.std_error]
    if record.parameters is None:
        out += [None] * 6
    return (*out, RECORD_VERSION, json.dumps(record.as_dict(), sort_keys=True))


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
        for version, migration in enumerate(MIGRATIONS[current:], start=current + 1):
            if callable(migration):
                migration(con, path)
            else:
                for statement in _statements(migration):
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


def open_db(path: str | Path, *, write: bool, create: bool = True) -> FleetDb:
    """Open the fleet database ``path``: ``write`` creates it (unless not ``create``; its
    folder must exist) and migrates it to :data:`SCHEMA_VERSION`; otherwise it is opened
    read-only (it must exist; a database of an older schema is read only after an ingest
    migrates it).

    A new database appears whole (:func:`_create`), so an empty file is never one (refused, as
    a file of anything else is); a file that must be written and cannot be is refused before
    it is opened. Either way nothing is left beside it."""
    p = Path(path)
    if p.is_dir():
        raise InputError("is a folder, not a fleet database file", p)
    if (not write or not create) and not p.exists():
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
