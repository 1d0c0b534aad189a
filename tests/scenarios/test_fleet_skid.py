"""A fleet's skid-steer robot (issue 28 item 6): its bags get the skid-steer fit, and the drift
history follows the effective track, not a differential wheelbase."""

from __future__ import annotations

from odocal.app.fleet import fleet_ingest
from odocal.app.fleet_status import fleet_status


def test_a_skid_steer_robot_in_a_fleet(realdata, tmp_path):
    skid = realdata / "norlab_skid"
    root = tmp_path / "fleet" / "warthog"
    root.mkdir(parents=True)
    (root / "robot.yaml").write_text(
        (skid / "robots" / "warthog.yaml").read_text() + "kinematics: skid_steer\n"
    )
    for day in ("2024_8_8_15h56s39", "2024_8_8_16h19s23"):
        bag = next((skid / f"warthog_wheels_grass_{day}").glob("*_bag"))
        (root / bag.name).symlink_to(bag)
    res = fleet_ingest(tmp_path / "fleet", tmp_path / "f.db")
    assert res.bags_new == 2 and res.bags_failed == 0, res.failures
    status = fleet_status(tmp_path / "f.db")
    robot = status.robots[0]
    d = status.as_dict()["robots"][0]
    # the effective track (1.6-1.75 x 1.08 m), not the physical 1.08 m wheelbase
    b = d["parameters"]["wheelbase_m"]
    value = b["value"] if isinstance(b, dict) else b
    assert 1.7 < value < 1.9, d["parameters"]
    assert robot.robot_id == "warthog"
    # and fleet export writes the skid-steer multiplier (the 25 % rule is a differential
    # drive's: a skid-steer track is 0.8-3 times the wheelbase by design)
    from odocal.app.fleet_status import fleet_export

    exported = fleet_export(tmp_path / "f.db", "warthog", tmp_path / "dd.yaml")
    text = (tmp_path / "dd.yaml").read_text()
    assert exported.written and "wheel_separation: 1.08" in text
    m = float(text.split("wheel_separation_multiplier: ")[1].split()[0])
    assert 1.6 < m < 1.75
