"""Choosing the test-track size from candidate summaries (docs/design.md, "The recommendation").

Rule: order the candidates by total travel (then by number of sides). Candidate C is *accepted*
when no other candidate D of larger travel (or of equal travel and another shape) beats it by
more than the tolerance. The recommendation is the accepted candidate of smallest travel (the
largest candidate is always accepted, so there is always one).

"D beats C by more than the tolerance" means mean_D < (1 - tolerance) mean_C, decided by the
kind of statistics the candidates carry:

- ``exact`` (expected values, e.g. the analytic design; ``trials`` is None): the means compared
  directly. This is the limit of the tests below for infinitely many trials.
- ``paired`` (Monte-Carlo candidates simulated with common random numbers, so that trial i of
  every candidate shares its random numbers): the one-sided paired t-test of
  d_i = e_D,i - (1 - tol) e_C,i, H1: mean(d) < 0, rejected at level alpha.
- ``welch`` (independent samples, summary statistics only): the one-sided Welch test of
  H0: mean_D >= (1 - tol) mean_C against H1: mean_D < (1 - tol) mean_C. Scaling sample C by
  (1 - tol) scales its mean and std, so t = (m_D - (1-tol) m_C) / sqrt(s_D^2/n_D +
  (1-tol)^2 s_C^2/n_C), with Welch-Satterthwaite df.

The table reported beside the recommendation is laid out like the paper's Tables 2 and 3: the
recommended track against its neighbours of the same shape (next smaller, next larger), with the
plain two-sided test (any difference), the rule's one-sided test and its verdict.

:func:`pick_spread` measures how stable the pick itself is: the rule applied to bootstrap
resamples of the trials (jointly for paired candidates), and the share of resamples that pick
each candidate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from typing import Literal, get_args

import numpy as np

from ..core.model import ModelError
from ..core.stats import TTest, student_t_quantile, student_t_sf, ttest_from_stats, ttest_paired
from .result import rounded
from .spec import CRITERIA, Criterion

__all__ = [
    "CRITERIA",
    "TESTS",
    "Test",
    "Comparison",
    "Recommendation",
    "Pick",
    "Stability",
    "recommend",
    "other_criterion",
    "compare",
    "pick_spread",
    "spread_range",
    "stability_of",
]

#: How "better by more than the tolerance" is decided (module docstring).
Test = Literal["exact", "paired", "welch"]
TESTS: tuple[Test, ...] = get_args(Test)

_TRAVEL_RTOL = 1e-9


@dataclass(frozen=True)
class Comparison:
    """One row of a t-test table: candidate ``other`` against candidate ``reference``.

    ``test`` is the plain two-sided test of other against reference (any difference; mean
    difference = other - reference), ``rule`` the one-sided tolerance test of the recommendation
    rule (H1: mean_other < (1 - tolerance) mean_reference); both None for ``kind`` 'exact'.
    ``significant``: the rule's verdict, "other is better by more than the tolerance".
    """

    other: int
    reference: int
    test: TTest | None
    rule: TTest | None
    significant: bool
    kind: Test = "welch"
    mean_difference: float = math.nan


@dataclass(frozen=True)
class Recommendation:
    """The chosen candidate and the evidence.

    Attributes
    ----------
    index : int
        Index of the recommended candidate in the list given to :func:`recommend`.
    alpha, tolerance : float
        Significance level and relative tolerance of the rule.
    neighbours : tuple of Comparison
        The recommended track against its same-shape neighbours (the Tables 2 and 3 layout).
    beaten_by : dict
        For each smaller candidate index, the index of a larger candidate that beats it
        significantly (why it was not chosen).
    per_shape : dict
        Number of sides -> index of the candidate the rule picks among that shape alone.
    criterion : str
        'error' or 'residual' (see CRITERIA); the tests compare that quantity.
    test : str
        'exact', 'paired' or 'welch' (see TESTS).
    spread : tuple of (int, float)
        Candidate index and the share of bootstrap resamples of the trials whose pick it is,
        most frequent first (empty when not measured; see :func:`pick_spread`).
    resamples : int
        Number of bootstrap resamples behind ``spread``.
    """

    index: int
    alpha: float
    tolerance: float
    neighbours: tuple[Comparison, ...]
    beaten_by: dict[int, int]
    per_shape: dict[int, int]
    criterion: Criterion = "error"
    test: Test = "welch"
    spread: tuple[tuple[int, float], ...] = ()
    resamples: int = 0


def _mean_std(c) -> tuple[float, float]:
    return c.post_error_mean_m, c.post_error_std_m


def _usable(c) -> bool:
    m, s = _mean_std(c)
    if not math.isfinite(m):
        return False
    if c.trials is None:
        return True
    return math.isfinite(s) and c.trials >= 2 and s >= 0


def _samples(c) -> np.ndarray | None:
    x = getattr(c, "post_errors_m", None)
    return None if x is None else np.asarray(x, dtype=float)


def _kind(o, r, paired: bool) -> Test:
    if o.trials is None or r.trials is None:
        return "exact"
    if paired and _samples(o) is not None and _samples(r) is not None:
        return "paired"
    return "welch"


def compare(
    candidates, other: int, reference: int, alpha: float, tolerance: float, paired: bool = False
) -> Comparison:
    """The plain two-sided test and the rule's tolerance test of ``other`` against
    ``reference`` (module docstring; ``paired`` for candidates with common random numbers)."""
    o, r = candidates[other], candidates[reference]
    scale = 1.0 - tolerance
    kind = _kind(o, r, paired)
    diff = o.post_error_mean_m - r.post_error_mean_m
    if kind == "exact":
        significant = o.post_error_mean_m < scale * r.post_error_mean_m
        return Comparison(other, reference, None, None, bool(significant), kind, diff)
    if kind == "paired":
        a, b = _samples(o), _samples(r)
        assert a is not None and b is not None
        test = ttest_paired(a, b)
        rule = ttest_paired(a, scale * b)
    else:
        test = ttest_from_stats(
            o.post_error_mean_m,
            o.post_error_std_m,
            o.trials,
            r.post_error_mean_m,
            r.post_error_std_m,
            r.trials,
            equal_var=False,
        )
        rule = ttest_from_stats(
            o.post_error_mean_m,
            o.post_error_std_m,
            o.trials,
            scale * r.post_error_mean_m,
            scale * r.post_error_std_m,
            r.trials,
            equal_var=False,
        )
    significant = bool(rule.p_less < alpha)
    return Comparison(other, reference, test, rule, significant, kind, diff)


def _larger(a, b) -> bool:
    """Is candidate b a competitor of candidate a (larger travel, or equal travel, other shape)?"""
    ta, tb = a.travel_m, b.travel_m
    if math.isclose(ta, tb, rel_tol=_TRAVEL_RTOL):
        return a.sides != b.sides
    return tb > ta


def _order(candidates, indices):
    return sorted(indices, key=lambda i: (candidates[i].travel_m, candidates[i].sides))


def _pick(candidates, indices, beats: Callable[[int, int], bool]):
    """The rule on ``indices``: the first candidate (by travel) no competitor beats."""
    beaten: dict[int, int] = {}
    order = _order(candidates, indices)
    for i in order:
        rivals = [j for j in order if j != i and _larger(candidates[i], candidates[j])]
        winner = next((j for j in rivals if beats(j, i)), None)
        if winner is None:
            return i, beaten
        beaten[i] = winner
    raise AssertionError("unreachable: the largest candidate has no rival")  # pragma: no cover


class _Residual:
    """A candidate seen through its residual error (for criterion 'residual')."""

    def __init__(self, c):
        self.sides, self.side_m, self.travel_m = c.sides, c.side_m, c.travel_m
        self.trials = c.trials
        self.post_error_mean_m = c.residual_error_mean_m
        self.post_error_std_m = c.residual_error_std_m
        self.post_errors_m = getattr(c, "residual_errors_m", None)


def _check(alpha: float, tolerance: float, criterion: str) -> None:
    if criterion not in CRITERIA:
        raise ModelError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    if not (0 < alpha < 1):
        raise ModelError(f"alpha must be in (0, 1), got {alpha!r}")
    if not (0 <= tolerance < 1):
        raise ModelError(f"tolerance must be in [0, 1), got {tolerance!r}")


def _view(candidates, criterion: str):
    return [_Residual(c) for c in candidates] if criterion == "residual" else list(candidates)


def recommend(
    candidates,
    alpha: float = 0.05,
    tolerance: float = 0.05,
    criterion: Criterion = "error",
    *,
    paired: bool = False,
) -> Recommendation:
    """Apply the rule (module docstring) to ``candidates`` (objects with the Candidate fields).

    ``criterion`` 'residual' judges the candidates on ``residual_error_mean_m`` and
    ``residual_error_std_m`` (and ``residual_errors_m``) instead of the post-calibration error.
    ``paired``: the candidates' per-trial samples (``post_errors_m``) share their random numbers
    trial by trial (common random numbers), so paired tests apply. Candidates without usable
    statistics (NaN mean or std, fewer than 2 trials) are ignored. Raises ModelError if none is
    usable or alpha/tolerance/criterion are out of range.
    """
    _check(alpha, tolerance, criterion)
    candidates = _view(candidates, criterion)
    usable = [i for i, c in enumerate(candidates) if _usable(c)]
    if not usable:
        raise ModelError("no candidate track has usable statistics (every calibration failed)")
    cache: dict[tuple[int, int], Comparison] = {}

    def comp(j: int, i: int) -> Comparison:
        if (j, i) not in cache:
            cache[j, i] = compare(candidates, j, i, alpha, tolerance, paired)
        return cache[j, i]

    def beats(j: int, i: int) -> bool:
        return comp(j, i).significant

    index, beaten = _pick(candidates, usable, beats)
    per_shape = {}
    for sides in sorted({candidates[i].sides for i in usable}):
        same = [i for i in usable if candidates[i].sides == sides]
        per_shape[sides] = _pick(candidates, same, beats)[0]

    rec = candidates[index]
    same = sorted(
        (i for i in usable if candidates[i].sides == rec.sides), key=lambda i: candidates[i].side_m
    )
    pos = same.index(index)
    around = same[max(pos - 1, 0) : pos] + same[pos + 1 : pos + 2]
    neighbours = tuple(comp(j, index) for j in around)
    test: Test = (
        comp(around[0], index).kind if around else ("exact" if rec.trials is None else "welch")
    )
    return Recommendation(index, alpha, tolerance, neighbours, beaten, per_shape, criterion, test)


def other_criterion(
    candidates, rec: Recommendation, *, paired: bool = False
) -> Recommendation | None:
    """The rule of ``rec`` under the other criterion ('error' <-> 'residual'), or None when the
    candidates carry no usable statistics for it (e.g. no residuals)."""
    other: Criterion = "residual" if rec.criterion == "error" else "error"
    try:
        return recommend(candidates, rec.alpha, rec.tolerance, other, paired=paired)
    except ModelError:
        return None


def pick_spread(
    candidates,
    rng: np.random.Generator,
    alpha: float = 0.05,
    tolerance: float = 0.05,
    criterion: Criterion = "error",
    *,
    paired: bool = False,
    resamples: int = 200,
) -> tuple[tuple[int, float], ...]:
    """How stable the rule's pick is: the rule applied to ``resamples`` bootstrap resamples of
    the trials (the same trial indices for every candidate when ``paired``, else independently
    per candidate). Returns (candidate index, share of resamples picking it), most frequent
    first; empty when the candidates carry no per-trial samples (e.g. analytic ones)."""
    _check(alpha, tolerance, criterion)
    view = _view(candidates, criterion)
    samples = [_samples(c) for c in view]
    if resamples < 1 or any(s is None or s.size < 2 for s in samples):
        return ()
    usable = [i for i, c in enumerate(view) if _usable(c)]
    if not usable:
        return ()
    X = np.full((len(view), max(s.size for s in samples if s is not None)), np.nan)
    for i, s in enumerate(samples):
        assert s is not None
        X[i, : s.size] = s
    n_trials = X.shape[1]
    scale = 1.0 - tolerance
    # centred on each candidate's mean, so that the moments below lose no digits to cancellation
    centre = np.array([np.mean(s[np.isfinite(s)]) if np.isfinite(s).any() else 0.0 for s in X])
    quantiles: dict[float, float] = {}  # lower alpha-quantile of Student's t, per df

    def below(t: float, df: float) -> bool:
        """P(T <= t) < alpha for Student's t with ``df`` degrees of freedom."""
        if df not in quantiles:
            quantiles[df] = student_t_quantile(alpha, df)
        return t < quantiles[df]

    counts: dict[int, int] = {}
    for _ in range(resamples):
        if paired:
            Xb = X[:, rng.integers(0, n_trials, n_trials)]
        else:
            Xb = np.take_along_axis(X, rng.integers(0, n_trials, X.shape), axis=1)
        beats = _resample_rule(Xb, centre, scale, paired, alpha, below)
        index, _ = _pick(view, usable, beats)
        counts[index] = counts.get(index, 0) + 1
    return tuple(
        sorted(((i, k / resamples) for i, k in counts.items()), key=lambda x: (-x[1], x[0]))
    )


def _resample_rule(Xb, centre, scale: float, paired: bool, alpha: float, below):
    """``beats(j, i)`` of the rule on one resample ``Xb`` (candidates x trials, NaN where a trial
    failed): the moments of every candidate (Welch) or of every pair's differences (paired) at
    once, the test decided per pair when :func:`_pick` asks."""
    ok = np.isfinite(Xb)
    w = ok.astype(float)
    z = np.where(ok, Xb - centre[:, None], 0.0)
    n = ok.sum(axis=1)
    if paired:
        # d = x_j - scale x_i over the trials both have, for every pair (j, i) at once
        z2 = z * z
        if ok.all():  # every trial of every candidate: sums over all trials
            m = np.full((len(z), len(z)), float(z.shape[1]))
            s1, s2 = z.sum(axis=1), z2.sum(axis=1)
            sum_d = s1[:, None] - scale * s1[None, :]
            sum_d2 = s2[:, None] - 2.0 * scale * (z @ z.T) + scale**2 * s2[None, :]
        else:
            m = w @ w.T
            sum_d = z @ w.T - scale * (w @ z.T)
            sum_d2 = z2 @ w.T - 2.0 * scale * (z @ z.T) + scale**2 * (w @ z2.T)
        with np.errstate(invalid="ignore", divide="ignore"):
            mean_d = sum_d / m + (centre[:, None] - scale * centre[None, :])
            var_d = np.maximum(sum_d2 - sum_d**2 / m, 0.0) / (m - 1)
            t_d = mean_d / np.sqrt(var_d / m)

        def beats_paired(j: int, i: int) -> bool:
            mj = int(m[j, i])
            if mj > 1 and var_d[j, i] > 0:
                return below(float(t_d[j, i]), mj - 1)
            return bool(mj and mean_d[j, i] < 0)

        return beats_paired
    mean = z.sum(axis=1) / np.maximum(n, 1)  # about the centre
    var = ((z - mean[:, None]) ** 2 * w).sum(axis=1) / np.maximum(n - 1, 1)
    mean = mean + centre

    def beats_welch(j: int, i: int) -> bool:
        va, vb = var[j] / n[j], scale**2 * var[i] / n[i]
        se = math.sqrt(va + vb)
        diff = mean[j] - scale * mean[i]
        if not se > 0:
            return bool(diff < 0)
        den = va**2 / (n[j] - 1) + vb**2 / (n[i] - 1)
        df = (va + vb) ** 2 / den if den > 0 else float(n[j] + n[i] - 2)
        return student_t_sf(-diff / se, df) < alpha

    return beats_welch


def spread_range(candidates: Sequence, spread, coverage: float = 0.9) -> tuple[int, ...]:
    """The candidates (indices, smallest travel first) that together hold at least ``coverage``
    of the bootstrap picks in ``spread``, most frequent first."""
    chosen, total = [], 0.0
    for i, share in spread:
        if total >= coverage - 1e-12:
            break
        chosen.append(i)
        total += share
    return tuple(sorted(chosen, key=lambda i: (candidates[i].travel_m, candidates[i].sides)))


@dataclass(frozen=True)
class Pick:
    """One candidate the bootstrap resamples pick: its shape, side and travel (m) and the share
    of the resamples that pick it."""

    sides: int
    side_m: float
    travel_m: float
    share: float

    def as_dict(self) -> dict:
        """JSON-ready (lengths in m, rounded)."""
        return {
            "sides": self.sides,
            "side_m": rounded(self.side_m),
            "travel_m": rounded(self.travel_m),
            "share": rounded(self.share, 4),
        }


@dataclass(frozen=True)
class Stability:
    """How stable a recommendation is (bootstrap of the trials; :func:`pick_spread`).

    Attributes
    ----------
    resamples : int
    picks : tuple of Pick
        Most frequent first.
    range_m, range_travel_m : (float, float)
        Smallest and largest side (and travel, m) of the candidates that hold 90 % of the picks.
    """

    resamples: int
    picks: tuple[Pick, ...]
    range_m: tuple[float, float]
    range_travel_m: tuple[float, float]

    @property
    def indistinguishable(self) -> bool:
        """True when the sizes that hold 90 % of the picks are not one size."""
        return self.range_m[0] != self.range_m[1]

    def as_dict(self) -> dict:
        """JSON-ready: the resamples, the picks and the ranges of side (m) and travel (m) that hold
        90 % of them."""
        return {
            "resamples": self.resamples,
            "picks": [p.as_dict() for p in self.picks],
            "range_m": [rounded(v) for v in self.range_m],
            "range_travel_m": [rounded(v) for v in self.range_travel_m],
        }


def stability_of(candidates: Sequence, rec: Recommendation) -> Stability | None:
    """The stability of ``rec`` over ``candidates``, or None when it was not measured."""
    if not rec.spread:
        return None
    held = spread_range(candidates, rec.spread)
    return Stability(
        rec.resamples,
        tuple(
            Pick(candidates[i].sides, candidates[i].side_m, candidates[i].travel_m, share)
            for i, share in rec.spread
        ),
        (min(candidates[i].side_m for i in held), max(candidates[i].side_m for i in held)),
        (min(candidates[i].travel_m for i in held), max(candidates[i].travel_m for i in held)),
    )
