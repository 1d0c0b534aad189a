"""odocal.app.validate on typed results: per-run errors of given parameters against the nominal
geometry."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.app.validate import validate_recordings
from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording

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
