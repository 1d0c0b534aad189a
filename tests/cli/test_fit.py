"""``odocal fit``: the JSON and the text it prints, the files it writes, exit codes."""

from __future__ import annotations

import json

import numpy as np
import pytest

from odocal.core.recording import Recording
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import load_params, load_robot
from odocal.io.ros2_export import read_ros2_params
from tests.support.recorded_runs import (
    TRUE,
    mixed_runs,
    values,
)


def test_fit_robot_out(cli, realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square"
    out = tmp_path / "robot.yaml"
    status, _, err = cli("fit", sq, "--method", "heading", "--robot-out", out)
    assert status == 0, err
    r = load_robot(out)
    # the heading method cannot see the scale (E_s 1); k as odocal noise measures it
    assert r.systematic.E_s == 1.0 and r.systematic.E_b == pytest.approx(1.00889, abs=1e-5)
    assert r.nonsystematic.k_r_m == pytest.approx(1.22e-6, rel=0.01)
    one = realdata / "optiodom_diff" / "square" / "231220200045"  # one run per direction
    cli("fit", one, "--robot-out", tmp_path / "r2.yaml").expect_error("no group of repeated")


def test_fit_cli_bands_refusal_and_plot(cli, realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square" / "231220200029"
    cli("fit", sq, "--wheelbase-model", "banded").expect_error("at least two bands", "spot")
    status, out, err = cli("fit", sq, "--motion-mix", "spot=1,bogus=2")
    assert status == 2 and "BAND=SHARE" in err
    status, out, err = cli("fit", sq, "--plot", tmp_path / "p", "--motion-mix", "spot=0.3,wide=0.7")
    assert status == 0, err
    assert (tmp_path / "p" / "effective_wheelbase.png").stat().st_size > 1000
    assert "single wheelbase for the motion mix" in out
    # the mix asks for a band these runs do not excite: the nearest excited band is used, said
    assert "wide" in err and "do not excite" in err


def _write_runs(folder, runs):
    folder.mkdir()
    for r in runs:
        write_generic_csv(folder / f"{r.name}.csv", r)
    return folder


def test_fit_cli_json_out_and_ros2(tmp_path, cli):
    folder = _write_runs(tmp_path / "runs", mixed_runs())
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.15\nwheelbase_m: 0.385\n")
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    status, stdout, err = cli(
        "fit", folder, "--robot", robot, "--json", "--out", out, "--ros2", ros2
    )
    assert status == 0, err
    d = json.loads(stdout)
    for key in (
        "method",
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
        "stderr",
        "runs",
    ):
        assert key in d
    assert d["method"] == "trajectory" and len(d["runs"]) == 6
    # the CSV stores 10 significant digits, so the fit is exact to about 1e-8
    np.testing.assert_allclose(values(load_params(out)), values(TRUE), rtol=1e-7)
    np.testing.assert_allclose(values(read_ros2_params(ros2)), values(load_params(out)), rtol=1e-8)
    status, stdout, _ = cli("fit", folder, "--robot", robot, "--method", "linear")
    assert status == 0 and "linear fit from 6 run(s)" in stdout


def test_fit_cli_errors(tmp_path, cli):
    # runs without metadata (no 'ran with' parameters): the nominal geometry is unknown
    runs = [
        Recording(r.name, r.time_s, r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ground_truth)
        for r in mixed_runs()
    ]
    swapped = [
        Recording(r.name, r.time_s, r.wheel_angle_left_rad, r.wheel_angle_right_rad, r.ground_truth)
        for r in runs
    ]
    folder = _write_runs(tmp_path / "swapped", swapped)
    out = tmp_path / "p.yaml"
    status, _, err = cli("fit", folder, "--method", "linear", "--out", out)
    assert status == 2 and "swapped" in err and err.count("\n") == 1 and not out.exists()
    good = _write_runs(tmp_path / "good", runs)
    status, _, err = cli("fit", good, "--ros2", tmp_path / "r.yaml")
    # no nominal geometry known (no metadata in the CSVs, no --robot): needed for --ros2
    assert status == 2 and "--robot" in err and not (tmp_path / "r.yaml").exists()
    status, _, err = cli("fit", good, "--exclude", "zzz")
    assert status == 2 and "'zzz' matches no run" in err
    status, _, err = cli(
        "fit",
        good,
        "--robot",
        "paper-fig5",
        "--ros2",
        tmp_path / "r.yaml",
        "--controller-name",
        "1bad name",
    )
    assert status == 2 and "controller name" in err and not (tmp_path / "r.yaml").exists()


def test_real_data_umbmark_reproduces_the_published_values(realdata, cli):
    # reference_results_diff.csv, UMBmark row of square/230620202042 (x-form)
    path = realdata / "optiodom_diff" / "square" / "230620202042"
    status, out, err = cli("fit", path, "--method", "umbmark", "--umbmark-form", "x", "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["wheelbase_m"] == pytest.approx(0.201458, abs=1e-6)
    assert d["wheel_diameter_right_m"] == pytest.approx(0.083954, abs=1e-6)
    assert d["wheel_diameter_left_m"] == pytest.approx(0.084046, abs=1e-6)


def test_real_data_trajectory_golden(realdata, cli):
    base = realdata / "optiodom_diff"
    status, out, err = cli(
        "fit", base / "square" / "231220200048", base / "ivanjko" / "231220200104", "--json"
    )
    assert status == 0, err
    d = json.loads(out)
    # golden values of this commit (5 runs); the published OptiOdom fits of these categories
    # give D 0.0834-0.0840 m and b 0.2000-0.2025 m
    assert d["wheel_diameter_right_m"] == pytest.approx(GOLDEN[0], abs=2e-6)
    assert d["wheel_diameter_left_m"] == pytest.approx(GOLDEN[1], abs=2e-6)
    assert d["wheelbase_m"] == pytest.approx(GOLDEN[2], abs=5e-6)
    assert len(d["runs"]) == 5


GOLDEN = (0.083884, 0.083923, 0.201740)


def test_list_topics_needs_a_bag(tmp_path, cli):
    path = tmp_path / "run.csv"
    path.write_text("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n1,1,1\n")
    status, _, err = cli("fit", path, "--list-topics")
    assert status == 2 and "run.csv" in err and "needs a ROS bag" in err


def test_real_data_square_methods_refuse_non_square_runs(realdata, cli):
    path = realdata / "optiodom_diff" / "ivanjko" / "231220200104"
    status, _, err = cli("fit", path, "--method", "heading")
    assert status == 2 and "231220200104_run-01.csv" in err and "not a closed square" in err
