"""`odocal fleet status` and `export` on databases filled with simulated histories (no bags):
the detector's alarms as the operator sees them."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.errors import InputError
from odocal.io.fleet_db import open_db
from tests.support.fleet import fake_result, fill_db, old_database

SE = np.array([5e-5, 5e-5, 2.5e-4])  # 0.1 % per bag
TRUE = np.array([0.0505, 0.0495, 0.25])


def _history(rng, n, step_at=None, step=(0.0, 0.0, 0.0)):
    out = []
    for i in range(n):
        v = TRUE * (1 + (np.asarray(step) if step_at is not None and i >= step_at else 0))
        out.append((tuple(v + SE * rng.standard_normal(3)), tuple(SE)))
    return out


@pytest.fixture
def db(tmp_path):
    rng = np.random.default_rng(2)
    path = tmp_path / "f.db"
    with open_db(path, write=True) as fdb:
        fill_db(fdb, {
            "steady": _history(rng, 40),
            "worn": _history(rng, 40, step_at=25, step=(0.006, 0, 0)),  # D_R +0.6 % (6 se)
            "old-step": _history(rng, 70, step_at=20, step=(0, 0, -0.005)),  # b -0.5 %, long ago
        })  # fmt: skip
    return path


def test_the_robot_with_a_step_comes_first_with_its_alarm(db):
    from odocal.app.fleet_status import fleet_status

    rows = fleet_status(db).as_dict()["robots"]
    assert [r["robot_id"] for r in rows] == ["worn", "old-step", "steady"]
    worn = rows[0]
    assert worn["drift_alarm"] is True
    d = worn["drift"]
    assert d["parameter"] == "wheel_diameter_right_m" and d["bag"].startswith("/fleet/worn/bag02")
    assert d["size_percent"] == pytest.approx(0.6, abs=0.2) and d["z"] > 3
    # after the step the current value is the new one
    p = worn["parameters"]["wheel_diameter_right_m"]
    assert p["value"] == pytest.approx(TRUE[0] * 1.006, abs=4 * p["std_error"])
    # an alarm more than 30 days of bag time before the latest bag is no longer active
    assert rows[1]["drift_alarm"] is False and rows[2]["drift_alarm"] is False
    assert rows[1]["parameters"]["wheelbase_m"]["value"] == pytest.approx(0.25 * 0.995, rel=6e-4)


def test_export_refuses_a_robot_without_a_trustworthy_bag(db, tmp_path):
    from odocal.app.fleet_status import fleet_export

    with open_db(db, write=True) as fdb:
        fdb.upsert_robot("new", {"wheel_diameter_right_m": 0.05, "wheel_diameter_left_m": 0.05,
                                 "wheelbase_m": 0.25}, "/fleet/new", "2026-01-01")  # fmt: skip
    with pytest.raises(InputError, match="robot 'new' has no trustworthy calibration yet"):
        fleet_export(db, "new", tmp_path / "x.yaml")
    assert not (tmp_path / "x.yaml").exists()
    res = fleet_export(db, "worn", tmp_path / "worn.yaml")  # no covariance in these results
    assert res.bags == 40 and "pose_covariance_diagonal" not in (tmp_path / "worn.yaml").read_text()


def test_the_ingest_stores_every_robot_s_alarms(db, tmp_path):
    from odocal.app.fleet import fleet_ingest
    from tests.support.fleet import robot_yaml

    robot_yaml(tmp_path / "root" / "steady")  # a run that finds no new bag
    assert fleet_ingest(tmp_path / "root", db).bags_total == 0
    with open_db(db, write=False) as fdb:
        (worn,) = fdb.alarms("worn")
        assert worn.parameter == "wheel_diameter_right_m"
        assert worn.content_hash.startswith("worn-002")
        assert worn.size == pytest.approx(0.006 * TRUE[0], rel=0.35) and worn.z > 3
        assert worn.bag.startswith("/fleet/worn/bag02") and not worn.acknowledged
        assert [a.parameter for a in fdb.alarms("old-step")] == ["wheelbase_m"]
        assert fdb.alarms("steady") == []


def test_a_route_that_holds_the_diameters_still_shows_and_exports_its_wheelbase(tmp_path):
    """The gyro route estimates b only (the diameters held at nominal, no standard error): the
    status shows b and the export writes it with the nominal diameters, saying so (the robot was
    shown without any parameter and could not be exported)."""
    from odocal.app.fleet_status import fleet_export, fleet_status
    from tests.support.fleet import NOMINAL

    path = tmp_path / "f.db"
    d = NOMINAL.diameter_right_m
    with open_db(path, write=True) as fdb:
        fill_db(fdb, {"gyro": [((d, d, 0.2512), (None, None, 2.5e-4))] * 3})
    (row,) = fleet_status(path).as_dict()["robots"]
    assert set(row["parameters"]) == {"wheelbase_m"}
    assert row["parameters"]["wheelbase_m"]["value"] == pytest.approx(0.2512, abs=1e-6)
    res = fleet_export(path, "gyro", tmp_path / "g.yaml")
    assert res.geometry.wheelbase_m == pytest.approx(0.2512, abs=1e-6)
    assert res.geometry.diameter_right_m == NOMINAL.diameter_right_m
    assert (
        "nominal (never estimated): wheel_diameter_right_m, wheel_diameter_left_m"
        in (tmp_path / "g.yaml").read_text()
    )


# ---- robot ids as folder names allow them (issue 27, item 16)

ODD_IDS = {
    "break": "r1\nwheel_separation: 99.0",  # a line break: a YAML key of its own, unescaped
    "long": "x" * 251,  # robots/<id>.html: 256 bytes, a file name too long
    "wide": "ü" * 126,  # 252 bytes in UTF-8
    "math": "odd $\\frac$ id",  # mathtext to matplotlib, which cannot parse it
    "html": "<b>&amp;",
}


def _odd_fleet(tmp_path):
    rng = np.random.default_rng(5)
    path = tmp_path / "f.db"
    with open_db(path, write=True) as fdb:
        fill_db(fdb, {rid: _history(rng, 6) for rid in ODD_IDS.values()})
    return path


def test_a_line_break_in_a_robot_id_stays_in_its_comment(tmp_path):
    """The id went into the exported file's comment as it is: a line break made the rest of
    it a top-level YAML key (here a second wheel_separation for the controller's reader)."""
    import yaml

    from odocal.app.fleet_status import fleet_export
    from odocal.io.ros2_export import read_ros2_params

    db = _odd_fleet(tmp_path)
    out = tmp_path / "r1.yaml"
    res = fleet_export(db, ODD_IDS["break"], out)
    text = out.read_text()
    assert list(yaml.safe_load(text)) == ["diff_drive_controller"]
    assert "# method: odocal fleet: robot 'r1\\nwheel_separation: 99.0', filtered level" in text
    assert read_ros2_params(out).wheelbase_m == pytest.approx(res.geometry.wheelbase_m)


def test_odd_robot_ids_get_a_dashboard_with_page_names_that_fit(tmp_path):
    """A 251-character id stopped the whole dashboard (its page's name was 256 bytes long)."""
    from odocal.app.fleet_report import fleet_report

    res = fleet_report(_odd_fleet(tmp_path), tmp_path / "html")
    assert res.robots == len(ODD_IDS)
    pages = sorted((tmp_path / "html" / "robots").iterdir())
    assert len(pages) == len(ODD_IDS)
    assert all(len(p.name.encode()) <= 255 and p.name.isprintable() for p in pages)
    index = (tmp_path / "html" / "index.html").read_text()
    import re
    from urllib.parse import unquote

    links = re.findall(r'<a href="(robots/[^"]+)">', index)
    assert sorted((tmp_path / "html" / unquote(a)) for a in links) == pages
    assert "&lt;b&gt;&amp;amp;" in index and "<b>" not in index
    assert "r1\\nwheel_separation: 99.0" in index  # shown escaped, on its own row


# ---- a robot without a trusted calibration is a problem, not a healthy row (item 18)


def test_a_robot_whose_bags_are_all_untrusted_is_no_healthy_robot(tmp_path):
    """Its row said: no drift (green 'no' on the dashboard), '-' parameters, failed 0, sorted
    among the healthy robots. It now says 'no trusted calibration', counts its untrusted bags
    and sorts with the problems: after the drift alarms, before the healthy robots."""
    from odocal.app.fleet_report import fleet_report
    from odocal.app.fleet_status import fleet_status

    rng = np.random.default_rng(2)
    path = tmp_path / "f.db"
    with open_db(path, write=True) as fdb:
        fill_db(fdb, {
            "a-steady": _history(rng, 40),
            "b-doubtful": _history(rng, 5),
            "c-worn": _history(rng, 40, step_at=25, step=(0.006, 0, 0)),
        }, untrusted=("b-doubtful",))  # fmt: skip
    rows = fleet_status(path).as_dict()["robots"]
    assert [r["robot_id"] for r in rows] == ["c-worn", "b-doubtful", "a-steady"]
    doubtful = rows[1]
    assert doubtful["trusted_calibration"] is False and doubtful["parameters"] is None
    assert (doubtful["bags"], doubtful["bags_untrusted"], doubtful["bags_failed"]) == (5, 5, 0)
    assert rows[0]["trusted_calibration"] and rows[2]["bags_untrusted"] == 0
    fleet_report(path, tmp_path / "html")
    index = (tmp_path / "html" / "index.html").read_text()
    body = index[index.index("<tbody>") :]
    order = [body.index(f">{r}</a>") for r in ("c-worn", "b-doubtful", "a-steady")]
    assert order == sorted(order)
    row = body[order[1] : order[2]]
    assert "no trusted calibration" in row and '<span class="ok">' not in row


# ---- the stored record (issue 27, item 3): only what a route estimated is a measurement


def _step_rows(n=40, at=25, statuses=("estimated", "estimated", "estimated"), step=(0, 0, 0)):
    """fit --json rows of a robot whose parameters step at bag ``at``, each parameter with the
    given status (as the bag route writes it today) and a standard error."""
    rng = np.random.default_rng(3)
    rows = []
    for i in range(n):
        v = TRUE * (1 + (np.asarray(step) if i >= at else 0)) + SE * rng.standard_normal(3)
        fit = fake_result(f"/b{i}", v, SE)
        for k, s in zip(fit["parameters"], statuses, strict=True):
            fit["parameters"][k]["status"] = s
        rows.append(("done", fit))
    return rows


def test_held_and_tied_parameters_never_enter_the_drift_history(tmp_path):
    """The detector read each parameter's value and standard error whatever the route did with
    it: a held wheelbase that a route reported with an error, and diameters tied to one scale
    (the nominal ratio), stepped the filter and raised alarms. Only estimated parameters do."""
    from odocal.app.fleet_status import fleet_status, robot_drift

    path = tmp_path / "old.db"
    old_database(path, {
        "held-b": _step_rows(statuses=("estimated", "estimated", "held"), step=(0, 0, 0.01)),
        "tied": _step_rows(statuses=("tied", "tied", "estimated"), step=(0.006, 0, 0)),
        "free": _step_rows(step=(0.006, 0, 0.01)),
    })  # fmt: skip
    open_db(path, write=True).close()  # migrated
    rows = {r.robot_id: r for r in fleet_status(path).robots}
    assert not rows["held-b"].drift_alarm and "wheelbase_m" not in rows["held-b"].parameters
    assert not rows["tied"].drift_alarm
    assert set(rows["tied"].parameters) == {"wheelbase_m"}
    assert {a["parameter"] for a in rows["free"].alarms} == {"wheel_diameter_right_m",
                                                             "wheelbase_m"}  # fmt: skip
    with open_db(path, write=False) as db:
        h = db.history("held-b")
    (b,) = [p for p in robot_drift(h).parameters if p.key == "wheelbase_m"]
    assert b.bags == () and b.track is None
    assert [p.status for p in h[0].record.parameters] == ["estimated", "estimated", "held"]
    assert h[0].record.parameters[2].std_error is None  # (its error was dropped: held)


def test_a_ratio_only_answer_never_feeds_the_diameters(tmp_path):
    """A gyro answer (a heading ratio, the diameters held at nominal) in the history of a robot
    whose diameters another route measured: the diameters' history is the other route's."""
    from odocal.app.fleet_status import robot_drift
    from odocal.calibration.route_answer import ParameterEstimate
    from odocal.io.fleet_record import CalibrationRecord

    path = tmp_path / "f.db"
    keys = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
    with open_db(path, write=True) as db:
        fill_db(db, {"r1": _history(np.random.default_rng(1), 6)})
        gyro = CalibrationRecord(
            "test", "gyro", "heading-ratio",
            (ParameterEstimate(keys[0], 0.05, None, "held"),
             ParameterEstimate(keys[1], 0.05, None, "held"),
             ParameterEstimate(keys[2], 0.2506, 2.5e-4, "estimated")),
            0.9976, 1e-3, True, (), (), None, WheelGeometry(0.05, 0.05, 0.25),
        )  # fmt: skip
        db.store_bag(content_hash="g" * 64, robot_id="r1", path="/gyro", size_bytes=1,
                     span_s=(1.8e9, 1.8e9 + 60), status="done", reason=None, version="t",
                     now="2026-02-01", record=gyro, report=fake_result("/gyro", (0.05, 0.05,
                     0.2506), (None, None, 2.5e-4)))  # fmt: skip
        h = db.history("r1")
    params = {p.key: p for p in robot_drift(h).parameters}
    assert h[-1].record.ratio_only and len(h) == 7
    assert params["wheel_diameter_right_m"].bags == tuple(range(6))
    assert params["wheel_diameter_left_m"].bags == tuple(range(6))
    assert params["wheelbase_m"].bags == tuple(range(7))  # its wheelbase (at nominal scale)


def test_export_never_writes_a_multiplier_beyond_the_25_percent_rule(db, tmp_path):
    """A filtered level far from the robot's nominal geometry (its robot.yaml changed since,
    or bags stored before a result 25 % from nominal made them untrustworthy) was written."""
    from odocal.app.fleet_status import fleet_export
    from odocal.errors import CalibrationError

    with open_db(db, write=True) as fdb:  # the robot's wheels are now said to be 0.07 m
        fdb.upsert_robot("worn", {"wheel_diameter_right_m": 0.07, "wheel_diameter_left_m": 0.07,
                                  "wheelbase_m": 0.25}, "/fleet/worn", "2026-02-01")  # fmt: skip
    out = tmp_path / "worn.yaml"
    with pytest.raises(CalibrationError, match=r"robot 'worn': the filtered level's "
                       r"wheel_diameter_right_m = 0.0508\d* m is -27 % from nominal 0.07 m: "
                       r"absurd for a calibration; has its robot.yaml changed.*\(and \d more\); "
                       "nothing written"):  # fmt: skip
        fleet_export(db, "worn", out)
    assert not out.exists()
    fleet_export(db, "steady", tmp_path / "steady.yaml")  # (within the rule: written)
    text = (tmp_path / "steady.yaml").read_text()
    for line in text.splitlines():
        if "multiplier:" in line:
            assert abs(float(line.split(":")[1]) - 1) < 0.25


# ---- alarms an operator acknowledged (issue 27, item 3)


def test_an_acknowledged_alarm_is_kept_but_no_longer_active(db, tmp_path):
    """The alarms table was written and never read: an alarm an operator had seen to stayed the
    robot's drift alarm for 30 days of bags."""
    from odocal.app.fleet import fleet_ingest
    from odocal.app.fleet_alarms import fleet_ack, fleet_alarms
    from odocal.app.fleet_report import fleet_report
    from odocal.app.fleet_status import fleet_status
    from tests.support.fleet import robot_yaml

    robot_yaml(tmp_path / "root" / "steady")
    fleet_ingest(tmp_path / "root", db)  # stores every robot's alarms
    listed = fleet_alarms(db)
    assert [(a.robot_id, a.parameter, active) for a, active in
            zip(listed.alarms, listed.active, strict=True)] == [
        ("old-step", "wheelbase_m", False), ("worn", "wheel_diameter_right_m", True)]  # fmt: skip
    done = fleet_ack(db, "worn", "D_R")
    assert (
        not done.already and done.alarm.acknowledged and done.alarm.bag.startswith("/fleet/worn/")
    )
    rows = {r["robot_id"]: r for r in fleet_status(db).as_dict()["robots"]}
    assert rows["worn"]["drift_alarm"] is False and rows["worn"]["alarms"] == []
    (ack,) = rows["worn"]["alarms_acknowledged"]
    assert ack["parameter"] == "wheel_diameter_right_m" and ack["z"] > 3
    # kept: listed, acknowledged, and still acknowledged after the next ingest
    fleet_ingest(tmp_path / "root", db)
    (a,) = [a for a in fleet_alarms(db).alarms if a.robot_id == "worn"]
    assert a.acknowledged_at == done.alarm.acknowledged_at
    assert fleet_ack(db, "worn", "wheel_diameter_right_m", a.content_hash[:12]).already
    fleet_report(db, tmp_path / "html")
    index = (tmp_path / "html" / "index.html").read_text()
    assert "0 with a drift alarm" in index and 'class="alarm"' not in index
    page = (tmp_path / "html" / "robots" / "worn.html").read_text()
    assert "No active drift alarm." in page and "Acknowledged" in page
