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
