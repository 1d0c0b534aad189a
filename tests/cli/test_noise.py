"""``odocal noise``: the JSON and the text it prints, bad tracks and inputs, --force."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest
import yaml

import odocal.app.noise as app_noise
from odocal.core.runs import EndPoseRuns
from odocal.core.tracks import out_and_back, straight_line
from odocal.io.robot_file import load_robot
from odocal.io.ros2_export import read_ros2_params
from odocal.io.runs_csv import write_runs
from tests.support.noise_runs import fwd_runs, noise_robot
from tests.support.printed import as_printed


def _write(tmp_path: Path, runs: EndPoseRuns) -> Path:
    p = tmp_path / "k-runs.csv"
    write_runs(p, runs)
    return p


def test_cli_json_contract(cli, tmp_path, returned):
    results = returned(app_noise, "noise")
    robot = noise_robot()
    path = _write(tmp_path, fwd_runs(robot, out_and_back(10.0), 12, seed=11))
    status, out, err = cli(
        "noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10", "--json"
    )
    assert status == 0, err
    doc = json.loads(out)
    assert {"k_sum_m", "k_sum_ci95", "k_r_m", "k_l_m", "runs"} <= set(doc)
    assert doc["runs"] == 12 and doc["k_r_m"] is None and doc["k_l_m"] is None
    # the app's typed estimate, printed (its numbers: tests/app/test_noise.py)
    assert doc == as_printed(results[0].as_dict())
    status, out, err = cli("noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10")
    assert status == 0
    assert "not identifiable" in out and "m^0.5" in out


@pytest.mark.parametrize(
    ("args", "needle"),
    [
        (("--track", "circle:10"), "out-and-back:D or straight:D"),
        (("--track", "straight:-1"), "at least 0.0001 m"),
        (("--track", "straight:ten"), "not a distance"),
    ],
)
def test_cli_bad_track(cli, tmp_path, args, needle):
    path = _write(tmp_path, fwd_runs(noise_robot(), straight_line(2.0), 5, seed=1))
    status, out, err = cli("noise", path, *args)
    assert status == 2 and needle in err
    assert err.startswith("odocal: error:") and "Traceback" not in err


def test_cli_bad_inputs(cli, tmp_path):
    status, _, err = cli("noise", tmp_path / "missing.csv", "--track", "straight:5")
    assert status == 2 and "no default robot" in err and "--robot" in err  # issue 20.1
    robot = ("--robot", "paper-fig5")
    status, _, err = cli("noise", tmp_path / "missing.csv", *robot, "--track", "straight:5")
    assert status == 2 and "missing.csv" in err and "no such file" in err
    p = tmp_path / "cw.csv"
    p.write_text("direction,x_m,y_m,theta_deg\ncw,0,0,1\nfwd,0,0,2\nfwd,0,0,3\n")
    status, _, err = cli("noise", p, *robot, "--track", "straight:5")
    assert status == 2 and "line 2" in err and "direction" in err and "fwd" in err
    p.write_text("direction,x_m,y_m,theta_deg\nfwd,0,0,1\nfwd,0,0,2\n")
    status, _, err = cli("noise", p, *robot, "--track", "straight:5")
    assert status == 2 and "at least 3" in err and len(err.strip().splitlines()) == 1


def test_cli_force_turns_the_error_into_a_warning(cli, tmp_path):
    runs = fwd_runs(noise_robot(), out_and_back(10.0), 15, seed=4)
    bad = EndPoseRuns(runs.directions, runs.errors + [0.0, 0.0, math.radians(2.0)])
    path = _write(tmp_path, bad)
    status, _, err = cli("noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10")
    assert status == 2 and "--force" in err
    status, out, err = cli(
        "noise", path, "--robot", "paper-fig5", "--track", "out-and-back:10", "--force", "--json"
    )
    assert status == 0 and "odocal: warning:" in err
    assert json.loads(out)["warnings"]


def test_noise_cli_on_optiodom_writes_robot_and_ros2(cli, realdata, tmp_path, returned):
    # one OptiOdom data set (6 repeated runs): what the command prints and writes; the golden
    # numbers of all the squares are tests/app/test_noise.py's
    results = returned(app_noise, "noise_recordings")
    sq = realdata / "optiodom_diff" / "square" / "231220200029"
    robot, ros2 = tmp_path / "robot.yaml", tmp_path / "dd.yaml"
    status, out, err = cli("noise", sq, "--robot-out", robot, "--ros2", ros2, "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d == as_printed(results[0].as_dict())
    assert set(d["written"]) == {str(ros2), str(robot)}
    # the files written are the numbers printed
    r = load_robot(robot)
    assert r.nonsystematic.k_r_m == pytest.approx(d["k_sum_m"] / 2, rel=1e-6)
    assert r.systematic.E_b == pytest.approx(d["robot"]["systematic"]["E_b"], rel=1e-6)
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


@pytest.mark.parametrize(
    "argv,needles",
    [
        (["--ros2", "dd.yaml", "--speed", "114"], ["--speed", "114 m/s", "did you type mm/s?"]),
        (["--ros2", "dd.yaml", "--speed", "1e-320"], ["--speed", "singular"]),
        (["--ros2", "dd.yaml", "--twist-window", "1e-300"], ["--twist-window", "velocity window"]),
        (["--ros2", "dd.yaml", "--twist-window", "3600"], ["--twist-window", "0.2 s"]),
        (["--track", "out-and-back:1e-320"], ["--track", "at least 0.0001 m"]),
        (["--pose-distance", "5e-324"], ["--pose-distance", "check the units"]),
        (["--sigma-theta-deg", "1e9"], ["--sigma-theta-deg", "<= 360"]),
        (["--ticks-per-rev", "1e-300"], ["--ticks-per-rev", "ticks per wheel turn"]),
    ],
)
def test_implausible_flags_are_refused_with_their_reason(cli, tmp_path, argv, needles):
    """Each bound comes from odocal.io.limits and says why (a speed in mm/s typed as m/s, a
    window or a distance so small the variances vanish and k becomes inf)."""
    cli("noise", tmp_path / "runs.csv", *argv).expect_error(*needles)


@pytest.mark.parametrize(
    "argv,needle",
    [
        (["design", "--sigma-xy-m", "1e9"], "--sigma-xy-m"),
    ],
)
def test_tiny_lengths_and_huge_noises_are_refused_by_the_other_commands(cli, argv, needle):
    cli(*argv).expect_error(needle)


def test_the_python_api_has_the_same_bounds(tmp_path):
    from odocal.app.noise import noise, noise_recordings
    from odocal.errors import OdocalError

    with pytest.raises(OdocalError, match="did you type mm/s"):
        noise_recordings(tmp_path / "x.csv", ros2=tmp_path / "dd.yaml", speed_m_s=114.0)
    with pytest.raises(OdocalError, match="window_s"):
        noise_recordings(tmp_path / "x.csv", window_s="0.2")
    with pytest.raises(OdocalError, match="distance_m"):
        noise(tmp_path / "x.csv", distance_m=1e-320)
