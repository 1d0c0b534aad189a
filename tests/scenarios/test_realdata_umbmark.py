"""Golden values: UMBmark on the real OptiOdom squares reproduces the published results."""

import csv

import numpy as np
import pytest

from odocal.calibration.umbmark import calibrate_umbmark
from odocal.core.odometry import dead_reckon, final_error
from odocal.core.runs import EndPoseRuns
from odocal.io.optiodom import load_optiodom_dataset


def _published(realdata, method):
    rows = {}
    with open(realdata / "optiodom_diff" / "reference_results_diff.csv", newline="") as f:
        for r in csv.DictReader(f):
            # rows with a note are the authors' "without worse runs" variants
            if r["method"] == method and not r["note"] and r["cal_b_m"]:
                rows[r["dataset"].rsplit("/", 1)[-1]] = r
    return rows


def _end_errors(recordings):
    """Final errors from dead-reckoning the recorded ticks with the firmware parameters."""
    errs = [
        final_error(
            r.ground_truth,
            dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ran_with),
        )
        for r in recordings
    ]
    return EndPoseRuns(tuple(r.label for r in recordings), np.array(errs))


def test_umbmark_x_form_reproduces_published_values(realdata):
    published = _published(realdata, "UMBmark")
    folders = sorted((realdata / "optiodom_diff" / "square").iterdir())
    assert len(folders) == 8
    for folder in folders:
        recs = load_optiodom_dataset(folder)
        ref = published[folder.name]
        assert len(recs) == int(ref["n_runs"])
        assert recs[0].ran_with.wheelbase_m == pytest.approx(float(ref["init_b_m"]))
        runs = _end_errors(recs)
        res = calibrate_umbmark(runs, recs[0].meta["side_m"], recs[0].ran_with, form="x")
        c = res.corrected
        # 2e-6 m: the published values are printed to 6 significant digits (5e-7 m here)
        assert c.wheelbase_m == pytest.approx(float(ref["cal_b_m"]), abs=2e-6), folder.name
        assert c.diameter_right_m == pytest.approx(float(ref["cal_Dr_m"]), abs=2e-6), folder.name
        assert c.diameter_left_m == pytest.approx(float(ref["cal_Dl_m"]), abs=2e-6), folder.name


def test_square_runs_show_the_umbmark_signature(realdata):
    # CW runs are labelled first; their final heading error has the opposite sign of the CCW ones
    recs = load_optiodom_dataset(realdata / "optiodom_diff" / "square" / "230620202042")
    runs = _end_errors(recs)
    assert runs.mean("cw")[2] > 0 > runs.mean("ccw")[2]
    # the ground truth heading itself ends near -2 pi (CW) and +2 pi (CCW)
    assert recs[0].ground_truth[-1, 2] == pytest.approx(-2 * np.pi, abs=0.2)
    assert recs[-1].ground_truth[-1, 2] == pytest.approx(2 * np.pi, abs=0.2)
