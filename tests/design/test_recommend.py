"""The recommendation rule (design.recommend) on synthetic summaries: the knee of the curve, the
tolerance, significance, shapes, the residual criterion, the bootstrap spread of the pick."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from odocal.design import (
    Candidate,
    recommend,
)
from odocal.design.recommend import compare
from odocal.errors import ModelError


def cand(side, mean, std=0.01, n=800, sides=4):
    """A candidate with only the required fields (the optional ones NaN, as a source that does
    not compute them leaves them)."""
    return Candidate(
        sides=sides, side_m=side, travel_m=sides * side, systematic_share=0.9,
        post_error_mean_m=mean, post_error_std_m=std, post_error_ci95_m=(0.0, 1.0),
        E_b_mean=1.0, E_b_std=0.0, E_d_mean=1.0, E_d_std=0.0, trials=n,
    )  # fmt: skip


def test_rule_picks_the_knee_of_a_falling_then_flat_curve():
    means = [1.0, 0.5, 0.3, 0.3, 0.3, 0.3]
    cs = [cand(0.5 * (i + 1), m) for i, m in enumerate(means)]
    rec = recommend(cs)
    assert rec.index == 2
    assert rec.beaten_by == {0: 1, 1: 2}


def test_rule_ignores_gains_within_the_tolerance():
    # 0.295 and 0.29 are significantly smaller than 0.30 (t about 10 and 20) but by < 5 %
    cs = [cand(1, 0.30), cand(2, 0.295), cand(3, 0.29)]
    assert recommend(cs, tolerance=0.05).index == 0
    # without tolerance the larger ones win
    assert recommend(cs, tolerance=0.0).index == 2
    # 10 % better beats 5 % tolerance
    cs = [cand(1, 0.30), cand(2, 0.27)]
    assert recommend(cs, tolerance=0.05).index == 1


def test_rule_needs_significance():
    # 20 % better on average, but with 5 samples and a large spread: not significant
    cs = [cand(1, 0.30, std=0.2, n=5), cand(2, 0.24, std=0.2, n=5)]
    assert recommend(cs).index == 0
    assert recommend([cand(1, 0.30, n=5), cand(2, 0.24, n=5)]).index == 1


def test_rule_test_is_welch_against_the_scaled_candidate():
    from scipy import stats

    cs = [cand(1, 0.30, std=0.02, n=50), cand(2, 0.28, std=0.03, n=40)]
    comp = compare(cs, 1, 0, alpha=0.05, tolerance=0.05)
    ref = stats.ttest_ind_from_stats(
        0.28, 0.03, 40, 0.95 * 0.30, 0.95 * 0.02, 50, equal_var=False, alternative="less"
    )
    assert comp.rule.t == pytest.approx(ref.statistic, rel=1e-12)
    assert comp.rule.p_less == pytest.approx(ref.pvalue, rel=1e-9)
    assert comp.test.mean_difference == pytest.approx(-0.02)
    assert comp.significant == (ref.pvalue < 0.05)


def test_rule_orders_by_travel_and_compares_shapes():
    # an octagon of 2 m travel and a square of 4 m travel: the square is larger
    cs = [cand(1.0, 0.2, sides=4), cand(0.25, 0.3, sides=8)]
    rec = recommend(cs)
    assert rec.index == 0 and rec.beaten_by == {1: 0}
    assert rec.per_shape == {4: 0, 8: 1}
    # equal travel, different shape: the better one is taken
    cs = [cand(1.0, 0.3, sides=4), cand(0.5, 0.2, sides=8)]
    assert recommend(cs).index == 1


def test_rule_neighbour_table_is_laid_out_like_the_papers_tables():
    cs = [cand(2, 0.5), cand(4, 0.3), cand(6, 0.3)]
    rec = recommend(cs)
    assert rec.index == 1
    assert [(c.other, c.reference) for c in rec.neighbours] == [(0, 1), (2, 1)]
    assert rec.neighbours[0].test.mean_difference == pytest.approx(0.2)  # 2 m minus 4 m
    assert rec.neighbours[0].test.t > 0


def test_rule_on_the_residual_criterion():
    cs = [
        dataclasses.replace(cand(side, 0.30), residual_error_mean_m=r, residual_error_std_m=0.01)
        for side, r in zip((1, 2, 3), [0.05, 0.03, 0.03], strict=True)
    ]
    assert recommend(cs).index == 0
    rec = recommend(cs, criterion="residual")
    assert rec.index == 1 and rec.criterion == "residual"
    assert rec.neighbours[0].test.mean_difference == pytest.approx(0.02)
    with pytest.raises(ModelError, match="criterion"):
        recommend(cs, criterion="nope")


def test_rule_skips_unusable_candidates_and_rejects_bad_parameters():
    cs = [cand(1, math.nan), cand(2, 0.3)]
    assert recommend(cs).index == 1
    with pytest.raises(ModelError, match="usable"):
        recommend([cand(1, math.nan)])
    with pytest.raises(ModelError, match="alpha"):
        recommend([cand(1, 0.3)], alpha=1.0)
    with pytest.raises(ModelError, match="tolerance"):
        recommend([cand(1, 0.3)], tolerance=1.0)


@pytest.mark.parametrize("paired", [True, False])
def test_pick_spread_is_the_rule_applied_to_each_resample(paired):
    """The bootstrap spread of the pick computes every pair's moments at once; each resample must
    pick what the rule itself (recommend) picks on candidates made of the resampled trials,
    failed trials (NaN) included."""
    from types import SimpleNamespace

    from odocal.design.recommend import pick_spread, recommend

    rng = np.random.default_rng(2)
    T = 60
    common = rng.standard_normal(T)
    X = []
    for k in range(8):  # errors that fall with the size, with common random numbers
        x = np.abs(0.01 * (1 + np.exp(-k / 2)) + 0.004 * common + 0.003 * rng.standard_normal(T))
        if k == 3:
            x[[4, 17]] = np.nan
        X.append(x)

    def candidates(samples):
        out = []
        for k, x in enumerate(samples):
            f = x[np.isfinite(x)]
            side = 0.5 + 0.5 * k
            out.append(
                SimpleNamespace(
                    sides=4, side_m=side, travel_m=4 * side, trials=f.size,
                    post_error_mean_m=f.mean(), post_error_std_m=f.std(ddof=1),
                    post_errors_m=x,
                )
            )  # fmt: skip
        return out

    spread = pick_spread(candidates(X), np.random.default_rng(7), paired=paired, resamples=40)
    # the same resamples, drawn the same way, through the rule itself
    draw, counts = np.random.default_rng(7), {}
    Xa = np.array(X)
    for _ in range(40):
        if paired:
            Xb = Xa[:, draw.integers(0, T, T)]
        else:
            Xb = np.take_along_axis(Xa, draw.integers(0, T, Xa.shape), axis=1)
        pick = recommend(candidates(list(Xb)), paired=paired).index
        counts[pick] = counts.get(pick, 0) + 1
    assert dict(spread) == {i: k / 40 for i, k in counts.items()}
    assert len(spread) > 1  # a spread, not a certainty: the test compares real decisions
