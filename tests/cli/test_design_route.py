"""``odocal design --route R`` and ``odocal plan --route R``: the JSON contract, the command
file, and the bad inputs (one line, exit 2, nothing written)."""

from __future__ import annotations

import csv
import json
import math
import re

import numpy as np
import pytest

from odocal.core.maneuvers import as_recording, command_series, simulate_recordings
from odocal.core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from odocal.design.route import candidate_maneuvers
from odocal.io.generic_csv import write_generic_csv
from odocal.presets import DEFAULT_ROBOT, PRESETS

FAST = ("--duration", "40", "--trials", "20", "--quiet")


def test_design_route_json_contract(cli):
    status, out, err = cli("design", "--route", "trajectory", *FAST, "--json")
    assert status == 0, err
    d = json.loads(out)
    rec = d["recommended"]
    assert isinstance(rec["maneuvers"], list) and rec["maneuvers"]
    assert rec["duration_s"] <= 40
    assert set(rec["predicted_std_error"]) == {"wheelbase", "wheel_diameter", "diameter_ratio"}
    assert all(v > 0 and math.isfinite(v) for v in rec["predicted_std_error"].values())
    assert rec["predicted_drift_percent_per_10m"] > 0
    assert any(c["duration_s"] == rec["duration_s"] and c["mix"] == rec["mix"]
               for c in d["candidates"])  # fmt: skip
    assert rec["monte_carlo"]["trials"] == 20


def test_design_route_same_seed_same_answer_and_plot(cli, tmp_path):
    a = cli("design", "--route", "gyro", *FAST, "--json", "--seed", "3", "--plot", tmp_path / "p")
    b = cli("design", "--route", "gyro", *FAST, "--json", "--seed", "3")
    assert a[0] == 0 and b[0] == 0
    da, db = json.loads(a[1]), json.loads(b[1])
    da.pop("written")
    db.pop("written")
    assert da == db
    png = tmp_path / "p" / "route_design.png"
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_plan_route_writes_commands_that_drive_the_recommendation(cli, tmp_path):
    out = tmp_path / "cmd.csv"
    status, text, err = cli("plan", "--route", "trajectory", *FAST, "--out", out, "--json")
    assert status == 0, err
    d = json.loads(text)
    rows = list(csv.reader(out.read_text().splitlines()))
    assert rows[0] == ["t", "v", "omega"]
    t, v, w = np.array(rows[1:], float).T
    assert t[0] == 0 and np.all(np.diff(t) > 0) and v[-1] == 0 and w[-1] == 0
    # the commands, held until the next row, give the protocol's totals
    dt = np.diff(t)
    assert float(np.sum(np.abs(v[:-1]) * dt)) == pytest.approx(d["totals"]["distance_m"], rel=1e-3)
    yaw = w[:-1] * dt
    assert math.degrees(yaw[yaw > 0].sum()) == pytest.approx(d["totals"]["yaw_ccw_deg"], rel=1e-3)
    assert math.degrees(-yaw[yaw < 0].sum()) == pytest.approx(d["totals"]["yaw_cw_deg"], abs=0.1)
    # each command is rounded to whole 50 Hz samples (0.01 s at most each)
    assert t[-1] == pytest.approx(d["recommended"]["duration_s"], abs=0.01 * len(t))
    assert all(m["checks"] for m in d["maneuvers"])
    # the floor needed: the commands integrated as a unicycle (an independent integration, in
    # 1 ms steps), its extent plus a wheelbase each side
    x = y = th = 0.0
    xs, ys = [0.0], [0.0]
    for k in range(len(dt)):
        n = max(1, int(round(dt[k] / 1e-3)))
        for _ in range(n):
            th += w[k] * dt[k] / n / 2
            x += v[k] * dt[k] / n * math.cos(th)
            y += v[k] * dt[k] / n * math.sin(th)
            th += w[k] * dt[k] / n / 2
            xs.append(x)
            ys.append(y)
    b = PRESETS[DEFAULT_ROBOT].nominal.wheelbase_m
    assert d["totals"]["floor_x_m"] == pytest.approx(np.ptp(xs) + 2 * b, abs=0.05)
    assert d["totals"]["floor_y_m"] == pytest.approx(np.ptp(ys) + 2 * b, abs=0.05)


def test_plan_route_text_has_the_checks(cli, tmp_path):
    status, text, err = cli("plan", "--route", "gyro", *FAST, "--out", tmp_path / "c.csv")
    assert status == 0, err
    assert "check: takes" in text and "turn rate" in text and "deg turned CCW" in text


def _bag_of(tmp_path, geometry, name):
    """A run file of a robot with ``geometry`` driving a recommended-like recording, truth with
    a tracker's noise (1 mm, 0.2 deg) and wheel noise k = 4e-6 m."""
    man = candidate_maneuvers("trajectory", "arcs+spins", 60.0, geometry.wheelbase_m, 0.3, 0.5)
    s = command_series(man, 10.0)
    angles, truth, _ = simulate_recordings(
        s, geometry, geometry, NonSystematicError(4e-6, 4e-6),
        MeasurementNoise(1e-3, math.radians(0.2)), 1, np.random.default_rng(5),
    )  # fmt: skip
    path = tmp_path / f"{name}.csv"
    write_generic_csv(path, as_recording(s, angles, truth[0], ran_with=geometry, name=name))
    return path


def test_noise_from_a_run_of_this_robot_is_measured(cli, tmp_path):
    nominal = PRESETS[DEFAULT_ROBOT].nominal
    path = _bag_of(tmp_path, nominal, "mine")
    status, out, err = cli("design", "--route", "trajectory", *FAST, "--noise-from", path, "--json")
    assert status == 0, err
    noise = json.loads(out)["noise"]
    assert "measured from mine.csv" in noise["source"]
    # the run: k = 4e-6 m per wheel, a 1 mm / 0.2 deg tracker, 60 s. The interval estimate
    # (calibration.slam_noise, what check uses) finds the tracker to 20 %; k only to a factor
    # of about 2 from one minute (docs/design.md: 5.6e-6 m from eight minutes; the wheels' and
    # the truth's heading noise trade off over 1 s intervals)
    assert noise["sigma_xy_m"] == pytest.approx(1e-3, rel=0.2)
    assert noise["sigma_theta_deg"] == pytest.approx(0.2, rel=0.25)
    assert 2e-6 < noise["k_r_m"] < 1e-5


def test_noise_from_another_robot_is_refused(cli, tmp_path):
    other = WheelGeometry(0.3, 0.3, 0.8)  # twice the preset's wheels and wheelbase
    path = _bag_of(tmp_path, other, "theirs")
    plot = tmp_path / "plot"
    args = ("design", "--route", "trajectory", *FAST, "--noise-from", path, "--plot", plot)
    cli(*args).expect_error("another robot", "ran with", "wheelbase 0.8 m")
    assert not plot.exists()
    # without the controller's parameters in the file: the fit of its truth tells
    lines = path.read_text().splitlines()
    path.write_text("\n".join(x for x in lines if not x.startswith("# wheel")) + "\n")
    cli(*args).expect_error("another robot", "wheels and truth give", "wheelbase")
    assert not plot.exists()


@pytest.mark.parametrize(
    ("args", "needles"),
    [
        (("--route", "trajectory", "--duration", "40", "--target-std-error", "wheelbase=0.001%"),
         ("no recording of up to", "best reachable", "wheelbase")),
        (("--route", "trajectory", "--duration", "10"), ("fits in 10 s", "takes")),
        (("--route", "trajectory", "--target-std-error", "wheelbase=0.03%"),
         ("best reachable is wheelbase", "runs for about", "would reach it")),
        (("--route", "gyro", "--target-std-error", "wheel_diameter=0.05%"),
         ("cannot see", "not observable")),
        (("--route", "trajectory", "--validate", "4:0.1:ccw"), ("--validate", "cannot simulate")),
        (("--route", "trajectory", "--target-std-error", "wheelbase=0.2"), ("a length needs",)),
        (("--route", "trajectory", "--target-std-error", "speed=1%"), ("NAME=VALUE",)),
        (("--route", "trajectory", "--duration", "-5"), ("--duration",)),
        # the message quoted rad/sqrt(s) under the deg/sqrt(h) flag; 1e9 was designed for
        (("--route", "gyro", "--gyro-arw-deg-per-sqrt-h", "-5"), ("got -5",)),
        (("--route", "gyro", "--gyro-arw-deg-per-sqrt-h", "1e9"), ("at most 100", "got 1e+09")),
        (("--route", "trajectory", "--sides", "5"), ("--sides", "only without --route")),
        # the polygon rule's flags with defaults were ignored without a word
        (("--route", "trajectory", "--criterion", "residual", "--alpha", "0.5"),
         ("--alpha, --criterion", "only without --route")),
        (("--route", "gyro", "--method", "umbmark"), ("--method", "only without --route")),
        (("--target-std-error", "wheelbase=1%"), ("only with --route",)),
    ],
)  # fmt: skip
def test_design_route_bad_inputs(cli, tmp_path, args, needles):
    plot = tmp_path / "plot"
    cli("design", *args, "--trials", "20", "--plot", plot).expect_error(*needles)
    assert not plot.exists()


def test_plan_route_bad_input_writes_nothing(cli, tmp_path, monkeypatch):
    out = tmp_path / "cmd.csv"
    cli("plan", "--route", "gyro", "--target-std-error", "wheel_diameter=1%", "--out", out
        ).expect_error("not observable")  # fmt: skip
    assert not out.exists()
    keep = tmp_path / "notes.csv"
    keep.write_text("a,b\n1,2\n")
    cli("plan", "--route", "gyro", *FAST, "--out", keep).expect_error("not a command file")
    assert keep.read_text() == "a,b\n1,2\n"
    cli("plan", "--duration", "30").expect_error("only with --route")
    # 1e8 trials: a MemoryError traceback after the candidates' predictions
    cli("plan", "--route", "gyro", "--trials", "100000000", "--out", out).expect_error(
        "--trials", "2 to 2000", "got 100000000"
    )
    cli("design", "--route", "trajectory", "--trials", "2001").expect_error("2 to 2000")
    assert not out.exists()
    for polygon in (("--sides", "5"), ("--side-length", "3"), ("--runs-per-direction", "3")):
        cli("plan", "--route", "gyro", *polygon, "--out", out).expect_error(
            polygon[0], "only without --route"
        )  # were ignored without a word
    # an empty --out wrote the default route-commands.csv into the working folder
    monkeypatch.chdir(tmp_path)
    cli("plan", "--route", "gyro", *FAST, "--out", "").expect_error("--out", "empty output name")
    assert not (tmp_path / "route-commands.csv").exists()


def test_plan_route_out_is_never_its_validation_file(cli, tmp_path):
    # the command file driven as --validate was replaced by the new plan (exit 0)
    drive = tmp_path / "drive.csv"
    text = "t,v,omega\n0,0.3,0\n20,0,0\n"
    drive.write_text(text)
    for force in ((), ("--force",)):
        cli("plan", "--route", "gyro", *FAST, "--validate", drive, "--out", drive, *force
            ).expect_error("drive.csv", "overwrite an input")  # fmt: skip
        assert drive.read_text() == text


def _commands(path):
    return np.array([r.split(",") for r in path.read_text().splitlines()[1:]], float).T


def test_plan_route_drives_at_the_stated_speed_and_turn_rate(cli, tmp_path):
    # whole samples: a command's speed is scaled by at most half a 50 Hz sample per command
    out = tmp_path / "cmd.csv"
    status, _, err = cli("plan", "--route", "trajectory", *FAST, "--speed", "0.45", "--out", out)
    assert status == 0, err
    _, v, _ = _commands(out)
    assert np.max(np.abs(v)) == pytest.approx(0.45, rel=0.01)
    status, text, err = cli("design", "--route", "gyro", *FAST, "--turn-rate", "0.8", "--json")
    assert status == 0, err
    spins = [m for c in json.loads(text)["candidates"] for m in c["maneuvers"] if "spin" in m]
    assert spins and all(m.endswith("at 0.8 rad/s") for m in spins)
    cli("design", "--route", "gyro", "--speed", "0").expect_error("--speed")


def test_a_planned_command_file_is_a_validation_driving(cli, tmp_path):
    drive = tmp_path / "drive.csv"
    assert cli("plan", "--route", "trajectory", *FAST, "--out", drive)[0] == 0
    status, out, err = cli("design", "--route", "gyro", *FAST, "--validate", drive, "--json")
    assert status == 0, err
    assert json.loads(out)["validation"] == ["the commands of drive.csv"]


@pytest.mark.parametrize(
    ("body", "needles"),
    [
        ("t,v,omega\n0,0.3,0\n2,0.3,0.1\n1,0,0\n", ("line 4", "do not increase")),
        ("t,v,omega\n0,30,0\n2,0,0\n", ("line 2", "implausibly large")),
        ("t,v,omega\n0,nan,0\n2,0,0\n", ("line 2", "cannot simulate")),
        ("t,v\n0,0.3\n2,0\n", ("omega",)),
        ("t,v,omega\n0,0,0\n2,0,0\n", ("never move",)),
        ("t,v,omega\n0,0.1,0\n4000,0,0\n", ("more than the model simulates",)),
        # a spin in place, a drive shorter than a piece: no drift per distance (was a traceback)
        ("t,v,omega\n0,0,0.5\n100,0,0\n", ("drive 0 m", "per distance")),
        ("t,v,omega\n0,0.3,0\n0.5,0,0\n", ("drive 0.15 m", "per distance")),
    ],
)  # fmt: skip
def test_a_validation_the_model_cannot_simulate_is_refused(cli, tmp_path, body, needles):
    f = tmp_path / "drive.csv"
    f.write_text(body)
    plot = tmp_path / "plot"
    cli("design", "--route", "trajectory", "--validate", f, "--plot", plot).expect_error(*needles)
    assert not plot.exists()
    cli("design", "--validate", f).expect_error("only with --route")


def test_noise_run_geometry_is_the_designs_truth(cli, tmp_path):
    # unequal wheels: the design's true robot is the run's fit, E_d included (a robot rebuilt
    # from the fit with E_d = 1 would have equal wheels and a Monte Carlo far from its
    # prediction)
    path = _bag_of(tmp_path, WheelGeometry(0.153, 0.148, 0.39), "mine")
    args = ("--duration", "40", "--trials", "100", "--quiet", "--noise-from", path, "--json")
    status, out, err = cli("design", "--route", "trajectory", *args)
    assert status == 0, err
    d = json.loads(out)
    fitted = [n for n in d["notes"] if "design's true geometry" in n]
    assert fitted
    d_r, d_l = map(float, re.search(r"diameters ([0-9.]+) / ([0-9.]+) m", fitted[0]).groups())
    # the fit of one noisy minute: within 1 mm of the truth, the ratio 1.034 within 0.01
    assert d_r == pytest.approx(0.153, abs=1e-3) and d_l == pytest.approx(0.148, abs=1e-3)
    assert d_r / d_l == pytest.approx(0.153 / 0.148, abs=0.01)
    true = d["geometry_assumed"]["true"]
    assert true["wheel_diameter_right_m"] == pytest.approx(d_r, abs=1e-4)
    assert true["wheel_diameter_left_m"] == pytest.approx(d_l, abs=1e-4)
    assert d["geometry_assumed"]["ran_with"]["wheelbase_m"] == 0.385  # the robot file's
    rec = d["recommended"]
    # 100 trials know a spread to about 7 %: 30 % is a real disagreement
    for k, real in rec["monte_carlo"]["realised_std_error"].items():
        assert real == pytest.approx(rec["predicted_std_error"][k], rel=0.3), k


def test_plan_route_of_several_runs_says_so(cli, tmp_path):
    # a target one run cannot reach but runs of two minutes can (docs/design.md)
    out = tmp_path / "c.csv"
    args = ("--trials", "20", "--quiet", "--target-std-error", "wheelbase=0.06%", "--out", out)
    status, text, err = cli("plan", "--route", "trajectory", *args)
    assert status == 0, err
    assert "Record 4 runs, a bag each" in text and "(each run)" in text
    t = _commands(out)[0]
    assert 100 < t[-1] < 160  # the command file is one run of about two minutes


def test_noise_from_measures_the_gyro_for_the_gyro_route(cli, tmp_path):
    from odocal.core.maneuvers import GyroNoise, arc, pause, spin

    g = PRESETS[DEFAULT_ROBOT].nominal
    s = command_series([pause(20), spin(6.0, 0.5), pause(20), arc(1.0, 3.0, 0.3), pause(20)], 50)
    angles, truth, gyro = simulate_recordings(
        s, g, g, NonSystematicError(2e-6, 2e-6), MeasurementNoise(1e-3, 0.003), 1,
        np.random.default_rng(0), gyro=GyroNoise(3e-4, 0.003),
    )  # fmt: skip
    path = tmp_path / "imu.csv"
    write_generic_csv(path, as_recording(s, angles, truth[0], gyro[0], ran_with=g, name="imu"))
    status, out, err = cli("design", "--route", "gyro", *FAST, "--noise-from", path, "--json")
    assert status == 0, err
    noise = json.loads(out)["noise"]
    # 60 s standing still: the bias to a few 1e-5 rad/s, the random walk (a batch-means
    # standard error of about 120 half-second batches) to about 10 %: 35 % is a real miss
    assert noise["gyro_bias_rad_s"] == pytest.approx(0.003, abs=2e-4)
    assert noise["gyro_arw_rad_sqrt_s"] == pytest.approx(3e-4, rel=0.35)
    assert "standing still" in noise["source"]


def test_stated_noise_moves_the_prediction(cli):
    def wheelbase_se(*args):
        status, out, err = cli("design", *args, *FAST, "--json")
        assert status == 0, err
        d = json.loads(out)
        return d["recommended"]["predicted_std_error"]["wheelbase"], d["noise"]

    quiet, _ = wheelbase_se("--route", "slam", "--sigma-xy-m", "0.001", "--sigma-theta-deg", "0.1")
    loud, noise = wheelbase_se("--route", "slam", "--sigma-xy-m", "0.05")
    # a part not stated keeps the route's default (the SLAM's 1 deg)
    assert noise["sigma_xy_m"] == 0.05 and noise["sigma_theta_deg"] == pytest.approx(1.0)
    assert loud > 2 * quiet
    a, _ = wheelbase_se("--route", "gyro", "--gyro-arw-deg-per-sqrt-h", "0.3")
    b, _ = wheelbase_se("--route", "gyro", "--gyro-arw-deg-per-sqrt-h", "10")
    # a MEMS gyro's 0.3 deg/sqrt(h) adds little to the wheels' noise over a spin; a poor
    # gyro's 10 deg/sqrt(h) dominates the ratio's error
    assert b > 2 * a
    cli("design", "--route", "gyro", "--sigma-xy-m", "0.01").expect_error("measures no pose")
    cli("design", "--route", "slam", "--gyro-arw-deg-per-sqrt-h", "1").expect_error("only with")


def test_plan_route_designs_with_the_same_sensor_noise_as_design_route(cli, tmp_path):
    """The sensors' noise flags reach plan --route's design: the recording it writes is the one
    design --route recommends for that noise (its predicted errors the same), not the one for
    the default noise."""
    noisy = ("--sigma-xy-m", "0.05", "--sigma-theta-deg", "2", "--trials", "20", "--quiet",
             "--json")  # fmt: skip
    status, out, err = cli("design", "--route", "slam", *noisy)
    assert status == 0, err
    designed = json.loads(out)["recommended"]["predicted_std_error"]
    status, out, err = cli("plan", "--route", "slam", *noisy, "--out", tmp_path / "a.csv")
    assert status == 0, err
    planned = json.loads(out)["recommended"]["predicted_std_error"]
    assert planned == pytest.approx(designed, rel=1e-9)
    status, out, err = cli("plan", "--route", "slam", "--trials", "20", "--quiet", "--json",
                           "--out", tmp_path / "b.csv")  # fmt: skip
    assert status == 0, err
    default = json.loads(out)["recommended"]["predicted_std_error"]
    assert default["wheelbase"] != pytest.approx(planned["wheelbase"], rel=0.05)


def test_a_skid_steer_design_assumes_a_skid_steer_robot_s_slip(cli, tmp_path):
    """A skid-steer robot's random error is its slip: without a stated k or --noise-from the
    design takes the slip measured on the Norlab robots (k about 5e-4 m), not a differential
    drive's 1e-6 m (which predicted a 20-30 times smaller error), and says so."""
    robot = tmp_path / "r.yaml"
    robot.write_text("wheel_diameter_m: 0.6\nwheelbase_m: 1.08\nkinematics: skid_steer\n")
    args = ("--route", "gyro", "--robot", robot, "--trials", "20", "--quiet", "--json")
    status, out, err = cli("design", *args)
    assert status == 0, err
    d = json.loads(out)
    assert d["noise"]["k_r_m"] == pytest.approx(5e-4) and "skid-steer slip" in d["noise"]["source"]
    skid_se = d["recommended"]["predicted_std_error"]["wheelbase"]
    robot.write_text("wheel_diameter_m: 0.6\nwheelbase_m: 1.08\n")
    status, out, err = cli("design", *args)
    assert status == 0, err
    diff_se = json.loads(out)["recommended"]["predicted_std_error"]["wheelbase"]
    assert skid_se > 5 * diff_se


def test_noise_from_a_skid_steer_bag_is_fitted_as_fit_skid_steer_fits_it(cli, tmp_path):
    """--kinematics skid-steer --noise-from BAG: the differential trajectory fit of a skidding
    robot's truth stamped 0.3 s late said "non-physical result ... wheels may be swapped" (on the
    real Warthog too, or wheels 50 % apart); the skid-steer fit recovers the robot."""
    from odocal.core.skid_steer import SkidSteerModel
    from tests.support.bag_files import BagWriter
    from tests.support.skid_robot import simulate_skid_log

    true = SkidSteerModel(0.3 * 0.96, 0.3 * 0.95, 1.08 * 1.65 / 2, -1.08 * 1.65 / 2)
    log = simulate_skid_log(true, np.random.default_rng(3), duration_s=90.0,
                            max_rate_rad_s=2.0, offset_s=0.3)  # fmt: skip
    bag = tmp_path / "skid.bag"
    with BagWriter(bag, "ros1") as w:
        for t, r, left in zip(log.time_s, log.angle_right_rad, log.angle_left_rad, strict=True):
            w.joints("/joint_states", 10 + t, ("left_wheel_joint", "right_wheel_joint"), [left, r])
        for t, (x, y, yaw) in zip(log.truth_time_s, log.truth_pose, strict=True):
            w.pose_stamped("/mocap/pose", 10 + t, x, y, yaw)
    robot = tmp_path / "r.yaml"
    robot.write_text("wheel_diameter_m: 0.6\nwheelbase_m: 1.08\nkinematics: skid_steer\n")
    args = ("--duration", "150", "--trials", "20", "--quiet", "--robot", robot, "--json")
    status, out, err = cli("design", "--route", "trajectory", *args, "--noise-from", bag)
    assert status == 0, err
    d = json.loads(out)
    g = d["geometry_assumed"]["true"]
    assert g["wheelbase_m"] == pytest.approx(1.08 * 1.65, rel=0.01)
    assert g["wheel_diameter_right_m"] == pytest.approx(0.6 * 0.96, rel=0.01)
    assert g["wheel_diameter_left_m"] == pytest.approx(0.6 * 0.95, rel=0.01)
    offset = [n for n in d["notes"] if "clock offset of the truth" in n]
    assert offset and re.search(r"\+0\.[23]\d* s", offset[0])


def test_plan_route_says_what_the_design_assumed(cli, tmp_path):
    """plan --route dropped the design's notes: a tracked robot without a multiplier was planned
    for its physical track without a word (design says so)."""
    robot = tmp_path / "tracked.yaml"
    robot.write_text("wheel_diameter_m: 0.15\nwheelbase_m: 0.35\nkinematics: tracked\n")
    out = tmp_path / "cmd.csv"
    args = ("plan", "--route", "trajectory", *FAST, "--robot", robot, "--out", out)
    status, text, err = cli(*args)
    assert status == 0, err
    assert "note: skid-steer without a wheel_separation_multiplier" in text
    status, text, err = cli(*args, "--json")
    assert status == 0, err
    assert any("without a wheel_separation_multiplier" in n for n in json.loads(text)["notes"])


def test_one_target_per_parameter(cli):
    status, out, err = cli("design", "--route", "trajectory", "--target-std-error",
                           "wheelbase=0.2%", "--target-std-error", "wheelbase=1mm")  # fmt: skip
    assert status == 2 and out == "" and "wheelbase given more than once" in err
