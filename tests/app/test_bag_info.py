"""``odocal.app.bag_info.bag_info`` on its typed result: the topics of ROS 1 and ROS 2 bags (name,
message type, count) and their JSON."""

from __future__ import annotations

import pytest

from odocal.app.bag_info import BagInfo, bag_info
from odocal.errors import InputError
from tests.support.bag_files import KINDS, BagWriter, bag_path

JOINTS = ("left_wheel_joint", "right_wheel_joint")


@pytest.mark.parametrize("kind", KINDS)
def test_the_topics_of_a_bag(tmp_path, kind):
    path = bag_path(tmp_path, kind, "tiny")
    with BagWriter(path, kind) as w:
        for k in range(3):
            w.joints("/joint_states", 1.0 + 0.1 * k, JOINTS, [0.1 * k, 0.2 * k])
        w.pose_stamped("/mocap/pose", 1.1, 0.5, 0.0, 0.1)
    info = bag_info(path)
    assert isinstance(info, BagInfo) and info.path == str(path)
    counts = {t.name: (t.msgtype, t.count) for t in info.topics}
    assert counts == {
        "/joint_states": ("sensor_msgs/msg/JointState", 3),
        "/mocap/pose": ("geometry_msgs/msg/PoseStamped", 1),
    }
    d = info.as_dict()
    assert d["path"] == str(path)
    assert sorted(d["topics"], key=lambda t: t["name"]) == [
        {"name": "/joint_states", "type": "sensor_msgs/msg/JointState", "count": 3},
        {"name": "/mocap/pose", "type": "geometry_msgs/msg/PoseStamped", "count": 1},
    ]


def test_a_file_that_is_not_a_bag(tmp_path):
    path = tmp_path / "run.bag"
    path.write_text("time_s,wheel_right_rad\n")
    with pytest.raises(InputError, match="run.bag"):
        bag_info(path)


def _tf(w, topic, t, edges):
    """One TFMessage on ``topic`` at ``t`` s holding an identity transform per (parent, child)."""
    ts = [
        w.T("geometry_msgs/msg/TransformStamped")(
            header=w.header(t, parent),
            child_frame_id=child,
            transform=w.T("geometry_msgs/msg/Transform")(
                translation=w.vec(0.0, 0.0, 0.0), rotation=w.quat((0.0, 0.0, 0.0, 1.0))
            ),
        )
        for parent, child in edges
    ]
    w.write(topic, "tf2_msgs/msg/TFMessage", t, w.T("tf2_msgs/msg/TFMessage")(transforms=ts))


@pytest.mark.parametrize("kind", KINDS)
def test_the_duration_and_the_frame_tree(tmp_path, kind):
    """bag-info shows how long the bag runs and the frames of /tf and /tf_static (each edge
    once, as a tree), beside the topics."""
    path = bag_path(tmp_path, kind, "tf")
    with BagWriter(path, kind) as w:
        _tf(w, "/tf_static", 1.0, [("base_link", "laser"), ("base_link", "imu_link")])
        for k in range(4):
            w.joints("/joint_states", 1.0 + 0.5 * k, JOINTS, [0.1 * k, 0.2 * k])
            _tf(w, "/tf", 1.0 + 0.5 * k, [("/map", "odom"), ("odom", "base_link")])
    info = bag_info(path)
    assert info.duration_s == pytest.approx(1.5, abs=1e-6)
    assert info.frames == (
        ("base_link", "laser", True),
        ("base_link", "imu_link", True),
        ("map", "odom", False),
        ("odom", "base_link", False),
    )
    text = str(info)
    assert f"{path}: 3 topics, 1.500 s" in text
    assert "  map\n    -> odom\n      -> base_link\n        -> laser (static)\n" in text
    d = info.as_dict()
    assert d["duration_s"] == pytest.approx(1.5, abs=1e-6)
    assert {"parent": "odom", "child": "base_link", "static": False} in d["frames"]
