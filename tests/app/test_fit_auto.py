"""`odocal fit BAG --method auto`: one bag, every route it allows, one answer (synthetic bags
with known clock offsets, written by tests/synthetic_robot.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from tests.support.synthetic_robot import (
    Gyro,
    Laser,
    default_track,
    repeat_run,
    simulate_robot,
    write_ros2_bag,
)

TRUE = WheelGeometry(0.0505, 0.0495, 0.262)
BELIEVED = WheelGeometry.symmetric(0.050, 0.250)
DELAY_S = 0.1  # the laser's and the SLAM's stamps run 0.1 s late


@pytest.fixture(scope="module")
def bag(tmp_path_factory):
    rng = np.random.default_rng(11)
    run = simulate_robot(
        default_track(), TRUE, BELIEVED, laser=Laser(every=10, n_rays=180),
        gyro=Gyro(0.002, 0.001), rng=rng,
    )  # fmt: skip
    path = tmp_path_factory.mktemp("auto") / "bag"
    write_ros2_bag(path, repeat_run(run, 3), map_odom_every=25, laser_delay_s=DELAY_S,
                   slam_delay_s=DELAY_S, slam_noise=(0.002, 0.001), rng=rng)  # fmt: skip
    return path


@pytest.fixture(scope="module")
def robot(tmp_path_factory):
    path = tmp_path_factory.mktemp("robot") / "robot.yaml"
    path.write_text("wheel_diameter_m: 0.050\nwheelbase_m: 0.250\n")
    return path


@pytest.fixture(scope="module")
def result(bag, robot, tmp_path_factory):
    from odocal.app.fit_auto import fit_auto

    out = tmp_path_factory.mktemp("report") / "report"
    ros2 = out.parent / "dd.yaml"
    return fit_auto(bag, robot=str(robot), out=out, ros2=ros2), out, ros2


@pytest.fixture(scope="module")
def answer(result):
    res, out, ros2 = result
    status = 0 if res.enough else 3  # the command's exit status
    return status, json.loads(json.dumps(res.as_dict())), out, ros2


def test_the_json_contract(answer):
    status, d, _, _ = answer
    assert status == 0, d["verdict"]
    assert [r["name"] for r in d["routes"]] == ["trajectory", "slam", "scan", "gyro"]
    assert all(set(r) >= {"name", "used", "reason"} for r in d["routes"])
    used = {r["name"]: r["used"] for r in d["routes"]}
    assert used == {"trajectory": False, "slam": True, "scan": True, "gyro": True}
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        assert set(d["parameters"][key]) == {"value", "std_error", "status"}
    assert set(d["heldout"]) >= {"nominal_final_error_m", "calibrated_final_error_m"}
    assert (
        set(d["verdict"]) == {"enough", "reasons", "written_despite_reasons"}
        and d["verdict"]["enough"] is True
    )


def test_the_clock_offsets_are_found(answer):
    _, d, _, _ = answer
    # within 10 ms of the 0.1 s written (a tenth of the scan period)
    assert d["time_offsets_s"]["slam"] == pytest.approx(DELAY_S, abs=0.010)
    assert d["time_offsets_s"]["laser"] == pytest.approx(DELAY_S, abs=0.010)


def test_the_parameters_within_their_stated_uncertainty(answer):
    _, d, _, _ = answer
    for key, true in TRUE.as_dict().items():
        p = d["parameters"][key]
        assert abs(p["value"] - true) < 4 * p["std_error"], (key, p, true)
    # and the routes agree with each other
    assert all(c["agree"] for c in d["cross_checks"])


def test_the_held_out_check_and_the_covariances(answer):
    _, d, out, ros2 = answer
    h = d["heldout"]
    assert h["calibrated_final_error_m"] < h["nominal_final_error_m"]
    assert d["covariance"]["pose_covariance_diagonal"][0] > 0
    assert sorted(p.name for p in out.iterdir()) == [
        "heldout.png", "params.yaml", "report.md", "time_offset.png"
    ]  # fmt: skip
    text = ros2.read_text()
    assert "pose_covariance_diagonal" in text and "wheel_separation_multiplier" in text
    assert "Verdict: trustworthy" in (out / "report.md").read_text()


def test_text_output_and_refusals(result, bag, robot, cli, capsys):
    out = str(result[0])  # the text the command prints
    assert "verdict: trustworthy" in out and "clock offset of the slam" in out
    # without the robot file there is nothing to hold the calibration against
    status, out, err = cli("fit", bag)
    assert status == 2 and "--robot" in err and err.count("\n") == 1
    # a bag and another input: one bag only
    status, out, err = cli("fit", bag, bag, "--robot", robot, "--method", "auto")
    assert status == 2 and "one bag" in err


def test_an_answer_that_is_no_robot_is_never_written_even_with_force(tmp_path):
    # the one command writes through the one export path: the same guard as every export
    from pathlib import Path

    from odocal.app.fit_auto import _write
    from odocal.app.fit_auto_result import AutoFitResult, RouteRun
    from odocal.calibration.route_answer import route_answer
    from odocal.errors import CalibrationError
    from odocal.io.bag_survey import RouteOption
    from odocal.io.outputs import OutputPlan

    g = WheelGeometry(7e-4, 7e-4, 0.088)
    odd = RouteRun(
        RouteOption("slam", True, ""), True, "", route_answer("slam", "full", g, (None,) * 3)
    )
    result = AutoFitResult(Path("x.bag"), (odd,), odd, WheelGeometry(0.042, 0.042, 0.088))
    with pytest.raises(CalibrationError, match="not a plausible robot"):
        _write(OutputPlan([]), result, tmp_path / "report", None, "diff_drive_controller", True)
    assert not (tmp_path / "report").exists()


def test_the_25_percent_rule_holds_on_every_route_and_names_the_units(bag, tmp_path):
    # a robot file in inches passes the reader (a 2 in wheel, a 9.8 in wheelbase); before,
    # each route's '-97 % from nominal: absurd' was a warning and the verdict 'trustworthy'
    from odocal.app.fit_auto import fit_auto

    inches = tmp_path / "inches.yaml"
    inches.write_text(
        f"wheel_diameter_m: {0.050 / 0.0254:.4f}\nwheelbase_m: {0.250 / 0.0254:.4f}\n"
    )
    out = tmp_path / "report"
    res = fit_auto(bag, robot=inches, out=out)
    assert not res.enough and not out.exists()
    absurd = [r for r in res.reasons if "absurd for a calibration" in r]
    assert absurd and all("inches" in r for r in absurd)
    assert {r.split(":")[0] for r in absurd} == {res.answer.name}
    assert "absurd" not in " ".join(res.warnings)


def test_a_robot_file_in_millimetres_is_refused_before_the_bag_is_read(tmp_path):
    from odocal.app.fit_auto import fit_auto
    from odocal.errors import InputError

    mm = tmp_path / "mm.yaml"
    mm.write_text("wheel_diameter_m: 330\nwheelbase_m: 555\n")
    with pytest.raises(InputError, match="millimetres"):
        fit_auto(tmp_path / "no-such.bag", robot=mm)


@pytest.fixture(scope="module")
def husky_forced(realdata, tmp_path_factory):
    """The Husky bag (controller odometry + IMU) with a TurtleBot-sized preset, written with
    --force: the verdict and its reasons are those of a run without it (force only writes)."""
    from odocal.app.fit_auto import fit_auto

    out = tmp_path_factory.mktemp("husky") / "report"
    ros2 = out.parent / "dd.yaml"
    res = fit_auto(realdata / "husky" / "husky_test1.bag", robot="paper-fig5", out=out,
                   ros2=ros2, force=True)  # fmt: skip
    return res, out, ros2


def test_a_gyro_answer_is_a_ratio_not_a_calibration(husky_forced):
    # the Husky bag (controller odometry + IMU): a TurtleBot3 file gave a 'trustworthy'
    # 0.154 m; the gyro measures the heading ratio only, so any scale passed
    res, _, _ = husky_forced
    assert res.answer is not None and res.answer.name == "gyro"
    a = res.answer.answer
    assert a.model == "heading-ratio" and a.held == ("wheel_diameter_right_m",
                                                     "wheel_diameter_left_m")  # fmt: skip
    assert a.ratio is not None and a.parameters[2].value * a.ratio == pytest.approx(
        res.nominal.wheelbase_m
    )
    assert not res.enough
    assert any("heading ratio only" in r and "scale" in r for r in res.reasons)
    d = res.as_dict()
    gyro = next(r for r in d["routes"] if r["name"] == "gyro")
    assert gyro["heading_ratio"]["value"] == pytest.approx(a.ratio)
    assert d["verdict"]["enough"] is False


def test_files_written_with_force_carry_the_verdict(husky_forced):
    # a week later a forced file must not look like a trustworthy one
    from odocal.io.robot_file import load_params

    res, out, ros2 = husky_forced
    assert not res.enough and res.written
    assert res.as_dict()["verdict"]["written_despite_reasons"] is True
    assert "written anyway (--force)" in res.text()
    params = (out / "params.yaml").read_text()
    for text in (params, ros2.read_text()):
        assert "# NOT TO BE TRUSTED: written with --force despite:" in text
        assert "heading ratio only" in text
    assert "trusted: false" in params
    load_params(out / "params.yaml")  # still a parameter file odocal reads back
    assert "NOT to be trusted" in (out / "report.md").read_text()
