"""One bag in a worker: its calibration record, built from the bag route's typed result, is the
one its JSON gives through the record's upgrade of the stored fit --json (both paths agree on
every kind of answer: a SLAM calibration, a gyro's heading ratio, no route at all)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.core.tracks import polygon
from odocal.io.fleet_record import CalibrationRecord
from tests.support.fleet import NOMINAL, robot_yaml, write_bag
from tests.support.synthetic_robot import Gyro, Laser, default_track, simulate_robot, write_ros2_bag

TRUE = WheelGeometry(0.0505, 0.0495, 0.262)
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    """A SLAM bag (the fleet's synthetic bag), a gyro-only bag (a square with an IMU, no SLAM,
    an 8-ray laser the scan route declines) and a bag no route calibrates (45 deg of net turn for
    the gyro, nothing else)."""
    folder = tmp_path_factory.mktemp("task")
    rng = np.random.default_rng(3)
    write_bag(folder / "slam", TRUE, 0, rng)
    for name, track in (("gyro", polygon(4, 1.0, "ccw")), ("none", default_track())):
        run = simulate_robot(track, TRUE, NOMINAL, laser=Laser(every=10, n_rays=8),
                             gyro=Gyro(0.002, 0.001), rng=rng, still_s=2.0)  # fmt: skip
        write_ros2_bag(folder / name, run)
    return folder, robot_yaml(folder)


@pytest.fixture(scope="module")
def results(bags):
    from odocal.app.fit_auto import fit_auto

    folder, robot = bags
    return {name: fit_auto(folder / name, robot=str(robot)) for name in ("slam", "gyro", "none")}


def test_the_record_of_the_typed_result_is_the_record_of_its_json(results):
    from odocal.app.fleet_task import calibration_record

    for name, res in results.items():
        record = calibration_record(res, "0.1.0")
        fit = json.loads(json.dumps(res.as_dict()))
        upgraded = CalibrationRecord.from_dict(
            {"record_version": 0, "odocal_version": "0.1.0", "fit": fit}
        )
        assert record == upgraded, name
        assert CalibrationRecord.from_dict(json.loads(json.dumps(record.as_dict()))) == record


def test_each_kind_of_answer_in_its_record(results):
    from odocal.app.fleet_task import calibration_record

    slam, gyro, none = (calibration_record(results[n]) for n in ("slam", "gyro", "none"))
    assert slam.route == "slam" and slam.model == "full" and slam.covariance is not None
    assert all(slam.measurement(k) is not None for k in KEYS) and slam.enough
    assert [o.source for o in slam.time_offsets] == ["slam"]
    # the gyro: a heading ratio, its diameters held, never a measurement of them
    assert gyro.route == "gyro" and gyro.ratio_only and gyro.heading_ratio is not None
    assert [p.status for p in gyro.parameters] == ["held", "held", "estimated"]
    assert gyro.parameters[2].value * gyro.heading_ratio == pytest.approx(NOMINAL.wheelbase_m)
    assert not gyro.enough and "heading ratio only" in gyro.reasons[0]
    assert gyro.measurement(KEYS[0]) is None and gyro.measurement(KEYS[2]) is None
    assert none.route is None and none.parameters is None and not none.enough
    assert none.reasons[0].startswith("no route could calibrate this bag")


def test_a_worker_returns_the_record_and_the_report(bags, results):
    from odocal.app.fleet_task import BagTask, calibrate_bag, calibration_record
    from odocal.io.fleet_files import snapshot

    folder, robot = bags
    bag = folder / "gyro"
    out = calibrate_bag(BagTask("r1", str(bag), str(robot), "h", snapshot(bag)))
    assert out.status == "done" and out.record == calibration_record(results["gyro"])
    assert out.report == json.loads(json.dumps(results["gyro"].as_dict()))
