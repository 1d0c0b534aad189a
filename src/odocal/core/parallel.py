"""Independent pieces of work on the cores this process may use (the standard library's pools).

- :func:`workers`: how many: ``ODOCAL_THREADS`` if set (``1`` runs everything in this process
  and thread), else the CPUs this process may use.
- :func:`run_tasks`: run zero-argument callables, each in a worker process, and return their
  results in order. The workers are forked (Linux only; concurrent.futures' process pool, which
  notices a worker that dies), so a task may be any callable (a closure, a lambda): only its
  result travels back, pickled. Elsewhere, with one worker or one task, the
  tasks run here, one after the other. Tasks must not depend on one another or on their order:
  the results are the same either way (each task owns its random stream).
- :func:`shared_zeros`: an array of zeros that forked workers write into and this process sees.
- :func:`signals_held`: SIGINT and SIGTERM held back while a block runs (their handlers run
  after it), for work that must not be cut in the middle.
- :func:`end_with_parent`: the initializer of a process pool's workers that must never outlive
  the process that started them (killed with ``kill -9``, they held its pipes for ever), with
  :func:`callers_signals_blocked` around the submits that fork them, :func:`end_workers` and
  :func:`worker_endings` (how a pool's workers ended: one line).
"""

from __future__ import annotations

import mmap
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator, Sequence
from contextlib import contextmanager
from types import FrameType
from typing import Any, TypeVar

import numpy as np

from ..errors import WorkerLost

__all__ = [
    "workers",
    "run_tasks",
    "can_fork",
    "shared_zeros",
    "signals_held",
    "callers_signals_blocked",
    "end_with_parent",
    "end_workers",
    "worker_endings",
]

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


@contextmanager
def signals_held() -> Iterator[None]:
    """Hold SIGINT and SIGTERM back: their Python handlers run when the block ends.

    Done with Python-level handlers, not a thread signal mask: a process-directed signal may be
    delivered to any thread (numpy's BLAS starts some) and Python then runs the handler in the
    main thread anyway, so a mask on the main thread alone would not hold it."""
    pending: list[int] = []

    def note(signum: int, frame: FrameType | None) -> None:  # noqa: ARG001 - signal's API
        pending.append(signum)

    held = (signal.SIGINT, signal.SIGTERM)
    try:
        old = {s: signal.signal(s, note) for s in held}
    except ValueError:  # not the main thread: signals cannot be handled here anyway
        yield
        return
    try:
        yield
    finally:
        for s, handler in old.items():
            signal.signal(s, handler)
        if pending:
            signum = pending[0]
            handler = old[signal.Signals(signum)]
            if callable(handler):
                handler(signum, None)  # e.g. raises KeyboardInterrupt
            elif handler == signal.SIG_DFL:
                os.kill(os.getpid(), signum)


#: The signals the caller decides about: its workers never run the caller's handlers for them.
_CALLERS_SIGNALS = (signal.SIGINT, signal.SIGTERM)


def _quiet_worker() -> None:
    """A worker leaves interruptions to the caller: Ctrl-C is ignored, SIGTERM (also the one sent
    to the whole process group) ends it at once, without the caller's handlers. The worker was
    forked with both signals blocked (:func:`run_tasks`), so that one arriving before this point
    cannot run a handler inherited from the caller (a traceback of its own); it is delivered
    only now, under these settings."""
    signal.signal(signal.SIGINT, signal.SIG_IGN)
    signal.signal(signal.SIGTERM, signal.SIG_DFL)
    signal.pthread_sigmask(signal.SIG_UNBLOCK, _CALLERS_SIGNALS)


#: How often a worker's watchdog looks for its parent (s), where the kernel cannot be asked to
#: end the worker with it.
PARENT_POLL_S = 0.5


def _die_with_parent() -> bool:
    """Ask the kernel to send this process SIGKILL when its parent ends (Linux's
    ``prctl(PR_SET_PDEATHSIG)``); False where that cannot be done."""
    if not sys.platform.startswith("linux"):
        return False
    try:
        import ctypes

        pr_set_pdeathsig = 1
        libc = ctypes.CDLL(None, use_errno=True)
        return int(libc.prctl(pr_set_pdeathsig, int(signal.SIGKILL), 0, 0, 0)) == 0
    except (OSError, AttributeError):
        return False


def _parent_gone(parent_pid: int) -> bool:
    """Has the process ``parent_pid`` (the pool's owner) ended?"""
    try:
        os.kill(parent_pid, 0)
    except ProcessLookupError:
        return True
    except OSError:  # (exists, another user's: a pid used again)
        return False
    return False


def _watch_parent(ppid: int) -> None:
    """A worker's watchdog thread: end the process once its parent is gone (it is then
    someone else's child: ``os.getppid()`` changes)."""
    while os.getppid() == ppid:
        time.sleep(PARENT_POLL_S)
    os._exit(1)


def end_with_parent(parent_pid: int) -> None:
    """The initializer of a pool's worker process (``ProcessPoolExecutor(initializer=...,
    initargs=(os.getpid(),))``): the worker ends with its parent, however the parent ends (a
    worker of a parent killed with ``kill -9`` waited for work for ever, holding the parent's
    pipes: a caller reading its output waited for ever too).

    Linux: the kernel sends it SIGKILL when its parent ends (``PR_SET_PDEATHSIG``); elsewhere a
    daemon thread looks every :data:`PARENT_POLL_S` for a new parent (POSIX reparents an
    orphan). A parent gone before either is in place ends it at once. The worker also leaves
    interruptions to the parent, as :func:`run_tasks`'s do: Ctrl-C is ignored, SIGTERM ends it
    at once, without the parent's handlers (the signals blocked in the parent around the
    submits that fork it, :func:`callers_signals_blocked`, are unblocked here)."""
    if os.name != "posix":  # (no signal masks, no reparenting to see)
        signal.signal(signal.SIGINT, signal.SIG_IGN)
        return
    _quiet_worker()
    ppid = os.getppid()
    armed = _die_with_parent()
    if os.getppid() != ppid or (ppid != parent_pid and _parent_gone(parent_pid)):
        os._exit(1)  # (orphaned already: fork, spawn; forkserver's parent is its server)
    if not armed:
        threading.Thread(
            target=_watch_parent, args=(ppid,), name="odocal-parent-watch", daemon=True
        ).start()


@contextmanager
def callers_signals_blocked() -> Iterator[None]:
    """Block SIGINT and SIGTERM in this thread meanwhile: the processes forked (and the threads
    started) inside inherit the mask. (A signal that comes meanwhile waits, or is taken by
    another thread of this process, numpy's BLAS threads say, and Python runs its handler in
    the main thread anyway: :func:`signals_held` holds that back.)"""
    old = signal.pthread_sigmask(signal.SIG_BLOCK, _CALLERS_SIGNALS)
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, old)


def _indexed(i: int) -> tuple[bool, Any]:
    """Task ``i`` in a worker: (True, its result) or (False, the exception it raised)."""
    try:
        return True, _TASKS[i]()
    except Exception as exc:  # noqa: BLE001 - raised again by the caller, in task order
        return False, exc


def end_workers(workers: Sequence[Any]) -> None:
    """End the worker processes (``multiprocessing`` processes) at once (SIGTERM, their default
    action; SIGKILL for one that has not ended a few seconds later) and reap them."""
    for p in workers:
        if p.exitcode is None:
            p.terminate()
    for p in workers:
        p.join(5.0)
        if p.exitcode is None:
            p.kill()
            p.join()


def worker_endings(workers: Sequence[Any]) -> str:
    """How the pool's worker processes ended, one line ('signal 9; out of memory?'), once each
    is ended and reaped (:func:`end_workers`); '' when none ended by itself (the pool ends the
    others with SIGTERM, which says nothing)."""
    end_workers(workers)
    codes = {p.exitcode for p in workers} - {None, 0}
    if codes - {-signal.SIGTERM}:
        codes.discard(-signal.SIGTERM)
    how = ", ".join(f"signal {-c}" if c < 0 else f"exit status {c}" for c in sorted(codes))
    if -signal.SIGKILL in codes:
        how += "; out of memory?"
    return how


def _lost_worker(workers: list[Any]) -> WorkerLost:
    """The error for a worker process that ended without returning its task's result."""
    how = worker_endings(workers)
    return WorkerLost(
        "a worker process ended before returning its result"
        + (f" ({how})" if how else "")
        + "; nothing was written"
    )


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
    interruption here (Ctrl-C, SIGTERM, an exception) ends the workers at once. The workers
    ignore Ctrl-C and end on SIGTERM, leaving what to do to this process; a worker that ends
    without its result (killed) raises :class:`~odocal.errors.WorkerLost` here, never a wait
    for ever."""
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
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from concurrent.futures.process import BrokenProcessPool

    _TASKS = tasks
    out: dict[int, Any] = {}
    failed: dict[int, BaseException] = {}
    first = 1 if share else 0
    others = set(mp.active_children())
    forked: list[Any] = []
    pool = ProcessPoolExecutor(n - first, mp.get_context("fork"), initializer=_quiet_worker)
    try:
        # the workers are forked at the first submit: they inherit the signals blocked, and
        # this process takes a signal only once it knows every worker (a handler run in the
        # middle of a fork could leave one unknown, and alive)
        with signals_held(), callers_signals_blocked():
            futures = {pool.submit(_indexed, i): i for i in range(first, len(tasks))}
            forked = [p for p in mp.active_children() if p not in others]
        if meanwhile is not None:
            meanwhile()
        if share:
            out[0] = tasks[0]()
            if done is not None:
                done(0)
        for future in as_completed(futures):
            i = futures[future]
            try:
                ok, result = future.result()
            except BrokenProcessPool:
                raise _lost_worker(forked) from None
            if ok:
                out[i] = result
            else:
                failed[i] = result
            if done is not None:
                done(i)
        pool.shutdown()
    except BaseException:
        # the workers ended first, then the pool's threads joined: none may still be running
        # when this process exits (Python 3.11 then fails in its exit handler, or aborts)
        with signals_held():
            end_workers(forked or [p for p in mp.active_children() if p not in others])
            pool.shutdown(wait=True, cancel_futures=True)
        raise
    finally:
        _TASKS = ()
    if failed:
        raise failed[min(failed)]
    return [out[i] for i in range(len(tasks))]
