"""The blocked cross-validation of a calibration (calibration.heldout)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration.heldout import MODELS, fit_base_motion, heldout_check
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon_rows
from odocal.errors import CalibrationError

NOMINAL = WheelGeometry(0.2, 0.2, 0.5)
TRUE = WheelGeometry(0.203, 0.199, 0.52)


def intervals(true: WheelGeometry, n=600, k=10, noise=(0.002, 0.002, 0.002), drift=0.0, seed=0):
    """n consecutive 1 s intervals of k wheel samples; the base motion measured with white
    noise; ``drift`` (rad per interval) a heading drift no wheel geometry explains."""
    rng = np.random.default_rng(seed)
    seg = np.repeat(rng.uniform(-1.0, 1.0, size=(n // 5 + 1, 2)), 5, axis=0)[:n]
    base = rng.uniform(0.5, 2.0, size=(n, 1))
    inc_r = np.repeat(base + seg[:, :1], k, axis=1) / k
    inc_l = np.repeat(base + seg[:, 1:], k, axis=1) / k
    motion = dead_reckon_rows(inc_r, inc_l, true)[:, :, -1].T.copy()
    motion[:, 2] += drift
    motion += rng.standard_normal(motion.shape) * np.asarray(noise)
    start = np.arange(n, dtype=float)
    return start, start + 1.0, inc_r, inc_l, motion


def test_models_recover_what_they_can():
    a, b, r, lft, m = intervals(TRUE, noise=(1e-4, 1e-4, 1e-4))
    full = fit_base_motion("full", r, lft, m, NOMINAL).geometry
    assert full.diameter_right_m == pytest.approx(TRUE.diameter_right_m, rel=1e-3)
    assert full.diameter_left_m == pytest.approx(TRUE.diameter_left_m, rel=1e-3)
    assert full.wheelbase_m == pytest.approx(TRUE.wheelbase_m, rel=1e-3)
    eq = fit_base_motion("equal-diameters", r, lft, m, NOMINAL).geometry
    assert eq.diameter_right_m == eq.diameter_left_m
    sc = fit_base_motion("scale", r, lft, m, NOMINAL).geometry
    assert sc.wheelbase_m == NOMINAL.wheelbase_m and sc.diameter_right_m == sc.diameter_left_m


def test_a_good_calibration_beats_the_nominal_on_held_out_blocks():
    a, b, r, lft, m = intervals(TRUE)
    cal = fit_base_motion("full", r, lft, m, NOMINAL).geometry
    h = heldout_check(a, b, r, lft, m, NOMINAL, cal, chain_s=30.0)
    assert h.calibration_helps and h.preferred == "full"
    assert h.calibrated_final_error_m < 0.5 * h.nominal_final_error_m
    # the full model helps: the restricted ones are not tried
    assert [s.model for s in h.models] == ["full"]
    d = h.as_dict()
    assert d["nominal_final_error_m"] == h.nominal_final_error_m
    assert "helps" in h.verdict()


def test_a_calibration_of_an_already_calibrated_robot_does_not_beat_it():
    a, b, r, lft, m = intervals(NOMINAL, seed=2)
    cal = fit_base_motion("full", r, lft, m, NOMINAL).geometry
    h = heldout_check(a, b, r, lft, m, NOMINAL, cal, chain_s=30.0)
    assert [s.model for s in h.models] == list(MODELS)  # the full one did not help: all tried
    assert not h.calibration_helps
    assert h.calibrated_final_error_m == pytest.approx(h.nominal_final_error_m, rel=0.2)
    if h.preferred is None:
        assert h.verdict().endswith("NO model beats the nominal parameters on data it did not fit")


def test_dropped_intervals_carry_the_chains_but_not_the_fits():
    a, b, r, lft, m = intervals(TRUE, seed=3)
    m_bad = m.copy()
    m_bad[::50, 2] += 0.5  # loop-closure-like jumps
    mask = np.ones(len(a), dtype=bool)
    mask[::50] = False
    cal = fit_base_motion("full", r[mask], lft[mask], m_bad[mask], NOMINAL).geometry
    h = heldout_check(a, b, r, lft, m_bad, NOMINAL, cal, fit_mask=mask, chain_s=30.0)
    assert h.chains >= 20
    # the folds' fits leave the bad intervals out (with them, their 0.5 rad would spoil b)
    assert h.calibration_helps and h.preferred == "full"


def test_too_short_a_log_is_refused():
    a, b, r, lft, m = intervals(TRUE, n=6)
    with pytest.raises(CalibrationError, match="too short for a held-out check"):
        heldout_check(a, b, r, lft, m, NOMINAL, TRUE, folds=4, chain_s=30.0)


def test_the_robust_covariance_of_a_model_covers_the_truth():
    # 40 seeded logs with white noise: the time-block sandwich's 95 % interval of b covers the
    # true wheelbase about 95 % of the time (binomial sd 3.4 %; 5 sd allowed below)
    hits = 0
    for seed in range(40):
        a, b, r, lft, m = intervals(TRUE, n=300, noise=(0.003, 0.003, 0.004), seed=100 + seed)
        fit = fit_base_motion("full", r, lft, m, NOMINAL, a)
        assert fit.stderr is not None and fit.dof == 24
        hits += abs(fit.geometry.wheelbase_m - TRUE.wheelbase_m) < 2.064 * fit.stderr[2]
    assert hits >= 31
