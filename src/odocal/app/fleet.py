"""``odocal fleet ingest ROOT --db FLEET_DB``: every new bag of every robot calibrated with the
one-command bag route (:func:`odocal.app.fit_auto.fit_auto`, unchanged) and stored
(docs/fleet.md).

1. **Find** the robots (``ROOT/<robot_id>/robot.yaml``) and their bags
   (:mod:`odocal.io.fleet_files`); hash each bag (sha256 of its bytes; a path whose size and
   modification time are those of the last run keeps its hash).
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

import time
from collections.abc import Callable, Generator, Sequence
from contextlib import closing
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from .._version import __version__
from ..errors import InputError
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
        (bag path, one-line reason) of each bag of this run that failed or waits for a retry.
    warnings : tuple of str
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
        }


@dataclass
class _Found:
    """One bag content found under ROOT: every (robot, path, snapshot) holding it."""

    claims: list[tuple[RobotFolder, Path, Snapshot]] = field(default_factory=list)


def _hash(db: FleetDb, bag: Path) -> tuple[str, Snapshot, bool]:
    """(content hash, snapshot, steady): the cached hash when the bag is unchanged since it was
    hashed; ``steady`` False when it changed while being hashed."""
    before = snapshot(bag)
    cached = db.known_file(str(bag), before.size_bytes, before.mtime_ns)
    if cached is not None:
        return cached, before, True
    h = content_hash(bag)
    steady = snapshot(bag) == before
    if steady:
        db.remember_file(str(bag), before.size_bytes, before.mtime_ns, h)
    return h, before, steady


def _engine(workers: int, dask: str | None) -> str:
    if dask is not None:
        return f"dask {dask}"
    return "this process" if workers == 1 else f"{workers} processes"


def _run_local(tasks: Sequence[BagTask], workers: int) -> Generator[BagOutcome, None, None]:
    """The tasks in this process, or in a process pool (results as they finish)."""
    if workers == 1 or len(tasks) <= 1:
        yield from map(calibrate_bag, tasks)
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed

    pool = ProcessPoolExecutor(max_workers=min(workers, len(tasks)))
    try:
        futures = [pool.submit(calibrate_bag, t) for t in tasks]
        for f in as_completed(futures):
            yield f.result()
    finally:
        pool.shutdown(wait=False, cancel_futures=True)


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
        result=o.result,
    )


def _choose(db: FleetDb, robots: Sequence[RobotFolder]):
    """Hash every bag; the tasks to run, the bags recorded as retry now, the warnings."""
    found: dict[str, _Found] = {}
    unsteady: list[tuple[RobotFolder, Path, Snapshot, str]] = []
    for r in robots:
        for bag in find_bags(r.folder):
            h, snap, steady = _hash(db, bag)
            if not steady:
                unsteady.append((r, bag, snap, h))
                continue
            found.setdefault(h, _Found()).claims.append((r, bag, snap))
    tasks, retry, warnings = [], [], []
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
    return found, tasks, retry, warnings


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
    robots = find_robots(root)
    nominals = {r.robot_id: load_robot(str(r.robot_file)).nominal.as_dict() for r in robots}
    with open_db(db_path, write=True) as db:
        now = now_utc()
        for r in robots:
            db.upsert_robot(r.robot_id, nominals[r.robot_id], str(r.folder), now)
        found, tasks, retry, warnings = _choose(db, robots)
        db.forget_stale_retries(set(found))
        failures: list[tuple[str, str]] = []
        for task, why in retry:
            _store(db, BagOutcome(task, "retry", why, None, None), now)
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
        bags_total=len(found) + sum(1 for _, w in retry if w == CHANGED),
        bags_new=counts["done"],
        bags_failed=counts["failed"] + counts["retry"],
        bags_retry=counts["retry"],
        bags_skipped=skipped,
        seconds=time.perf_counter() - start,
        robots=len(robots),
        engine=_engine(workers, dask),
        failures=tuple(sorted(failures)),
        warnings=tuple(warnings),
    )
