"""odocal design: closed-form metrics, the recommendation rule, the Monte-Carlo sweep, the CLI."""

from __future__ import annotations

import dataclasses
import json
import math

import numpy as np
import pytest

from odocal.core.model import MeasurementNoise, NonSystematicError
from odocal.core.simulate import drive
from odocal.core.tracks import straight_line
from odocal.design import (
    Candidate,
    DesignSpec,
    SimulationSettings,
    ValidationTrack,
    design_json,
    leg_heading_noise_rad,
    leg_heading_systematic_rad,
    recommend,
    run_design,
    systematic_share,
)
from odocal.design.recommend import compare
from odocal.errors import ModelError
from odocal.presets import PRESETS

FIG3 = PRESETS["paper-fig3"]
FIG5 = PRESETS["paper-fig5"]

# --- closed-form metrics ------------------------------------------------------------------


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


# --- the recommendation rule on synthetic summaries ---------------------------------------


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


# --- the Monte-Carlo sweep ----------------------------------------------------------------


def test_sweep_same_seed_same_json_and_contract_keys():
    kw = dict(side_lengths_m=[0.5, 2.0, 4.0], trials=60)
    spec = DesignSpec(**kw)
    a = design_json(run_design(FIG5, spec, np.random.default_rng(5)), seed=5)
    b = design_json(run_design(FIG5, spec, np.random.default_rng(5)), seed=5)
    c = design_json(run_design(FIG5, spec, np.random.default_rng(6)), seed=6)
    assert json.dumps(a) == json.dumps(b)
    assert a["candidates"] != c["candidates"]
    keys = {
        "sides", "side_m", "travel_m", "systematic_share", "post_error_mean_m",
        "post_error_std_m", "E_b_mean", "E_b_std", "E_d_mean", "E_d_std",
    }  # fmt: skip
    assert all(keys <= set(cd) for cd in a["candidates"])
    assert set(a["recommended"]) >= {"sides", "side_m"}
    assert a["floor_m"] < a["uncalibrated_m"]
    assert a["criterion"] == "error"
    assert a["recommended_by_other_criterion"]["criterion"] == "residual"


def test_sweep_calibrates_without_bias_and_spreads_as_predicted():
    """E_b, E_d are unbiased; std(E_b) follows methods-notes 2.5:
    sigma(E_b) ~ E_b^2 (2/pi) sigma_run / (4 sqrt(2n)), sigma_run^2 = (k_r+k_l)(4L + pi b)/b^2."""
    trials, n, L = 1500, 5, 4.0
    res = run_design(FIG5, DesignSpec(side_lengths_m=(L,), trials=trials), np.random.default_rng(2))
    c = res.candidates[0]
    s = FIG5.systematic
    b = FIG5.true_geometry.wheelbase_m
    sigma_run = math.sqrt(2 * 1.69e-6 * (4 * L + math.pi * b)) / b
    sd_eb = s.E_b**2 * (2 / math.pi) * sigma_run / (4 * math.sqrt(2 * n))
    # mean within 4 standard errors; std within 4 relative standard errors (1/sqrt(2 trials))
    assert c.E_b_mean == pytest.approx(s.E_b, abs=4 * sd_eb / math.sqrt(trials))
    assert c.E_b_std == pytest.approx(sd_eb, rel=4 / math.sqrt(2 * trials))
    assert c.E_d_mean == pytest.approx(s.E_d, abs=4 * c.E_d_std / math.sqrt(trials))
    assert c.failed_trials == 0 and c.trials == trials
    lo, hi = c.post_error_ci95_m
    assert lo < c.post_error_mean_m < hi
    # calibration gains most of the uncalibrated error, and cannot beat the floor by much
    assert c.post_error_mean_m < 0.2 * res.uncalibrated.mean_m
    assert c.post_error_mean_m > res.floor.mean_m - 4 * res.floor.std_m / math.sqrt(trials)


def test_fast_simulation_matches_the_1cm_midpoint_reference():
    """The fast setting (exact arcs, 10 increments per segment; one increment for the heading
    test runs) and the 1 cm midpoint reference give the same statistics.

    Two independent samples of `trials` values each: means must agree within 4 standard errors
    of their difference, standard deviations within 4 relative standard errors of the
    difference (sqrt(2) / sqrt(2 (trials - 1)) each)."""
    trials = 1500
    kw = dict(side_lengths_m=[0.5, 3.0], trials=trials)
    spec = DesignSpec(**kw)
    fast = run_design(FIG5, spec, np.random.default_rng(11))
    ref = run_design(FIG5, spec, np.random.default_rng(12), settings=SimulationSettings.reference())
    rel_sd = 4 * math.sqrt(2) / math.sqrt(2 * (trials - 1))

    def close(m1, s1, m2, s2):
        assert abs(m1 - m2) < 4 * math.hypot(s1, s2) / math.sqrt(trials)
        assert s1 == pytest.approx(s2, rel=rel_sd)

    for f, r in zip(fast.candidates, ref.candidates, strict=True):
        close(f.post_error_mean_m, f.post_error_std_m, r.post_error_mean_m, r.post_error_std_m)
        close(f.E_b_mean, f.E_b_std, r.E_b_mean, r.E_b_std)
        close(f.E_d_mean, f.E_d_std, r.E_d_mean, r.E_d_std)
    for a, b in ((fast.floor, ref.floor), (fast.uncalibrated, ref.uncalibrated)):
        close(a.mean_m, a.std_m, b.mean_m, b.std_m)


def test_sweep_umbmark_and_measurement_noise():
    noisy = dataclasses.replace(FIG5, measurement=MeasurementNoise.from_degrees(0.01, 0.5))
    spec = DesignSpec(side_lengths_m=(1.0, 4.0), trials=200, method="umbmark")
    res = run_design(noisy, spec, np.random.default_rng(0))
    assert all(abs(c.E_b_mean - 1.028) < 0.005 for c in res.candidates)
    # a heading instrument of 0.5 deg adds std(beta_hat) = 0.5 deg sqrt(2/5) / 8 per leg, i.e.
    # about 2.7e-4 to std(E_d) on a 1 m square: 3.4e-4 -> 4.4e-4 (ratio 1.28); each std has a
    # relative standard error of 1/sqrt(2 * 300) = 4 %, so 1.15 is a safe lower bound
    kw = dict(side_lengths_m=[1.0], trials=300)
    clean = run_design(FIG5, DesignSpec(**kw), np.random.default_rng(0)).candidates[0]
    h = run_design(noisy, DesignSpec(**kw), np.random.default_rng(0)).candidates[0]
    assert h.E_d_std > 1.15 * clean.E_d_std
    with pytest.raises(ModelError, match="squares"):
        DesignSpec(sides=(8,), trials=10, method="umbmark")


def test_equal_travel_for_several_shapes():
    spec = DesignSpec(sides=(4, 8), side_lengths_m=(1.0, 2.0), trials=20)
    res = run_design(FIG5, spec, np.random.default_rng(0))
    travel = [(c.sides, c.side_m, c.travel_m) for c in res.candidates]
    assert travel == [(4, 1.0, 4.0), (4, 2.0, 8.0), (8, 0.5, 4.0), (8, 1.0, 8.0)]


def test_validation_track_checks():
    assert ValidationTrack(4, 4.0, "ccw").label == "4 m x 4 m square CCW"
    assert ValidationTrack(3, 5.0, "cw").label == "5 m triangle CW"
    with pytest.raises(ModelError):
        ValidationTrack(2, 4.0, "cw")
    with pytest.raises(ModelError):
        ValidationTrack(4, 4.0, "up")


# --- the CLI ------------------------------------------------------------------------------


def test_cli_design_defaults_print_a_recommendation(cli):
    status, out, err = cli("design", "--trials", "100")
    assert status == 0, err
    assert "paper-fig5" in out and "4 m x 4 m square CCW" in out
    assert "Recommended: square, side" in out
    assert "against the recommended" in out and "judged on the residual" in out
    assert out.count("square ") >= 20  # one row per candidate side 0.5 ... 10 m
    assert err == ""  # no progress bar when stderr is not a terminal


def test_cli_design_json_is_identical_for_identical_seeds(cli):
    args = ("design", "--side-lengths", "1:3:1", "--trials", "40", "--json", "--seed", "3")
    s1, out1, _ = cli(*args)
    s2, out2, _ = cli(*args)
    assert s1 == s2 == 0 and out1 == out2
    d = json.loads(out1)
    assert [c["side_m"] for c in d["candidates"]] == [1.0, 2.0, 3.0]
    assert d["seed"] == 3 and d["trials"] == 40 and d["validation"]["direction"] == "ccw"


def test_cli_design_options(cli, tmp_path):
    status, out, err = cli(
        "design", "--sides", "4", "--sides", "8", "--side-lengths", "0.3:0.9:0.3",
        "--trials", "20", "--validate", "3:5:cw", "--runs-per-direction", "3",
        "--alpha", "0.01", "--tolerance", "0.1", "--plot", tmp_path / "figs", "--json",
    )  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    assert d["validation"] == {"sides": 3, "side_m": 5.0, "direction": "cw"}
    assert d["runs_per_direction"] == 3 and d["alpha"] == 0.01 and d["tolerance"] == 0.1
    assert [c["side_m"] for c in d["candidates"]][:3] == [0.3, 0.6, 0.9]  # STOP inclusive
    assert {c["sides"] for c in d["candidates"]} == {4, 8}
    pngs = sorted((tmp_path / "figs").glob("*.png"))
    assert len(pngs) == 3
    for p in pngs:
        assert p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and p.stat().st_size > 5000


@pytest.mark.parametrize(
    "args, needle",
    [
        (("--side-lengths", "a:b:c"), "START:STOP:STEP"),
        (("--side-lengths", "5:1:1"), "STOP must be >= START"),
        (("--side-lengths", "0:1:0.5"), "> 0"),
        (("--side-lengths", "1:2"), "START:STOP:STEP"),
        (("--side-lengths", "0.001:100:0.001"), "too many"),
        (("--validate", "4:4:up"), "DIRECTION"),
        (("--validate", "2:4:cw"), "at least 3 sides"),
        (("--validate", "4:-1:cw"), "LENGTH"),
        (("--validate", "4:4"), "SIDES:LENGTH:DIRECTION"),
        (("--sides", "2"), "at least 3 sides"),
        (("--trials", "1"), ">= 2"),
        (("--alpha", "1.5"), "(0, 1)"),
        (("--tolerance", "1"), "[0, 1)"),
        (("--method", "umbmark", "--sides", "8"), "squares only"),
        (("--robot", "no-such-robot.yaml"), "no-such-robot.yaml"),
        (("--trials", "100000", "--side-lengths", "0.1:10:0.1"), "too many"),
    ],
)
def test_cli_design_bad_inputs(cli, args, needle):
    cli("design", *args).expect_error(needle)


def test_cli_design_plot_into_a_file_fails_cleanly(cli, tmp_path):
    f = tmp_path / "file"
    f.write_text("x")
    cli("design", "--trials", "5", "--side-lengths", "1", "--plot", f).expect_error("file")


def test_report_json_and_plots_work_from_required_fields_only(tmp_path, capsys):
    """Candidates whose optional statistics are missing (NaN) still give a report, JSON and
    figures."""
    from odocal.cli.design import print_design
    from odocal.design import DesignResult, ErrorSummary
    from odocal.plot.design import design_figures

    cs = [cand(0.5 * (i + 1), m) for i, m in enumerate([0.2, 0.12, 0.1, 0.1])]
    floor = ErrorSummary(0.09, 0.04, (0.01, 0.2), 800)
    uncal = ErrorSummary(0.6, 0.07, (0.5, 0.7), 800)
    res = DesignResult(
        tuple(cs), floor, uncal, recommend(cs), ValidationTrack(4, 4.0, "ccw"), "heading", 5, 800
    )
    d = design_json(res, method_source="analytic")
    assert d["recommended"]["side_m"] == 1.5 and d["floor_m"] == 0.09
    assert d["candidates"][0]["residual_error_mean_m"] is None
    assert d["recommended_by_other_criterion"] is None
    json.dumps(d, allow_nan=False)
    print_design(res, "analytic robot")
    out = capsys.readouterr().out
    assert "Recommended: square, side 1.5 m" in out
    from odocal.io.outputs import OutputPlan

    figs = design_figures(res)
    plan = OutputPlan()
    plan.folder(tmp_path, "--plot")
    paths = plan.commit({tmp_path / name: fig for name, fig in figs.items()})
    assert len(paths) == 3 and all(p.stat().st_size > 5000 for p in paths)


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
