"""odocal.core.parallel: independent tasks on worker processes, results in order."""

import os
import signal
import sys
import time

import numpy as np
import pytest

from odocal.core import parallel
from odocal.core.parallel import run_tasks, shared_zeros


@pytest.mark.parametrize("share", [False, True])
def test_results_in_order_from_worker_processes(monkeypatch, share):
    monkeypatch.setenv("ODOCAL_THREADS", "2")
    done = []
    tasks = [lambda i=i: (i, os.getpid()) for i in range(5)]
    out = run_tasks(tasks, done=done.append, share=share)
    assert [i for i, _ in out] == list(range(5))
    assert sorted(done) == list(range(5))
    pids = {pid for _, pid in out}
    if parallel.can_fork():
        assert pids - {os.getpid()}  # some ran elsewhere
        assert (os.getpid() in pids) == share  # with share, this process ran the first task
    assert parallel._TASKS == ()


def test_one_worker_runs_here_in_order(monkeypatch):
    monkeypatch.setenv("ODOCAL_THREADS", "1")
    seen = []
    out = run_tasks([lambda i=i: seen.append(i) or os.getpid() for i in range(3)])
    assert seen == [0, 1, 2] and set(out) == {os.getpid()}


def test_a_failing_task_raises_here(monkeypatch):
    monkeypatch.setenv("ODOCAL_THREADS", "2")

    def bad():
        raise ValueError("task 1 failed")

    with pytest.raises(ValueError, match="task 1 failed"):
        run_tasks([lambda: 1, bad, lambda: 3])
    assert parallel._TASKS == ()


@pytest.mark.parametrize("share", [False, True])
def test_the_first_failure_in_task_order_is_raised(monkeypatch, share):
    """Several tasks fail, the later one first in time: the error is the same on every run."""
    import time

    from odocal.errors import InputError

    # without share two workers for three tasks, with share this process runs the first task
    # and two workers the others: in both, quick_bad runs while slow_bad waits for it
    monkeypatch.setenv("ODOCAL_THREADS", "3" if share else "2")
    quick_failed = shared_zeros((1,))  # seen by every forked worker
    saw_quick_fail = shared_zeros((1,))

    def slow_bad():
        # fails after quick_bad has (the wait ends at 5 s if it never does: then the order in
        # time and in the list agree, and the test cannot tell)
        deadline = time.monotonic() + 5.0
        while quick_failed[0] == 0 and time.monotonic() < deadline:
            time.sleep(0.001)
        saw_quick_fail[0] = quick_failed[0]
        raise InputError("bad file", "a.csv", 3)

    def quick_bad():
        quick_failed[0] = 1
        raise InputError("also bad", "b.csv", 1)

    with pytest.raises(InputError, match="a.csv, line 3: bad file"):
        run_tasks([lambda: 0, slow_bad, quick_bad], share=share)
    assert saw_quick_fail[0] == 1  # the later task failed first in time


def test_workers_write_into_shared_memory(monkeypatch):
    monkeypatch.setenv("ODOCAL_THREADS", "2")
    a = shared_zeros((4, 3))
    assert a.shape == (4, 3) and np.all(a == 0)

    def fill(i):
        a[i] = i + 1

    run_tasks([lambda i=i: fill(i) for i in range(4)])
    np.testing.assert_array_equal(a[:, 0], [1, 2, 3, 4])


def test_no_nesting_inside_a_worker(monkeypatch):
    monkeypatch.setenv("ODOCAL_THREADS", "2")

    def inner():
        return run_tasks([os.getpid, os.getpid])  # runs in the worker itself

    for pids in run_tasks([inner, inner]):
        assert len(set(pids)) == 1


@pytest.mark.parametrize("share", [False, True])
def test_one_worker_inside_a_task(monkeypatch, share):
    # the workers already take the cores: no threads of their own inside a task (the simulator
    # would run its blocks on workers() threads), in this process's share of the tasks too
    monkeypatch.setenv("ODOCAL_THREADS", "2")
    assert parallel.workers() == 2
    assert run_tasks([parallel.workers, parallel.workers], share=share) == [1, 1]
    assert parallel.workers() == 2


def _inside_a_pool_worker(_):
    os.environ["ODOCAL_THREADS"] = "2"
    return run_tasks([os.getpid, os.getpid])


def test_inside_a_daemonic_pool_worker_runs_here():
    """A worker of the caller's own pool may not have children: the tasks run in it."""
    import multiprocessing as mp

    with mp.get_context("fork").Pool(1) as pool:
        pids = pool.map(_inside_a_pool_worker, [0])[0]
    assert len(set(pids)) == 1


def _die():
    os.kill(os.getpid(), signal.SIGKILL)


def test_a_killed_worker_is_reported_not_waited_for(monkeypatch):
    """A worker that ends without its result (killed; the pool of multiprocessing waited for
    ever): one clear error, the other workers reaped."""
    import multiprocessing as mp

    from odocal.errors import WorkerLost

    monkeypatch.setenv("ODOCAL_THREADS", "2")

    def hung(signum, frame):
        raise TimeoutError("run_tasks waited for a dead worker")

    previous = signal.signal(signal.SIGALRM, hung)
    signal.alarm(20)
    try:
        with pytest.raises(WorkerLost, match="worker process ended .*signal 9"):
            run_tasks([lambda: time.sleep(0.2), _die, lambda: 3])
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    assert mp.active_children() == [] and parallel._TASKS == ()


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="worker processes fork on Linux")
def test_workers_start_with_the_callers_signals_blocked(monkeypatch):
    """A signal between the fork and the worker's own handlers cannot run the caller's handler
    in the worker (which printed a traceback of its own): it waits, blocked, until the worker
    ignores Ctrl-C and takes SIGTERM's default action."""
    monkeypatch.setenv("ODOCAL_THREADS", "2")
    assert parallel.can_fork()
    seen = shared_zeros((4,))
    real = parallel._quiet_worker

    def recording() -> None:
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, [])
        seen[0] = 1 + (signal.SIGINT in blocked) + 2 * (signal.SIGTERM in blocked)
        real()

    monkeypatch.setattr(parallel, "_quiet_worker", recording)

    def state():
        blocked = signal.pthread_sigmask(signal.SIG_BLOCK, [])
        return (
            signal.getsignal(signal.SIGINT),
            signal.getsignal(signal.SIGTERM),
            signal.SIGINT in blocked or signal.SIGTERM in blocked,
        )

    before = signal.pthread_sigmask(signal.SIG_BLOCK, [])
    assert run_tasks([state, state]) == [(signal.SIG_IGN, signal.SIG_DFL, False)] * 2
    assert seen[0] == 4  # both blocked when the worker began
    assert signal.pthread_sigmask(signal.SIG_BLOCK, []) == before  # here, as it was


def test_an_interruption_leaves_no_worker_and_no_pool_thread(monkeypatch):
    """Ctrl-C or SIGTERM here (in ``meanwhile``) while the workers compute: they are ended and
    the pool's threads joined before the interruption goes on (a pool thread still running at
    exit made Python 3.11 print a traceback from its exit handler, or abort)."""
    import multiprocessing as mp
    import threading

    monkeypatch.setenv("ODOCAL_THREADS", "2")
    threads = set(threading.enumerate())

    def interrupted():
        raise KeyboardInterrupt

    start = time.monotonic()
    with pytest.raises(KeyboardInterrupt):
        run_tasks([lambda: time.sleep(30)] * 3, meanwhile=interrupted)
    assert time.monotonic() - start < 10  # not waiting for the tasks
    assert set(threading.enumerate()) <= threads
    assert mp.active_children() == [] and parallel._TASKS == ()
