"""The paper's experiment on the real OptiOdom robot (odocal reproduce --realdata): the JSON
contract, the real numbers, the verdict, the report and figures (the replay that predicts it is
tested in tests/core/test_replay.py, the paired t-test in tests/core/test_stats.py)."""

from __future__ import annotations

import json

import numpy as np
import pytest


@pytest.fixture(scope="module")
def produced(realdata, tmp_path_factory):
    """``odocal reproduce --realdata ... --out ... --json`` as the app runs it: the JSON (through
    the same finite-only encoding as the CLI), the output folder and the typed result."""
    from odocal.app.reproduce import reproduce

    out = tmp_path_factory.mktemp("real")
    res = reproduce(out / "rep", trials=40, realdata=realdata / "optiodom_diff")
    doc = json.loads(json.dumps(res.as_dict(), allow_nan=False))
    return doc, out / "rep", res


def test_json_contract(produced):
    d, _, _ = produced
    r = d["real_experiment"]
    assert [s["side_m"] for s in r["squares"]] == [0.75, 1.7]
    for s in r["squares"]:
        assert {"side_m", "E_b", "E_d", "heldout_error_m"} <= set(s)
        assert s["method"] == "heading" and s["scope"] == "pooled"
    assert set(r["design"]["predicted_error_m"]) == {"0.75", "1.7"}
    assert r["design"]["preferred_side_m"] > 0
    assert {"t", "p_two_sided", "df", "kind"} <= set(r["ttest"])
    assert r["heldout"]["count"] == 19
    assert r["reference"] == {
        "wheel_diameter_right_m": 0.084, "wheel_diameter_left_m": 0.084, "wheelbase_m": 0.2,
    }  # fmt: skip
    assert "text" in r["verdict"] and r["verdict"]["text"].split(".")[0] in ("Yes", "Partly", "No")


def test_real_numbers(produced):
    """Deterministic real results (bench_real_experiment.py, README): the heading method pooled
    over each size, relative to the nominal geometry, validated on the 19 held-out runs."""
    r = produced[0]["real_experiment"]
    small, large = r["squares"]
    assert small["E_b"] == pytest.approx(1.00701, abs=1e-5)
    assert large["E_b"] == pytest.approx(1.01236, abs=1e-5)
    assert small["heldout_error_m"] == pytest.approx(0.0334, abs=2e-4)
    assert large["heldout_error_m"] == pytest.approx(0.0125, abs=2e-4)
    assert r["ttest"]["t"] == pytest.approx(4.78, abs=0.01)
    assert r["ttest"]["p_two_sided"] < 0.001
    # per data set: relative to the firmware values the gain changes by under 0.06 %
    for c in r["per_data_set"]:
        rw = c.get("relative_to_ran_with")
        if rw:
            assert abs(rw["turning_gain_difference"]) / c["turning_gain"] < 6e-4


def test_the_verdict_says_no(produced):
    """The model predicts no real difference between the sizes (|difference| within a few mm at
    40 trials: std about 3 mm / sqrt(40)), the real one is 21 mm the other way."""
    v = produced[0]["real_experiment"]["verdict"]
    assert abs(v["predicted_difference_m"]) < 0.003
    assert v["real_difference_m"] == pytest.approx(0.0209, abs=3e-4)
    assert not v["difference_within_prediction"]
    # one experiment like the real one: the model expects no significant difference (at any
    # trial count: only a few % of its simulated experiments are significant), the real one is
    assert v["predicted_outcome"] == "no significant difference"
    assert v["real_outcome"] == "1.7 m better" and not v["ordering_predicted"]
    assert v["text"].startswith("No.")
    assert "0.057 m/s" in v["text"] and "1.01 rad/s" in v["text"]


def test_the_verdict_is_typed(produced):
    """The verdict the JSON and the words come from: typed fields, judged once in app."""
    doc, _, res = produced
    exp, v = res.real, res.verdict
    assert v is not None and exp is not None
    assert v.sides_m == exp.sides_m == (0.75, 1.7)
    assert v.answer == "No" and not v.ordering_predicted
    assert v.real_outcome == 1.7 and v.predicted_outcome is None
    small, large = (exp.calibration(s) for s in exp.sides_m)
    assert v.real_difference_m == small.heldout_error_m - large.heldout_error_m
    assert v.real_error_m == (small.heldout_error_m, large.heldout_error_m)
    assert v.predicted_difference_ci95_m == exp.prediction.ttest.difference_ci95_m
    j = doc["real_experiment"]["verdict"]
    assert j["real_outcome"] == "1.7 m better" and j["ordering_predicted"] is False
    # the evidence behind the words: the sizes were not driven alike, spot turns and arcs differ
    e = v.evidence
    assert not e.driven_alike and e.spot_wheelbase_m and e.arc_wheelbase_m
    assert e.best_gain == pytest.approx(float(exp.gain_grid[np.nanargmin(exp.gain_curve_m)]))
    # typed evidence, keyed by side (not by formatted text)
    assert set(exp.profiles) == set(exp.closing) == set(exp.turning.squares) == {0.75, 1.7}
    assert list(exp.turning.named()) == ["0.75 m squares", "1.7 m squares", "held-out runs"]
    assert exp.ttests["heading"].paired.t == pytest.approx(doc["real_experiment"]["ttest"]["t"])
    assert set(doc["real_experiment"]["motion"]) == {"0.75", "1.7", "heldout"}


def test_report_and_figures(produced):
    _, folder, _ = produced
    text = (folder / "REPORT.md").read_text()
    assert "The experiment on a real robot (OptiOdom)" in text
    assert "### Verdict" in text and "paired t" in text
    for name in ("real_design_vs_real.png", "real_turning_gain.png",
                 "real_effective_wheelbase.png", "fig5_square_post_error.png"):  # fmt: skip
        assert (folder / name).stat().st_size > 5000, name
