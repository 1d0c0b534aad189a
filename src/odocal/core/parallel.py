"""Independent pieces of work on the cores this process may use (the standard library's pools).

- :func:`workers`: how many: ``ODOCAL_THREADS`` if set (``1`` runs everything in this process
  and thread), else the CPUs this process may use.
- :func:`run_tasks`: run zero-argument callables, each in a worker process, and return their
  results in order. The workers are forked (Linux only), so a task may be any callable (a closure,
  a lambda): only its result travels back, pickled. Elsewhere, with one worker or one task, the
  tasks run here, one after the other. Tasks must not depend on one another or on their order:
  the results are the same either way (each task owns its random stream).
- :func:`shared_zeros`: an array of zeros that forked workers write into and this process sees.
"""

from __future__ import annotations

import mmap
import os
import signal
import sys
from collections.abc import Callable, Sequence
from typing import Any, TypeVar

import numpy as np

__all__ = ["workers", "run_tasks", "can_fork", "shared_zeros"]

T = TypeVar("T")


def workers() -> int:
    """Workers for independent pieces of work: ODOCAL_THREADS, else the usable CPUs; one inside a
    task of :func:`run_tasks` (its workers already take the cores: threads of their own would
    only compete with them)."""
    if _TASKS:
        return 1
    env = os.environ.get("ODOCAL_THREADS", "")
    if env.strip().isdigit() and int(env) > 0:
        return int(env)
    try:
        return len(os.sched_getaffinity(0))
    except AttributeError:  # not on Linux
        return os.cpu_count() or 1


def can_fork() -> bool:
    """Does :func:`run_tasks` run its tasks in forked processes here (Linux, not already inside
    one of its workers, nor inside a daemonic process, e.g. a worker of the caller's own
    multiprocessing pool, which may not have children)?"""
    if not sys.platform.startswith("linux") or _TASKS:
        return False
    import multiprocessing as mp

    return not mp.current_process().daemon


def shared_zeros(shape: tuple[int, ...]) -> np.ndarray:
    """float64 zeros in memory shared with the worker processes :func:`run_tasks` forks (an
    anonymous shared mapping): what a worker writes into it, this process sees."""
    size = max(1, int(np.prod(shape, dtype=np.int64))) * 8
    return np.frombuffer(mmap.mmap(-1, size), dtype=np.float64)[: int(np.prod(shape))].reshape(
        shape
    )


# The tasks of the current run_tasks call: forked workers inherit them (nothing is pickled).
_TASKS: Sequence[Callable[[], Any]] = ()


def _quiet_worker() -> None:
    """A worker leaves interruptions to the caller: Ctrl-C is ignored, SIGTERM (the pool's
    terminate) ends it at once, without the caller's handlers."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)


def _indexed(i: int) -> tuple[int, bool, Any]:
    """Task ``i`` in a worker: (i, True, its result) or (i, False, the exception it raised)."""
    try:
        return i, True, _TASKS[i]()
    except Exception as exc:  # noqa: BLE001 - raised again by the caller, in task order
        return i, False, exc


def run_tasks(
    tasks: Sequence[Callable[[], T]],
    max_workers: int | None = None,
    done: Callable[[int], None] | None = None,
    *,
    share: bool = False,
    meanwhile: Callable[[], object] | None = None,
) -> list[T]:
    """The results of ``tasks`` (zero-argument callables), in order (module docstring).

    ``share``: this process runs the first task itself meanwhile, with one worker process fewer
    (for tasks of about equal work). ``meanwhile``: something else for this process to do while
    the workers work (called once in any case). ``done(i)`` is called here as task ``i``
    finishes (for a progress display). An exception in a task is raised here once the tasks
    have ended (the first failed task's, in task order, however the workers were scheduled); an
    interruption here (Ctrl-C, an exception) ends the workers at once."""
    global _TASKS
    n = min(len(tasks), workers() if max_workers is None else max_workers)
    if n <= 1 or not can_fork():  # inside a worker too: no nesting
        if meanwhile is not None:
            meanwhile()
        results = []
        for i, task in enumerate(tasks):
            results.append(task())
            if done is not None:
                done(i)
        return results
    import multiprocessing as mp

    _TASKS = tasks
    out: dict[int, Any] = {}
    failed: dict[int, BaseException] = {}
    first = 1 if share else 0
    try:
        with mp.get_context("fork").Pool(n - first, initializer=_quiet_worker) as pool:
            pending = pool.imap_unordered(_indexed, range(first, len(tasks)))
            if meanwhile is not None:
                meanwhile()
            if share:
                out[0] = tasks[0]()
                if done is not None:
                    done(0)
            for i, ok, result in pending:
                if ok:
                    out[i] = result
                else:
                    failed[i] = result
                if done is not None:
                    done(i)
    finally:  # leaving the with block has terminated the workers
        _TASKS = ()
    if failed:
        raise failed[min(failed)]
    return [out[i] for i in range(len(tasks))]
