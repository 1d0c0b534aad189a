"""`odocal fleet`: parsing, printing and exit codes (the work is tested in tests/app)."""

from __future__ import annotations

import json
import multiprocessing as mp
import os
import signal
import sqlite3
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from odocal.io.fleet_db import open_db
from tests.support.fleet import fill_db, robot_yaml

SE = (5e-5, 5e-5, 2.5e-4)


def _db(path, n=6):
    rng = np.random.default_rng(1)
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": [(tuple(np.array([0.05, 0.05, 0.25]) + np.array(SE) *
                                   rng.standard_normal(3)), SE) for _ in range(n)]})  # fmt: skip
    return path


def test_status_text_and_json(cli, tmp_path):
    db = _db(tmp_path / "f.db")
    status, out, err = cli("fleet", "status", "--db", db)
    assert status == 0 and err == ""
    header, row = out.splitlines()
    assert header.split() == ["robot", "bags", "failed", "untrusted", "D_R", "mm", "D_L", "mm",
                              "b", "mm", "drift"]  # fmt: skip
    assert row.split()[:4] == ["r1", "6", "0", "0"] and row.split()[-1] == "-"
    status, out, _ = cli("fleet", "status", "--db", db, "--json")
    (r,) = json.loads(out)["robots"]
    assert r["drift_alarm"] is False and set(r["parameters"]) == {
        "wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"}  # fmt: skip


def test_export(cli, tmp_path):
    db = _db(tmp_path / "f.db")
    status, out, _ = cli("fleet", "export", "r1", "--db", db, "--ros2", tmp_path / "r1.yaml")
    assert status == 0 and "filtered level of 6 bags" in out
    assert "diff_drive_controller:" in (tmp_path / "r1.yaml").read_text()
    status, out, _ = cli("fleet", "export", "r1", "--db", db, "--ros2", tmp_path / "2.yaml",
                         "--json")  # fmt: skip
    assert status == 0 and json.loads(out)["bags"] == 6


def test_ingest_text(cli, tmp_path):
    robot_yaml(tmp_path / "root" / "r1")
    (tmp_path / "root" / "r1" / "x.bag").write_bytes(b"junk")
    status, out, err = cli("fleet", "ingest", tmp_path / "root", "--db", tmp_path / "f.db")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("1 bags under") and "0 new, 1 failed (0 to retry)" in lines[0]
    assert lines[1].startswith("  failed: ") and lines[1].count("x.bag") == 1


def _one_line(status, out, err, *needles):
    assert status == 2 and out == "" and err.count("\n") == 1, err
    assert err.startswith("odocal: error: ")
    for n in needles:
        assert n in err, err


def test_bad_inputs_are_one_line(cli, tmp_path):
    root = tmp_path / "root"
    (root / "r1").mkdir(parents=True)
    _one_line(*cli("fleet", "ingest", root, "--db", tmp_path / "f.db"),
              "r1: robot folder without robot.yaml")  # fmt: skip
    assert not (tmp_path / "f.db").exists()
    db = _db(tmp_path / "new.db")
    with open_db(db, write=True) as fdb, fdb.transaction() as c:
        c.execute("UPDATE schema_version SET version = 7")
    robot_yaml(root / "r1")
    for argv in (("ingest", root), ("status",), ("report", "--html", tmp_path / "h")):
        _one_line(*cli("fleet", *argv, "--db", db), "newer odocal (schema 7")
    _one_line(*cli("fleet", "status", "--db", tmp_path / "missing.db"), "no fleet database")
    _one_line(*cli("fleet", "ingest", root, "--db", tmp_path / "f.db", "--workers", "0"))
    _one_line(*cli("fleet", "export", "r1", "--db", db, "--ros2", db), "overwrite an input")
    _one_line(*cli("fleet", "status"), "--db")


def test_ingest_names_a_robot_it_could_not_ingest_and_goes_on(cli, tmp_path):
    robot_yaml(tmp_path / "root" / "r1")
    (tmp_path / "root" / "r1" / "x.bag").write_bytes(b"junk")
    (tmp_path / "root" / "r2").mkdir()
    status, out, err = cli("fleet", "ingest", tmp_path / "root", "--db", tmp_path / "f.db")
    assert status == 0, err
    lines = out.splitlines()
    assert lines[0].startswith("1 bags under") and "(1 robots)" in lines[0]
    assert lines[-1] == (f"  robot not ingested: {tmp_path / 'root' / 'r2'}: robot folder without "
                         "robot.yaml (each robot's folder holds its nominal geometry: "
                         "wheel_diameter_m, wheelbase_m; docs/fleet.md)")  # fmt: skip


# ---- killed: a worker, or the ingest itself (issue 27, item 14). Linux: /proc lists the
# processes; the workers are forked (the driver's slow calibration is theirs)

needs_proc_and_fork = pytest.mark.skipif(
    not sys.platform.startswith("linux") or mp.get_start_method() != "fork",
    reason="the process tree is read from /proc; the pool's workers must be forked",
)
REPO = Path(__file__).resolve().parents[2]


def _state(pid: int) -> str | None:
    """The process's state letter (Z: ended, not yet reaped), None when it is gone."""
    try:
        with open(f"/proc/{pid}/stat") as f:
            return f.read().rsplit(")", 1)[1].split()[0]
    except OSError:
        return None


def _children(pid: int) -> list[int]:
    out = []
    for d in os.listdir("/proc"):
        if d.isdigit():
            try:
                with open(f"/proc/{d}/stat") as f:
                    fields = f.read().rsplit(")", 1)[1].split()
            except OSError:
                continue
            if int(fields[1]) == pid and fields[0] != "Z":
                out.append(int(d))
    return sorted(out)


def _alive(pid: int) -> bool:
    return _state(pid) not in (None, "Z")


def _until(what, seconds: float):
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        got = what()
        if got:
            return got
        time.sleep(0.05)
    return what()


def _start_slow_ingest(tmp_path, *flags, session=False, bags=2):
    """The driver with two bags in flight on two workers (and the rest queued): (its process,
    the workers' pids). ``session``: in a process group of its own (for a signal to the whole
    group)."""
    root = tmp_path / "root"
    robot_yaml(root / "r1")
    for i in range(bags):
        (root / "r1" / f"b{i}.bag").write_bytes(f"bag {i}".encode())
    proc = subprocess.Popen(
        [sys.executable, "-m", "tests.support.fleet_driver", root, tmp_path / "f.db", "2", *flags],
        cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=session,
    )  # fmt: skip
    workers = _until(lambda: (c := _children(proc.pid)) and len(c) == 2 and c, 60)
    assert workers, f"no two workers within 60 s: {_children(proc.pid)}"
    return proc, workers


def _ours(pid: int) -> bool:
    """Is ``pid`` still one of the driver's processes (forked from it: its command line)?"""
    try:
        with open(f"/proc/{pid}/cmdline", "rb") as f:
            return b"tests.support.fleet_driver" in f.read()
    except OSError:
        return False


def _end(proc, workers):
    """End what the test started that is still running (never waits for ever)."""
    for pid in workers:
        if _alive(pid) and _ours(pid):
            os.kill(pid, signal.SIGKILL)
    if proc.poll() is None:
        proc.kill()
    try:
        proc.communicate(timeout=10)
    except subprocess.TimeoutExpired:
        pass


@needs_proc_and_fork
@pytest.mark.parametrize("guard", ["pdeathsig", "watchdog"])
def test_the_workers_end_with_a_killed_ingest(tmp_path, guard):
    """kill -9 of 'fleet ingest --workers 2' left both workers alive for ever, holding the
    caller's pipes (a cron wrapper reading its output waited for ever too). They end with it:
    by the kernel's parent-death signal, or by their watchdog thread where there is none."""
    proc, workers = _start_slow_ingest(tmp_path, *(["--watchdog"] if guard == "watchdog" else []))
    try:
        time.sleep(0.3)  # (the bags in flight)
        os.kill(proc.pid, signal.SIGKILL)
        proc.wait(10)
        assert _until(lambda: not any(map(_alive, workers)), 10), "workers still alive"
        proc.communicate(timeout=10)  # the pipes closed: nobody holds them any more
    finally:
        _end(proc, workers)


@needs_proc_and_fork
def test_a_killed_worker_is_one_line_and_its_bags_are_retried(tmp_path):
    """kill -9 of one worker ended the ingest with a traceback (BrokenProcessPool). Now one
    line, exit status 2, and the bags in flight stored as retry (tried again next time)."""
    proc, workers = _start_slow_ingest(tmp_path)
    try:
        time.sleep(0.3)
        os.kill(workers[0], signal.SIGKILL)
        out, err = proc.communicate(timeout=30)
        assert proc.returncode == 2 and out == "", err
        assert err.count("\n") == 1, err
        assert err.startswith(
            "odocal: error: a worker process ended before returning its result (signal 9; out "
            "of memory?): the 2 bags in flight are stored as retry (tried again at the next "
            "ingest)"
        ), err
        assert _until(lambda: not any(map(_alive, workers)), 10)
        with sqlite3.connect(tmp_path / "f.db") as con:
            rows = con.execute("SELECT status, reason FROM bags").fetchall()
        assert [s for s, _ in rows] == ["retry", "retry"]
        assert all("a worker process ended before returning its result" in r for _, r in rows)
    finally:
        _end(proc, workers)


@needs_proc_and_fork
@pytest.mark.parametrize("how", [signal.SIGINT, signal.SIGTERM])
def test_an_interrupted_ingest_ends_its_workers_at_once(tmp_path, how):
    """Ctrl-C (to the whole process group, as a terminal sends it) or SIGTERM: one line, and the
    workers ended at once. (Ctrl-C waited for a queued bag to be calibrated: a minute here.)"""
    proc, workers = _start_slow_ingest(tmp_path, session=True, bags=3)
    try:
        time.sleep(0.3)
        os.killpg(proc.pid, how)
        out, err = proc.communicate(timeout=15)
        assert proc.returncode == 128 + how and out == ""
        said = "interrupted" if how == signal.SIGINT else "terminated (SIGTERM)"
        assert err == f"odocal: {said}; nothing half-written\n"
        assert _until(lambda: not any(map(_alive, workers)), 10)
    finally:
        _end(proc, workers)


def test_status_shows_a_robot_id_with_a_line_break_on_one_row(cli, tmp_path):
    rng = np.random.default_rng(3)
    with open_db(tmp_path / "f.db", write=True) as db:
        fill_db(db, {"a\nb": [((0.05, 0.05, 0.25) + np.array(SE) * rng.standard_normal(3), SE)]})
    status, out, _ = cli("fleet", "status", "--db", tmp_path / "f.db")
    assert status == 0
    _, row = out.splitlines()
    assert row.split()[0] == "'a\\nb'"


def test_status_says_when_a_robot_has_no_trusted_calibration(cli, tmp_path):
    with open_db(tmp_path / "f.db", write=True) as db:
        fill_db(db, {"r1": [((0.05, 0.05, 0.25), SE)] * 3}, untrusted=("r1",))
    status, out, _ = cli("fleet", "status", "--db", tmp_path / "f.db")
    assert status == 0
    header, row = out.splitlines()
    assert header.split()[:4] == ["robot", "bags", "failed", "untrusted"]
    assert row.split()[:4] == ["r1", "3", "0", "3"]
    assert row.endswith("no trusted calibration")


# ---- the alarms, read and acknowledged (issue 27, item 3)


def _alarmed(tmp_path):
    """A database whose robot r1 has one drift alarm (its wheelbase 2 % up from bag 20), stored
    by an ingest as every ingest does."""
    from odocal.app.fleet import fleet_ingest

    rng = np.random.default_rng(1)
    bags = []
    for i in range(30):
        v = np.array([0.05, 0.05, 0.25 * (1.02 if i >= 20 else 1.0)])
        bags.append((tuple(v + np.array(SE) * rng.standard_normal(3)), SE))
    db = tmp_path / "f.db"
    with open_db(db, write=True) as fdb:
        fill_db(fdb, {"r1": bags, "r2": bags[:10]})
    robot_yaml(tmp_path / "root" / "r2")
    fleet_ingest(tmp_path / "root", db)
    return db


def test_alarms_are_listed_and_one_is_acknowledged(cli, tmp_path):
    """The alarms table was written by every ingest and read by nothing."""
    db = _alarmed(tmp_path)
    status, out, err = cli("fleet", "alarms", "--db", db)
    assert status == 0 and err == ""
    header, row = out.splitlines()
    assert header.split() == ["robot", "parameter", "bag", "size", "mm", "z", "raised", "state"]
    assert row.split()[:3] == ["r1", "wheelbase_m", "/fleet/r1/bag020"]
    assert row.split()[-1] == "ACTIVE" and float(row.split()[3]) > 3  # (+5 mm)
    status, out, _ = cli("fleet", "status", "--db", db)
    assert (
        out.splitlines()[1].split()[0] == "r1" and out.splitlines()[1].split()[-2] == "wheelbase_m"
    )
    # acknowledged: kept, no longer the robot's drift alarm
    status, out, err = cli("fleet", "ack", "--db", db, "r1", "b")
    assert status == 0 and err == ""
    assert out.startswith("r1 wheelbase_m: the alarm raised by /fleet/r1/bag020 (")
    assert " acknowledged at 20" in out
    status, out, _ = cli("fleet", "alarms", "--db", db, "--json")
    (a,) = json.loads(out)["alarms"]
    assert a["acknowledged"] is True and a["active"] is False and a["acknowledged_at"]
    assert (a["robot_id"], a["parameter"], a["bag"]) == ("r1", "wheelbase_m", "/fleet/r1/bag020")
    assert a["z"] > 3 and a["size_m"] > 0 and a["raised_at"]
    status, out, _ = cli("fleet", "status", "--db", db, "--json")
    rows = {r["robot_id"]: r for r in json.loads(out)["robots"]}
    assert rows["r1"]["drift_alarm"] is False and len(rows["r1"]["alarms_acknowledged"]) == 1
    status, out, _ = cli("fleet", "status", "--db", db)
    assert [r.split()[-1] for r in out.splitlines()[1:]] == ["-", "-"]  # r1 is well again
    status, out, _ = cli("fleet", "alarms", "--db", db)
    assert "acknowledged 20" in out.splitlines()[1]
    status, out, _ = cli("fleet", "ack", "--db", db, "r1", "wheelbase_m", "/fleet/r1/bag020",
                         "--json")  # fmt: skip
    assert status == 0 and json.loads(out)["already_acknowledged"] is True


def test_ack_errors_are_one_line(cli, tmp_path):
    db = _alarmed(tmp_path)
    for argv, said in (
        (("r1", "diameter"), "no parameter 'diameter': one of wheel_diameter_right_m"),
        (("r9", "b"), "no robot r9 in the fleet database (robots: r1, r2)"),
        (("r1", "D_L"), "no alarm of wheel_diameter_left_m on robot r1 to acknowledge"),
        (("r1", "b", "/fleet/r1/bag003"), "no alarm of wheelbase_m on robot r1 raised by bag "
         "/fleet/r1/bag003 (its alarms: /fleet/r1/bag020)"),
    ):  # fmt: skip
        status, out, err = cli("fleet", "ack", "--db", db, *argv)
        assert status == 2 and out == "" and said in err, err
        assert err.count("\n") == 1
    status, _, err = cli("fleet", "ack", "--db", tmp_path / "none.db", "r1", "b")
    assert status == 2 and "no fleet database here" in err and not (tmp_path / "none.db").exists()
    empty = tmp_path / "e.db"
    open_db(empty, write=True).close()
    status, out, _ = cli("fleet", "alarms", "--db", empty)
    assert status == 0 and out.startswith("no drift alarm in ")
