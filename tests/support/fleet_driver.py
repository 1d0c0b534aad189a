"""``python -m tests.support.fleet_driver ROOT DB WORKERS [--watchdog]``: ``odocal fleet ingest
ROOT --db DB --workers WORKERS`` whose every bag takes a minute to calibrate, for the tests that
kill the ingest or one of its workers while bags are in flight (tests/cli/test_fleet.py).

The worker processes are forked from this one, so they calibrate with the slow stand-in set
here. ``--watchdog``: the workers may not ask the kernel to end them with their parent
(PR_SET_PDEATHSIG), as where it does not exist: the portable watchdog thread must do it."""

from __future__ import annotations

import sys
import time


def _slow_fit_auto(*args, **kwargs):
    time.sleep(60)
    raise RuntimeError("a minute passed: the test that started this should have ended it")


def main(argv: list[str]) -> int:
    import types

    # the bag route's module replaced before anything imports it (its own imports are most of
    # a second of CPU): calibrate_bag imports fit_auto from it when it runs
    stand_in = types.ModuleType("odocal.app.fit_auto")
    stand_in.fit_auto = _slow_fit_auto  # type: ignore[attr-defined]
    sys.modules["odocal.app.fit_auto"] = stand_in

    import odocal.core.parallel as parallel
    from odocal.cli.main import main as odocal

    if "--watchdog" in argv:
        parallel._die_with_parent = lambda: False
    root, db, workers = argv[:3]
    return odocal(["fleet", "ingest", root, "--db", db, "--workers", workers])


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
