"""A fleet's skid-steer robot (issue 28 item 6): its bags get the skid-steer fit, and the drift
history and the export follow the effective track, not a differential wheelbase."""

from __future__ import annotations

import pytest

from odocal.app.fit import fit
from odocal.app.fleet import fleet_ingest
from odocal.app.fleet_status import fleet_export, fleet_status
from odocal.io.fleet_db import open_db


def test_a_skid_steer_robot_in_a_fleet(realdata, tmp_path):
    skid = realdata / "norlab_skid"
    root = tmp_path / "fleet" / "warthog"
    root.mkdir(parents=True)
    robot = root / "robot.yaml"
    robot.write_text((skid / "robots" / "warthog.yaml").read_text() + "kinematics: skid_steer\n")
    bags = []
    for day in ("2024_8_8_15h56s39", "2024_8_8_16h19s23"):
        bag = next((skid / f"warthog_wheels_grass_{day}").glob("*_bag"))
        (root / bag.name).symlink_to(bag)
        bags.append(root / bag.name)
    res = fleet_ingest(tmp_path / "fleet", tmp_path / "f.db")
    assert res.bags_new == 2 and res.bags_failed == 0, res.failures
    with open_db(tmp_path / "f.db", write=False) as db:
        records = [b.record for b in db.history("warthog") if b.status == "done"]
    # each bag's record is that bag's skid-steer fit (its halves held out): the same numbers
    # as the command on the bag alone
    assert [r.model for r in records] == ["skid-steer", "skid-steer"]
    alone = fit([bags[0]], robot=robot).answer()
    stored = {round(r.parameters[2].value, 9) for r in records}
    assert round(alone.parameters[2].value, 9) in stored
    tracks = sorted(r.parameters[2].value for r in records)
    # the status's level is the filtered level of those tracks: between them
    d = fleet_status(tmp_path / "f.db").as_dict()["robots"][0]
    b = d["parameters"]["wheelbase_m"]
    level = b["value"] if isinstance(b, dict) else b
    assert tracks[0] - 1e-9 <= level <= tracks[1] + 1e-9
    # and fleet export writes that level as the skid-steer multiplier (the differential 25 %
    # rule refused it: a skid-steer track is 0.8-3 times the wheelbase by design)
    exported = fleet_export(tmp_path / "f.db", "warthog", tmp_path / "dd.yaml")
    text = (tmp_path / "dd.yaml").read_text()
    assert exported.written and "wheel_separation: 1.08" in text
    m = float(text.split("wheel_separation_multiplier: ")[1].split()[0])
    assert m == pytest.approx(level / 1.08, rel=1e-9)


def test_a_skid_steer_robot_with_an_imu_and_no_truth(realdata, tmp_path):
    """The shared Husky bag (its controller's odometry and an IMU, no truth) in a fleet whose
    robot.yaml states the stock multiplier: the gyro route's record, the diameters held, the
    effective track the command's; without the stated multiplier, that bag fails with the
    reason (no guess)."""
    from odocal.app.fleet_task import _calibrate

    husky = realdata / "husky" / "husky_test1.bag"
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.33\nwheelbase_m: 0.555\nkinematics: skid_steer\n"
                     "wheel_separation_multiplier: 1.875\n")  # fmt: skip
    record, report = _calibrate(husky, str(robot))
    assert record.route == "gyro" and report["route"] == "gyro"
    statuses = [p.status for p in record.parameters]
    assert statuses == ["held", "held", "estimated"]
    alone = fit([husky], robot=robot)
    assert record.parameters[2].value == pytest.approx(alone.geometry.wheelbase_m, rel=1e-9)
    bare = tmp_path / "bare.yaml"
    bare.write_text("wheel_diameter_m: 0.33\nwheelbase_m: 0.555\nkinematics: skid_steer\n")
    from odocal.errors import InputError

    with pytest.raises(InputError, match="does not say what the controller ran with"):
        _calibrate(husky, str(bare))
