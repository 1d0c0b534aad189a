"""Choosing the test-track size from candidate summaries (docs/design.md, "The recommendation").

Rule: order the candidates by total travel (then by number of sides). Candidate C is *accepted*
when no other candidate D of larger travel (or of equal travel and another shape) beats it
significantly by more than the tolerance, i.e. when for every such D the one-sided Welch test of

    H0: mean_D >= (1 - tolerance) mean_C    against    H1: mean_D < (1 - tolerance) mean_C

is not rejected at level alpha. The recommendation is the accepted candidate of smallest travel
(the largest candidate is always accepted, so there is always one).

The test works on summary statistics only (mean, std, n of the post-calibration error), so Monte-
Carlo and analytic candidates are treated alike. Scaling sample C by (1 - tolerance) scales its
mean and std, so the test is Welch's t-test of D against the scaled C:

    t = (m_D - (1-tol) m_C) / sqrt(s_D^2/n_D + (1-tol)^2 s_C^2/n_C),

with Welch-Satterthwaite df for those two variance terms.

The table reported beside the recommendation is laid out like the paper's Tables 2 and 3: the
recommended track against its neighbours of the same shape (next smaller, next larger), with the
plain two-sided Welch t, df, p and the mean difference (neighbour - recommended).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

from ..core.model import ModelError
from ..core.stats import TTest, ttest_from_stats

__all__ = ["CRITERIA", "Comparison", "Recommendation", "recommend", "compare"]

#: What the rule compares: the error after calibration on the validation track ('error', the
#: paper's quantity) or the residual, the same drive without wheel noise ('residual').
CRITERIA = ("error", "residual")

_TRAVEL_RTOL = 1e-9


@dataclass(frozen=True)
class Comparison:
    """One row of a t-test table: candidate ``other`` against candidate ``reference``.

    ``test`` is the two-sided Welch test of other against reference (mean difference = other -
    reference); ``rule`` is the one-sided tolerance test of the recommendation rule (H1: mean_other
    < (1 - tolerance) mean_reference), ``significant`` its outcome at alpha.
    """

    other: int
    reference: int
    test: TTest
    rule: TTest
    significant: bool


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
    """

    index: int
    alpha: float
    tolerance: float
    neighbours: tuple[Comparison, ...]
    beaten_by: dict
    per_shape: dict
    criterion: str = "error"


def _usable(c) -> bool:
    return (
        math.isfinite(c.post_error_mean_m)
        and math.isfinite(c.post_error_std_m)
        and c.trials >= 2
        and c.post_error_std_m >= 0
    )


def _rule(candidates, other: int, reference: int, tolerance: float) -> TTest:
    """The rule's test: is ``other`` better than ``reference`` by more than the tolerance?"""
    o, r = candidates[other], candidates[reference]
    scale = 1.0 - tolerance
    return ttest_from_stats(
        o.post_error_mean_m,
        o.post_error_std_m,
        o.trials,
        scale * r.post_error_mean_m,
        scale * r.post_error_std_m,
        r.trials,
        equal_var=False,
    )


def compare(candidates, other: int, reference: int, alpha: float, tolerance: float) -> Comparison:
    """The plain Welch test and the rule's tolerance test of ``other`` against ``reference``."""
    o, r = candidates[other], candidates[reference]
    test = ttest_from_stats(
        o.post_error_mean_m,
        o.post_error_std_m,
        o.trials,
        r.post_error_mean_m,
        r.post_error_std_m,
        r.trials,
        equal_var=False,
    )
    rule = _rule(candidates, other, reference, tolerance)
    return Comparison(other, reference, test, rule, bool(rule.p_less < alpha))


def _larger(a, b) -> bool:
    """Is candidate b a competitor of candidate a (larger travel, or equal travel, other shape)?"""
    ta, tb = a.travel_m, b.travel_m
    if math.isclose(ta, tb, rel_tol=_TRAVEL_RTOL):
        return a.sides != b.sides
    return tb > ta


def _order(candidates, indices):
    return sorted(indices, key=lambda i: (candidates[i].travel_m, candidates[i].sides))


def _pick(candidates, indices, alpha, tolerance):
    beaten = {}
    order = _order(candidates, indices)
    for i in order:
        rivals = [j for j in order if j != i and _larger(candidates[i], candidates[j])]
        winner = next(
            (j for j in rivals if _rule(candidates, j, i, tolerance).p_less < alpha), None
        )
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


def recommend(
    candidates, alpha: float = 0.05, tolerance: float = 0.05, criterion: str = "error"
) -> Recommendation:
    """Apply the rule (module docstring) to ``candidates`` (objects with the Candidate fields).

    ``criterion`` 'residual' judges the candidates on ``residual_error_mean_m`` and
    ``residual_error_std_m`` instead of the post-calibration error. Candidates without usable
    statistics (NaN mean or std, fewer than 2 trials) are ignored. Raises ModelError if none is
    usable or alpha/tolerance/criterion are out of range.
    """
    if criterion not in CRITERIA:
        raise ModelError(f"criterion must be one of {', '.join(CRITERIA)}, got {criterion!r}")
    if criterion == "residual":
        candidates = [_Residual(c) for c in candidates]
    if not (0 < alpha < 1):
        raise ModelError(f"alpha must be in (0, 1), got {alpha!r}")
    if not (0 <= tolerance < 1):
        raise ModelError(f"tolerance must be in [0, 1), got {tolerance!r}")
    usable = [i for i, c in enumerate(candidates) if _usable(c)]
    if not usable:
        raise ModelError("no candidate track has usable statistics (every calibration failed)")
    index, beaten = _pick(candidates, usable, alpha, tolerance)

    per_shape = {}
    shapes = sorted({candidates[i].sides for i in usable})
    for sides in shapes:
        same = [i for i in usable if candidates[i].sides == sides]
        # one shape: the same pick as above
        per_shape[sides] = (
            index if len(shapes) == 1 else _pick(candidates, same, alpha, tolerance)[0]
        )

    rec = candidates[index]
    same = sorted(
        (i for i in usable if candidates[i].sides == rec.sides), key=lambda i: candidates[i].side_m
    )
    pos = same.index(index)
    around = same[max(pos - 1, 0) : pos] + same[pos + 1 : pos + 2]
    neighbours = tuple(compare(candidates, j, index, alpha, tolerance) for j in around)
    return Recommendation(index, alpha, tolerance, neighbours, beaten, per_shape, criterion)
