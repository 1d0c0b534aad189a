"""``odocal validate`` reports the drift the way the field does (KITTI style, issue 28 item 4)
and writes the trajectories evo reads (``--tum``)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.app.validate import validate
from odocal.core.model import WheelGeometry
from odocal.core.path_drift import path_drift
from odocal.io.tum import read_tum


def test_validate_drift_and_tum_files(realdata, tmp_path):
    runs = realdata / "optiodom_diff" / "circular" / "231220200121"
    params = WheelGeometry(0.0835, 0.0839, 0.296)
    tum = tmp_path / "tum"
    res = validate([runs], params, tum=tum)
    d = res.as_dict()
    drift, nominal = d["drift_percent_per_10m"], d["nominal_drift_percent_per_10m"]
    assert set(drift) >= {"median", "mean", "pieces"} and drift["piece_length_m"] == 1.0
    assert drift["pieces"] == nominal["pieces"] > 10  # small indoor runs: 1 m pieces
    assert "re-anchored to the truth at its start" in d["drift_alignment"]
    # the files say the same: every run's truth and calibrated dead reckoning read back give
    # the pooled pieces (what evo_rpe --delta 1 --delta_unit m --pairs_from_reference reads)
    errors = []
    for truth_file in sorted(tum.glob("*.truth.tum")):
        _, truth = read_tum(truth_file)
        _, est = read_tum(str(truth_file).replace(".truth.", ".calibrated."))
        errors.append(path_drift(truth, est, length_m=1.0).error_pct)
        assert (tum / truth_file.name.replace(".truth.", ".nominal.")).exists()
    pooled = np.concatenate(errors)
    assert len(pooled) == drift["pieces"]
    assert float(np.median(pooled)) == pytest.approx(drift["median"], rel=1e-6)
    assert "drift with these parameters: median" in res.text()
