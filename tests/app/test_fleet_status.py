"""`odocal fleet status` and `export` on databases filled with simulated histories (no bags):
the detector's alarms as the operator sees them."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.errors import InputError
from odocal.io.fleet_db import open_db
from tests.support.fleet import fill_db

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
        assert worn[0] == "wheel_diameter_right_m" and worn[1].startswith("worn-002")
        assert worn[3] == pytest.approx(0.006 * TRUE[0], rel=0.35) and worn[4] > 3
        assert [a[0] for a in fdb.alarms("old-step")] == ["wheelbase_m"]
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
