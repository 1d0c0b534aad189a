"""A SLAM pose on /tf as ground truth, end to end: bags written by tests/support/synthetic_robot.py
(map -> odom updated at a low rate, odom -> base_link from the wheel odometry with the believed
geometry), `odocal fit BAG --truth-frames map:base_link` and `odocal validate ... --truth-frames`.
"""

from __future__ import annotations

import json

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from tests.conftest import CliResult
from tests.support.synthetic_robot import Laser, default_track, simulate_robot, write_ros2_bag

TRUE = WheelGeometry(0.0655, 0.0662, 0.163)  # TurtleBot3-sized, 0.8 % / 0.3 % / 1.9 % off
BELIEVED = WheelGeometry.symmetric(0.066, 0.160)


@pytest.fixture(scope="module")
def run():
    # the SLAM route reads no scan: an 8-ray laser instead of the default 720 rays (noise-free,
    # so the wheel angles, the poses and /tf are the same)
    return simulate_robot(default_track(), TRUE, BELIEVED, laser=Laser(n_rays=8))


@pytest.fixture(scope="module")
def slam_bag(run, tmp_path_factory):
    path = tmp_path_factory.mktemp("slam") / "bag"
    write_ros2_bag(path, run, map_odom_every=25, imu=False)  # SLAM updates at 2 Hz
    return path


def test_fit_recovers_the_true_geometry_from_the_slam_updates(cli, slam_bag):
    status, out, err = cli("fit", slam_bag, "--truth-frames", "map:base_link", "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["method"] == "relative" and d["sensor_pose_fixed"] is True
    # noise-free updates and the odometry integrated over the wheel samples of each interval:
    # the geometry is recovered to rounding (the arc model alone would be 0.4 % off here, since
    # the intervals mix straights, spot turns and arcs)
    for key, true in TRUE.as_dict().items():
        assert d[key] == pytest.approx(true, rel=1e-9), key
    slam = d["slam"][0]
    assert slam["chain"] == "map -> odom -> base_link" and slam["correction_edge"] == "map -> odom"
    assert slam["used"] >= 30 and slam["jump"] == 0
    # the text report says what was used: test_plot_draws_the_clock_offset_and_the_held_out_check


def test_validate_against_the_slam_pose(cli, slam_bag, tmp_path):
    good = tmp_path / "true.yaml"
    bad = tmp_path / "believed.yaml"
    for path, g in ((good, TRUE), (bad, BELIEVED)):
        path.write_text("".join(f"{k}: {v}\n" for k, v in g.as_dict().items()))
    errs = {}
    for name, params in (("true", good), ("believed", bad)):
        status, out, err = cli(
            "validate", slam_bag, "--params", params, "--truth-frames", "map:base_link", "--json"
        )
        assert status == 0, err
        errs[name] = json.loads(out)["mean_final_error_m"]
    # the true geometry matches the SLAM pose at its updates (to the midpoint rule's error over
    # the wheel samples); the believed one drifts by centimetres over the 8 m tour
    assert errs["true"] < 1e-4 < 0.01 < errs["believed"]


@pytest.mark.parametrize(
    "frames, needles",
    [
        ("map:nowhere", ["frame 'nowhere' never appears", "base_link"]),
        ("map", ["PARENT:CHILD"]),
        ("laser:laser", ["must differ"]),
    ],
)
def test_bad_truth_frames(cli, slam_bag, frames, needles):
    cli("fit", slam_bag, "--truth-frames", frames).expect_error(*needles)


def test_a_bag_without_slam_updates(cli, tmp_path):
    # refusals need no tour: 0.5 m and a quarter turn (84 increments)
    from odocal.core.tracks import Track, spot_turn, straight

    short = Track("short", (straight(0.5), spot_turn(np.pi / 2)))
    run = simulate_robot(short, TRUE, BELIEVED, laser=Laser(n_rays=8), still_s=0.2)
    path = tmp_path / "nomap"
    write_ros2_bag(path, run, map_odom_every=None, imu=False)
    cli("fit", path, "--truth-frames", "map:base_link").expect_error("frame 'map'")
    # too few updates for a calibration (4 here): the counts are named
    few = tmp_path / "few"
    write_ros2_bag(few, run, map_odom_every=25, imu=False)
    cli("fit", few, "--truth-frames", "map:base_link").expect_error("usable SLAM intervals")


def test_truth_frames_only_with_the_relative_method(cli, slam_bag):
    cli("fit", slam_bag, "--truth-frames", "map:base_link", "--method", "trajectory").expect_error(
        "--method relative"
    )


def test_plot_draws_the_clock_offset_and_the_held_out_check(cli, slam_bag, tmp_path):
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
    figs = tmp_path / "figs"
    status, out, err = cli(
        "fit", slam_bag, "--truth-frames", "map:base_link", "--robot", robot, "--plot", figs
    )
    assert status == 0, err
    assert sorted(p.name for p in figs.iterdir()) == ["heldout.png", "time_offset.png"]
    assert "held out" in out and "clock offset of the slam" in out
    # the text report says what was used (the fit's text, here with the robot file's check)
    assert "SLAM updates" in out and "wheelbase_m" in out


def test_check_of_a_slam_bag_uses_the_logs_own_noise_and_the_routes_model(cli, run, tmp_path):
    # a SLAM pose with 1 cm / 0.5 deg noise: the check names where its noise came from and
    # predicts the SLAM route's standard errors, close to what the fit then states
    import numpy as np

    path = tmp_path / "noisy"
    write_ros2_bag(path, run, map_odom_every=25, imu=False, slam_noise=(0.01, 0.0087),
                   rng=np.random.default_rng(3))  # fmt: skip
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
    status, out, err = cli("check", path, "--truth-frames", "map:base_link", "--robot", robot,
                           "--json")  # fmt: skip
    assert status in (0, 3), err
    d = json.loads(out)
    assert "from the log's own residuals" in d["noise_source"]
    assert "relative-motion fit" in d["settings"]["prediction"]
    status, out, err = cli("fit", path, "--truth-frames", "map:base_link", "--robot", robot,
                           "--json", "--force")  # fmt: skip
    assert status == 0, err
    fit = json.loads(out)
    ratio = d["stderr"]["wheelbase_m"] / fit["stderr"]["wheelbase_m"]
    assert 0.33 < ratio < 3.0, ratio


def test_without_joint_states_the_odometry_stands_in(cli, run, tmp_path):
    # the same drive with only odom -> base_link on /tf: inverted through the geometry the
    # controller ran with (ROBOT.yaml's believed), the SLAM route gives the joints' answer
    path = tmp_path / "odom_only"
    write_ros2_bag(path, run, map_odom_every=25, imu=False, joints=False)
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")  # believed = nominal
    status, out, err = cli("fit", path, "--truth-frames", "map:base_link", "--robot", robot,
                           "--json", "--force")  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    # the synthetic odometry was integrated with the midpoint rule, the inversion takes each
    # step as an exact arc: they differ by dtheta^2 / 24 per step (1 cm steps here), a few 1e-6
    for key, true in TRUE.as_dict().items():
        assert d[key] == pytest.approx(true, rel=3e-5), key
    # without the robot file there is no geometry to invert through: said so
    status, _, err = cli("fit", path, "--truth-frames", "map:base_link")
    assert status == 2 and "the geometry the controller ran with" in err


def test_the_same_slam_bag_twice_under_two_names_is_refused(cli, slam_bag, tmp_path):
    # a copy of the bag: its intervals would count twice (standard errors sqrt 2 too small)
    import shutil

    copy = tmp_path / "copy"
    shutil.copytree(slam_bag, copy)
    status, out, err = cli("fit", slam_bag, copy, "--truth-frames", "map:base_link")
    assert status == 2 and out == "", err
    assert "cover the same time" in err and "count twice" in err and len(err.splitlines()) == 1


def test_a_truth_frame_mounted_on_the_base_is_read_as_the_base(slam_bag):
    # map:laser: the laser hangs below base_link by /tf_static (0.15, 0.05, 0.1 rad); its motion
    # taken for the base's put the geometry 0.6-2.4 % off. The base's motion is used, and said
    from odocal.app.slam_bags import load_slam_bag
    from odocal.io.bag_options import BagOptions

    base = load_slam_bag(slam_bag, ("map", "base_link"), BagOptions(), time_offset_s=0.0)
    laser = load_slam_bag(slam_bag, ("map", "laser"), BagOptions(), time_offset_s=0.0)
    np.testing.assert_array_equal(
        laser.relative_motions.sensor_motion, base.relative_motions.sensor_motion
    )
    (note,) = set(laser.wheel_warnings) - set(base.wheel_warnings)
    assert (
        "'laser' is mounted on 'base_link' by /tf_static (x 0.15 m, y 0.05 m, yaw 0.1 rad)" in note
    )


def test_robot_out_is_refused_before_the_slam_route_works(cli, slam_bag, tmp_path):
    """Issue #20: `fit BAG --truth-frames --out P --robot-out M` was a RuntimeError (no content
    for the planned output) after the whole fit."""
    out, measured = tmp_path / "p.yaml", tmp_path / "m.yaml"
    cli(
        "fit", slam_bag, "--truth-frames", "map:base_link", "--out", out, "--robot-out", measured
    ).expect_error("--robot-out needs runs with ground truth")
    assert list(tmp_path.iterdir()) == []


def test_the_wheel_odometry_cannot_be_its_own_truth(cli, slam_bag):
    """Issue 27 item 19: `--truth-frames odom:base_link` (the odometry's own edge, every 20 ms)
    was 'the robot only turns on the spot'."""
    for frames in ("odom:base_link", "odom:laser"):
        cli("fit", slam_bag, "--truth-frames", frames).expect_error(
            "--truth-frames", "the wheel odometry", "cannot be its own reference", "map:"
        )


def test_a_slam_pose_that_changes_every_20_ms_says_its_intervals_are_too_short(cli, run, tmp_path):
    """Issue 27 item 19: a correction changed at every wheel step (0.02 s intervals, of which
    only the fastest spot turns pass the gates) was 'the robot only turns on the spot'."""
    path = tmp_path / "fast"
    write_ros2_bag(path, run, map_odom_every=1, imu=False)
    status, out, err = cli("fit", path, "--truth-frames", "map:base_link")
    CliResult((status, out, err)).expect_error("every 20 ms", "too short")
    assert "only turns on the spot" not in err.split("(")[0]
