"""Figures of a track design and of the paper's reproduction (the paper's Figs. 3-6, 8, 9)."""

from __future__ import annotations

import math
from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ..design.result import rounded
from ._figure import method_style, shape_colour
from ._figure import new_figure as _new_figure

if TYPE_CHECKING:
    from ..design.reproduce import Reproduction
    from ..design.sweep import DesignResult

__all__ = [
    "leg_heading_figure",
    "share_figure",
    "post_error_figure",
    "calibration_figure",
    "design_figures",
    "range_figures",
    "reproduce_figures",
]


def leg_heading_figure(curve, title: str):
    """Fig. 3: |beta(L)| and sigma_theta(L) (deg) against the leg length L (m)."""
    fig = _new_figure()
    ax = fig.add_subplot()
    ax.plot(curve.side_m, np.degrees(curve.beta_rad), lw=2, label="systematic |beta(L)|")
    ax.plot(
        curve.side_m,
        np.degrees(curve.sigma_rad),
        lw=2,
        ls="--",
        label="non-systematic sigma_theta(L), one run",
    )
    n = curve.runs_per_direction
    ax.plot(
        curve.side_m,
        np.degrees(curve.sigma_rad) / math.sqrt(n),
        lw=1.5,
        ls=":",
        label=f"non-systematic, mean of {n} runs",
    )
    ax.set_xlabel("side length L of the test track (m)")
    ax.set_ylabel("heading error of one straight leg (deg)")
    ax.set_title(title)
    ax.set_xlim(0, float(curve.side_m.max()))
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(loc="upper left")
    return fig


def share_figure(curve, title: str, mark_side_m: float = 4.0, paper_share: float | None = None):
    """Fig. 4 / Fig. 8: systematic share (%) against the leg length (m)."""
    fig = _new_figure()
    ax = fig.add_subplot()
    ax.plot(curve.side_m, 100 * curve.share, lw=2, label="odocal (model)")
    ours = 100 * curve.share_at(mark_side_m)
    ax.plot([mark_side_m], [ours], "o", color="C0", ms=7)
    ax.annotate(
        f"{ours:.1f} % at {mark_side_m:g} m",
        (mark_side_m, ours),
        xytext=(12, -26),
        textcoords="offset points",
        arrowprops={"arrowstyle": "-", "color": "0.4"},
    )
    if paper_share is not None:
        ax.plot(
            [mark_side_m], [100 * paper_share], "x", color="C3", ms=10, mew=2,
            label=f"paper: about {100 * paper_share:g} % at {mark_side_m:g} m",
        )  # fmt: skip
    ax.set_xlabel("side length L of the test track (m)")
    ax.set_ylabel("systematic share of the leg heading error (%)")
    ax.set_title(title)
    ax.set_xlim(0, float(curve.side_m.max()))
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    ax.text(
        0.02,
        0.97,
        f"share = beta^2 / (beta^2 + sigma_theta^2 / n), n = {curve.runs_per_direction}",
        transform=ax.transAxes,
        va="top",
        fontsize=9,
        color="0.3",
    )
    return fig


def post_error_figure(
    series,
    title: str,
    x: str = "side",
    floor_m: float | None = None,
    uncalibrated_m: float | None = None,
    paper_choice: float | None = None,
    validation_label: str = "",
    indistinguishable: tuple[float, float] | None = None,
):
    """Figs. 5, 6, 9: post-calibration error against the side length or the travel.

    ``series``: list of (label, candidates, recommended candidate or None, colour, line style).
    Monte-Carlo candidates get error bars, the 95 % confidence intervals of their means; expected
    values (``trials`` None: analytic) are drawn without, as what they are. The dotted line is the
    residual (no wheel noise). ``x``: 'side' (m) or 'travel' (m). ``paper_choice``: the paper's
    chosen size on that axis. ``indistinguishable``: (low, high) on that axis, shaded: the sizes
    the rule picks in bootstrap resamples of the trials.
    """
    fig = _new_figure(7.4 if len(series) == 1 else 8.4, 5.8 if len(series) == 1 else 6.2)
    ax = fig.add_subplot()
    top = 0.0
    for label, cands, rec, color, ls in series:
        xs = np.array([c.side_m if x == "side" else c.travel_m for c in cands])
        mean = np.array([c.post_error_mean_m for c in cands])
        top = max(top, float(np.nanmax(mean)))
        if all(c.trials is not None for c in cands):
            half = np.array(
                [1.96 * c.post_error_std_m / math.sqrt(max(c.trials, 1)) for c in cands]
            )
            top = max(top, float(np.nanmax(mean + half)))
            ax.errorbar(
                xs, mean, yerr=half, fmt="o", ls=ls, ms=4, capsize=2, color=color,
                label=f"{label}: after calibration (mean, 95 % CI of the mean)",
            )  # fmt: skip
        else:
            ax.plot(
                xs, mean, marker="o", ls=ls, ms=4, color=color,
                label=f"{label}: after calibration (expected, first order)",
            )  # fmt: skip
        resid = np.array([c.residual_error_mean_m for c in cands])
        if np.any(np.isfinite(resid)):
            ax.plot(
                xs, resid, ls=":", marker=".", color=color,
                label=f"{label}: residual (validation without wheel noise)",
            )  # fmt: skip
        if rec is not None:
            rx = rec.side_m if x == "side" else rec.travel_m
            ax.plot(
                [rx], [rec.post_error_mean_m], "*", ms=18, color=color, mec="k",
                label=f"{label}: recommended ({rec.side_m:g} m side, {rec.travel_m:g} m travel)",
                zorder=5,
            )  # fmt: skip
    if indistinguishable is not None and indistinguishable[1] > indistinguishable[0]:
        lo, hi = indistinguishable
        ax.axvspan(lo, hi, color="0.85", zorder=0, label="indistinguishable sizes (bootstrap)")
    notes = []
    if validation_label:
        notes.append(f"validation: {validation_label}")
    if floor_m is not None and math.isfinite(floor_m):
        ax.axhline(floor_m, color="0.35", ls="--", lw=1.2, label="floor: the true parameters")
        notes.append(f"floor with the true parameters: {floor_m:.3f} m")
    if uncalibrated_m is not None and math.isfinite(uncalibrated_m):
        if uncalibrated_m <= 1.5 * top:
            ax.axhline(uncalibrated_m, color="0.1", ls="-.", lw=1.2, label="uncalibrated")
            top = max(top, uncalibrated_m)
        else:
            notes.append(f"uncalibrated: {uncalibrated_m:.3f} m (off the scale)")
    if paper_choice is not None:
        ax.axvline(
            paper_choice, color="C3", ls="-.", lw=1.2, label=f"paper's choice ({paper_choice:g} m)"
        )
    ax.set_xlabel(
        "side length of the test track (m)" if x == "side" else "travel of one test run (m)"
    )
    ax.set_ylabel("final position error on the validation track (m)")
    ax.set_title(title)
    # room above the data for the notes, so that they never cover a point
    ax.set_ylim(0, top * (1.12 + 0.07 * len(notes)))
    ax.grid(alpha=0.3)
    if notes:
        ax.text(
            0.99, 0.98, "\n".join(notes), transform=ax.transAxes, ha="right", va="top",
            fontsize=9, color="0.25",
        )  # fmt: skip
    # two columns unless a label is too long for half the width (it would be cut off)
    labels = ax.get_legend_handles_labels()[1]
    ncol = 2 if max(map(len, labels), default=0) <= 58 else 1
    fig.legend(loc="outside lower center", ncol=ncol, fontsize=8)
    return fig


def calibration_figure(
    candidates, title: str, truth: tuple[float, float] | None = None, x: str = "side"
):
    """Calibrated E_b and E_d (mean +- std over the trials, or the first-order std) against the
    side length or the travel (m), with the true values (relative to the parameters the robot ran
    with) where known."""
    from ..design.result import shape_name

    fig = _new_figure(7.0, 5.8)
    ax_b, ax_d = fig.subplots(2, 1, sharex=True)
    for sides in sorted({c.sides for c in candidates}):
        cs = [c for c in candidates if c.sides == sides]
        xs = [c.side_m if x == "side" else c.travel_m for c in cs]
        how = "mean +- std" if all(c.trials is not None for c in cs) else "first order, +- std"
        for ax, mean, std in (
            (ax_b, [c.E_b_mean for c in cs], [c.E_b_std for c in cs]),
            (ax_d, [c.E_d_mean for c in cs], [c.E_d_std for c in cs]),
        ):
            ax.errorbar(
                xs, mean, yerr=std, fmt="o-", ms=3, capsize=2, color=shape_colour(sides),
                label=f"{shape_name(sides)}, {how}" if ax is ax_b else None,
            )  # fmt: skip
    if truth is not None:
        ax_b.axhline(truth[0], color="k", ls="--", lw=1, label="true value")
        ax_d.axhline(truth[1], color="k", ls="--", lw=1)
    ax_b.set_ylabel("calibrated E_b (-)")
    ax_d.set_ylabel("calibrated E_d (-)")
    ax_d.set_xlabel(
        "side length of the test track (m)" if x == "side" else "travel of one test run (m)"
    )
    for ax in (ax_b, ax_d):
        ax.grid(alpha=0.3)
        ax.margins(y=0.1)  # caps and the truth line inside the axes, never on the frame
        ax.ticklabel_format(axis="y", useOffset=False)
    ax_b.set_title(title)
    fig.legend(loc="outside lower center", ncol=3, fontsize=8)
    return fig


def _series(result, label: str):
    """One series per shape, each with the candidate the rule picks for that shape."""
    shapes = sorted({c.sides for c in result.candidates})
    out = []
    for sides in shapes:
        cs = [c for c in result.candidates if c.sides == sides]
        best = result.candidates[result.recommendation.per_shape[sides]]
        name = label if len(shapes) == 1 else f"{sides}-gon"
        out.append((name, cs, best, shape_colour(sides), "-"))
    return out


def _how(result) -> str:
    if result.trials is None:
        return "first-order analytic (expected values, no trials)"
    crn = ", common random numbers" if result.paired else ""
    return f"{result.trials} Monte-Carlo trials{crn}"


def _indistinguishable(result: DesignResult, x: str) -> tuple[float, float] | None:
    """The sizes the bootstrap cannot tell apart on the x axis, as the JSON reports them."""
    st = result.stability
    if st is None:
        return None
    lo, hi = st.range_m if x == "side" else st.range_travel_m
    return rounded(lo), rounded(hi)


def design_figures(result) -> dict:
    """Figures of ``odocal design --plot DIR``: file name -> figure."""
    from ..design.result import shape_name

    cands = result.candidates
    multi = len({c.sides for c in cands}) > 1
    x = "travel" if multi else "side"
    label = "design" if multi else shape_name(cands[0].sides)
    written = {}
    fig = post_error_figure(
        _series(result, label),
        f"Post-calibration error, {result.method} method, {result.runs_per_direction} runs "
        f"per direction\n{_how(result)}",
        x=x,
        floor_m=result.floor.mean_m,
        uncalibrated_m=result.uncalibrated.mean_m,
        validation_label=result.validation.label,
        indistinguishable=_indistinguishable(result, x),
    )
    written["design_error.png"] = fig
    fig = calibration_figure(
        cands,
        f"Calibrated factors against the test-track size\n{_how(result)}",
        truth=result.truth_factors,
        x=x,
    )
    written["design_calibration.png"] = fig
    fig = _new_figure(7.0, 4.4)
    ax = fig.add_subplot()
    for sides in sorted({c.sides for c in cands}):
        cs = [c for c in cands if c.sides == sides]
        xs = [c.side_m for c in cs]
        ax.plot(
            xs, [100 * c.systematic_share for c in cs], "o-", ms=3, label=shape_name(sides),
            color=shape_colour(sides),
        )  # fmt: skip
    ax.set_xlabel("side length of the test track (m)")
    ax.set_ylabel("systematic share of the leg heading error (%)")
    ax.set_ylim(0, 100)
    ax.grid(alpha=0.3)
    ax.legend(loc="lower right")
    ax.set_title(
        f"Systematic share (closed form; n = {result.runs_per_direction} runs per direction)"
    )
    written["design_share.png"] = fig
    return written


def range_figures(design) -> dict:
    """Figure of a design over plausible errors (``odocal design`` for a robot whose errors are
    not given): every plausible robot's error after calibration relative to its best size.

    The y axis is error / best error on a log scale, its ticks labelled in the rule's measure
    (how much the best size beats this one, as a share of this one's error: 1 - best / error), so
    the dashed tolerance line sits on its tick and the recommended star (its worst case) below
    it; both the steep small tracks and the 5 % tolerance are readable."""
    from ..design.result import shape_name

    fig = _new_figure(7.4, 5.6)
    ax = fig.add_subplot()
    cands = design.candidates
    xs = np.array([c.side_m for c in cands])
    ratio = 1.0 / (1.0 - design.shortfall)  # error / best error
    for k in range(ratio.shape[0]):
        ax.plot(xs, ratio[k], color="0.75", lw=0.8, label="one plausible robot" if k == 0 else None)
    worst = np.nanmax(ratio, axis=0)
    colour = shape_colour(cands[0].sides)
    ax.plot(xs, worst, color=colour, lw=2.2, marker="o", ms=3, label="worst case")
    r = design.recommended
    ax.plot(
        [r.side_m], [1.0 / (1.0 - design.within)], "*", ms=18, color=colour, mec="k", zorder=5,
        label=f"recommended: {r.side_m:g} m, beaten by at most {100 * design.within:.1f} %",
    )  # fmt: skip
    tol = 1.0 / (1.0 - design.tolerance)
    ax.axhline(
        tol, color="C3", ls="--", lw=1,
        label=f"tolerance: beaten by no larger size by more than {100 * design.tolerance:g} %",
    )  # fmt: skip
    ax.set_yscale("log")
    top = float(np.nanmax(worst))
    shares = sorted({0.0, design.tolerance, 0.1, 0.2, 0.5, 0.8, 0.9})
    ticks = [1.0 / (1.0 - s) for s in shares if 1.0 / (1.0 - s) <= 1.2 * top]
    ax.set_yticks(ticks, [f"{100 * (1.0 - 1.0 / t):.3g} %" for t in ticks])
    ax.minorticks_off()
    ax.set_ylim(0.99, 1.15 * top)
    ax.set_xlabel(f"side length of the {shape_name(cands[0].sides)} test track (m)")
    ax.set_ylabel("how much the best size beats it\n(share of its error after calibration)")
    eb, ed, k = (design.level_range(key) for key in ("E_b", "E_d", "k_m"))
    ax.set_title(
        f"Design over plausible errors ({len(design.scenarios)} robots, first-order analytic)\n"
        f"E_b {eb[0]:g}-{eb[1]:g}, E_d {ed[0]:g}-{ed[1]:g}, k {k[0]:.2g}-{k[1]:.2g} m"
    )
    ax.grid(alpha=0.3)
    fig.legend(loc="outside lower center", ncol=2, fontsize=8)
    return {"design_range.png": fig}


def precision_figure(sweep, title: str):
    """Recommended side length against the ground-truth instrument's precision."""
    fig = _new_figure(7.0, 4.6)
    ax = fig.add_subplot()
    x = [sth for _, sth in sweep.levels]
    styles = {}
    for method in ("heading", "umbmark"):
        color, name = method_style(method)
        styles[method, "error"] = (color, "-", "o", f"{name}, error after calibration")
        styles[method, "residual"] = (color, ":", "s", f"{name}, residual")
    for key, (color, ls, marker, label) in styles.items():
        if key in sweep.recommended_side_m:
            ax.plot(x, sweep.recommended_side_m[key], color=color, ls=ls, marker=marker,
                    label=label)  # fmt: skip
    ax.set_xscale("log")
    ax.set_xticks(x)
    ax.set_xticklabels([f"{sxy * 1000:g} mm\n{sth:g} deg" for sxy, sth in sweep.levels])
    ax.minorticks_off()
    ax.set_xlabel("ground-truth instrument: sigma per position coordinate / per heading")
    ax.set_ylabel("recommended side of the square (m)")
    ax.set_ylim(bottom=0)
    ax.axhline(4.0, color="0.5", ls="--", lw=1, label="paper's choice (4 m)")
    ax.annotate("motion capture", (x[0], 0.2), ha="left", fontsize=8, color="0.3")
    if len(x) >= 4:
        ax.annotate("tape measure +\nprotractor", (x[3], 0.2), ha="center", fontsize=8,
                    color="0.3")  # fmt: skip
    ax.set_title(title)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="upper left")
    return fig


def _cond(name: str) -> str:
    """The conditions of a built-in robot, for a title."""
    from ..presets import PRESETS

    r = PRESETS[name]
    return f"E_b {r.systematic.E_b:g}, E_d {r.systematic.E_d:g}, k {r.nonsystematic.k_r_m:.3g} m"


def _post_error(
    series: list, title: str, result: DesignResult, x: str, paper_choice: float
) -> Callable[[], Any]:
    """A post-error figure of the reproduction, with the floor, the uncalibrated error and the
    validation track of ``result``."""
    return partial(
        post_error_figure,
        series,
        title,
        x=x,
        floor_m=result.floor.mean_m,
        uncalibrated_m=result.uncalibrated.mean_m,
        paper_choice=paper_choice,
        validation_label=result.validation.label,
    )


def reproduce_figures(rep: Reproduction) -> dict[str, tuple[str, Callable[[], Any]]]:
    """The paper's figures from a :class:`odocal.design.reproduce.Reproduction`:
    key -> (file name, a function drawing the figure: drawn when written, several at once)."""
    from ..design.reproduce import INSTRUMENT_SIGMA_THETA_DEG, PAPER
    from ..presets import PRESETS

    f5, f6, f9, fi = rep.fig5, rep.fig6, rep.fig9, rep.instrument
    square5 = ("square", f5.candidates, f5.recommended, shape_colour(4), "-")
    files: dict[str, tuple[str, Callable[[], Any]]] = {
        "fig3": (
            "fig3_leg_heading_error.png",
            partial(
                leg_heading_figure, rep.fig3, f"Fig. 3: leg heading error ({_cond('paper-fig3')})"
            ),
        ),
        "fig4": (
            "fig4_systematic_share.png",
            partial(
                share_figure,
                rep.fig3,
                f"Fig. 4: systematic share ({_cond('paper-fig3')})",
                paper_share=PAPER["fig4_share_at_4m"],
            ),
        ),
        "fig5": (
            "fig5_square_post_error.png",
            _post_error(
                [square5],
                f"Fig. 5: square test tracks\n{_cond('paper-fig5')}\n{_how(f5)}",
                f5,
                "side",
                PAPER["chosen_side_m"],
            ),
        ),
        "fig6": (
            "fig6_octagon_post_error.png",
            _post_error(
                [
                    ("square (Fig. 5)", *square5[1:]),
                    ("octagon", f6.candidates, f6.recommended, shape_colour(8), "-"),
                ],
                f"Fig. 6: octagon vs square at equal travel\n{_cond('paper-fig5')}\n{_how(f6)}",
                f6,
                "travel",
                PAPER["chosen_travel_m"],
            ),
        ),
        "fig8": (
            "fig8_systematic_share_experiment.png",
            partial(
                share_figure,
                rep.fig8,
                f"Fig. 8: systematic share ({_cond('paper-experiment')})",
                paper_share=PAPER["fig8_share_at_4m"],
            ),
        ),
        "fig9": (
            "fig9_experiment_post_error.png",
            _post_error(
                [("square", f9.candidates, f9.recommended, shape_colour(4), "-")],
                f"Fig. 9: experimental robot\n{_cond('paper-experiment')}\n{_how(f9)}",
                f9,
                "side",
                PAPER["chosen_side_m"],
            ),
        ),
        "fig5_instrument": (
            "fig5_instrument_post_error.png",
            _post_error(
                [
                    ("square, perfect instrument (Fig. 5)", *square5[1:]),
                    (  # the same shape, so a shade of its colour
                        f"square, heading instrument {INSTRUMENT_SIGMA_THETA_DEG:g} deg",
                        fi.candidates,
                        fi.recommended,
                        "#08306b",
                        "--",
                    ),
                ],
                f"Fig. 5 with a noisy heading instrument\n{_cond('paper-fig5')}\n{_how(fi)}",
                f5,
                "side",
                PAPER["chosen_side_m"],
            ),
        ),
    }
    r5 = PRESETS["paper-fig5"].systematic
    files["fig5_calibration"] = (
        "fig5_calibrated_factors.png",
        partial(
            calibration_figure,
            f5.candidates,
            f"Calibrated factors on square tracks ({_cond('paper-fig5')})",
            truth=(r5.E_b, r5.E_d),
        ),
    )
    if rep.precision is not None:
        files["precision"] = (
            "precision_recommended_size.png",
            partial(
                precision_figure,
                rep.precision,
                f"Recommended track size vs instrument precision\n{_cond('paper-fig5')}",
            ),
        )
    return files
