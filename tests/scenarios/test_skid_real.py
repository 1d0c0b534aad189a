"""``odocal fit BAG... --kinematics skid-steer`` on the real Norlab recordings (issue 28): the
effective track, the multipliers diff_drive_controller needs, the held-out drift, and what a
robot file in the wrong units or a bag without a truth says."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from odocal.app.fit import fit
from odocal.errors import InputError


@pytest.fixture(scope="module")
def skid(realdata):
    return realdata / "norlab_skid"


def _bag(skid, name):
    return next((skid / name).glob("*_bag"))


def _csv(skid, name):
    return skid / name / f"{name}.csv"


def skid_dir(res):
    return Path(res.names[0]).parent.parent


def _agrees_with_plain(res, csvs):
    from tests.support.skid_plain import plain_turning_gains

    model = res.fit.model
    fitted = (model.radius_right_m / model.track_m, model.radius_left_m / model.track_m)
    plain = plain_turning_gains(csvs)
    for f, p in zip(fitted, plain, strict=True):
        assert f == pytest.approx(p, rel=0.02), (fitted, plain)


@pytest.fixture(scope="module")
def husky(skid, tmp_path_factory):
    out = tmp_path_factory.mktemp("husky")
    res = fit([_bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")],
              robot=skid / "robots" / "husky.yaml", kinematics="skid-steer",
              ros2=out / "dd.yaml", plot=out / "plots")  # fmt: skip
    return res, out / "dd.yaml"


def test_the_husky_s_multiplier_with_its_error_and_the_drift_it_buys(husky):
    res, ros2 = husky
    m, se = res.track_multiplier
    # its turning gains (each side's rolling radius over the effective track) are those of a
    # plain regression of the ICP heading on the wheels, from the CSV copy, within 2 % (the
    # fit's errors are 0.4-0.9 %): a side swapped, a radius taken for a diameter or a track
    # off by its multiplier would be 10-100 % off
    _agrees_with_plain(res, [_csv(skid_dir(res), "husky_wheels-deflated_tile_2023_12_12_16h16")])
    # the deflated Husky on tile against Clearpath's default multiplier 1.875
    assert se > 0 and abs(m - 1.875) > 5 * se
    d = json.loads(json.dumps(res.as_dict()))
    drift, nominal = d["drift_percent_per_10m"], d["nominal_drift_percent_per_10m"]
    assert set(drift) >= {"median", "mean", "pieces"} and drift["pieces"] >= 10
    # held out (fitted on one half, scored on the other): a fifth of the nominal drift or less
    assert drift["median"] < 0.2 * nominal["median"]
    assert d["heldout"]["best"] in d["heldout"]["models"] and d["verdict"]["enough"] is True
    text = ros2.read_text()
    assert "wheel_separation: 0.55" in text
    assert (
        f"wheel_separation_multiplier: {res.multipliers['wheel_separation_multiplier']!r}" in text
    )
    assert d["ros2"]["wheel_separation_multiplier"] == pytest.approx(m)
    assert "the multiplier against the turn rate" in res.text() and d["turn_rate"]
    figure = ros2.parent / "plots" / "track_multiplier.png"
    assert figure in res.written and figure.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_two_warthog_recordings_each_with_its_own_multiplier(skid):
    bags = [_bag(skid, f"warthog_wheels_grass_2024_8_8_{t}") for t in ("15h56s39", "16h19s23")]
    res = fit(bags, robot=skid / "robots" / "warthog.yaml", kinematics="skid-steer")
    _agrees_with_plain(res, [b.parent / (b.parent.name + ".csv") for b in bags])
    assert [r.z is not None for r in res.per_recording] == [True, True]
    # the same day: the recordings agree within 3 combined errors
    assert all(abs(r.z) < 3 for r in res.per_recording)
    assert len(res.heldout.held_out) == 2
    exported = res.drift("effective-track (left-right)")
    assert exported.median_pct < 0.2 * res.drift("nominal").median_pct


def test_skid_steer_bad_inputs(skid, tmp_path, cli):
    husky = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    # the sprocket's radius given as the wheel's diameter: each side rolls half as far
    half = tmp_path / "half.yaml"
    half.write_text("wheel_diameter_m: 0.66\nwheelbase_m: 0.55\nkinematics: skid_steer\n")
    # a bag without a truth pose track or a SLAM pose, whose wheels are the controller's
    # odometry (the shared Husky bag: that odometry, an IMU and a GPS), and a robot file that
    # does not say what the controller ran with: no guess
    ros = skid.parent / "husky" / "husky_test1.bag"
    with pytest.raises(InputError, match="does not say what the controller ran with"):
        fit([ros], robot=skid / "robots" / "husky.yaml", kinematics="skid-steer")
    status, out, err = cli("fit", husky, "--robot", half, "--json", "--ros2", tmp_path / "x.yaml")
    assert status == 2 and out == "" and err.count("\n") == 1
    assert "sprocket radius given as a wheel diameter" in err
    assert not (tmp_path / "x.yaml").exists()


def test_a_recording_that_never_turns_cannot_show_the_track():
    import numpy as np

    from odocal.app.fit_skid import skid_fit
    from odocal.calibration.skid_steer import SkidLog
    from odocal.core.model import Robot, WheelGeometry

    t = np.arange(0.0, 60.0, 0.05)
    angle = 2.0 * t  # both sides at 2 rad/s: straight ahead
    truth_t = np.arange(0.1, 59.0, 0.1)
    truth = np.column_stack([0.3 * 2.0 * truth_t, np.zeros_like(truth_t), np.zeros_like(truth_t)])
    log = SkidLog("straight", t, angle, angle, truth_t, truth)
    robot = Robot(WheelGeometry.symmetric(0.6, 1.08), kinematics="skid-steer")
    with pytest.raises(InputError, match="cannot be seen without turning"):
        skid_fit([log], robot)


def test_a_slam_pose_on_tf_is_a_truth_track_too_and_laser_scans_see_the_same_turning(realdata):
    # the MIT half: no truth topic, a SLAM pose (map -> odom -> base_link) at its updates; the
    # effective track agrees with the differential SLAM route's wheelbase (0.4868 +- 0.0043 m)
    import numpy as np

    half = realdata / "mit_csail" / "csail_half1"
    robot = realdata / "mit_csail" / "robot_virtual.yaml"
    res = fit([half], robot=robot, kinematics="skid-steer")
    m, se = res.track_multiplier
    slam_b, slam_se = 0.4868 / 0.5, 0.0043 / 0.5
    assert abs(m - slam_b) < 3 * (se**2 + slam_se**2) ** 0.5
    # --method scan: the scan-matched laser's heading changes against the wheels' (a turning
    # gain with the wheels held at nominal), against the SLAM fit's turning gain (mean wheel
    # scale over the multiplier): within 3 combined errors
    scan = fit([half], method="scan", robot=robot, kinematics="skid-steer")
    g, g_se = float(scan.fit.gain[0]), float(scan.fit.gain_stderr[0])
    i = [res.fit.names.index(n) for n in ("scale_right", "scale_left", "track_multiplier")]
    v, cov = res.fit.values[i], res.fit.covariance[np.ix_(i, i)]
    slam_g = 0.5 * (v[0] + v[1]) / v[2]
    jac = np.array([0.5 / v[2], 0.5 / v[2], -slam_g / v[2]])
    slam_g_se = float(np.sqrt(jac @ cov @ jac))
    assert abs(g - slam_g) < 3 * np.hypot(g_se, slam_g_se), (g, g_se, slam_g, slam_g_se)
    assert scan.as_dict()["route"] == "scan" and scan.answer().route == "scan"


def test_validate_reads_a_skid_steer_bag_with_its_truth_on_the_wheels_clock(husky, skid):
    """``validate --kinematics skid-steer``: the bag read as the fit reads it, the ICP's clock
    offset estimated and applied (stated), and the drift the same as the skid-steer layer's own
    dead reckoning of the log at that offset (an independent path: no Recording, no inserted
    samples)."""
    from odocal.app.validate import validate
    from odocal.calibration.skid_steer import log_drift
    from odocal.core.skid_steer import SkidSteerModel
    from odocal.io.bag_options import BagOptions
    from odocal.io.bag_skid import read_skid_log
    from odocal.io.bags import read_bag_once

    res, _ = husky
    bag = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    robot = skid / "robots" / "husky.yaml"
    v = validate([bag], res.geometry, robot=robot, kinematics="skid-steer")
    (offset,) = v.offsets
    assert offset.how == "estimated"
    assert offset.offset_s == pytest.approx(res.offsets[0].offset_s, abs=1e-6)
    d = v.as_dict()
    assert d["kinematics"] == "skid-steer" and d["time_offsets"][0]["offset_s"] == offset.offset_s
    assert "clock offset of the truth" in v.text()
    log = read_skid_log(read_bag_once(bag, (None, None, None)), BagOptions(), None)
    own = log_drift(log, SkidSteerModel.from_geometry(res.geometry), offset_s=offset.offset_s)
    assert v.drift is not None and v.drift.pieces == own.pieces
    # (the offset left out moves it by 4 %)
    assert v.drift.median_pct == pytest.approx(own.median_pct, rel=0.005)
    # the nominal geometry drifts several times further
    assert v.nominal_drift is not None and v.nominal_drift.median_pct > 3 * v.drift.median_pct


def test_check_of_a_skid_steer_bag_uses_the_fit_s_own_errors(husky, skid, cli):
    """``check --kinematics skid-steer``: the effective track's standard error is the fit's
    multiplier error times the wheelbase (not a stated wheel noise's), the clock offset is the
    fit's, the turn rates of the curve said."""
    res, _ = husky
    bag = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    status, out, err = cli("check", bag, "--robot", skid / "robots" / "husky.yaml",
                           "--kinematics", "skid-steer", "--json")  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    m, se = res.track_multiplier
    assert d["kinematics"] == "skid-steer"
    assert d["stderr"]["wheelbase_m"] == pytest.approx(se * 0.55, rel=0.01)
    b = dict(zip(d["parameters"], d["values"], strict=True))["wheelbase_m"]
    assert b == pytest.approx(m * 0.55, rel=1e-3)
    assert any(f"{res.offsets[0].offset_s:+.4f}" in n for n in d["notes"])
    assert any("can be read at yaw rates" in n for n in d["notes"])


def test_check_of_a_skid_steer_log_that_never_turns():
    """A straight-only log: the check says NOT enough and why (the track is blind), not an
    error; the fit itself refuses it (above)."""
    import numpy as np

    from odocal.app.check import check_skid_logs
    from odocal.calibration.skid_steer import SkidLog
    from odocal.core.model import Robot, WheelGeometry

    t = np.arange(0.0, 60.0, 0.05)
    angle = 2.0 * t
    truth_t = np.arange(0.1, 59.0, 0.1)
    truth = np.column_stack([0.3 * 2.0 * truth_t, np.zeros_like(truth_t), np.zeros_like(truth_t)])
    log = SkidLog("straight", t, angle, angle, truth_t, truth)
    robot = Robot(WheelGeometry.symmetric(0.6, 1.08), kinematics="skid-steer")
    res = check_skid_logs([log], robot)
    assert not res.check.ok
    assert any(g.severity == "blind" for g in res.check.degeneracies)
    assert any("no skid-steer fit" in n for n in res.notes)
    assert any("cannot be read" in n for n in res.notes)


def test_validate_and_check_skid_steer_refuse_what_they_cannot_read(skid, tmp_path, cli):
    husky = skid / "robots" / "husky.yaml"
    params = tmp_path / "p.yaml"
    params.write_text(
        "wheel_diameter_right_m: 0.30\nwheel_diameter_left_m: 0.32\nwheelbase_m: 0.98\n"
    )
    csv = _csv(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    for command in (("validate", csv, "--params", params), ("check", csv)):
        status, out, err = cli(*command, "--robot", husky, "--kinematics", "skid-steer")
        assert status == 2 and out == "" and err.count("\n") == 1
        assert "reads ROS bags" in err
    bag = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    flags = ("--kinematics", "skid-steer", "--truth-frames", "map:base_link")
    status, _, err = cli("validate", bag, "--params", params, "--robot", husky, *flags)
    assert status == 2 and "--truth-frames" in err


def test_the_gyro_route_agrees_with_the_lidar_icp_on_the_husky(husky, skid):
    """The gyro's turning gain (its yaw rate over the wheels', as the nominal geometry says)
    against the ICP fit's (each side's wheel scale over the effective track, their mean), two
    independent sensors on one recording: within 3 combined standard errors (measured: 0.5250
    +- 0.0011 against 0.5248 +- 0.0009). The gyro sees no wheel scale, which its answer says."""
    import numpy as np

    from odocal.app.fit_skid_gyro import SkidGyroResult

    res, _ = husky
    bag = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    gyro = fit([bag], method="gyro", robot=skid / "robots" / "husky.yaml", kinematics="skid-steer")
    assert isinstance(gyro, SkidGyroResult)
    g, g_se = float(gyro.fit.gain[0]), float(gyro.fit.gain_stderr[0])
    names = ("scale_right", "scale_left", "track_multiplier")
    i = [res.fit.names.index(n) for n in names]
    v, cov = res.fit.values[i], res.fit.covariance[np.ix_(i, i)]
    icp = 0.5 * (v[0] + v[1]) / v[2]
    jac = np.array([0.5 / v[2], 0.5 / v[2], -icp / v[2]])
    icp_se = float(np.sqrt(jac @ cov @ jac))
    assert abs(g - icp) < 3 * np.hypot(g_se, icp_se), (g, g_se, icp, icp_se)
    d = gyro.as_dict()
    assert d["ros2"]["left_wheel_radius_multiplier"] == 1.0
    assert "NOT estimated" in d["not_estimated"]
    assert d["heldout"]["rms_heading_error_deg"]["effective track"] < 0.1 * (
        d["heldout"]["rms_heading_error_deg"]["nominal"]
    )


def test_the_shared_husky_bag_with_its_stock_multiplier_stated(skid, tmp_path, cli):
    """The controller's odometry, inverted through the stock multiplier 1.875 the robot file
    states; no truth in the bag, so the gyro route (said), its multiplier with its error, and the
    stock one's held-out heading error beside the calibrated one's."""
    robot = tmp_path / "husky.yaml"
    robot.write_text(
        "wheel_diameter_m: 0.33\nwheelbase_m: 0.555\nkinematics: skid_steer\n"
        "wheel_separation_multiplier: 1.875\n"
    )
    ros2 = tmp_path / "dd.yaml"
    status, out, err = cli("fit", skid.parent / "husky" / "husky_test1.bag", "--robot", robot,
                           "--ros2", ros2, "--json")  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    assert d["route"] == "gyro" and any("no truth pose track" in n for n in d["notes"])
    m = d["ros2"]["wheel_separation_multiplier"]
    se = d["ros2"]["wheel_separation_multiplier_stderr"]
    assert 0 < se < 0.02 and abs(m - 1.875) > 5 * se  # the stock multiplier is off
    held = d["heldout"]["rms_heading_error_deg"]
    assert held["effective track"] < held["ran with (multiplier 1.875)"] < held["nominal"]
    assert f"wheel_separation_multiplier: {m!r}" in ros2.read_text()


def test_a_skid_steer_fit_of_a_bag_without_truth_or_imu(tmp_path, cli):
    """Wheels only: no route can see the track (one line naming both ways); a truth and no
    IMU with --method gyro: that the gyro route needs an IMU. Nothing written either way."""
    import math

    from odocal.core.tracks import Track, spot_turn, straight
    from tests.support.bag_files import make_run, write_bag

    run = make_run(Track("short", (straight(0.5), spot_turn(math.pi))))
    robot = tmp_path / "r.yaml"
    robot.write_text("wheel_diameter_m: 0.2\nwheelbase_m: 0.5\nkinematics: skid_steer\n")
    bare = write_bag(tmp_path / "bare.bag", "ros1", run, imu=False, truth=False, tf=False)
    status, out, err = cli("fit", bare, "--robot", robot, "--ros2", tmp_path / "x.yaml")
    assert status == 2 and out == "" and err.count("\n") == 1
    assert "truth pose track" in err and "or an IMU" in err and "has neither" in err
    truth = write_bag(tmp_path / "truth.bag", "ros1", run, imu=False, truth=True, tf=False)
    status, out, err = cli("fit", truth, "--robot", robot, "--method", "gyro",
                           "--ros2", tmp_path / "x.yaml")  # fmt: skip
    assert status == 2 and "--method gyro needs an IMU" in err
    assert not (tmp_path / "x.yaml").exists()


def test_validate_and_check_skid_steer_warn_of_an_offset_they_do_not_use(skid, tmp_path, cli):
    husky = skid / "robots" / "husky.yaml"
    bag = _bag(skid, "husky_wheels-deflated_tile_2023_12_12_16h16")
    params = tmp_path / "p.yaml"
    params.write_text(
        "wheel_diameter_right_m: 0.30\nwheel_diameter_left_m: 0.32\nwheelbase_m: 0.98\n"
    )
    for command in (("validate", bag, "--params", params), ("check", bag)):
        status, _, err = cli(*command, "--robot", husky, "--kinematics", "skid-steer",
                             "--time-offset", "imu=0.1")  # fmt: skip
        assert status == 0 and "--time-offset imu=0.1 was given" in err and "not used" in err
