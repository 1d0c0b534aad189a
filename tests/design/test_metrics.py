"""The closed-form design metrics (design.metrics): the leg heading errors of model.md, the
paper's 91 % systematic share, agreement with the simulator."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.model import NonSystematicError
from odocal.core.simulate import drive
from odocal.core.tracks import straight_line
from odocal.design import (
    leg_heading_noise_rad,
    leg_heading_systematic_rad,
    systematic_share,
)
from odocal.presets import PRESETS

FIG3 = PRESETS["paper-fig3"]
FIG5 = PRESETS["paper-fig5"]


def test_leg_heading_errors_match_model_md_closed_forms():
    L = np.array([0.5, 4.0, 10.0])
    s = FIG3.systematic
    b_n = FIG3.nominal.wheelbase_m
    beta = 2 * L * (s.E_d - 1) / ((s.E_d + 1) * s.E_b * b_n)
    np.testing.assert_allclose(leg_heading_systematic_rad(FIG3, L), beta, rtol=1e-12)
    sigma = np.sqrt(2e-6 * L) / (s.E_b * b_n)
    np.testing.assert_allclose(leg_heading_noise_rad(FIG3, L), sigma, rtol=1e-12)


def test_systematic_share_at_4m_is_the_papers_91_percent():
    # hand calculation: beta = -0.0101412 rad, sigma^2 = 5.1370e-5 rad^2, n = 5
    beta = leg_heading_systematic_rad(FIG3, 4.0)
    sigma = leg_heading_noise_rad(FIG3, 4.0)
    assert float(beta) == pytest.approx(-0.0101412, rel=1e-5)
    share = systematic_share(beta, sigma, 5)
    assert float(share) == pytest.approx(beta**2 / (beta**2 + sigma**2 / 5), rel=1e-12)
    assert float(share) == pytest.approx(0.9092, abs=5e-4)
    assert systematic_share(0.0, 0.1, 5) == 0.0 and systematic_share(0.1, 0.0, 5) == 1.0


def test_leg_heading_metrics_match_the_simulator():
    # noise-free: the final heading of a straight leg is beta exactly
    L = 3.0
    res = drive(straight_line(L), FIG5.true_geometry, FIG5.nominal, NonSystematicError(), 1, None)
    assert res.errors[0, 2] == pytest.approx(float(leg_heading_systematic_rad(FIG5, L)), rel=1e-9)
    # with noise: the std over N runs; relative std error of a sample std is 1/sqrt(2(N-1)),
    # 5 of them is the tolerance
    n = 4000
    res = drive(
        straight_line(L), FIG5.true_geometry, FIG5.nominal, FIG5.nonsystematic, n,
        np.random.default_rng(1), steps_per_segment=50,
    )  # fmt: skip
    std = res.errors[:, 2].std(ddof=1)
    assert std == pytest.approx(float(leg_heading_noise_rad(FIG5, L)), rel=5 / math.sqrt(2 * n))
