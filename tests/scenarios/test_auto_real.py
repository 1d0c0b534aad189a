"""``odocal fit BAG --method auto`` on real bags (the typed seam's verdicts, issue 27): what a
held parameter, a robot file in the wrong units, or a ground truth taken for the wheels did to
real answers."""

from __future__ import annotations

import pytest

from odocal.app.fit_auto import fit_auto


@pytest.fixture(scope="module")
def mit_halves(realdata):
    robot = realdata / "mit_csail" / "robot_virtual.yaml"
    return [
        fit_auto(realdata / "mit_csail" / f"csail_half{k}", robot=robot) for k in (1, 2)
    ]


def test_a_held_parameter_is_never_cross_checked_and_the_mit_halves_agree(mit_halves):
    # before: each half's one restricted route held b at nominal with a "std. error 0", and
    # that alone made both halves "NOT to be trusted" (slam vs scan on b: -3.08, +4.62)
    for res in mit_halves:
        held = {
            p.name
            for r in res.routes
            if r.answer is not None
            for p in r.answer.parameters
            if p.status == "held"
        }
        assert held, "a route settles on a restricted model on each half"
        assert not [c for c in res.cross_checks if c.quantity in held]
        assert res.enough, res.reasons
        d = res.as_dict()
        for r in d["routes"]:
            for name, p in r.get("parameters", {}).items():
                if p["status"] == "held":
                    assert p["std_error"] is None, (r["name"], name)
        assert "held" in res.text()
    # the halves' answers agree with each other where both measured (independent data)
    a, b = (res.answer.answer for res in mit_halves)
    ma, mb = a.mean_diameter(), b.mean_diameter()
    assert abs(ma[0] - mb[0]) < 3 * (ma[1] ** 2 + mb[1] ** 2) ** 0.5


def test_the_joint_states_are_the_wheels_and_a_map_frame_odometry_is_a_truth(realdata):
    # the Warthog bag holds /joint_states and the lidar-ICP pose /icp_odom (nav_msgs/Odometry
    # in 'map'); before, the gyro route inverted the ICP as the wheel odometry (its net turn
    # equals the gyro's) and called the nominal 1.08 m wheelbase 'trustworthy' (1.0779 m)
    from odocal.io.bag_survey import survey
    from odocal.io.bags import read_bag_once

    skid = realdata / "norlab_skid"
    bag = next((skid / "warthog_wheels_grass_2024_8_8_16h19s23").glob("*_bag"))
    contents = read_bag_once(bag)
    icp = next(t for t in contents.topics if t.name == "/icp_odom")
    assert icp.world_pose and not icp.wheel_odometry_frame
    found = survey(contents)
    assert found.route("trajectory").usable and "/icp_odom" in found.route("trajectory").reason
    assert "joint states on /joint_states" in found.route("gyro").reason
    res = fit_auto(bag, robot=skid / "robots" / "warthog.yaml")
    gyro = next(r for r in res.routes if r.name == "gyro")
    assert gyro.used and gyro.detail.gyro.meta["odometry_source"] == "joint_states"
    # the wheels turn 1.9 times as far as the gyro: the skid-steer track, not the file's
    assert gyro.answer.ratio == pytest.approx(0.52, abs=0.03)
    assert not res.enough
    # and the one command says what the robot is, and what to run instead
    assert any("skid-steer" in r and "--kinematics skid-steer" in r for r in res.reasons)


def test_the_wheel_odometry_named_as_the_truth_is_refused(realdata):
    from odocal.app.fit import fit
    from odocal.errors import InputError
    from odocal.io.bag_options import BagOptions

    half = realdata / "mit_csail" / "csail_half1"
    robot = realdata / "mit_csail" / "robot_virtual.yaml"
    with pytest.raises(InputError, match="wheel odometry.*own reference"):
        fit([half], robot=robot, bag=BagOptions(truth_topic="/odom"))
    with pytest.raises(InputError, match="wheel odometry.*own reference"):
        fit_auto(half, robot=robot, options=BagOptions(truth_topic="/odom"))


def test_check_answers_for_every_bag_fit_reads_and_fit_prints_its_section(realdata, cli):
    # the Husky bag (the controller's Odometry + IMU) was refused with "no JointState"
    bag = realdata / "husky" / "husky_test1.bag"
    status, out, err = cli("check", bag, "--robot", "paper-fig5")
    assert status in (0, 3) and "Is this log enough?" in out, err
    assert "information, not whether a calibration of it is right" in out
    assert "/husky_velocity_controller/odom" not in err  # its wheels, not a missing truth
    # and the one command prints the section the README promises ("fit prints the same")
    res = fit_auto(bag, robot="paper-fig5")
    assert res.log_check is not None and "Is this log enough? (odocal check)" in res.text()
    assert res.as_dict()["log_check"]["parameters"] == list(res.log_check.check.parameters)
