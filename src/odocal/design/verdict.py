"""The verdicts of the two studies: did odocal reproduce the paper's claims
(:func:`check_claims`, :func:`judge_reproduction`), and did the design predict what the real
robot's calibrations did (:func:`judge_experiment`)?

Numbers and decisions only; the words are :mod:`odocal.io.report`'s and
:mod:`odocal.io.real_experiment_report`'s.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Literal

import numpy as np

from .real_experiment import RealExperiment
from .real_motion import ClosingHeading
from .recommend import Stability, compare
from .reproduce import PAPER, Reproduction, residual_recommendation
from .result import Candidate
from .sweep import DesignResult

__all__ = [
    "ClaimCheck",
    "check_claims",
    "PaperVerdict",
    "judge_reproduction",
    "Evidence",
    "Verdict",
    "judge_experiment",
]


def _index_of_side(result: DesignResult, side_m: float) -> int | None:
    for i, c in enumerate(result.candidates):
        if math.isclose(c.side_m, side_m, rel_tol=1e-9):
            return i
    return None


@dataclass(frozen=True)
class ClaimCheck:
    """Qualitative checks of one post-error sweep (Fig. 5, 6 or 9) against the paper's claims.

    Attributes
    ----------
    worst : Candidate
        The candidate with the largest mean error.
    worst_is_smallest : bool
        Whether that is the candidate of smallest travel.
    recommended, residual_recommended : Candidate
        The rule's pick, and its pick on the residual alone.
    paper_accepted : bool or None
        No larger candidate beats the paper's choice by more than the tolerance (None: the
        paper's choice is not among the candidates).
    spread_beyond : float
        Relative max-min spread of the means from the paper's choice on, as a fraction of their
        mean (NaN without the paper's choice).
    beaten_by : Candidate or None
        The candidate that beats the paper's choice, if any.
    stability : Stability or None
        The stability of the pick (bootstrap of the trials).
    """

    worst: Candidate
    worst_is_smallest: bool
    recommended: Candidate
    residual_recommended: Candidate
    paper_accepted: bool | None
    spread_beyond: float
    beaten_by: Candidate | None
    stability: Stability | None


def check_claims(result: DesignResult, paper_side_m: float) -> ClaimCheck:
    """:class:`ClaimCheck` of ``result`` against the paper's choice of side ``paper_side_m`` (m)."""
    cands = result.candidates
    rec = result.recommendation
    means = np.array([c.post_error_mean_m for c in cands])
    worst = int(np.nanargmax(means))
    smallest = int(np.argmin([c.travel_m for c in cands]))
    accepted: bool | None = None
    spread_beyond = math.nan
    beaten_by = None
    i = _index_of_side(result, paper_side_m)
    if i is not None:
        larger = [j for j, c in enumerate(cands) if c.travel_m > cands[i].travel_m]
        beaten = [
            j
            for j in larger
            if compare(cands, j, i, rec.alpha, rec.tolerance, result.paired).significant
        ]
        accepted = not beaten
        beaten_by = cands[beaten[0]] if beaten else None
        beyond = means[[i, *larger]]
        spread_beyond = float((beyond.max() - beyond.min()) / beyond.mean())
    return ClaimCheck(
        cands[worst],
        worst == smallest,
        cands[rec.index],
        cands[residual_recommendation(result)],
        accepted,
        spread_beyond,
        beaten_by,
        result.stability,
    )


@dataclass(frozen=True)
class PaperVerdict:
    """The reproduction against the paper's numbers.

    Attributes
    ----------
    share_fig4, share_fig8 : float
        The systematic share at L = 4 m of Fig. 4's and of Fig. 8's robot.
    share_fig4_agrees, share_fig8_agrees : bool
        Within one point of the paper's 91 % and 91.5 %.
    fig5, fig6, fig9, instrument : ClaimCheck
        The sweeps against the paper's choice (4 m sides; 16 m travel for the octagons); the
        last one is Fig. 5 with a noisy heading instrument.
    instrument_closer : bool
        The noisy instrument moves the residual rule's pick towards the paper's larger choice.
    E_b_2m_sigmas : float
        The paper's E_b on the 2 m square, in predicted standard deviations from the mean.
    E_b_6m_sigmas : float
        The same, unsigned, on the 6 m square.
    with_paper_params_m : (float, float)
        Smallest and largest predicted error of the 4 and 6 m calibrations on both validation
        tracks with the paper's Table 1 parameters (m).
    """

    share_fig4: float
    share_fig8: float
    share_fig4_agrees: bool
    share_fig8_agrees: bool
    fig5: ClaimCheck
    fig6: ClaimCheck
    fig9: ClaimCheck
    instrument: ClaimCheck
    instrument_closer: bool
    E_b_2m_sigmas: float
    E_b_6m_sigmas: float
    with_paper_params_m: tuple[float, float]


def judge_reproduction(rep: Reproduction) -> PaperVerdict:
    """:class:`PaperVerdict` of a reproduction."""
    s4 = rep.fig3.share_at(4.0)
    s8 = rep.fig8.share_at(4.0)
    c5 = check_claims(rep.fig5, PAPER["chosen_side_m"])
    ci = check_claims(rep.instrument, PAPER["chosen_side_m"])
    exp = rep.experiment
    sq, tri = exp.validations[0], exp.validations[1]
    return PaperVerdict(
        s4,
        s8,
        abs(s4 - 0.91) < 0.01,
        abs(s8 - 0.915) < 0.01,
        c5,
        check_claims(rep.fig6, PAPER["chosen_travel_m"] / 8),
        check_claims(rep.fig9, PAPER["chosen_side_m"]),
        ci,
        ci.residual_recommended.side_m > c5.residual_recommended.side_m,
        (1.137 - exp.E_b_mean[0]) / exp.E_b_std[0],
        abs(1.0213 - exp.E_b_mean[2]) / exp.E_b_std[2],
        (
            min(sq.with_paper_params_m[1:].min(), tri.with_paper_params_m[1:].min()),
            max(sq.with_paper_params_m[1:].max(), tri.with_paper_params_m[1:].max()),
        ),
    )


@dataclass(frozen=True)
class Evidence:
    """Why the real result came out as it did: how the two sizes were driven and how the robot
    turns.

    Attributes
    ----------
    driven_alike : bool
        The two sizes' straight speeds and spot-turn rates are within 20 % of each other.
    spot_rotation_rad : (float, float)
        Mean odometric rotation on the spot per run of each size (rad; NaN when unknown).
    turning_gain_gap_pct : float
        Difference of the two pooled heading calibrations' turning gains mean(D)/b (%).
    E_b_gap_sigmas : float
        Difference of their E_b, in the calibration scatter the model predicts.
    spot_wheelbase_m, arc_wheelbase_m : tuple of float
        Effective wheelbases in the squares' spot turns and on the held-out runs' arcs (m).
    best_gain, best_gain_error_m : float or None
        The turning gain of the smallest held-out error on the gain curve, and that error (m);
        None without gain points.
    """

    driven_alike: bool
    spot_rotation_rad: tuple[float, float]
    turning_gain_gap_pct: float
    E_b_gap_sigmas: float
    spot_wheelbase_m: tuple[float, ...]
    arc_wheelbase_m: tuple[float, ...]
    best_gain: float | None
    best_gain_error_m: float | None


@dataclass(frozen=True)
class Verdict:
    """Did the design predict the real ordering and the size of the difference?

    Sides are compared in the experiment's order (first minus second); an *outcome* is the side
    significantly better (paired t, 5 %) in one experiment like the real one, None for no
    significant difference (the model's: what most of its simulated experiments show).
    """

    sides_m: tuple[float, float]
    preferred_side_m: float
    predicted_error_m: tuple[float, float]
    real_error_m: tuple[float, float]
    predicted_difference_m: float
    predicted_difference_ci95_m: tuple[float, float]
    real_difference_m: float
    real_paired_t: float
    real_paired_p: float
    predicted_better_side_m: float
    predicted_outcome: float | None
    real_better_side_m: float
    real_outcome: float | None
    ordering_predicted: bool
    difference_within_prediction: bool
    real_below_predicted_floor: bool
    evidence: Evidence

    @property
    def answer(self) -> Literal["Yes", "Partly", "No"]:
        """Yes: the ordering and the size of the difference; Partly: one of them; No: neither."""
        if self.ordering_predicted and self.difference_within_prediction:
            return "Yes"
        if self.ordering_predicted or self.difference_within_prediction:
            return "Partly"
        return "No"


def _spot_rotation(closing: dict[str, ClosingHeading]) -> float:
    vals = [abs(x.spot_rotation_rad) for x in closing.values()]
    return sum(vals) / len(vals) if vals else math.nan


def _driven_alike(exp: RealExperiment) -> bool:
    a, b = (exp.profiles[s] for s in exp.sides_m)
    return not any(
        x is not None and y is not None and abs(x / y - 1) > 0.2
        for x, y in (
            (a.straight_speed_m_s, b.straight_speed_m_s),
            (a.spot_turn_rate_rad_s, b.spot_turn_rate_rad_s),
        )
    )


def _evidence(exp: RealExperiment) -> Evidence:
    a, b = exp.sides_m
    pa, pb = exp.prediction.real[a], exp.prediction.real[b]
    ca, cb = exp.calibration(a), exp.calibration(b)
    spot = tuple(
        x.band("spot").wheelbase_m
        for x in (exp.turning.squares.get(a), exp.turning.squares.get(b))
        if x is not None and x.band("spot").excited
    )
    arcs = tuple(
        e.wheelbase_m
        for e in exp.turning.heldout.bands
        if e.band in ("tight", "wide") and e.excited and e.wheelbase_m is not None
    )
    best_gain = best_error = None
    if exp.gains:
        best_error = float(np.nanmin(exp.gain_curve_m))
        best_gain = float(exp.gain_grid[int(np.nanargmin(exp.gain_curve_m))])
    return Evidence(
        _driven_alike(exp),
        (_spot_rotation(exp.closing.get(a, {})), _spot_rotation(exp.closing.get(b, {}))),
        100 * abs(ca.turning_gain / cb.turning_gain - 1),
        abs(ca.E_b - cb.E_b) / max(pa.E_b_std, pb.E_b_std),
        tuple(w for w in spot if w is not None),
        arcs,
        best_gain,
        best_error,
    )


def judge_experiment(exp: RealExperiment) -> Verdict:
    """:class:`Verdict` of the real experiment: the numbers the report's words are built from."""
    a, b = exp.sides_m
    ca, cb = exp.calibration(a), exp.calibration(b)
    pred = exp.prediction
    pa, pb = pred.real[a], pred.real[b]
    real_diff = ca.heldout_error_m - cb.heldout_error_m
    t = pred.ttest
    lo, hi = t.difference_ci95_m
    paired = exp.ttests["heading"].paired
    real_better = a if real_diff < 0 else b
    # what one experiment like the real one shows: a significant ordering (paired t, 5 %) or none;
    # the model predicts an ordering when most of its simulated experiments show it
    real_outcome = real_better if paired.p_two_sided < 0.05 else None
    pred_outcome = (
        a
        if t.fraction_first_significantly_better > 0.5
        else b
        if t.fraction_second_significantly_better > 0.5
        else None
    )
    return Verdict(
        (a, b),
        pred.preferred.side_m,
        (pa.post_error_mean_m, pb.post_error_mean_m),
        (ca.heldout_error_m, cb.heldout_error_m),
        t.mean_difference_m,
        (lo, hi),
        real_diff,
        paired.t,
        paired.p_two_sided,
        a if t.mean_difference_m < 0 else b,
        pred_outcome,
        real_better,
        real_outcome,
        real_outcome == pred_outcome,
        lo <= real_diff <= hi,
        min(ca.heldout_error_m, cb.heldout_error_m) < pred.floor.mean_m,
        _evidence(exp),
    )
