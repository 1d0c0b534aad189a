"""A fleet robot whose robot.yaml is in millimetres is refused (issue 27: "fit on a millimetre
robot file and the fleet on a millimetre robot.yaml both refuse")."""

from __future__ import annotations

from odocal.app.fleet import fleet_ingest
from tests.support.fleet import robot_yaml


def test_a_robot_yaml_in_millimetres_is_refused_and_the_run_goes_on(tmp_path):
    root = tmp_path / "root"
    robot_yaml(root / "ok")
    (root / "ok" / "a.bag").write_bytes(b"not a bag")  # its own failure, the robot is read
    (root / "mm").mkdir(parents=True)
    (root / "mm" / "robot.yaml").write_text("wheel_diameter_m: 50\nwheelbase_m: 250\n")
    (root / "mm" / "b.bag").write_bytes(b"not a bag either")
    res = fleet_ingest(root, tmp_path / "f.db")
    assert res.robots == 1
    ((folder, why),) = res.robot_failures
    assert folder.endswith("mm") and "millimetres" in why
