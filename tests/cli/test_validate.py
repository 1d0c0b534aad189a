"""``odocal validate``: its JSON and text, the plots, bad inputs (the numbers:
tests/app/test_validate.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

import odocal.app.validate as app_validate
from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import params_yaml
from tests.support.printed import as_printed

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


@pytest.fixture
def runs_dir(tmp_path):
    """Two runs (a turn each way): a figure per run, and not a third to draw."""
    folder = tmp_path / "runs"
    folder.mkdir()
    for i, turn in enumerate([math.pi / 2, -math.pi]):
        write_generic_csv(folder / f"run{i}.csv", run(f"run{i}", turn))
    return folder


def test_validate_cli_json_and_plots(tmp_path, runs_dir, cli, returned):
    results = returned(app_validate, "validate")
    params = tmp_path / "params.yaml"
    params.write_text(params_yaml(TRUE, method="test"))
    plots = tmp_path / "plots"
    status, out, err = cli("validate", runs_dir, "--params", params, "--json", "--plot", plots)
    assert status == 0, err
    d = json.loads(out)
    assert set(d["runs"][0]) >= {"path", "final_error_m", "max_error_m"}
    # the app's typed result, printed (its numbers: tests/app/test_validate.py)
    assert d == as_printed(results[0].as_dict())
    assert d["plots"] == [str(plots / f"run{i}.png") for i in range(2)]
    pngs = sorted(plots.glob("*.png"))
    assert [p.name for p in pngs] == ["run0.png", "run1.png"]
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in pngs)
    status, out, _ = cli("validate", runs_dir, "--params", params)
    assert status == 0 and out.splitlines()[-1].split()[0] == "mean"


def test_validate_cli_bad_input(tmp_path, runs_dir, cli):
    status, _, err = cli("validate", runs_dir, "--params", tmp_path / "missing.yaml")
    assert status == 2 and "missing.yaml" in err and err.count("\n") == 1
    params = tmp_path / "p.yaml"
    params.write_text("wheel_diameter_right_m: 0.15\nwheel_diameter_left_m: 0.15\n")
    status, _, err = cli("validate", runs_dir, "--params", params)
    assert status == 2 and "wheelbase_m" in err
    params.write_text(params_yaml(TRUE))
    no_truth = tmp_path / "nt.csv"
    no_truth.write_text("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n1,1,1\n")
    status, _, err = cli("validate", no_truth, "--params", params)
    assert status == 2 and "nt.csv" in err and "ground truth" in err
    status, _, err = cli("validate", runs_dir)
    assert status == 2 and "--params" in err
