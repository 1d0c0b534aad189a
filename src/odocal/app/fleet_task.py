"""One bag of a fleet, calibrated where a worker runs it (a process of the pool, a Dask worker,
or the ingest's own process): plain data in, plain data out, no database.

The task carries the bag's :class:`~odocal.io.fleet_files.Snapshot` taken before its bytes
were hashed; the worker takes another after the calibration, and a bag that changed in between
(still being written) comes back as ``retry``, not as a result.
"""

from __future__ import annotations

import json
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from threadpoolctl import threadpool_limits

from ..errors import OdocalError
from ..io.fleet_files import Snapshot, bag_span_s, snapshot

__all__ = ["BagTask", "BagOutcome", "calibrate_bag", "CHANGED"]

CHANGED = "the bag changed while it was read (still being written?): tried again at the next ingest"


@dataclass(frozen=True)
class BagTask:
    """What a worker needs: the robot, the bag, its content hash and its snapshot."""

    robot_id: str
    bag: str
    robot_file: str
    content_hash: str
    before: Snapshot


@dataclass(frozen=True)
class BagOutcome:
    """What a worker returns. ``status``: done, failed (``reason``) or retry (``reason``);
    ``result``: the JSON of ``odocal fit BAG --method auto`` when done."""

    task: BagTask
    status: str
    reason: str | None
    span_s: tuple[float, float] | None
    result: dict[str, Any] | None


def calibrate_bag(task: BagTask) -> BagOutcome:
    """Run the one-command bag route on the task's bag (module docstring). Never raises for a
    bag that cannot be calibrated: the reason comes back as one line."""
    from .fit_auto import fit_auto

    bag = Path(task.bag)
    result: dict[str, Any] | None = None
    reason: str | None = None
    try:
        # one core per bag: the workers are the parallelism (BLAS's own threads on a busy
        # machine made a bag 4 times slower)
        with threadpool_limits(limits=1):
            res = fit_auto(bag, robot=task.robot_file)
        # through JSON: the same plain values whichever process or machine ran it
        result = json.loads(json.dumps(res.as_dict()))
        status = "done"
    except OdocalError as exc:
        status, reason = "failed", str(exc).splitlines()[0]
    except Exception as exc:  # noqa: BLE001 - one bad bag must not end the night's run
        status, reason = "failed", f"unexpected {type(exc).__name__}: {exc}".splitlines()[0]
    span = bag_span_s(bag) if status == "done" else None
    try:
        changed = snapshot(bag) != task.before
    except OdocalError:
        changed = True
    if changed:
        return BagOutcome(task, "retry", CHANGED, None, None)
    return BagOutcome(task, status, reason, span, result)
