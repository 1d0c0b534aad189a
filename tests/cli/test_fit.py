"""``odocal fit``: the JSON and the text it prints, the files it writes, exit codes."""

from __future__ import annotations

import json

import numpy as np

import odocal.app.fit as app_fit
from odocal.core.recording import Recording
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import load_params
from odocal.io.ros2_export import read_ros2_params
from tests.support.printed import as_printed
from tests.support.recorded_runs import mixed_runs, values


def test_fit_cli_bands_refusal_and_plot(cli, realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square" / "231220200029"
    cli("fit", sq, "--wheelbase-model", "banded").expect_error("at least two bands", "spot")
    status, out, err = cli("fit", sq, "--motion-mix", "spot=1,bogus=2")
    assert status == 2 and "BAND=SHARE" in err
    # the mix asks for a band these runs do not excite: refused, nothing written (issue 20.7)
    cli("fit", sq, "--plot", tmp_path / "p", "--motion-mix", "spot=0.3,wide=0.7").expect_error(
        "did not measure how the robot turns", "wide"
    )
    assert not (tmp_path / "p").exists()
    status, out, err = cli("fit", sq, "--plot", tmp_path / "p")
    assert status == 0, err
    assert (tmp_path / "p" / "effective_wheelbase.png").stat().st_size > 1000


def _write_runs(folder, runs):
    folder.mkdir()
    for r in runs:
        write_generic_csv(folder / f"{r.name}.csv", r)
    return folder


def test_fit_cli_json_out_and_ros2(tmp_path, cli, returned):
    results = returned(app_fit, "fit")
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
    # the app's typed result, printed (its numbers: tests/app/test_fit.py), and the files of
    # --out and --ros2 hold the geometry printed (nine significant digits)
    assert d == as_printed(results[0].as_dict())
    assert set(results[0].written) == {out, ros2}
    printed = [d["wheel_diameter_right_m"], d["wheel_diameter_left_m"], d["wheelbase_m"]]
    np.testing.assert_allclose(values(load_params(out)), printed, rtol=1e-8)
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
    # --robot-out needs repeated runs for k: none here (the measured robot: tests/app); refused
    # before the fit
    three = _write_runs(tmp_path / "three", runs[:3])
    cli("fit", three, "--robot", "paper-fig5", "--robot-out", tmp_path / "r.yaml").expect_error(
        "no group of repeated"
    )
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


def test_list_topics_needs_a_bag(tmp_path, cli):
    path = tmp_path / "run.csv"
    path.write_text("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n1,1,1\n")
    status, _, err = cli("fit", path, "--list-topics")
    assert status == 2 and "run.csv" in err and "needs a ROS bag" in err


def test_real_data_square_methods_refuse_non_square_runs(realdata, cli):
    path = realdata / "optiodom_diff" / "ivanjko" / "231220200104"
    status, _, err = cli("fit", path, "--method", "heading")
    assert status == 2 and "231220200104_run-01.csv" in err and "not a closed square" in err
