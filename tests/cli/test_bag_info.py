"""``odocal bag-info``: the topic table and its JSON."""

from __future__ import annotations

import json

import odocal.app.bag_info as app_bag_info
from tests.support.printed import as_printed


def test_husky_bag_info_cli(cli, realdata, returned):
    results = returned(app_bag_info, "bag_info")
    status, out, err = cli("bag-info", realdata / "husky" / "husky_test1_ros2")
    assert status == 0 and err == ""
    assert "/husky_velocity_controller/odom" in out and "nav_msgs/msg/Odometry" in out
    assert "11865" in out
    status, out, _ = cli("bag-info", realdata / "husky" / "husky_test1.bag", "--json")
    data = json.loads(out)
    assert data == as_printed(results[-1].as_dict())  # the app's typed result, printed
    assert {t["name"]: t["count"] for t in data["topics"]}["/imu/data"] == 11865
