"""``odocal fleet ingest ROOT --db FLEET_DB``: every new bag of every robot calibrated with the
one-command bag route (:func:`odocal.app.fit_auto.fit_auto`, unchanged) and stored
(docs/fleet.md).

1. **Find** the robots (``ROOT/<robot_id>/robot.yaml``) and their bags
   (:mod:`odocal.io.fleet_files`); hash each bag (sha256 of its bytes; a path whose size and
   modification time are those of the last run keeps its hash). A robot folder that cannot be
   used (no ``robot.yaml``, one that cannot be read) and a bag that cannot be read (a link to
   nothing, an empty file) are failures of this run, named, and the run goes on; what is not a
   regular file or folder (a FIFO) is skipped with a warning, never opened; the database's own
   files are not bags.
2. **Choose**: a bag whose hash is stored as done or failed is skipped (a copy or a renamed bag
   too); a bag claimed by two robots is recorded as ``retry`` with both names; a bag that
   changes while it is hashed is ``retry``.
3. **Calibrate** the rest where the workers are: this process (``workers=1``), a
   ``concurrent.futures.ProcessPoolExecutor`` (``workers=N``) or a Dask distributed cluster
   (``dask=ADDRESS``: ``Client(ADDRESS).map``). Workers return plain results
   (:mod:`odocal.app.fleet_task`); this process alone writes the database, one transaction per
   bag as its result arrives, so an interrupted run loses only the bags in flight.
4. **Watch**: every robot's change detector runs again on its history and its alarms are
   stored (:mod:`odocal.app.fleet_status`).
"""

from __future__ import annotations

import os
import time
from collections.abc import Callable, Generator, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .._version import __version__
from ..core.parallel import (
    callers_signals_blocked,
    end_with_parent,
    end_workers,
    signals_held,
    worker_endings,
)
from ..errors import InputError, OdocalError, WorkerLost, one_line, quote_path
from ..io.fleet_db import FleetDb, open_db
from ..io.fleet_files import RobotFolder, Snapshot, content_hash, find_bags, find_robots, snapshot
from ..io.robot_file import load_robot
from .fleet_status import robot_drift
from .fleet_task import CHANGED, BagOutcome, BagTask, calibrate_bag

__all__ = ["IngestResult", "fleet_ingest", "now_utc"]


def now_utc() -> str:
    """The time now, ISO 8601 in UTC to the second."""
    return datetime.now(UTC).replace(microsecond=0).isoformat()


@dataclass(frozen=True)
class IngestResult:
    """What one ingest did.

    Attributes
    ----------
    bags_total : int
        Distinct bags found under ROOT (a copy counts once).
    bags_new : int
        Bags calibrated and stored by this run.
    bags_failed : int
        Bags of this run that could not be calibrated (stored as failed, with the reason) or are
        to be tried again (``bags_retry`` of them: being written, claimed by two robots).
    bags_retry : int
    bags_skipped : int
        Bags already in the database (done or failed before).
    seconds : float
        Wall time of the run.
    robots : int
    engine : str
        Where the bags ran: 'this process', 'N processes' or 'dask ADDRESS'.
    failures : tuple of (str, str)
        (bag path, one-line reason) of each bag of this run that failed or waits for a retry;
        also of each bag that could not be read (a link to nothing, an empty file: not stored,
        there is no content to know it by; tried again at the next ingest).
    warnings : tuple of str
    robot_failures : tuple of (str, str)
        (robot folder, one-line reason) of each folder of ROOT that is not a usable robot (no
        robot.yaml, one that cannot be read): its bags were not looked at.
    """

    bags_total: int
    bags_new: int
    bags_failed: int
    bags_retry: int
    bags_skipped: int
    seconds: float
    robots: int
    engine: str
    failures: tuple[tuple[str, str], ...] = ()
    warnings: tuple[str, ...] = field(default_factory=tuple)
    robot_failures: tuple[tuple[str, str], ...] = ()

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet ingest --json``."""
        return {
            "bags_total": self.bags_total,
            "bags_new": self.bags_new,
            "bags_failed": self.bags_failed,
            "bags_retry": self.bags_retry,
            "bags_skipped": self.bags_skipped,
            "seconds": self.seconds,
            "robots": self.robots,
            "engine": self.engine,
            "failures": [{"bag": b, "reason": r} for b, r in self.failures],
            "warnings": list(self.warnings),
            "robots_failed": [{"robot": f, "reason": r} for f, r in self.robot_failures],
        }


@dataclass
class _Found:
    """One bag content found under ROOT: every (robot, path, snapshot) holding it."""

    claims: list[tuple[RobotFolder, Path, Snapshot]] = field(default_factory=list)


#: Why an empty bag is not stored (every empty file has the same hash: it is no bag's identity).
EMPTY = "an empty file (0 bytes): nothing to calibrate; tried again at the next ingest"


class _Unreadable(Exception):
    """A bag that cannot be read (its one-line reason)."""


def _hash(db: FleetDb, bag: Path, before: Snapshot) -> tuple[str, bool]:
    """(content hash, steady): the cached hash when the bag is unchanged since it was hashed
    (``before``: its snapshot now); ``steady`` False when it changed while being hashed."""
    cached = db.known_file(str(bag), before.size_bytes, before.mtime_ns)
    if cached is not None:
        return cached, True
    try:
        h = content_hash(bag)
        steady = snapshot(bag) == before
    except InputError as exc:  # the bag (not the database): gone or unreadable since found
        raise _Unreadable(one_line(str(exc))) from None
    if steady:
        db.remember_file(str(bag), before.size_bytes, before.mtime_ns, h)
    return h, steady


def _engine(workers: int, dask: str | None) -> str:
    if dask is not None:
        return f"dask {dask}"
    return "this process" if workers == 1 else f"{workers} processes"


#: Why a bag whose worker process ended without its result is stored as retry.
LOST = "a worker process ended before returning its result ({how}): tried again at the next ingest"


def _run_local(tasks: Sequence[BagTask], workers: int) -> Generator[BagOutcome, None, None]:
    """The tasks in this process, or in a process pool (results as they finish).

    The pool's workers end with this process however it ends (:func:`~odocal.core.parallel.
    end_with_parent`: a ``kill -9`` left them alive for ever, holding its pipes), and an
    interruption here ends them at once (not after their bags). A worker that ends without its
    result (killed; out of memory) breaks the pool: every bag in flight comes back as
    ``retry``, then :class:`~odocal.errors.WorkerLost` (one line)."""
    if workers == 1 or len(tasks) <= 1:
        yield from map(calibrate_bag, tasks)
        return
    import multiprocessing as mp
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    others = set(mp.active_children())
    pool = ProcessPoolExecutor(
        max_workers=min(workers, len(tasks)), initializer=end_with_parent, initargs=(os.getpid(),)
    )
    forked: list[Any] = []
    finished = False
    try:
        # the workers are forked at the submits, with SIGINT and SIGTERM blocked until their
        # initializer has set their own handling (not this process's handlers)
        with signals_held(), callers_signals_blocked():
            futures = {pool.submit(calibrate_bag, t): t for t in tasks}
            forked = [p for p in mp.active_children() if p not in others]
        lost: list[BagTask] = []
        for f in as_completed(futures):
            if isinstance(f.exception(), BrokenProcessPool):
                lost.append(futures[f])
                continue
            yield f.result()
        if lost:
            how = worker_endings(forked) or "killed"
            for t in sorted(lost, key=lambda t: t.bag):
                yield BagOutcome(t, "retry", LOST.format(how=how), None)
            n = f"the {len(lost)} bags" if len(lost) > 1 else "the bag"
            raise WorkerLost(
                f"a worker process ended before returning its result ({how}): {n} in flight "
                "are stored as retry (tried again at the next ingest); every bag stored so far "
                "is kept"
            )
        finished = True
    finally:
        with signals_held():  # (a second Ctrl-C does not stop the workers being ended)
            if not finished:
                end_workers(forked or [p for p in mp.active_children() if p not in others])
            pool.shutdown(wait=True, cancel_futures=True)


#: How long to try to reach the Dask scheduler (s): Dask retries a refused connection until then.
DASK_CONNECT_TIMEOUT_S = 10.0


def _run_dask(tasks: Sequence[BagTask], address: str) -> Generator[BagOutcome, None, None]:
    """The tasks on the Dask cluster at ``address`` (results as they finish)."""
    try:
        from dask.distributed import Client, as_completed
    except ImportError:
        raise InputError("--dask needs dask.distributed: pip install 'odocal[fleet]'") from None
    try:
        client = Client(address, timeout=f"{DASK_CONNECT_TIMEOUT_S}s", set_as_default=False)
    except (OSError, TimeoutError, ValueError) as exc:
        raise InputError(f"cannot reach the Dask scheduler at {address} ({exc})") from None
    try:
        if not tasks:
            return
        futures = client.map(calibrate_bag, list(tasks), pure=False)
        for f in as_completed(futures, loop=client.loop):
            yield f.result()
    finally:
        client.close()


def _store(db: FleetDb, o: BagOutcome, now: str) -> None:
    t = o.task
    db.store_bag(
        content_hash=t.content_hash,
        robot_id=t.robot_id,
        path=t.bag,
        size_bytes=t.before.size_bytes,
        span_s=o.span_s,
        status=o.status,
        reason=o.reason,
        version=__version__,
        now=now,
        record=o.record,
        report=o.report,
    )


@dataclass(frozen=True)
class _Choice:
    """What :func:`_choose` found: every bag content under ROOT (by hash), the tasks to run,
    the bags to record as retry now (with why), the bags that could not be read (path, why:
    not stored), the warnings."""

    found: dict[str, _Found]
    tasks: list[BagTask]
    retry: list[tuple[BagTask, str]]
    unread: list[tuple[str, str]]
    warnings: list[str]


def _choose(db: FleetDb, robots: Sequence[RobotFolder], skip: Sequence[Path]) -> _Choice:
    """Hash every bag (module docstring, steps 1 and 2)."""
    found: dict[str, _Found] = {}
    unsteady: list[tuple[RobotFolder, Path, Snapshot, str]] = []
    unread: list[tuple[str, str]] = []
    warnings: list[str] = []
    folders = [r.folder for r in robots]
    for r in robots:
        # a path through another robot's folder (a link back up the tree) is no claim
        scan = find_bags(r.folder, others=folders, skip=skip)
        warnings += scan.warnings
        unread += [(str(p), why) for p, why in scan.failures]
        for bag in scan.bags:
            try:
                snap = snapshot(bag)
            except InputError as exc:  # (gone or unreadable since it was found)
                unread.append((str(bag), one_line(str(exc))))
                continue
            if snap.size_bytes == 0:
                unread.append((str(bag), f"{quote_path(bag)}: {EMPTY}"))
                continue
            try:
                h, steady = _hash(db, bag, snap)
            except _Unreadable as exc:
                unread.append((str(bag), str(exc)))
                continue
            if not steady:
                unsteady.append((r, bag, snap, h))
                continue
            found.setdefault(h, _Found()).claims.append((r, bag, snap))
    tasks, retry = [], []
    for h, f in found.items():
        owners = sorted({r.robot_id for r, _, _ in f.claims})
        stored = db.bag_status(h)
        if stored is not None and stored[0] in ("done", "failed"):
            strays = [str(p) for r, p, _ in f.claims if r.robot_id != stored[1]]
            warnings += [
                f"{p}: the same bag as one of robot {stored[1]}: counted once, for {stored[1]}"
                for p in strays
            ]
            continue
        r, bag, snap = f.claims[0]
        if len(owners) > 1:
            paths = ", ".join(str(p) for _, p, _ in f.claims)
            why = (
                f"one bag claimed by robots {' and '.join(owners)} ({paths}): move it to "
                "its robot's folder; tried again at the next ingest"
            )
            retry.append((BagTask(r.robot_id, str(bag), str(r.robot_file), h, snap), why))
            continue
        tasks.append(BagTask(r.robot_id, str(bag), str(r.robot_file), h, snap))
    retry += [
        (BagTask(r.robot_id, str(b), str(r.robot_file), h, s), CHANGED) for r, b, s, h in unsteady
    ]
    return _Choice(found, tasks, retry, unread, warnings)


def _database_files(db_path: str | Path) -> list[Path]:
    """The database and the files SQLite keeps beside it: never bags, even inside ROOT."""
    p = Path(db_path)
    return [p, *(p.with_name(p.name + s) for s in ("-wal", "-shm", "-journal"))]


def _usable_robots(
    root: str | Path, skip: Sequence[Path]
) -> tuple[list[RobotFolder], dict[str, dict], list[tuple[str, str]]]:
    """The robots of ``root`` whose robot.yaml reads, their nominal geometries, and the folders
    that are not usable robots (folder, one-line reason). None usable: the first reason is the
    error (nothing would be ingested)."""
    scan = find_robots(root, skip=skip)
    robots, nominals = [], {}
    failures = [(str(p), why) for p, why in scan.failures]
    for r in scan.robots:
        try:
            nominals[r.robot_id] = load_robot(str(r.robot_file)).nominal.as_dict()
        except OdocalError as exc:
            failures.append((str(r.folder), one_line(str(exc))))
            continue
        robots.append(r)
    if not robots and failures:
        raise InputError(sorted(failures)[0][1])
    return robots, nominals, sorted(failures)


def fleet_ingest(
    root: str | Path,
    db_path: str | Path,
    *,
    workers: int = 1,
    dask: str | None = None,
    on_stored: Callable[[BagOutcome, int, int], None] | None = None,
) -> IngestResult:
    """Calibrate and store every new bag under ``root`` (module docstring). ``on_stored(outcome,
    done, total)`` is called after each bag is committed (a progress bar)."""
    start = time.perf_counter()
    if workers < 1:
        raise InputError(f"--workers must be at least 1, got {workers}")
    skip = _database_files(db_path)
    robots, nominals, robot_failures = _usable_robots(root, skip)
    with open_db(db_path, write=True) as db:
        now = now_utc()
        for r in robots:
            db.upsert_robot(r.robot_id, nominals[r.robot_id], str(r.folder), now)
        choice = _choose(db, robots, skip)
        found, tasks, retry, warnings = choice.found, choice.tasks, choice.retry, choice.warnings
        db.forget_stale_retries(set(found))
        failures: list[tuple[str, str]] = list(choice.unread)
        for task, why in retry:
            _store(db, BagOutcome(task, "retry", why, None), now)
            failures.append((task.bag, why))
        counts = {"done": 0, "failed": 0, "retry": len(retry)}
        outcomes = _run_dask(tasks, dask) if dask is not None else _run_local(tasks, workers)
        with closing(outcomes):  # an interruption stops the pool or the client at once
            for done, o in enumerate(outcomes, start=1):
                _store(db, o, now_utc())
                counts[o.status] += 1
                if o.status != "done":
                    failures.append((o.task.bag, o.reason or ""))
                if on_stored is not None:
                    on_stored(o, done, len(tasks))
        # every robot's alarms (milliseconds each): also those of a run interrupted before here
        for robot_id, _ in db.robots():
            drift = robot_drift(db.history(robot_id))
            db.replace_alarms(robot_id, drift.alarm_rows(), now)
        skipped = len(found) - len(tasks) - sum(1 for t, w in retry if w != CHANGED)
    return IngestResult(
        bags_total=len(found) + sum(1 for _, w in retry if w == CHANGED) + len(choice.unread),
        bags_new=counts["done"],
        bags_failed=counts["failed"] + counts["retry"] + len(choice.unread),
        bags_retry=counts["retry"],
        bags_skipped=skipped,
        seconds=time.perf_counter() - start,
        robots=len(robots),
        engine=_engine(workers, dask),
        failures=tuple(sorted(failures)),
        warnings=tuple(warnings),
        robot_failures=tuple(robot_failures),
    )
