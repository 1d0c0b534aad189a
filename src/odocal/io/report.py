"""The Markdown report of ``odocal reproduce``: the paper's numbers beside odocal's."""

from __future__ import annotations

import math

import numpy as np

__all__ = ["reproduce_markdown", "claim_checks"]


def _pct(x: float) -> str:
    return f"{100 * x:.1f} %"


def _index_of_side(result, side_m: float) -> int | None:
    for i, c in enumerate(result.candidates):
        if math.isclose(c.side_m, side_m, rel_tol=1e-9):
            return i
    return None


def claim_checks(result, paper_side_m: float) -> dict:
    """Qualitative checks of one post-error sweep (Fig. 5, 6 or 9) against the paper's claims.

    Returns a dict: worst (candidate with the largest mean error), worst_is_smallest, recommended
    and residual-rule candidates, paper_accepted (no larger candidate beats the paper's choice by
    more than the tolerance), spread_beyond (relative max-min spread of the means from the paper's
    choice on, as a fraction of their mean), beaten_by (the candidate that beats the paper's
    choice, if any).
    """
    from ..design.recommend import compare
    from ..design.reproduce import residual_recommendation

    cands = result.candidates
    rec = result.recommendation
    means = np.array([c.post_error_mean_m for c in cands])
    worst = int(np.nanargmax(means))
    smallest = int(np.argmin([c.travel_m for c in cands]))
    out = {
        "worst": cands[worst],
        "worst_is_smallest": worst == smallest,
        "recommended": cands[rec.index],
        "residual_recommended": cands[residual_recommendation(result)],
        "paper_accepted": None,
        "spread_beyond": math.nan,
        "beaten_by": None,
    }
    i = _index_of_side(result, paper_side_m)
    if i is not None:
        larger = [j for j, c in enumerate(cands) if c.travel_m > cands[i].travel_m]
        beaten = [
            j
            for j in larger
            if compare(cands, j, i, rec.alpha, rec.tolerance, result.paired).significant
        ]
        out["paper_accepted"] = not beaten
        out["beaten_by"] = cands[beaten[0]] if beaten else None
        beyond = means[[i, *larger]]
        out["spread_beyond"] = float((beyond.max() - beyond.min()) / beyond.mean())
    return out


def _yes(flag) -> str:
    return "agrees" if flag else "differs"


def _design_table(result) -> list[str]:
    rows = [
        "| side (m) | travel (m) | share | E_b mean +- std | E_d mean +- std | error after "
        "calibration (m), mean +- std | residual (m) |",
        "|---:|---:|---:|---|---|---|---:|",
    ]
    rec = result.recommendation.index
    for i, c in enumerate(result.candidates):
        mark = " **(recommended)**" if i == rec else ""
        rows.append(
            f"| {c.side_m:g}{mark} | {c.travel_m:g} | {_pct(c.systematic_share)} | "
            f"{c.E_b_mean:.5f} +- {c.E_b_std:.5f} | {c.E_d_mean:.6f} +- {c.E_d_std:.6f} | "
            f"{c.post_error_mean_m:.4f} +- {c.post_error_std_m:.4f} | "
            f"{c.residual_error_mean_m:.4f} |"
        )
    return rows


def _precision_section(rep, img) -> list[str]:
    sweep = rep.precision
    if sweep is None:
        return []
    rows = [
        "| instrument (sigma xy, sigma heading) | heading method: error / residual | "
        "UMBmark (mean): error / residual |",
        "|---|---|---|",
    ]
    rec = sweep.recommended_side_m
    for i, (sxy, sth) in enumerate(sweep.levels):
        rows.append(
            f"| {sxy * 1000:g} mm, {sth:g} deg | {rec[('heading', 'error')][i]:g} m / "
            f"{rec[('heading', 'residual')][i]:g} m | {rec[('umbmark', 'error')][i]:g} m / "
            f"{rec[('umbmark', 'residual')][i]:g} m |"
        )
    return [
        "## How the recommended size moves with the instrument's precision",
        "",
        img("precision", "Recommended size vs instrument precision"),
        "",
        "The paper warns that a small track makes the result hostage to the precision of the "
        "pose measurement. The recommended square for Fig. 5's robot, from motion capture "
        "(1 mm, 0.1 deg) to a tape measure and protractor (1 cm, 1 deg) and worse, computed "
        "with the analytic design (`odocal design --analytic`: first-order propagation, "
        "expected values, so the curve shows the trend without Monte-Carlo scatter; the rule "
        "compares the expected errors directly):",
        "",
        *rows,
        "",
        "The heading method reads only the final heading, so only the heading precision "
        "matters to it; UMBmark reads only the final position. A poorer instrument pushes "
        "both towards larger tracks, whose end errors stand out against the measurement "
        "noise.",
        "",
    ]


def reproduce_markdown(rep, figures: dict, version: str) -> str:
    """The report text. ``figures`` maps 'fig3', 'fig4', ... to file names (relative links);
    ``version``: the odocal version that wrote it."""
    from ..design.reproduce import INSTRUMENT_SIGMA_THETA_DEG, PAPER

    f5, f6, f9 = rep.fig5, rep.fig6, rep.fig9
    c5 = claim_checks(f5, PAPER["chosen_side_m"])
    c6 = claim_checks(f6, PAPER["chosen_travel_m"] / 8)
    c9 = claim_checks(f9, PAPER["chosen_side_m"])
    fi = rep.instrument
    ci = claim_checks(fi, PAPER["chosen_side_m"])
    for c, res in ((c5, f5), (c6, f6), (c9, f9), (ci, fi)):
        c["stability"] = res.stability
    s4 = rep.fig3.share_at(4.0)
    s8 = rep.fig8.share_at(4.0)
    exp = rep.experiment
    tol = f5.recommendation.tolerance
    settings = f5.settings.describe() if f5.settings else "analytic"

    def img(key: str, alt: str) -> str:
        return f"![{alt}]({figures[key]})" if key in figures else ""

    def flat_text(c) -> str:
        r = c["recommended"]
        rr = c["residual_recommended"]
        acc = c["paper_accepted"]
        beaten = "" if acc else f" (by the {c['beaten_by'].side_m:g} m side)"
        st = c.get("stability")
        spread = ""
        if st is not None and st.indistinguishable:
            spread = (
                f"; {st.range_m[0]:g}-{st.range_m[1]:g} m indistinguishable at "
                f"{rep.trials} trials, bootstrap"
            )
        return (
            f"rule picks side {r.side_m:g} m ({r.travel_m:g} m travel{spread}); on the "
            f"residual alone "
            f"{rr.side_m:g} m ({rr.travel_m:g} m); no larger track beats the paper's choice by "
            f"> {100 * tol:g} %: {'yes' if acc else 'no' + beaten}; means from it on spread by "
            f"{_pct(c['spread_beyond'])}"
        )

    sq = exp.validations[0]
    tri = exp.validations[1]
    lines = [
        '# Reproducing Jung et al. (2014), "Design of Experimental Test Tracks for Odometry '
        'Calibration"',
        "",
        f"Generated by odocal {version} (`odocal reproduce`): {rep.trials} Monte-Carlo trials "
        f"per candidate, seed {rep.seed}, heading-error calibration with 5 runs per direction, "
        f"simulation with {settings}.",
        "Conditions are the paper's as stated (built-in robots `paper-fig3`, `paper-fig5`, "
        "`paper-experiment`: TETRA-DS II, wheel diameter 0.15 m, wheelbase 0.385 m). "
        '"Error" is the final position error on the validation track, sqrt(eps_x^2 + '
        'eps_y^2); "residual" is the same drive without wheel noise (what the calibrated '
        'parameters alone leave); "floor" is the error with the TRUE parameters.',
        "",
        "## Summary",
        "",
        "| claim | paper | odocal | verdict |",
        "|---|---|---|---|",
        f"| Fig. 4: systematic share at L = 4 m | about 91 % | {_pct(s4)} | "
        f"{_yes(abs(s4 - 0.91) < 0.01)} |",
        f"| Fig. 8: systematic share at L = 4 m (experimental robot) | 91.5 % | {_pct(s8)} | "
        f"{'agrees within 1 point' if abs(s8 - 0.915) < 0.01 else 'differs'} |",
        f"| Fig. 5: worst track | 0.5 m (2 m travel) | {c5['worst'].side_m:g} m | "
        f"{_yes(c5['worst_is_smallest'])} |",
        f"| Fig. 5: error falls until 4 m, flat after | flat from 4 m | {flat_text(c5)} | "
        f"{'agrees that 4 m is enough; our curve flattens earlier' if c5['paper_accepted'] else 'differs'} |",  # noqa: E501
        f"| Fig. 6: octagon worst at 2 m travel | 2 m | {c6['worst'].travel_m:g} m travel | "
        f"{_yes(c6['worst_is_smallest'])} |",
        f"| Fig. 6: flat from 16 m travel | 16 m | {flat_text(c6)} | "
        f"{'agrees that 16 m is enough; flattens earlier' if c6['paper_accepted'] else 'differs'} |",  # noqa: E501
        f"| Fig. 9: falls until 4 m, flat 4-10 m | 4 m | {flat_text(c9)} | "
        f"{'agrees that 4 m is enough; flattens earlier' if c9['paper_accepted'] else 'differs'} |",  # noqa: E501
        f"| Fig. 5 with a {INSTRUMENT_SIGMA_THETA_DEG:g} deg heading instrument (odocal's "
        f"assumption) | 4 m | {flat_text(ci)} | "
        f"{'closer to the paper' if ci['residual_recommended'].side_m > c5['residual_recommended'].side_m else 'no closer'} |",  # noqa: E501
        f"| Table 1: E_b on the 2 m square | 1.1370 | {exp.E_b_mean[0]:.4f} +- "
        f"{exp.E_b_std[0]:.4f} | differs (far outside the model's spread) |",
        f"| Table 1: E_b, E_d on the 4 and 6 m squares | 1.0247/1.0016, 1.0213/1.0015 | "
        f"{exp.E_b_mean[1]:.4f}/{exp.E_d_mean[1]:.4f}, {exp.E_b_mean[2]:.4f}/"
        f"{exp.E_d_mean[2]:.4f} | E_d agrees; E_b of 6 m about "
        f"{abs(1.0213 - exp.E_b_mean[2]) / exp.E_b_std[2]:.1f} std off |",
        f"| Fig. 10: 4x4 CCW error after 2/4/6 m calibrations | 1.69/0.14/0.09 m | "
        f"{'/'.join(f'{v:.2f}' for v in sq.mean_m)} m (simulated calibrations); "
        f"{'/'.join(f'{v:.2f}' for v in sq.with_paper_params_m)} m with the paper's Table 1 "
        "parameters | agrees given the paper's parameters |",
        f"| Fig. 11: 5 m triangle CW error | 2.28/0.24/0.14 m | "
        f"{'/'.join(f'{v:.2f}' for v in tri.mean_m)} m; "
        f"{'/'.join(f'{v:.2f}' for v in tri.with_paper_params_m)} m with the paper's "
        "parameters | agrees in trend given the paper's parameters |",
        f"| Tables 2, 3: 2 m significantly worse than 4 m | t = 26.9, 30.3 | median t "
        f"{sq.ttests[0].median_t:.2f}, {tri.ttests[0].median_t:.2f} (significant in "
        f"{_pct(sq.ttests[0].fraction_significant)}, {_pct(tri.ttests[0].fraction_significant)}"
        " of simulated experiments) | differs (see Tables 1-3) |",
        f"| Tables 2, 3: 6 m not significantly better than 4 m | p = 0.408, 0.121 | median p "
        f"{sq.ttests[1].median_p:.2f}, {tri.ttests[1].median_p:.2f} | agrees |",
        "",
        "## Figs. 3 and 4: heading error of a straight leg, systematic share",
        "",
        img("fig3", "Fig. 3"),
        "",
        img("fig4", "Fig. 4"),
        "",
        "The systematic part |beta(L)| = 2 L |E_d - 1| / ((E_d + 1) E_b b_n) grows linearly with "
        "the side, the random part sigma_theta(L) = sqrt((k_r + k_l) L) / b as its square root, "
        "as in the paper's Fig. 3. The paper gives no formula for its Fig. 4 share; odocal "
        "defines it as the share of the variance of the 5-run-averaged leg heading error "
        "explained by the systematic part, beta^2 / (beta^2 + sigma_theta^2 / n), which gives "
        f"{_pct(s4)} at 4 m (paper: about 91 %) and {_pct(s8)} for the experimental robot "
        "(paper: 91.5 %, Fig. 8). The 0.6-point gap in Fig. 8 is within what an unstated "
        "formula (or a rounded k) can explain; the shape of the curves (steep rise below 2 m, "
        "slow approach to 100 %) is the same.",
        "",
        img("fig8", "Fig. 8"),
        "",
        "## Fig. 5: square test tracks",
        "",
        img("fig5", "Fig. 5"),
        "",
        f"Validation on the {f5.validation.label}: uncalibrated {f5.uncalibrated.mean_m:.3f} m, "
        f"floor {f5.floor.mean_m:.4f} m.",
        "",
        *_design_table(f5),
        "",
        img("fig5_calibration", "Calibrated factors"),
        "",
        "**Agreement.** As in the paper, the smallest track (0.5 m, 2 m travel) is the worst and "
        "the error falls with the track size and then stays flat; 4 m (16 m travel) is "
        "comfortably in the flat part, so the paper's recommendation is a safe one under the "
        "model.",
        "",
        "**Difference.** Our curve flattens earlier than the paper's (the rule picks "
        f"{c5['recommended'].side_m:g} m; judged on the residual alone, "
        f"{c5['residual_recommended'].side_m:g} m). Two reasons: (1) the error after "
        "calibration includes the validation run's own wheel noise, the same for every "
        f"candidate (floor {f5.floor.mean_m:.3f} m), which dilutes the differences between "
        "candidates; the residual (dotted) shows the part the test track controls, and it "
        "keeps falling until about 2-4 m. (2) The trade-off that makes larger tracks better is "
        "E_d: its spread falls with L while the spread of E_b grows (figure above). The "
        "simulated robot has a perfect heading instrument; a real one (the paper's "
        "STARGAZER) adds measurement noise that hurts small tracks most (the paper's own "
        "argument for not making tracks too small), which would move the flat part to larger "
        "tracks. The paper does not say whether its Fig. 5 validation drive had wheel noise, "
        'nor how it judged "flat".',
        "",
        f"## Sensitivity: a heading instrument of {INSTRUMENT_SIGMA_THETA_DEG:g} deg",
        "",
        img("fig5_instrument", "Fig. 5 with a noisy heading instrument"),
        "",
        "The heading method needs the final heading of every test run; the paper's experiment "
        "used a STARGAZER absolute-position sensor and states no accuracy for it. Adding a "
        "measurement "
        f"noise of {INSTRUMENT_SIGMA_THETA_DEG:g} deg (standard deviation per measured heading; "
        "an assumption, not a number from the paper) to Fig. 5's robot penalises small tracks, "
        "whose leg heading errors are small against it: the rule now picks "
        f"{ci['recommended'].side_m:g} m by error after calibration and "
        f"{ci['residual_recommended'].side_m:g} m by residual, against "
        f"{c5['recommended'].side_m:g} m and {c5['residual_recommended'].side_m:g} m with a "
        "perfect instrument. A realistic instrument is thus one plausible reason for the "
        "paper's later flattening (4 m). Give your instrument's noise in ROBOT.yaml "
        "(`measurement: {sigma_theta_deg: ...}`) when designing a track.",
        "",
        *_precision_section(rep, img),
        "## Fig. 6: regular octagons, at equal travel",
        "",
        img("fig6", "Fig. 6"),
        "",
        f"The octagon's worst candidate is at {c6['worst'].travel_m:g} m travel (paper: 2 m) "
        "and its curve lies on top of the square's at equal travel, as the paper finds: "
        "the heading method sees total travel and total rotation, not the shape. The rule "
        f"picks {c6['recommended'].travel_m:g} m travel; the paper's 16 m is "
        f"{'inside' if c6['paper_accepted'] else 'not inside'} the flat part.",
        "",
        "## Fig. 9: the experimental robot",
        "",
        img("fig9", "Fig. 9"),
        "",
        *_design_table(f9),
        "",
        f"Same picture as Fig. 5 (worst at {c9['worst'].side_m:g} m; the rule picks "
        f"{c9['recommended'].side_m:g} m, the residual rule {c9['residual_recommended'].side_m:g} "
        "m; the paper's 4 m is in the flat part).",
        "",
        "## Tables 1-3: the experiment",
        "",
        f"Predicted by simulating the experiment {exp.trials} times under the model "
        "(`paper-experiment`: E_b 1.0255, E_d 1.0017, k 2.89e-6 m; 5 runs per direction on "
        "each square; 5 validation runs per parameter set).",
        "",
        "**Table 1** (calibrated factors; odocal: mean +- std, central 95 % of experiments)",
        "",
        "| track | paper E_b | odocal E_b | paper E_d | odocal E_d |",
        "|---|---:|---|---:|---|",
    ]
    for k, s in enumerate(exp.side_m):
        pb, pd = PAPER["table1"][s]
        lines.append(
            f"| {s:g} m x {s:g} m | {pb:.4f} | {exp.E_b_mean[k]:.4f} +- {exp.E_b_std[k]:.4f} "
            f"({exp.E_b_range[k, 0]:.4f}-{exp.E_b_range[k, 1]:.4f}) | {pd:.4f} | "
            f"{exp.E_d_mean[k]:.4f} +- {exp.E_d_std[k]:.4f} "
            f"({exp.E_d_range[k, 0]:.4f}-{exp.E_d_range[k, 1]:.4f}) |"
        )
    lines += [
        "",
        "The 4 m and 6 m results agree with the model for E_d and roughly for E_b. The 2 m "
        f"track's E_b = 1.137 is about {(1.137 - exp.E_b_mean[0]) / exp.E_b_std[0]:.0f} "
        "standard deviations from what the model predicts: it means a per-turn under-rotation "
        "of about 11 deg, a CW-CCW heading difference of about 87 deg over the run. Wheel noise "
        "of the measured size cannot do that. Something outside the model must have acted on "
        "the short track: e.g. wheel slip or controller overshoot in the spot turns (which "
        "matter more when legs are short), or the heading measurement. The paper's conclusion "
        "(2 m is too small) therefore rests on an effect the model does not contain.",
        "",
        "**Figs. 10, 11 and Tables 2, 3** (final position error, m)",
        "",
        "| validation | calibrated on | paper | odocal, simulated calibration (mean, run std) | "
        "odocal, robot running with the paper's Table 1 parameters |",
        "|---|---|---:|---|---:|",
    ]
    for v in exp.validations:
        for k, s in enumerate(exp.side_m):
            lines.append(
                f"| {v.track.label} | {s:g} m | {v.paper_mean_m[k]:.2f} | {v.mean_m[k]:.3f} "
                f"({v.run_std_m[k]:.3f}) | {v.with_paper_params_m[k]:.3f} |"
            )
    lines += [
        "",
        "| validation | test | paper t, p, mean difference (m) | odocal median t, median p, "
        "share of experiments with p < 0.05, mean difference (m) |",
        "|---|---|---|---|",
    ]
    for v in exp.validations:
        for t in v.ttests:
            pt, pp, pdiff = t.paper
            lines.append(
                f"| {v.track.label} | {t.label} | {pt:.3f}, {pp:.3f}, {pdiff:+.3f} | "
                f"{t.median_t:.2f}, {t.median_p:.2f}, {_pct(t.fraction_significant)}, "
                f"{t.mean_difference_m:+.3f} |"
            )
    lines += [
        "",
        "With the paper's own Table 1 parameters installed, the model reproduces the large "
        f"errors after the 2 m calibration ({sq.with_paper_params_m[0]:.2f} m against 1.69 m "
        f"on the square, {tri.with_paper_params_m[0]:.2f} m against 2.28 m on the triangle) "
        "and the order of magnitude of the others "
        f"({min(sq.with_paper_params_m[1:].min(), tri.with_paper_params_m[1:].min()):.2f}-"
        f"{max(sq.with_paper_params_m[1:].max(), tri.with_paper_params_m[1:].max()):.2f} m "
        "against 0.09-0.24 m; the measured ones are somewhat larger, as expected from an "
        "instrument and a floor that the model does not contain). So the validation part of "
        "the experiment is consistent with the model. What the model does not reproduce is "
        "the 2 m calibration itself: under the model a 2 m square calibrates almost as well as "
        "a 4 m one, so the predicted t-test of 2 m against 4 m is not significant in most "
        "simulated experiments, while the paper's is (t = 26.9 and 30.3). "
        "For 6 m against 4 m both agree: no significant difference.",
        "",
        "## Conclusion",
        "",
        "Under the paper's model and stated conditions odocal reproduces the share figures "
        "(Figs. 3, 4, 8), the shape of the post-calibration curves (worst at the smallest "
        "track, flat for large ones, squares and octagons alike at equal travel) and the "
        "validation errors given the paper's calibrated parameters. The model's curves flatten "
        "earlier than the paper's (a 1.5-3 m square already calibrates nearly as well as a 4 m "
        "one), and the experiment's bad 2 m calibration lies outside the model. With a heading "
        f"instrument of {INSTRUMENT_SIGMA_THETA_DEG:g} deg the model's choice moves to "
        f"{ci['recommended'].side_m:g}-{ci['residual_recommended'].side_m:g} m, close to the "
        "paper's. A 4 m x 4 m square (16 m travel) remains a safe choice; smaller tracks need a "
        "good heading measurement and a robot whose spot turns behave as modelled.",
        "",
    ]
    return "\n".join(line for line in lines) + "\n"


def real_experiment_markdown(exp, figures: dict, heading_level: int = 2) -> str:
    """The report section of the real experiment (``odocal reproduce --realdata``): its
    Tables 1-3, the design's prediction, the verdict and the evidence. ``figures``: key ->
    file name (relative links)."""
    from ..design.real_experiment import verdict, verdict_text

    h = "#" * heading_level
    a, b = exp.sides_m
    pred = exp.prediction
    v = verdict(exp)
    mm = 1000.0

    def img(key: str, alt: str) -> str:
        return f"![{alt}]({figures[key]})" if key in figures else ""

    def ci(pair, scale=1.0, fmt=".5f"):
        return "-" if pair is None else f"{pair[0] * scale:{fmt}}-{pair[1] * scale:{fmt}}"

    ref = exp.reference
    lines = [
        f"{h} The experiment on a real robot (OptiOdom)",
        "",
        "The paper checks its design with a real experiment. Here the same procedure runs on a "
        "real robot from its recordings: the OptiOdom differential-drive robot (Sousa et al. "
        "2022) drove 0.75 m and 1.7 m squares CW and CCW under motion capture, plus circles "
        "and free paths that no calibration below uses.",
        "",
        f"- Held-out runs: {exp.heldout_split}.",
        f"- Reference geometry: D {ref.mean_diameter_m:g} m, b {ref.wheelbase_m:g} m (the "
        "robot's nominal values, which it ran with in every 1.7 m data set and in two of the "
        "four 0.75 m ones; the others ran with b0 = 0.205 m, one also with D0 = 0.085 m, on "
        "purpose). Every square's final error is its ground-truth final pose minus the pose "
        "dead-reckoned from its wheel rotations with the reference, so E_b and E_d are relative "
        "to the reference. Relative to the firmware values instead (per data set, composed with "
        "them) the turning gain mean(D)/b differs by at most "
        + (
            f"{max(abs(c.as_dict().get('relative_to_ran_with', {}).get('turning_gain_difference') or 0.0) for c in exp.calibrations) / exp.calibration(a).turning_gain * 100:.3f} %"  # noqa: E501
        )
        + " (column 'vs firmware' below).",
        "- Metric: the mean final position error of dead-reckoning the held-out runs with the "
        "calibrated parameters against motion capture.",
        "",
        f"{h}# Table 1: calibrated factors",
        "",
        "| square | method | data set | runs CW + CCW | E_b (95 %) | E_d (95 %) | b (m) | "
        "gain mean(D)/b | vs firmware (gain difference) |",
        "|---:|---|---|---|---|---|---:|---:|---:|",
    ]
    for c in sorted(exp.calibrations, key=lambda c: (c.side_m, c.method, c.scope != "pooled")):
        d = c.as_dict()
        rw = d.get("relative_to_ran_with")
        lines.append(
            f"| {c.side_m:g} m | {c.method} | {c.scope} | {c.runs_cw} + {c.runs_ccw} | "
            f"{c.E_b:.5f}"
            + (f" ({ci(c.E_b_ci95)})" if c.E_b_ci95 else "")
            + f" | {c.E_d:.6f}"
            + (f" ({ci(c.E_d_ci95, fmt='.6f')})" if c.E_d_ci95 else "")
            + f" | {float(c.geometry.wheelbase_m):.6f} | {c.turning_gain:.5f} | "
            + (
                "-"
                if rw is None
                else "ran with the reference"
                if c.ran_with == exp.reference
                else f"{rw['turning_gain_difference']:+.1e}"
            )
            + " |"
        )
    lines += [
        "",
        f"{h}# Tables 2 and 3: held-out errors and t-tests",
        "",
        "| square | method | held-out mean final error (mm) | bootstrap 95 % (mm) | "
        "predicted by the design (mm, mean +- std) |",
        "|---:|---|---:|---|---|",
    ]
    for s in exp.sides_m:
        for method in ("heading", "umbmark"):
            c = exp.calibration(s, method)
            p = pred.real[s] if method == "heading" else None
            lines.append(
                f"| {s:g} m | {method} | {c.heldout_error_m * mm:.1f} | "
                f"{ci(c.heldout_ci95_m, mm, '.1f')} | "
                + (
                    "-"
                    if p is None
                    else f"{p.post_error_mean_m * mm:.1f} +- {p.post_error_std_m * mm:.1f}"
                )
                + " |"
            )
    lines += [
        "",
        f"t-tests of the held-out errors, {a:g} m minus {b:g} m (the same {len(exp.heldout_names)} "
        "runs replayed with both parameter sets, so the paired test is the right one; the "
        "paper's Student test of independent samples beside it):",
        "",
        "| method | paired t | df | p | mean difference (mm) | Student t | p |",
        "|---|---:|---:|---:|---:|---:|---:|",
    ]
    for method, tests in exp.ttests.items():
        pt, st = tests["paired"], tests["student"]
        lines.append(
            f"| {method} | {pt.t:.2f} | {pt.df:.0f} | {pt.p_two_sided:.2g} | "
            f"{pt.mean_difference * mm:+.1f} | {st.t:.2f} | {st.p_two_sided:.2g} |"
        )
    pt = pred.ttest
    lines += [
        "",
        f"The design predicts for the heading method: median paired t {pt['median_t']:.2f}, "
        f"median p {pt['median_p']:.2f}, significant in {100 * pt['fraction_significant']:.0f} % "
        f"of simulated experiments, mean difference {pt['mean_difference_m'] * mm:+.1f} mm "
        f"(95 %: {pt['difference_ci95_m'][0] * mm:+.1f} to {pt['difference_ci95_m'][1] * mm:+.1f}"
        " mm).",
        "",
        img("real_design", "Design against the real calibrations"),
        "",
        f"{h}# The design for this robot",
        "",
        "Steps 2-3 from the runs (`odocal noise`, `odocal design --robot-from`): "
        f"E_b {pred.robot.systematic.E_b:.5f}, E_d {pred.robot.systematic.E_d:.6f}, "
        f"E_s {pred.robot.systematic.E_s:.5f} (trajectory fit of the squares and Ivanjko runs, "
        f"relative to the reference), k_r = k_l = {pred.robot.nonsystematic.k_r_m:.3g} m (the "
        "squares' run-to-run heading spread), instrument "
        f"{pred.robot.measurement.sigma_xy_m * mm:.2f} mm / "
        f"{math.degrees(pred.robot.measurement.sigma_theta_rad):.2f} deg (the tracker's jitter). "
        f"Candidates: squares with {pred.runs_per_direction} runs per direction, heading method, "
        "validated by replaying the held-out runs' wheel rotations through the model "
        f"({pred.trials} simulated experiments each); uncalibrated "
        f"{pred.uncalibrated.mean_m * mm:.1f} mm, floor {pred.floor.mean_m * mm:.1f} mm.",
        "",
        "| side (m) | predicted error (mm, mean +- std) | E_b std | E_d std |",
        "|---:|---|---:|---:|",
    ]
    for i, c in enumerate(pred.sweep):
        mark = " **(preferred)**" if i == pred.recommendation.index else ""
        lines.append(
            f"| {c.side_m:g}{mark} | {c.post_error_mean_m * mm:.1f} +- "
            f"{c.post_error_std_m * mm:.1f} | {c.E_b_std:.5f} | {c.E_d_std:.6f} |"
        )
    lines += [
        "",
        f"{h}# Verdict",
        "",
        verdict_text(exp),
        "",
        img("real_gain", "Held-out error against the turning gain"),
        "",
        "| parameters | turning gain mean(D)/b | held-out error (mm) |",
        "|---|---:|---:|",
    ]
    for g in sorted(exp.gains, key=lambda g: g.heldout_error_m):
        note = "" if g.held_out else " (fitted with the held-out runs: not a validation)"
        lines.append(f"| {g.label}{note} | {g.turning_gain:.5f} | {g.heldout_error_m * mm:.1f} |")
    lines += [
        "",
        "Motion of the runs (90th percentiles, from the wheel rotations):",
        "",
        "| runs | straight speed (m/s) | spot-turn rate (rad/s) | odometric spot rotation per "
        "run (rad) |",
        "|---|---:|---:|---:|",
    ]
    for key, prof in exp.profiles.items():
        name = f"{key:g} m squares" if isinstance(key, float) else "held-out runs"
        cl = exp.closing.get(key) if isinstance(key, float) else None
        spot = (
            "-"
            if not cl
            else " / ".join(
                f"{abs(x['spot_rotation_rad']):.2f} ({d.upper()})" for d, x in cl.items()
            )
        )
        sv, sw = prof["straight_speed_m_s"], prof["spot_turn_rate_rad_s"]
        lines.append(
            f"| {name} | {'-' if sv is None else f'{sv:.3f}'} | "
            f"{'-' if sw is None else f'{sw:.2f}'} | {spot} |"
        )
    lines += [
        "",
        img("real_bands", "Effective wheelbase per band of motion"),
        "",
        "| runs | " + " | ".join(b.band for b in next(iter(exp.turning.values())).bands) + " |",
        "|---|" + "---|" * len(next(iter(exp.turning.values())).bands),
    ]
    for name, t in exp.turning.items():
        cells = []
        for e in t.bands:
            if e.excited and e.wheelbase_m is not None and e.ci95_m is not None:
                cells.append(
                    f"{e.wheelbase_m * mm:.2f} ({e.ci95_m[0] * mm:.2f}-{e.ci95_m[1] * mm:.2f})"
                )
            else:
                cells.append("not excited")
        lines.append(f"| {name} | " + " | ".join(cells) + " |")
    lines += [
        "",
        "(effective wheelbase in mm at the diameters of odocal's default fit, 95 % interval "
        "over runs; bands by the turn radius R of the axle centre, see docs/real-robots.md)",
        "",
        f"Reproduce with `odocal reproduce --realdata DIR --out OUT` (trials "
        f"{pred.trials}); the numbers of the README come from "
        "`benchmarks/bench_real_experiment.py`.",
        "",
    ]
    del v
    return "\n".join(lines) + "\n"
