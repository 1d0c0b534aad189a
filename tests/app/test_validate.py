"""odocal.app.validate on typed results: per-run errors of given parameters against the nominal
geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.validate import validate, validate_recordings
from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import params_yaml

NOMINAL = WheelGeometry(0.15, 0.15, 0.385)
TRUE = NOMINAL.with_systematic(SystematicError(E_b=1.02, E_d=1.004))


def run(name, turn):
    """Straight 2 m, turn by ``turn`` rad on the spot, straight 1 m (commanded with NOMINAL)."""
    n = 200
    f = np.linspace(0, 1, n)
    r = np.concatenate([f * 2 * 2.0 / 0.15, 2 * 2.0 / 0.15 + f * turn * 0.385 / 0.15])
    ll = np.concatenate([f * 2 * 2.0 / 0.15, 2 * 2.0 / 0.15 - f * turn * 0.385 / 0.15])
    r = np.concatenate([r, r[-1] + f * 2 / 0.15])
    ll = np.concatenate([ll, ll[-1] + f * 2 / 0.15])
    return Recording(
        name=name,
        time_s=np.arange(len(r)) * 0.1,
        wheel_angle_right_rad=r,
        wheel_angle_left_rad=ll,
        ground_truth=dead_reckon(r, ll, TRUE),
        ran_with=NOMINAL,
    )


def test_true_parameters_have_zero_error_and_nominal_does_not():
    runs = [run("a", math.pi / 2), run("b", -math.pi)]
    v = validate_recordings(runs, TRUE).as_dict()
    assert v["mean_final_error_m"] == pytest.approx(0, abs=1e-12)
    assert v["mean_max_error_m"] == pytest.approx(0, abs=1e-12)
    # the nominal geometry: the 2 % wheelbase error turns 90 deg into 88.2 deg, so the last 1 m
    # leg ends about 1 m x 1.76 deg = 31 mm off, plus the E_d curvature of the legs
    nom = [r["nominal_final_error_m"] for r in v["runs"]]
    assert all(0.02 < e < 0.2 for e in nom)
    assert v["mean_nominal_final_error_m"] == pytest.approx(np.mean(nom))
    assert v["runs"][0]["path"] == "a"


def test_the_runs_and_the_params_file_are_read(tmp_path, runs_dir):
    params = tmp_path / "params.yaml"
    params.write_text(params_yaml(TRUE, method="test"))
    v = validate(runs_dir, params)
    assert [r["path"] for r in v.runs] == [str(runs_dir / f"run{i}.csv") for i in range(3)]
    assert v.nominal_source == "firmware" and v.nominal_known and v.written == ()
    d = v.as_dict()
    assert set(d["runs"][0]) >= {"path", "final_error_m", "max_error_m"}
    # the CSV keeps 10 significant digits: errors of the true parameters are below a micrometre
    assert d["mean_final_error_m"] < 1e-6 and d["mean_max_error_m"] < 1e-6
    assert d["mean_nominal_final_error_m"] > 0.02
    # against ROBOT.yaml's nominal geometry instead of each run's firmware parameters
    by_robot = validate(runs_dir, TRUE, robot="paper-fig5")
    assert by_robot.nominal_source == "robot"
    assert by_robot.as_dict()["nominal_params"] == by_robot.runs[0]["nominal_params"]


def test_real_data_held_out_circles(realdata):
    # the published OptiOdom ALL_DATASETS_COMBINED parameters on one circular data set
    path = realdata / "optiodom_diff" / "circular" / "250620202104"
    v = validate(path, WheelGeometry(0.083255, 0.083322, 0.200946))
    d = v.as_dict()
    assert len(d["runs"]) == 6 and v.nominal_source == "firmware"
    # golden values of this commit (nominal = the firmware parameters in the metadata)
    assert d["mean_final_error_m"] == pytest.approx(GOLDEN_FINAL, abs=1e-5)
    assert d["mean_nominal_final_error_m"] == pytest.approx(GOLDEN_NOMINAL, abs=1e-5)


GOLDEN_FINAL, GOLDEN_NOMINAL = 0.0032822, 0.0421159


@pytest.fixture
def runs_dir(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    for i, turn in enumerate([math.pi / 2, -math.pi / 2, math.pi]):
        write_generic_csv(folder / f"run{i}.csv", run(f"run{i}", turn))
    return folder
