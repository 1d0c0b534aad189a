"""Standard errors that hold when residuals are correlated and the model is not exact.

A least-squares fit's formal covariance, s^2 (J^T J)^-1, assumes independent residuals that the
model explains up to white noise. Real logs break both: a wheel that slips for a second, a heading
drift the model cannot express, a SLAM pose that is off for a stretch, a session that differs
from the next. Those residuals come in runs, and the formal standard errors come out 3-10 times
too small (OptiOdom, MIT CSAIL: docs/uncertainty.md).

The cluster-robust ("sandwich") covariance keeps the estimate and replaces the middle of the
formula by what the residuals did, summed within clusters that are independent of each other
(runs, or contiguous time blocks of one log):

    cov = c (J^T J)^-1 [ sum_g (J_g^T r_g)(J_g^T r_g)^T ] (J^T J)^-1,
    c = G / (G - 1) (m - 1) / (m - p)

with J and r the weighted Jacobian and residual at the solution (m rows, p parameters) and g
the G clusters (Liang & Zeger 1986; the small-sample factor c as Stata's). Correlation inside a
cluster and a model mismatch that varies between clusters both widen it. Its degrees of
freedom are G - 1: intervals use Student's t with G - 1, so a log cut into few blocks gets wide
intervals rather than falsely narrow ones.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import CalibrationError

__all__ = ["ClusterCovariance", "cluster_covariance", "cluster_jackknife_covariance"]


@dataclass(frozen=True)
class ClusterCovariance:
    """A cluster-robust covariance.

    Attributes
    ----------
    covariance : ndarray, shape (p, p)
        In the units of the parameters, squared.
    clusters : int
        Independent clusters G behind it.
    dof : int
        Degrees of freedom of its standard errors (G - 1).
    formal : ndarray, shape (p, p)
        The formal s^2 (J^T J)^-1 on the same residuals, for comparison.
    """

    covariance: np.ndarray
    clusters: int
    dof: int
    formal: np.ndarray

    @property
    def stderr(self) -> np.ndarray:
        """Square roots of the diagonal, shape (p,)."""
        return np.sqrt(np.diag(self.covariance))

    def inflation(self) -> np.ndarray:
        """Robust over formal standard error per parameter, shape (p,)."""
        return self.stderr / np.sqrt(np.diag(self.formal))


def cluster_covariance(
    jacobian: np.ndarray,
    residual: np.ndarray,
    clusters: np.ndarray,
    curvature: np.ndarray | None = None,
) -> ClusterCovariance:
    """The cluster-robust covariance (module docstring).

    Parameters
    ----------
    jacobian : ndarray, shape (m, p)
        Derivatives of the weighted residuals with respect to the parameters at the solution.
    residual : ndarray, shape (m,)
        Weighted residuals at the solution.
    clusters : ndarray of int, shape (m,)
        Cluster of each residual row (any integer labels).
    curvature : ndarray, shape (m,), optional
        For an M-estimate (a robust loss): give ``residual`` as the loss's psi(r) and here its
        derivative psi'(r); the bread is then sum psi'(r_i) J_i J_i^T (default: least squares,
        psi(r) = r, psi' = 1).

    Raises
    ------
    CalibrationError
        Fewer than 2 clusters, or a singular J^T J.
    """
    j = np.asarray(jacobian, dtype=float)
    r = np.asarray(residual, dtype=float)
    labels, g = np.unique(np.asarray(clusters), return_inverse=True)
    m, p = j.shape
    n_g = len(labels)
    if n_g < 2:
        raise CalibrationError("a cluster-robust covariance needs at least 2 clusters")
    jtj = j.T @ j if curvature is None else (j * np.asarray(curvature, float)[:, None]).T @ j
    try:
        bread = np.linalg.inv(jtj)
    except np.linalg.LinAlgError:
        raise CalibrationError("the parameters are not identified (singular J^T J)") from None
    scores = np.zeros((n_g, p))
    np.add.at(scores, g, j * r[:, None])
    meat = scores.T @ scores
    c = n_g / (n_g - 1) * (m - 1) / max(m - p, 1)
    cov = c * bread @ meat @ bread
    s2 = float(r @ r) / max(m - p, 1)
    return ClusterCovariance(0.5 * (cov + cov.T), n_g, n_g - 1, s2 * bread)


@dataclass(frozen=True)
class Consistency:
    """Do the groups of a log (its data sets, or its time halves) agree within their own
    uncertainty?

    Each group's estimate is the pooled one moved by a Gauss-Newton step on the group's rows
    alone. Its variance is phi_i [(J_g^T J_g)^-1]_ii per parameter i, with one dispersion phi_i
    pooled over the subclusters (runs, time blocks) of every group: the sum over groups of
    sum_c ((J_g^T J_g)^-1 s_c)_i^2, the subclusters' scores s_c = J_c^T e_c at the group's own
    estimate, over the sum of [(J_g^T J_g)^-1]_ii (C_g - p) / C_g (a group's own few subclusters
    cannot estimate its covariance: at its own estimate their scores sum to zero). Cochran's
    Q = sum_g (theta_g - mean)^2 / var_g per parameter (the mean weighted by 1 / var_g); Q / (G -
    1) is compared with F(G - 1, sum_g (C_g - p)). Checked on simulated logs that agree (at most
    1.25 % below 0.01 over linear models with white and clustered noise, 0 of 120 trajectory
    logs of 4 data sets of 4 runs) and on the OptiOdom robot, whose June and December wheelbases
    differ by 0.8 mm (docs/uncertainty.md). Taken at the pooled residuals instead, a group's
    variance grew with its disagreement and no disagreement showed.

    Attributes
    ----------
    groups : tuple of str
        The groups compared.
    estimates : ndarray, shape (G, p)
        Each group's estimate.
    stderr : ndarray, shape (G, p)
        Its standard error (the pooled dispersion's).
    statistic : ndarray, shape (p,)
        Q per parameter.
    dof : int
        G - 1.
    p_value : ndarray, shape (p,)
        Of Q / (G - 1) against F(G - 1, ``dispersion_dof``).
    consistent : bool
        No parameter's p-value below 0.01.
    dispersion_dof : int
        Degrees of freedom of the pooled dispersion, sum_g (C_g - p).
    """

    groups: tuple[str, ...]
    estimates: np.ndarray
    stderr: np.ndarray
    statistic: np.ndarray
    dof: int
    p_value: np.ndarray
    consistent: bool
    dispersion_dof: int = 0

    def as_dict(self, names: tuple[str, ...]) -> dict:
        """JSON-ready, parameters by ``names``."""
        return {
            "groups": list(self.groups),
            "dof": self.dof,
            "dispersion_dof": self.dispersion_dof,
            "consistent": self.consistent,
            "statistic": dict(zip(names, (float(q) for q in self.statistic), strict=True)),
            "p_value": dict(zip(names, (float(v) for v in self.p_value), strict=True)),
            "estimates": {
                g: dict(zip(names, (float(v) for v in row), strict=True))
                for g, row in zip(self.groups, self.estimates, strict=True)
            },
            "stderr": {
                g: dict(zip(names, (float(v) for v in row), strict=True))
                for g, row in zip(self.groups, self.stderr, strict=True)
            },
        }


def group_consistency(
    jacobian: np.ndarray,
    residual: np.ndarray,
    estimate: np.ndarray,
    groups: np.ndarray,
    subclusters: np.ndarray,
    names: dict[int, str] | None = None,
    *,
    pooled: bool = True,
) -> Consistency | None:
    """The agreement of the groups of a least-squares fit (:class:`Consistency`): ``jacobian``
    (m, p) and ``residual`` (m,) at the pooled ``estimate`` (p,); ``groups`` and
    ``subclusters`` (m,) integer labels per row. Groups with fewer than 3 subclusters or a
    singular information are left out; None when fewer than 2 groups remain or no group has
    more subclusters than parameters.

    ``pooled`` False: each group's own cluster-robust covariance at the pooled residuals and Q
    against chi-square (the former check, kept where the subclusters are time blocks of one run:
    their random-walk residuals make the pooled dispersion too small, 13 false warnings in 40
    simulated single-run logs against 4; conservative instead, since a group's disagreement
    inflates its own standard error)."""
    if not pooled:
        return _own_covariance_consistency(jacobian, residual, estimate, groups, subclusters, names)
    from scipy.stats import f as f_dist  # here: a slow import

    j = np.asarray(jacobian, dtype=float)
    r = np.asarray(residual, dtype=float)
    p_dim = j.shape[1]
    labels = [int(g) for g in np.unique(groups)]
    rows, est, unit, spread, dfs, sizes, kept = [], [], [], [], [], [], []
    for g in labels:
        sel = np.asarray(groups) == g
        subs = np.asarray(subclusters)[sel]
        n_sub = len(np.unique(subs))
        if n_sub < 3:
            continue
        try:
            bread = np.linalg.inv(j[sel].T @ j[sel])
        except np.linalg.LinAlgError:
            continue
        step = bread @ (j[sel].T @ r[sel])
        own = r[sel] - j[sel] @ step  # the group's residuals at its own estimate
        _, sub_index = np.unique(subs, return_inverse=True)
        scores = np.zeros((n_sub, p_dim))
        np.add.at(scores, sub_index, j[sel] * own[:, None])
        rows.append(g)
        est.append(np.asarray(estimate, dtype=float) - step)
        unit.append(np.diag(bread))
        spread.append(((scores @ bread) ** 2).sum(axis=0))
        dfs.append(max(n_sub - p_dim, 0))
        sizes.append(n_sub)
        kept.append(names.get(g, str(g)) if names else str(g))
    df_pooled = sum(dfs)
    if len(rows) < 2 or df_pooled < 1:
        return None
    # one dispersion per parameter, pooled over every group's subclusters: a group's own few
    # subclusters cannot estimate its covariance (at its own estimate their scores sum to zero)
    share = np.array(dfs, dtype=float) / np.array(sizes, dtype=float)  # E[spread] / (phi unit)
    phi = np.array(spread).sum(axis=0) / (np.array(unit) * share[:, None]).sum(axis=0)
    e, s = np.array(est), np.sqrt(phi * np.array(unit))
    exact = ~(phi > 0)  # residuals without scatter (noise-free data): agreement is equality
    w = 1.0 / np.where(exact, 1.0, s) ** 2
    mean = (w * e).sum(axis=0) / w.sum(axis=0)
    q = (w * (e - mean) ** 2).sum(axis=0)
    if exact.any():
        agree = np.ptp(e, axis=0) <= 1e-12 * np.abs(mean)
        q[exact] = np.where(agree[exact], 0.0, np.inf)
    dof = len(rows) - 1
    p = f_dist.sf(q / dof, dof, df_pooled)
    return Consistency(tuple(kept), e, s, q, dof, p, bool(np.all(p >= 0.01)), df_pooled)


def _own_covariance_consistency(
    jacobian: np.ndarray,
    residual: np.ndarray,
    estimate: np.ndarray,
    groups: np.ndarray,
    subclusters: np.ndarray,
    names: dict[int, str] | None,
) -> Consistency | None:
    """:func:`group_consistency` with ``pooled`` False."""
    from scipy.stats import chi2  # here: a slow import

    j = np.asarray(jacobian, dtype=float)
    r = np.asarray(residual, dtype=float)
    labels = [int(g) for g in np.unique(groups)]
    rows, est, err, kept = [], [], [], []
    for g in labels:
        sel = np.asarray(groups) == g
        subs = np.asarray(subclusters)[sel]
        if len(np.unique(subs)) < 3:
            continue
        try:
            cc = cluster_covariance(j[sel], r[sel], subs)
            step = np.linalg.solve(j[sel].T @ j[sel], j[sel].T @ r[sel])
        except (CalibrationError, np.linalg.LinAlgError):
            continue
        if not np.all(np.diag(cc.covariance) > 0):  # a group that cannot pin a parameter
            continue
        rows.append(g)
        est.append(np.asarray(estimate, dtype=float) - step)
        err.append(cc.stderr)
        kept.append(names.get(g, str(g)) if names else str(g))
    if len(rows) < 2:
        return None
    e, s = np.array(est), np.array(err)
    w = 1.0 / np.maximum(s, 1e-300) ** 2
    mean = (w * e).sum(axis=0) / w.sum(axis=0)
    q = (w * (e - mean) ** 2).sum(axis=0)
    dof = len(rows) - 1
    p = chi2.sf(q, dof)
    return Consistency(tuple(kept), e, s, q, dof, p, bool(np.all(p >= 0.01)))


def cluster_jackknife_covariance(
    jacobian: np.ndarray,
    residual: np.ndarray,
    clusters: np.ndarray,
    curvature: np.ndarray | None = None,
) -> ClusterCovariance:
    """The delete-one-cluster jackknife covariance ("CR3"), from one Gauss-Newton step per
    deleted cluster: with H = sum_i w_i J_i J_i^T (w_i = ``curvature``, default 1), H_g its
    part from cluster g and s_g = sum_{i in g} J_i r_i, deleting g moves the estimate by
    d_g = (H - H_g)^-1 s_g, and

        cov = (G - 1) / G sum_g (d_g - mean d)(d_g - mean d)^T.

    Arguments as :func:`cluster_covariance`. Unlike that sandwich it accounts for each cluster's
    leverage (a cluster that pulls the estimate hard also shrinks its own residuals), so it is
    larger with few or unequal clusters: on simulated skid-steer logs with slip correlated over
    seconds its 95 % intervals covered 93-96 % where the sandwich's covered 89-92 %
    (tests/calibration/test_skid_steer.py). A cluster whose deletion leaves H singular makes it
    fail (CalibrationError)."""
    j = np.asarray(jacobian, dtype=float)
    r = np.asarray(residual, dtype=float)
    w = np.ones(len(r)) if curvature is None else np.asarray(curvature, dtype=float)
    labels, g = np.unique(np.asarray(clusters), return_inverse=True)
    m, p = j.shape
    n_g = len(labels)
    if n_g < 2:
        raise CalibrationError("a cluster jackknife needs at least 2 clusters")
    h_g = np.zeros((n_g, p, p))
    np.add.at(h_g, g, (j * w[:, None])[:, :, None] * j[:, None, :])
    scores = np.zeros((n_g, p))
    np.add.at(scores, g, j * r[:, None])
    h = h_g.sum(axis=0)
    try:
        d = np.linalg.solve(h[None, :, :] - h_g, scores[:, :, None])[:, :, 0]
        bread = np.linalg.inv(h)
    except np.linalg.LinAlgError:
        raise CalibrationError(
            "the parameters are not identified without one of the clusters"
        ) from None
    dev = d - d.mean(axis=0)
    cov = (n_g - 1) / n_g * dev.T @ dev
    s2 = float(r @ r) / max(m - p, 1)
    return ClusterCovariance(0.5 * (cov + cov.T), n_g, n_g - 1, s2 * bread)
