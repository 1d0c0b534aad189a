"""``odocal design``: what it prints (text, JSON, figures), its options and bad inputs."""

from __future__ import annotations

import json

import pytest

import odocal.app.design as app_design
from odocal.design import (
    Candidate,
    ValidationTrack,
    design_json,
    recommend,
)
from tests.support.printed import as_printed


def test_cli_design_robot_from_prints_the_measured_robot(cli, realdata, returned):
    results = returned(app_design, "design")
    sq = realdata / "optiodom_diff" / "square" / "231220200029"
    status, out, err = cli("design", "--robot-from", sq, "--side-lengths", "0.5:1.5:0.5",
                           "--trials", "30", "--sigma-theta-deg", "0.5", "--json")  # fmt: skip
    assert status == 0, err
    d = json.loads(out)
    assert d == as_printed(results[0].as_dict())  # its numbers: tests/app/test_design.py
    assert d["robot_measured"]["measurement"]["source"] == "given"
    assert d["robot"] == f"robot measured from {sq}"


def cand(side, mean, std=0.01, n=800, sides=4):
    """A candidate with only the required fields (the optional ones NaN, as a source that does
    not compute them leaves them)."""
    return Candidate(
        sides=sides, side_m=side, travel_m=sides * side, systematic_share=0.9,
        post_error_mean_m=mean, post_error_std_m=std, post_error_ci95_m=(0.0, 1.0),
        E_b_mean=1.0, E_b_std=0.0, E_d_mean=1.0, E_d_std=0.0, trials=n,
    )  # fmt: skip


def test_cli_design_defaults_print_a_recommendation(cli):
    # the defaults but the trials: parsing and printing need no precise statistics
    status, out, err = cli("design", "--trials", "20")
    assert status == 0, err
    assert "paper-fig5" in out and "4 m x 4 m square CCW" in out
    assert "Recommended: square, side" in out
    assert "against the recommended" in out and "judged on the residual" in out
    assert out.count("square ") >= 20  # one row per candidate side 0.5 ... 10 m
    assert err == ""  # no progress bar when stderr is not a terminal


def test_cli_design_json_is_identical_for_identical_seeds(cli, returned):
    results = returned(app_design, "design")
    args = ("design", "--side-lengths", "1:3:1", "--trials", "40", "--json", "--seed", "3")
    s1, out1, _ = cli(*args)
    s2, out2, _ = cli(*args)
    assert s1 == s2 == 0 and out1 == out2
    d = json.loads(out1)
    assert d == as_printed(results[0].as_dict())  # the app's typed result, printed
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


def test_report_json_and_plots_work_from_required_fields_only(tmp_path):
    """Candidates whose optional statistics are missing (NaN) still give a report, JSON and
    figures."""
    from odocal.app.design_text import design_report
    from odocal.app.text import Text
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
    text = Text()
    design_report(text, res, "analytic robot")
    out = str(text)
    assert "Recommended: square, side 1.5 m" in out
    from odocal.io.outputs import OutputPlan

    figs = design_figures(res)
    plan = OutputPlan()
    plan.folder(tmp_path, "--plot")
    paths = plan.commit({tmp_path / name: fig for name, fig in figs.items()})
    assert len(paths) == 3 and all(p.stat().st_size > 5000 for p in paths)


def test_analytic_json_has_the_monte_carlo_contract(cli):
    status, out, err = cli("design", "--analytic", "--json", "--side-lengths", "1:4:1")
    assert status == 0, err
    data = json.loads(out)
    assert data["engine"] == "analytic"
    keys = {
        "sides",
        "side_m",
        "travel_m",
        "systematic_share",
        "post_error_mean_m",
        "post_error_std_m",
        "E_b_mean",
        "E_b_std",
        "E_d_mean",
        "E_d_std",
    }
    assert len(data["candidates"]) == 4
    for c in data["candidates"]:
        assert keys <= set(c)
    assert set(data["recommended"]) >= {"sides", "side_m"}
    assert data["floor_m"] < data["uncalibrated_m"]
    # the analytic mode is deterministic: no seed enters it
    assert (
        cli("design", "--analytic", "--json", "--side-lengths", "1:4:1", "--seed", "9")[1].replace(
            '"seed": 9', '"seed": 0'
        )
        == out
    )


def test_analytic_text_report_and_plots(cli, tmp_path):
    status, out, err = cli("design", "--analytic", "--plot", tmp_path, "--sides", 4, "--sides", 8)
    assert status == 0, err
    assert "first-order analytic" in out and "Recommended:" in out
    pngs = sorted(tmp_path.glob("*.png"))
    assert pngs and all(p.stat().st_size > 10_000 for p in pngs)
