"""A fleet on disk: robot folders, the bags below them, content hashes and snapshots."""

from __future__ import annotations

import shutil

import pytest

from odocal.errors import InputError
from odocal.io.fleet_files import content_hash, find_bags, find_robots, snapshot
from tests.support.fleet import run_within


def _ros2(folder, data=b"rows"):
    folder.mkdir(parents=True)
    (folder / "metadata.yaml").write_text("rosbag2_bagfile_information: {}\n")
    (folder / "bag_0.db3").write_bytes(data)
    return folder


def test_robots_and_their_bags(tmp_path):
    for r in ("r2", "r1"):
        (tmp_path / r).mkdir()
        (tmp_path / r / "robot.yaml").write_text("wheel_diameter_m: 0.05\nwheelbase_m: 0.25\n")
    (tmp_path / ".trash").mkdir()  # hidden: not a robot
    _ros2(tmp_path / "r1" / "2026" / "jan" / "run1")
    (tmp_path / "r1" / "a.bag").write_bytes(b"ros1")
    (tmp_path / "r1" / "b.mcap").write_bytes(b"mcap")
    (tmp_path / "r1" / "notes.txt").write_text("not a bag")
    (tmp_path / "r1" / ".partial.bag").write_bytes(b"hidden")
    robots = find_robots(tmp_path).robots
    assert [r.robot_id for r in robots] == ["r1", "r2"]
    scan = find_bags(robots[0].folder)
    assert [b.relative_to(tmp_path).as_posix() for b in scan.bags] == [
        "r1/2026/jan/run1", "r1/a.bag", "r1/b.mcap"]  # fmt: skip
    assert scan.failures == () and scan.warnings == ()
    assert find_bags(robots[1].folder).bags == ()


def test_a_robot_folder_without_robot_yaml_is_named(tmp_path):
    """A failure of that folder, not of the fleet (the other robots go on); a folder holding
    the fleet database is no robot."""
    (tmp_path / "r1").mkdir()
    (tmp_path / "r2").mkdir()
    (tmp_path / "r2" / "robot.yaml").write_text("wheel_diameter_m: 0.05\nwheelbase_m: 0.25\n")
    (tmp_path / "db").mkdir()
    scan = find_robots(tmp_path, skip=[tmp_path / "db" / "fleet.db"])
    assert [r.robot_id for r in scan.robots] == ["r2"]
    ((folder, why),) = scan.failures
    assert folder == tmp_path / "r1" and why.endswith("r1: robot folder without robot.yaml (each "
                                                      "robot's folder holds its nominal geometry:"
                                                      " wheel_diameter_m, wheelbase_m; "
                                                      "docs/fleet.md)")  # fmt: skip
    with pytest.raises(InputError, match="not a folder"):
        find_robots(tmp_path / "missing")
    with pytest.raises(InputError, match="no robot folders"):
        find_robots(tmp_path / "r1")


def test_a_copy_or_a_renamed_bag_has_the_same_hash(tmp_path):
    a = _ros2(tmp_path / "a", b"x" * 1_500_000)
    shutil.copytree(a, tmp_path / "copy")
    (tmp_path / "copy").rename(tmp_path / "renamed")
    assert content_hash(a) == content_hash(tmp_path / "renamed")
    (tmp_path / "one.bag").write_bytes(b"y" * 10)
    shutil.copy(tmp_path / "one.bag", tmp_path / "two.bag")
    assert content_hash(tmp_path / "one.bag") == content_hash(tmp_path / "two.bag")
    assert content_hash(tmp_path / "one.bag") != content_hash(a)


def test_a_bag_being_written_changes_its_snapshot(tmp_path):
    bag = tmp_path / "a.bag"
    bag.write_bytes(b"x")
    s = snapshot(bag)
    assert s.size_bytes == 1 and snapshot(bag) == s
    with bag.open("ab") as f:
        f.write(b"more")
    assert snapshot(bag) != s and snapshot(bag).size_bytes == 5
    with pytest.raises(InputError, match="cannot read the bag"):
        snapshot(tmp_path / "gone.bag")


def test_a_linked_bag_folder_is_followed_and_a_loop_is_not(tmp_path):
    """Bag storage linked into a robot's folder (a ROS 2 bag folder behind a link was not
    found); a link back up the tree is walked once, not for ever."""
    storage = _ros2(tmp_path / "storage" / "run1")
    robot = tmp_path / "fleet" / "r1"
    robot.mkdir(parents=True)
    (robot / "run1").symlink_to(storage)
    (robot / "loop").symlink_to(robot)
    assert [b.name for b in find_bags(robot).bags] == ["run1"]


def test_what_cannot_be_read_is_skipped_or_named_never_opened(tmp_path):
    """A FIFO (or a device) with a bag's name is skipped with a warning (hashing it waited for
    ever), also inside a ROS 2 bag folder; a link to nothing with a bag's name is a failure
    naming it; one without, a warning (linked bag storage gone); the database is no bag."""
    import os

    robot = tmp_path / "r1"
    robot.mkdir()
    os.mkfifo(robot / "pipe.bag")
    (robot / "dead.mcap").symlink_to(tmp_path / "gone.mcap")
    (robot / "storage").symlink_to(tmp_path / "unmounted")
    os.mkfifo(_ros2(robot / "run1") / "bag_1.db3")
    (robot / "fleet.db3").write_bytes(b"SQLite format 3")
    (robot / "fleet.db3-wal").write_bytes(b"")
    (robot / "ok.bag").write_bytes(b"ros1")
    scan = find_bags(robot, skip=[robot / "fleet.db3", robot / "fleet.db3-wal"])
    assert [b.name for b in scan.bags] == ["ok.bag"]
    ((dead, why),) = scan.failures
    assert dead == robot / "dead.mcap" and why == (
        f"{dead}: a link to nothing ({tmp_path / 'gone.mcap'}): nothing to read"
    )
    assert sorted(scan.warnings) == sorted([
        f"{robot / 'pipe.bag'}: a FIFO with a bag's name, not a bag: skipped (reading it could "
        "wait for ever)",
        f"{robot / 'run1'}: a ROS 2 bag folder holding bag_1.db3, a FIFO: skipped (reading it "
        "could wait for ever)",
        f"{robot / 'storage'}: a link to nothing ({tmp_path / 'unmounted'}): skipped (bag "
        "storage gone?)",
    ])  # fmt: skip


def test_the_hash_never_waits_on_a_fifo(tmp_path):
    """A FIFO put in a bag's place after the bags were found: refused at once, not read."""
    import os

    fifo = tmp_path / "late.bag"
    os.mkfifo(fifo)
    with pytest.raises(InputError, match=r"late.bag: cannot read the bag \(a FIFO, not a regular"):
        run_within(10, lambda: content_hash(fifo), fifo=fifo)


def test_no_path_through_another_robot_s_folder(tmp_path):
    """Links back up to the root, into another robot's folder or to one of its files: none
    finds that robot's bags. Bag storage linked into two robots' folders is found by both."""
    for r in ("r1", "r2"):
        (tmp_path / r).mkdir()
    (tmp_path / "r2" / "own.bag").write_bytes(b"r2")
    _ros2(tmp_path / "r2" / "run1")
    _ros2(tmp_path / "storage" / "shared")
    (tmp_path / "r1" / "up").symlink_to(tmp_path)
    (tmp_path / "r1" / "into-r2").symlink_to(tmp_path / "r2" / "run1")
    (tmp_path / "r1" / "file.bag").symlink_to(tmp_path / "r2" / "own.bag")
    for r in ("r1", "r2"):
        (tmp_path / r / "storage").symlink_to(tmp_path / "storage")
    folders = [tmp_path / "r1", tmp_path / "r2"]
    r1 = find_bags(folders[0], others=folders)
    assert [b.relative_to(tmp_path).as_posix() for b in r1.bags] == ["r1/storage/shared"]
    r2 = find_bags(folders[1], others=folders)
    assert [b.relative_to(tmp_path).as_posix() for b in r2.bags] == [
        "r2/own.bag", "r2/run1", "r2/storage/shared"]  # fmt: skip
