"""``odocal bag-info``: the topic table and its JSON."""

from __future__ import annotations


def test_husky_bag_info_cli(cli, realdata):
    status, out, err = cli("bag-info", realdata / "husky" / "husky_test1_ros2")
    assert status == 0 and err == ""
    assert "/husky_velocity_controller/odom" in out and "nav_msgs/msg/Odometry" in out
    assert "11865" in out
    status, out, _ = cli("bag-info", realdata / "husky" / "husky_test1.bag", "--json")
    import json

    data = json.loads(out)
    assert {t["name"]: t["count"] for t in data["topics"]}["/imu/data"] == 11865
