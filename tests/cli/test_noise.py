"""``odocal noise``: the JSON and the text it prints, bad tracks and inputs, --force."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from odocal.core.model import (
    MeasurementNoise,
    NonSystematicError,
    Robot,
    SystematicError,
    WheelGeometry,
)
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import measure, simulate
from odocal.core.tracks import out_and_back, straight_line
from odocal.io.robot_file import load_robot
from odocal.io.ros2_export import read_ros2_params
from odocal.io.runs_csv import write_runs
from odocal.presets import TETRA_DS2


def _robot(k_r=2e-6, k_l=2e-6, meas=None):
    # systematic errors present on purpose: they must not leak into k. The nominal wheelbase
    # is the true one (E_b = 1) so the estimators' b is exact.
    meas = meas or MeasurementNoise()
    return Robot(TETRA_DS2, SystematicError(1.0, 1.004), NonSystematicError(k_r, k_l), meas)


def _runs(robot, track, n, seed):
    rng = np.random.default_rng(seed)
    e = measure(simulate(track, robot, n, rng, max_step_m=0.05).errors, robot, rng)
    return EndPoseRuns(("fwd",) * n, e)


def _write(tmp_path: Path, runs: EndPoseRuns) -> Path:
    p = tmp_path / "k-runs.csv"
    write_runs(p, runs)
    return p


def test_cli_json_contract(cli, tmp_path):
    robot = _robot()
    path = _write(tmp_path, _runs(robot, out_and_back(10.0), 12, seed=11))
    status, out, err = cli(
        "noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10", "--json"
    )
    assert status == 0, err
    doc = json.loads(out)
    assert {"k_sum_m", "k_sum_ci95", "k_r_m", "k_l_m", "runs"} <= set(doc)
    assert doc["runs"] == 12 and doc["k_r_m"] is None and doc["k_l_m"] is None
    lo, hi = doc["k_sum_ci95"]
    assert lo < doc["k_sum_m"] < hi
    status, out, err = cli("noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10")
    assert status == 0
    assert "not identifiable" in out and "m^0.5" in out


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--track", "circle:10"), "out-and-back:D or straight:D"),
        (("--track", "straight:-1"), "> 0 m"),
        (("--track", "straight:ten"), "not a distance"),
    ],
)
def test_cli_bad_track(cli, tmp_path, args, needle):
    path = _write(tmp_path, _runs(_robot(), straight_line(2.0), 5, seed=1))
    status, out, err = cli("noise", path, *args)
    assert status == 2 and needle in err
    assert err.startswith("odocal: error:") and "Traceback" not in err


def test_cli_bad_inputs(cli, tmp_path):
    status, _, err = cli("noise", tmp_path / "missing.csv", "--track", "straight:5")
    assert status == 2 and "missing.csv" in err and "no such file" in err
    p = tmp_path / "cw.csv"
    p.write_text("direction,x_m,y_m,theta_deg\ncw,0,0,1\nfwd,0,0,2\nfwd,0,0,3\n")
    status, _, err = cli("noise", p, "--track", "straight:5")
    assert status == 2 and "line 2" in err and "direction" in err and "fwd" in err
    p.write_text("direction,x_m,y_m,theta_deg\nfwd,0,0,1\nfwd,0,0,2\n")
    status, _, err = cli("noise", p, "--track", "straight:5")
    assert status == 2 and "at least 3" in err and len(err.strip().splitlines()) == 1


def test_cli_force_turns_the_error_into_a_warning(cli, tmp_path):
    runs = _runs(_robot(), out_and_back(10.0), 15, seed=4)
    bad = EndPoseRuns(runs.directions, runs.errors + [0.0, 0.0, math.radians(2.0)])
    path = _write(tmp_path, bad)
    status, _, err = cli("noise", path, "--track", "out-and-back:10")
    assert status == 2 and "--force" in err
    status, out, err = cli("noise", path, "--track", "out-and-back:10", "--force", "--json")
    assert status == 0 and "odocal: warning:" in err
    assert json.loads(out)["warnings"]


def test_noise_cli_on_optiodom_writes_robot_and_ros2(cli, realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square"
    robot, ros2 = tmp_path / "robot.yaml", tmp_path / "dd.yaml"
    status, out, err = cli("noise", sq, "--robot-out", robot, "--ros2", ros2, "--json")
    assert status == 0, err
    d = json.loads(out)
    # golden (bench_real_experiment.py): k_r + k_l 2.44e-6 m from 40 repeated runs, 28 dof
    assert d["runs"] == 40 and d["dof"] == 28
    assert d["k_sum_m"] == pytest.approx(2.44e-6, rel=0.01)
    lo, hi = d["k_sum_ci95"]
    assert lo < d["k_sum_m"] < hi and hi / lo < 4
    assert d["k_r_m"] is None  # not identifiable from squares
    r = load_robot(robot)
    assert r.nominal == WheelGeometry(0.084, 0.084, 0.2)
    assert r.nonsystematic.k_r_m == pytest.approx(d["k_sum_m"] / 2, rel=1e-6)
    assert r.systematic.E_b == pytest.approx(1.00689, abs=1e-5)
    assert 0 < r.measurement.sigma_theta_rad < math.radians(0.5)
    params = yaml.safe_load(ros2.read_text())["diff_drive_controller"]["ros__parameters"]
    assert len(params["pose_covariance_diagonal"]) == 6
    assert params["twist_covariance_diagonal"][5] == pytest.approx(
        d["ros2_covariance"]["twist_covariance_diagonal"][5]
    )
    assert read_ros2_params(ros2).wheelbase_m == pytest.approx(
        d["robot"]["calibrated"]["wheelbase_m"], rel=1e-12
    )
    # the measured robot designs like any ROBOT.yaml
    status, out, err = cli("design", "--robot", robot, "--side-lengths", "0.5:1.5:0.5",
                           "--trials", "30", "--json")  # fmt: skip
    assert status == 0, err


def test_noise_cli_bad_inputs(cli, realdata, tmp_path):
    sq = realdata / "optiodom_diff" / "square" / "231220200045"  # one CW and one CCW run
    cli("noise", sq).expect_error("no group of repeated runs")
    cli("noise", sq, sq, "--track", "straight:2").expect_error("exactly one RUNS.csv")
    cli("noise", sq, "--params", tmp_path / "p.yaml").expect_error("--params is for RUNS.csv")
