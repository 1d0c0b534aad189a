"""The circle fit (calibration.circle_fit): exact points, batches, the known bias of the
algebraic fits on arcs, degenerate points."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.calibration.circle_fit import fit_circle
from odocal.core.model import ModelError


@pytest.mark.parametrize("algebraic", ["kasa", "pratt"])
@pytest.mark.parametrize("geometric", [False, True])
@pytest.mark.parametrize("span", [2 * math.pi, math.pi / 2])
def test_circle_fit_exact_points(algebraic, geometric, span):
    t = np.linspace(0.3, 0.3 + span, 40)
    pts = np.c_[1.3 + 2.5 * np.cos(t), -0.7 + 2.5 * np.sin(t)]
    f = fit_circle(pts, algebraic, geometric)
    assert f.center_x_m == pytest.approx(1.3, abs=1e-10)
    assert f.center_y_m == pytest.approx(-0.7, abs=1e-10)
    assert f.radius_m == pytest.approx(2.5, abs=1e-10)
    assert f.rms_residual_m < 1e-10


def test_circle_fit_batched_matches_single():
    rng = np.random.default_rng(3)
    t = np.linspace(0, 2 * math.pi, 60)
    pts = np.c_[np.cos(t), np.sin(t)] * np.array([[1.0], [3.0]])[:, :, None] / 1.0
    pts = pts + 0.01 * rng.standard_normal(pts.shape)
    batch = fit_circle(pts)
    for i in range(2):
        single = fit_circle(pts[i])
        assert batch.radius_m[i] == pytest.approx(single.radius_m, rel=1e-12)


def test_circle_fit_noisy_semicircle_bias():
    # 400 seeded fits of 100 points on a semicircle of radius 2 m, sigma 2 cm per coordinate.
    # The standard error of the mean radius is std/sqrt(400) ~ 0.24 mm; the geometric and Pratt
    # fits must be unbiased to within 3 standard errors, while Kasa's known under-estimate of the
    # radius on arcs shows (about -1 mm here, more than 3 standard errors).
    rng = np.random.default_rng(7)
    t = np.linspace(0, math.pi, 100)
    pts = np.c_[2 * np.cos(t), 2 * np.sin(t)] + rng.normal(0, 0.02, (400, 100, 2))
    for algebraic, geometric in (("pratt", True), ("pratt", False)):
        r = fit_circle(pts, algebraic, geometric).radius_m
        sem = r.std(ddof=1) / math.sqrt(len(r))
        assert abs(r.mean() - 2.0) < 3 * sem
    r = fit_circle(pts, "kasa", False).radius_m
    assert r.mean() - 2.0 < -3 * r.std(ddof=1) / math.sqrt(len(r))


def test_circle_fit_rejects_degenerate_points():
    with pytest.raises(ModelError, match="at least 3"):
        fit_circle([[0, 0], [1, 1]])
    with pytest.raises(ModelError, match="circle"):
        fit_circle([[0, 0], [1, 1], [2, 2], [3, 3]])
    with pytest.raises(ModelError, match="finite"):
        fit_circle([[0, 0], [1, np.nan], [2, 0]])
