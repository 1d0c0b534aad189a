"""Cluster-robust covariance (calibration.robust_covariance)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration.robust_covariance import cluster_covariance
from odocal.errors import CalibrationError


def test_clustered_errors_the_formal_misses_the_sandwich_holds():
    # y = 2 x + cluster effect + noise, x constant within a cluster: the formal standard
    # error ignores the shared cluster effect; over 400 seeded replicates the robust 95 %
    # interval covers the slope about 95 % of the time, the formal one far less
    rng = np.random.default_rng(7)
    g, per = 30, 20
    clusters = np.repeat(np.arange(g), per)
    cover_robust = cover_formal = 0
    reps = 400
    for _ in range(reps):
        x = np.repeat(rng.standard_normal(g), per)
        y = 2.0 * x + np.repeat(rng.standard_normal(g), per) + 0.3 * rng.standard_normal(g * per)
        slope = float(x @ y / (x @ x))
        res = y - slope * x
        cc = cluster_covariance(-x[:, None], res, clusters)
        formal_se = float(np.sqrt(cc.formal[0, 0]))
        cover_robust += abs(slope - 2.0) < 2.045 * cc.stderr[0]  # t(0.975, 29)
        cover_formal += abs(slope - 2.0) < 1.96 * formal_se
    # binomial sd of a 95 % coverage over 400 replicates: 1.1 %; 4 sd either side
    assert cover_robust / reps == pytest.approx(0.95, abs=0.045)
    assert cover_formal / reps < 0.6
    assert cc.clusters == g and cc.dof == g - 1
    assert cc.inflation()[0] > 2.0


def test_one_cluster_is_refused():
    with pytest.raises(CalibrationError, match="at least 2 clusters"):
        cluster_covariance(np.ones((5, 1)), np.zeros(5), np.zeros(5, dtype=int))


def test_the_sandwich_and_the_formal_covariance_by_hand():
    # m = 6 rows, p = 2 parameters, G = 3 clusters: the formula of the module docstring written
    # out, its small-sample factor c = G/(G-1) (m-1)/(m-p) = 1.5 * 5/4 included
    j = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 2.0], [1.0, 3.0], [1.0, 4.0], [1.0, 6.0]])
    r = np.array([0.3, -0.1, 0.2, -0.4, 0.1, 0.05])
    labels = np.array([7, 7, 2, 2, 9, 9])
    bread = np.linalg.inv(j.T @ j)
    scores = np.array([j[labels == k].T @ r[labels == k] for k in (2, 7, 9)])
    expected = 1.5 * 5 / 4 * bread @ scores.T @ scores @ bread
    cc = cluster_covariance(j, r, labels)
    np.testing.assert_allclose(cc.covariance, expected, rtol=1e-12)
    np.testing.assert_allclose(cc.formal, float(r @ r) / 4 * bread, rtol=1e-12)
    assert (cc.clusters, cc.dof) == (3, 2)


def _two_groups(shift):
    """A straight line fitted to two groups of 6 subclusters (10 rows each); the second group's
    intercept moved by ``shift``; the pooled least-squares fit's Jacobian and residual."""
    rng = np.random.default_rng(3)
    x = rng.uniform(-1.0, 1.0, 120)
    groups = np.repeat([0, 1], 60)
    subs = np.repeat(np.arange(12), 10)
    y = 1.0 + 2.0 * x + shift * groups + 0.1 * rng.standard_normal(120)
    jac = -np.column_stack([np.ones_like(x), x])
    est = np.linalg.lstsq(-jac, y, rcond=None)[0]
    return jac, y - (-jac @ est), est, groups, subs, x, y


def test_groups_that_agree_and_groups_that_do_not():
    from odocal.calibration.robust_covariance import group_consistency

    jac, res, est, groups, subs, x, y = _two_groups(0.0)
    c = group_consistency(jac, res, est, groups, subs, {0: "day 1", 1: "day 2"})
    assert c.groups == ("day 1", "day 2") and c.dof == 1 and c.consistent
    # each group's estimate is its own least-squares line (one Gauss-Newton step is exact here)
    for k in (0, 1):
        own = np.linalg.lstsq(-jac[groups == k], y[groups == k], rcond=None)[0]
        np.testing.assert_allclose(c.estimates[k], own, atol=1e-12)
    # the standard errors by hand: one dispersion per parameter pooled over both groups' six
    # subclusters, from the scores at each group's own line, (6 - 2) / 6 of it expected
    spread, unit = np.zeros(2), np.zeros(2)
    for k in (0, 1):
        sel = groups == k
        bread = np.linalg.inv(jac[sel].T @ jac[sel])
        own = res[sel] - jac[sel] @ (bread @ (jac[sel].T @ res[sel]))
        scores = np.array([jac[sel][subs[sel] == u].T @ own[subs[sel] == u]
                           for u in np.unique(subs[sel])])  # fmt: skip
        spread += ((scores @ bread) ** 2).sum(0)
        unit += np.diag(bread) * (6 - 2) / 6
    np.testing.assert_allclose(c.stderr[0] ** 2, spread / unit * np.diag(
        np.linalg.inv(jac[groups == 0].T @ jac[groups == 0])), rtol=1e-10)  # fmt: skip
    # Cochran's Q and its p-value against F(1, 8), by hand
    assert c.dispersion_dof == 2 * (6 - 2)
    w = 1.0 / c.stderr**2
    mean = (w * c.estimates).sum(0) / w.sum(0)
    q = (w * (c.estimates - mean) ** 2).sum(0)
    np.testing.assert_allclose(c.statistic, q, rtol=1e-12)
    from scipy.stats import f

    np.testing.assert_allclose(c.p_value, f.sf(q, 1, 8), rtol=1e-12)

    # the intercepts 0.11 apart: a p-value between 0.001 and 0.01 (the verdict's threshold)
    jac, res, est, groups, subs, *_ = _two_groups(0.11)
    c = group_consistency(jac, res, est, groups, subs)
    assert c.groups == ("0", "1") and c.p_value[0] < 0.01 and not c.consistent
    # a group of 2 subclusters is left out: one group remains, no verdict
    subs2 = np.where(groups == 1, 100 + subs % 2, subs)
    assert group_consistency(jac, res, est, groups, subs2) is None


@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_a_group_that_cannot_pin_a_parameter_is_left_out_of_the_own_covariance_check():
    """pooled=False: a group whose two columns are equal to 1e-12 (its J^T J near singular) got
    a negative variance, and numpy's "invalid value in sqrt" leaked onto design --route scan's
    stderr; the group is left out as a singular one is."""
    from odocal.calibration.robust_covariance import group_consistency

    rng = np.random.default_rng(0)
    good = rng.standard_normal((120, 3))  # groups 0 and 1: six subclusters each
    a = rng.standard_normal(40)
    bad = np.column_stack([a, a * (1 + 1e-12) + 1e-15 * rng.standard_normal(40),
                           rng.standard_normal(40)])  # fmt: skip
    jac = np.vstack([good, bad])
    res = 0.1 * rng.standard_normal(160)
    est = np.zeros(3)
    groups = np.repeat([0, 1, 2], [60, 60, 40])
    subs = np.concatenate([np.repeat(np.arange(12), 10), 100 + np.repeat(np.arange(4), 10)])
    c = group_consistency(jac, res, est, groups, subs, pooled=False)
    assert c is not None and c.groups == ("0", "1")
    assert np.all(np.isfinite(c.stderr))


def test_groups_far_apart_are_inconsistent_whatever_their_number_of_subclusters():
    # each group's variance from residuals at its own estimate: taken at the pooled ones (the
    # bug this catches) it grew with the disagreement and Q stayed below about 2 (G_s - 1), so
    # two groups of 3 subclusters 1000 noise sd apart were "consistent"
    from odocal.calibration.robust_covariance import group_consistency

    rng = np.random.default_rng(3)
    x = rng.uniform(-1.0, 1.0, 120)
    groups = np.repeat([0, 1], 60)
    subs = 100 * groups + (np.arange(120) % 60) // 20  # 3 subclusters per group
    y = 1.0 + 2.0 * x + 100.0 * groups + 0.1 * rng.standard_normal(120)  # 1000 noise sd apart
    jac = -np.column_stack([np.ones_like(x), x])
    est = np.linalg.lstsq(-jac, y, rcond=None)[0]
    c = group_consistency(jac, y + jac @ est, est, groups, subs)
    assert not c.consistent


def test_groups_that_agree_are_called_inconsistent_at_most_at_the_stated_rate():
    # 300 logs of 4 groups of 4 subclusters of 10 rows, a random effect per subcluster on top
    # of white noise, the groups agreeing: p < 0.01 for at most 3 % of them per parameter
    # (1 % expected; 3 % is 3.5 binomial standard errors above it); a shift of 4 subcluster
    # standard deviations in one group is found in most logs
    from odocal.calibration.robust_covariance import group_consistency

    rng = np.random.default_rng(0)

    def p_values(shift):
        x = rng.uniform(-1.0, 1.0, 160)
        groups, subs = np.repeat(np.arange(4), 40), np.repeat(np.arange(16), 10)
        y = 1.0 + 2.0 * x + 0.1 * rng.standard_normal(160) + 0.1 * rng.standard_normal(16)[subs]
        y += shift * (groups == 0)
        jac = -np.column_stack([np.ones_like(x), x])
        est = np.linalg.lstsq(-jac, y, rcond=None)[0]
        return group_consistency(jac, y + jac @ est, est, groups, subs).p_value

    agree = np.array([p_values(0.0) for _ in range(300)])
    assert np.all((agree < 0.01).mean(axis=0) <= 0.03)
    apart = np.array([p_values(0.4) for _ in range(50)])
    assert (apart[:, 0] < 0.01).mean() > 0.5


def test_time_blocks_of_one_run_keep_each_group_s_own_covariance():
    # pooled False (subclusters that are time blocks of one run, whose random-walk residuals
    # would make a pooled dispersion too small): each group's cluster-robust covariance at the
    # pooled residuals, Q against chi-square
    from scipy.stats import chi2

    from odocal.calibration.robust_covariance import cluster_covariance, group_consistency

    jac, res, est, groups, subs, *_ = _two_groups(0.05)
    c = group_consistency(jac, res, est, groups, subs, pooled=False)
    for k in (0, 1):
        sel = groups == k
        own = cluster_covariance(jac[sel], res[sel], subs[sel]).stderr
        np.testing.assert_allclose(c.stderr[k], own, rtol=1e-12)
    np.testing.assert_allclose(c.p_value, chi2.sf(c.statistic, 1), rtol=1e-12)
    assert c.dispersion_dof == 0


def test_the_cluster_jackknife_is_the_exact_delete_one_cluster_jackknife_of_least_squares():
    # for a linear least-squares fit one Gauss-Newton step from the full estimate is the exact
    # refit without the cluster, so the one-step jackknife equals the refitting one
    from odocal.calibration.robust_covariance import cluster_jackknife_covariance

    rng = np.random.default_rng(7)
    x = rng.normal(size=(120, 3))
    groups = np.repeat(np.arange(12), 10)
    y = x @ [1.0, -2.0, 0.5] + rng.normal(size=120) + rng.normal(size=12)[groups]
    beta = np.linalg.lstsq(x, y, rcond=None)[0]
    cc = cluster_jackknife_covariance(x, x @ beta - y, groups)
    refits = np.array(
        [np.linalg.lstsq(x[groups != g], y[groups != g], rcond=None)[0] for g in range(12)]
    )
    dev = refits - refits.mean(axis=0)
    assert cc.covariance == pytest.approx(11 / 12 * dev.T @ dev, rel=1e-9)
    assert cc.clusters == 12 and cc.dof == 11
