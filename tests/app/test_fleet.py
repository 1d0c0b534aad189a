"""`odocal fleet` end to end on a small simulated fleet of synthetic bags (tests/support/fleet.py):
ingest (idempotent, resumable, copies counted once, bad bags recorded), status, export, report,
and the same numbers on a process pool and on a Dask LocalCluster."""

from __future__ import annotations

import json
import shutil
import sqlite3

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.errors import InputError
from tests.support.fleet import robot_yaml, run_within, write_bag

TRUE = {"r1": WheelGeometry(0.0505, 0.0495, 0.262), "r2": WheelGeometry(0.0500, 0.0502, 0.255)}
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


@pytest.fixture(scope="module")
def fleet(tmp_path_factory):
    """Two robots (r1: two bags, r2: one bag and a broken one); ingested once in this
    process."""
    from odocal.app.fleet import fleet_ingest

    root = tmp_path_factory.mktemp("fleet") / "root"
    rng = np.random.default_rng(4)
    for rid, true in TRUE.items():
        robot_yaml(root / rid)
        for day in range(2 if rid == "r1" else 1):
            write_bag(root / rid / f"day{day}" / "bag", true, day, rng)
    (root / "r2" / "broken.bag").write_bytes(b"not a bag at all")
    db = root.parent / "fleet.db"
    return root, db, fleet_ingest(root, db)


def _copy(fleet, tmp_path):
    root, db, _ = fleet
    shutil.copytree(root, tmp_path / "root")
    shutil.copy(db, tmp_path / "fleet.db")
    return tmp_path / "root", tmp_path / "fleet.db"


def _calibrations(db):
    with sqlite3.connect(db) as con:
        return con.execute(
            "SELECT content_hash, d_right_m, d_right_se_m, d_left_m, wheelbase_m, result_json "
            "FROM calibrations ORDER BY content_hash"
        ).fetchall()


def test_the_json_contract_and_the_failed_bag(fleet):
    _, _, res = fleet
    d = json.loads(json.dumps(res.as_dict()))
    assert {"bags_total", "bags_new", "bags_failed", "seconds"} <= set(d)
    assert (d["bags_total"], d["bags_new"], d["bags_failed"], d["bags_retry"]) == (4, 3, 1, 0)
    assert d["seconds"] > 0 and d["robots"] == 2 and d["engine"] == "this process"
    (fail,) = d["failures"]
    assert fail["bag"].endswith("broken.bag") and "cannot read the bag" in fail["reason"]
    assert "\n" not in fail["reason"]


def test_status_one_row_per_robot_with_the_true_parameters(fleet):
    from odocal.app.fleet_status import fleet_status

    _, db, _ = fleet
    st = fleet_status(db).as_dict()
    rows = {r["robot_id"]: r for r in st["robots"]}
    assert list(rows) == ["r1", "r2"]  # no drift: by id
    assert (rows["r2"]["bags"], rows["r2"]["bags_done"], rows["r2"]["bags_failed"]) == (2, 1, 1)
    for rid, r in rows.items():
        assert r["drift_alarm"] is False and r["drift"] is None and r["last_calibrated"]
        for key, true in zip(KEYS, TRUE[rid].as_dict().values(), strict=True):
            p = r["parameters"][key]
            assert abs(p["value"] - true) < 5 * p["std_error"] + 1e-9, (rid, key)
            assert abs(p["value"] - true) / true < 3e-3


def test_a_second_run_processes_nothing_and_copies_count_once(fleet, tmp_path):
    from odocal.app.fleet import fleet_ingest

    root, db = _copy(fleet, tmp_path)
    before = _calibrations(db)
    res = fleet_ingest(root, db)
    assert (res.bags_total, res.bags_new, res.bags_failed, res.bags_skipped) == (4, 0, 0, 4)
    # a renamed copy in the same robot, and a copy under the other robot
    shutil.copytree(root / "r1" / "day0" / "bag", root / "r1" / "renamed")
    shutil.copytree(root / "r1" / "day1" / "bag", root / "r2" / "stray")
    res = fleet_ingest(root, db)
    assert (res.bags_total, res.bags_new, res.bags_failed) == (4, 0, 0)
    (w,) = res.warnings
    assert "r2/stray: the same bag as one of robot r1: counted once, for r1" in w
    assert _calibrations(db) == before


def test_two_robots_claiming_one_new_bag(fleet, tmp_path):
    from odocal.app.fleet import fleet_ingest
    from odocal.app.fleet_status import fleet_status

    root, db = _copy(fleet, tmp_path)
    for r in ("r1", "r2"):
        (root / r / "shared.bag").write_bytes(b"the same bytes")
    res = fleet_ingest(root, db)
    assert (res.bags_new, res.bags_failed, res.bags_retry) == (0, 1, 1)
    (bag, why) = res.failures[0]
    assert "claimed by robots r1 and r2" in why and "tried again" in why
    assert fleet_status(db).robots[0].bags_failed == 1  # recorded for one robot only
    (root / "r2" / "shared.bag").unlink()  # resolved: now r1's (and not a bag: failed)
    res = fleet_ingest(root, db)
    assert (res.bags_new, res.bags_failed, res.bags_retry) == (0, 1, 0)


def test_a_bag_still_being_written_is_retried_not_stored(fleet, tmp_path, monkeypatch):
    import odocal.app.fleet as app_fleet
    from odocal.app.fleet_task import BagTask, calibrate_bag
    from odocal.io.fleet_files import content_hash, snapshot

    root, db = _copy(fleet, tmp_path)
    growing = root / "r1" / "growing.bag"
    growing.write_bytes(b"#ROSBAG V2.0\n")

    def hash_while_written(bag):
        if bag == growing:
            with open(bag, "ab") as f:  # the recorder appends while the bag is read
                f.write(b"\0" * 100)
        return content_hash(bag)

    monkeypatch.setattr(app_fleet, "content_hash", hash_while_written)
    res = app_fleet.fleet_ingest(root, db)
    assert (res.bags_new, res.bags_failed, res.bags_retry) == (0, 1, 1)
    assert "changed while it was read" in res.failures[0][1]
    monkeypatch.undo()
    res = app_fleet.fleet_ingest(root, db)  # finished now: tried again (a truncated bag)
    assert (res.bags_total, res.bags_retry, res.bags_failed) == (4 + 1, 0, 1)
    with sqlite3.connect(db) as con:  # the partial bag's row is gone
        assert con.execute("SELECT COUNT(*) FROM bags WHERE status = 'retry'").fetchone() == (0,)
    # in a worker: the bag changed between the hash and the end of the calibration
    bag = root / "r1" / "day0" / "bag"
    task = BagTask("r1", str(bag), str(root / "r1" / "robot.yaml"), "h", snapshot(growing))
    out = calibrate_bag(task)
    assert out.status == "retry" and out.record is None and out.report is None


def test_an_interrupted_run_keeps_every_bag_stored(tmp_path):
    from odocal.app.fleet import fleet_ingest

    root = tmp_path / "root"
    robot_yaml(root / "r1")
    for i in range(3):
        (root / "r1" / f"b{i}.bag").write_bytes(f"not a bag {i}".encode())
    db = tmp_path / "f.db"
    seen = []

    def stop_after_one(outcome, done, total):
        seen.append((done, total))
        raise KeyboardInterrupt  # Ctrl-C (SIGTERM is raised the same way by the CLI)

    with pytest.raises(KeyboardInterrupt):
        fleet_ingest(root, db, on_stored=stop_after_one)
    assert seen == [(1, 3)]
    with sqlite3.connect(db) as con:
        assert con.execute("PRAGMA integrity_check").fetchone() == ("ok",)
        assert con.execute("SELECT COUNT(*) FROM bags").fetchone() == (1,)
    res = fleet_ingest(root, db)
    assert (res.bags_total, res.bags_failed, res.bags_skipped) == (3, 2, 1)


def test_a_disk_that_fills_up_during_the_ingest(tmp_path, monkeypatch):
    import odocal.app.fleet as app_fleet
    from odocal.io.fleet_db import open_db

    root = tmp_path / "root"
    robot_yaml(root / "r1")
    for i in range(3):
        (root / "r1" / f"b{i}.bag").write_bytes(b"x" * i)
    db = tmp_path / "f.db"
    app_fleet.fleet_ingest(root, db)
    for i in range(3, 40):
        (root / "r1" / f"b{i}.bag").write_bytes(b"x" * i)

    def small_disk(path, *, write):
        fdb = open_db(path, write=write)
        pages = fdb.con.execute("PRAGMA page_count").fetchone()[0]
        fdb.con.execute(f"PRAGMA max_page_count = {pages + 2}")  # SQLite's 'disk is full'
        return fdb

    monkeypatch.setattr(app_fleet, "open_db", small_disk)
    with pytest.raises(InputError, match="disk is full.*every bag stored so far is kept"):
        app_fleet.fleet_ingest(root, db)
    monkeypatch.undo()
    with open_db(db, write=False) as fdb:
        stored = fdb.count()
        assert 3 <= stored < 40
    assert app_fleet.fleet_ingest(root, db).bags_total == 40


def test_export_writes_the_current_parameters(fleet, tmp_path):
    from odocal.app.fleet_status import fleet_export, fleet_status
    from odocal.io.ros2_export import read_ros2_params

    _, db, _ = fleet
    out = tmp_path / "r1.yaml"
    res = fleet_export(db, "r1", out)
    assert res.written == (out,) and res.bags == 2
    current = next(r for r in fleet_status(db).robots if r.robot_id == "r1").parameters
    got = read_ros2_params(out).as_dict()
    for k in KEYS:
        assert got[k] == pytest.approx(current[k]["value"], rel=1e-12)
    assert "pose_covariance_diagonal" in out.read_text()
    with pytest.raises(InputError, match="no robot 'r9'.*robots: r1, r2"):
        fleet_export(db, "r9", tmp_path / "x.yaml")
    with pytest.raises(InputError):  # never over its input
        fleet_export(db, "r1", db)


def test_report_pages(fleet, tmp_path):
    from odocal.app.fleet_report import fleet_report

    _, db, _ = fleet
    res = fleet_report(db, tmp_path / "html")
    index = (tmp_path / "html" / "index.html").read_text()
    assert res.robots == 2 and res.bags == 4
    assert index.count('<tr><td><a href="robots/') == 2 and "<script" not in index
    page = (tmp_path / "html" / "robots" / "r2.html").read_text()
    assert "<svg" in page and page.count('">report</a>') == 1 and "broken.bag" in page
    assert len(list((tmp_path / "html" / "bags").iterdir())) == 3
    assert "http://" not in index and "https://" not in index


def test_a_bag_page_is_its_report_as_html_with_its_figure(fleet, tmp_path):
    """A bag's page was its Markdown report as raw text in a <pre>, its figures only named."""
    from odocal.app.fleet_report import fleet_report

    _, db, _ = fleet
    fleet_report(db, tmp_path / "html")
    pages = sorted((tmp_path / "html" / "bags").iterdir())
    assert len(pages) == 3
    for page in pages:
        text = page.read_text()
        assert "<pre>" not in text and "**" not in text and "| --- |" not in text
        assert "<h1>Odometry calibration of <code>" in text
        assert "<strong>Verdict: trustworthy</strong>" in text
        assert text.count("<table>") >= 3 and "<th>route</th>" in text
        assert "<h2>Held-out check</h2>" in text and "<h2>Figures</h2>" in text
        assert text.count("<svg") == 1 and 'aria-label="held-out check"' in text
        assert "time_offset.png" in text and "Figures: time_offset.png" not in text


@pytest.fixture(scope="module")
def cluster():
    import dask
    from dask.distributed import LocalCluster

    # worker processes forked from this one (odocal, numpy and scipy already imported): a third
    # of the CPU of spawned ones, which import everything again
    with (
        dask.config.set({"distributed.worker.multiprocessing-method": "fork"}),
        LocalCluster(
            n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
        ) as c,
    ):
        yield c


def test_the_same_numbers_on_a_process_pool_and_on_dask(fleet, tmp_path, cluster, monkeypatch):
    from odocal.app import fleet as app_fleet
    from odocal.app.fleet import fleet_ingest

    # Dask retries a refused connection until its timeout: the unreachable scheduler below
    # (refused at once on this machine; a timeout is reported as the same one line)
    monkeypatch.setattr(app_fleet, "DASK_CONNECT_TIMEOUT_S", 0.1)

    root, db, _ = fleet
    one = tmp_path / "one"  # robot r1 alone (two bags): cheaper
    one.mkdir()
    (one / "r1").symlink_to(root / "r1")
    pool, dask = tmp_path / "pool.db", tmp_path / "dask.db"
    res = fleet_ingest(one, pool, workers=2)
    assert res.bags_new == 2 and res.engine == "2 processes"
    res = fleet_ingest(one, dask, dask=cluster.scheduler_address)
    assert res.bags_new == 2 and res.engine.startswith("dask tcp://")
    # the same JSON and numbers as the ingest in this process (the fixture's), bit for bit;
    # only the bag's path differs
    ref = [r for r in _calibrations(db) if f"{root}/r1/" in r[-1]]
    assert len(ref) == 2
    for rows in (_calibrations(pool), _calibrations(dask)):
        assert [r[:-1] for r in rows] == [r[:-1] for r in ref]
        assert [r[-1].replace(str(one), str(root)) for r in rows] == [r[-1] for r in ref]
    with pytest.raises(InputError, match="cannot reach the Dask scheduler"):
        fleet_ingest(one, tmp_path / "x.db", dask="tcp://127.0.0.1:1")


# ---- the fleet's edges (issue 27): what is not a bag never hangs, stops or lies


def _ingest_within(seconds, root, db, *, fifo=None, **kw):
    """fleet_ingest, failed (not waited for) when it takes longer than ``seconds``."""
    from odocal.app.fleet import fleet_ingest

    return run_within(seconds, lambda: fleet_ingest(root, db, **kw), fifo=fifo)


def test_a_fifo_with_a_bag_s_name_is_skipped_not_waited_on(tmp_path):
    """A FIFO named like a bag hung the ingest for ever (every bag is hashed before any is
    calibrated: nothing was stored); it is skipped with a warning, never opened."""
    import os

    root = tmp_path / "root"
    robot_yaml(root / "r1")
    (root / "r1" / "a.bag").write_bytes(b"not a bag")
    os.mkfifo(root / "r1" / "pipe.bag")
    db = tmp_path / "f.db"
    res = _ingest_within(20, root, db, fifo=root / "r1" / "pipe.bag")
    assert (res.bags_total, res.bags_failed) == (1, 1)  # a.bag, stored as failed
    (w,) = res.warnings
    assert "pipe.bag: a FIFO with a bag's name, not a bag: skipped" in w
    with sqlite3.connect(db) as con:
        assert con.execute("SELECT path, status FROM bags").fetchall() == [
            (str(root / "r1" / "a.bag"), "failed")
        ]


def test_a_dead_link_an_unreadable_bag_and_a_robot_without_robot_yaml_do_not_stop_the_run(
    tmp_path, monkeypatch
):
    """Each was the end of the whole run (one error, nothing ingested), where docs/fleet.md
    promises a failure of that bag or robot and the run going on."""
    import odocal.app.fleet as app_fleet
    from odocal.io.fleet_files import content_hash

    root = tmp_path / "root"
    for r in ("r1", "r2"):
        robot_yaml(root / r)
        (root / r / "ok.bag").write_bytes(f"junk of {r}".encode())
    (root / "r1" / "dead.bag").symlink_to(tmp_path / "nowhere.bag")
    (root / "r1" / "locked.bag").write_bytes(b"no permission")
    (root / "r3").mkdir()  # no robot.yaml
    (root / "r4").mkdir()
    (root / "r4" / "robot.yaml").write_text("wheelbase_m: [\n")  # not YAML

    def permission_denied(bag):  # (the tests may run as root, who reads every file)
        if bag.name == "locked.bag":
            raise InputError("cannot read the bag (Permission denied)", bag)
        return content_hash(bag)

    monkeypatch.setattr(app_fleet, "content_hash", permission_denied)
    res = _ingest_within(20, root, tmp_path / "f.db")
    assert res.robots == 2 and (res.bags_total, res.bags_failed) == (4, 4)
    why = dict(res.failures)
    assert "a link to nothing" in why[str(root / "r1" / "dead.bag")]
    assert "cannot read the bag (Permission denied)" in why[str(root / "r1" / "locked.bag")]
    assert "cannot read the bag;" in why[str(root / "r2" / "ok.bag")]  # calibrated: failed
    (r3, r3_why), (r4, r4_why) = res.robot_failures
    assert r3 == str(root / "r3") and "robot folder without robot.yaml" in r3_why
    assert r4 == str(root / "r4") and "invalid YAML" in r4_why
    d = res.as_dict()
    assert [f["robot"] for f in d["robots_failed"]] == [r3, r4]
    with sqlite3.connect(tmp_path / "f.db") as con:  # the bags that were read are stored
        assert con.execute("SELECT COUNT(*) FROM bags WHERE status = 'failed'").fetchone() == (2,)


def test_empty_files_are_each_their_own_failure(tmp_path):
    """Every empty file has the same sha256: three empty 'bags' under two robots were one bag,
    'claimed by two robots', retried for ever. Each is now its own failure, and none stored."""
    root = tmp_path / "root"
    for r in ("r1", "r2"):
        robot_yaml(root / r)
    for p in ("r1/a.bag", "r1/b.mcap", "r2/c.bag"):
        (root / p).touch()
    for _ in range(2):  # and again at the next ingest (nothing was stored)
        res = _ingest_within(20, root, tmp_path / "f.db")
        assert (res.bags_total, res.bags_failed, res.bags_retry) == (3, 3, 0)
        assert sorted(b for b, _ in res.failures) == [str(root / p) for p in (
            "r1/a.bag", "r1/b.mcap", "r2/c.bag")]  # fmt: skip
        assert all("an empty file (0 bytes)" in why for _, why in res.failures)
    with sqlite3.connect(tmp_path / "f.db") as con:
        assert con.execute("SELECT COUNT(*) FROM bags").fetchone() == (0,)


def test_the_database_inside_root_is_not_a_bag(tmp_path):
    """--db ROOT/r1/fleet.db3 was hashed as a bag: each run stored the database, changed since,
    as one more failed bag. A folder of ROOT without robot.yaml holding it is no robot either."""
    for where in ("r1/fleet.db3", "db/fleet.db"):
        root = tmp_path / where.replace("/", "-") / "root"
        robot_yaml(root / "r1")
        (root / "r1" / "a.bag").write_bytes(b"not a bag")
        db = root / where
        db.parent.mkdir(exist_ok=True)
        for _ in range(2):
            res = _ingest_within(20, root, db)
            assert res.bags_total == 1 and res.robot_failures == ()
        with sqlite3.connect(db) as con:
            assert con.execute("SELECT path FROM bags").fetchall() == [(str(root / "r1/a.bag"),)]


def test_a_link_back_up_the_tree_is_no_claim_on_another_robot_s_bags(tmp_path):
    """r1/up -> ROOT made r2's bag 'claimed by two robots' (r1 reached it through r2's folder),
    recorded as retry at every ingest, for ever; so did a link into r2's folder and a linked
    file. A path through another robot's folder is no claim: the bag is r2's."""
    root = tmp_path / "root"
    for r in ("r1", "r2"):
        robot_yaml(root / r)
    (root / "r2" / "day0").mkdir()
    (root / "r2" / "day0" / "x.bag").write_bytes(b"r2's bag (not one the route can read)")
    (root / "r1" / "up").symlink_to(root)
    (root / "r1" / "borrowed").symlink_to(root / "r2" / "day0")
    (root / "r1" / "linked.bag").symlink_to(root / "r2" / "day0" / "x.bag")
    for run in range(2):
        res = _ingest_within(20, root, tmp_path / "f.db")
        assert (res.bags_total, res.bags_retry, res.warnings) == (1, 0, ()), res
        assert res.bags_failed == (1 if run == 0 else 0)  # stored as failed (not a bag), once
    with sqlite3.connect(tmp_path / "f.db") as con:
        assert con.execute("SELECT robot_id, path, status FROM bags").fetchall() == [
            ("r2", str(root / "r2" / "day0" / "x.bag"), "failed")
        ]
