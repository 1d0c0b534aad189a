"""``odocal fit FOLDERS --method auto``: the procedure chosen by leave-one-data-set-out error."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from odocal.core.model import WheelGeometry
from odocal.design import run_procedures as rp
from odocal.design.run_procedures import (
    LodoTable,
    Procedure,
    ScoredProcedure,
    choose,
    selection_corrected,
)

# Small real subsets: two 1.7 m square sets of 2 runs each and two short Ivanjko sets (10 runs,
# 4 data sets; every method and kind, quick to fit); a 0.75 m set beside them for the candidates.
SUBSET = (
    "square/231220200045",
    "square/231220200048",
    "ivanjko/231220200104",
    "ivanjko/231220200107",
)
JUNE = "square/230620202042"


def _table(folds: dict[Procedure, tuple[float, ...]], runs: dict[Procedure, int]) -> LodoTable:
    n = len(next(iter(folds.values())))
    cands = tuple(ScoredProcedure(p, runs[p], 2, e) for p, e in folds.items())
    return LodoTable(tuple(f"s{i}" for i in range(n)), (1,) * n, ("square",) * n, cands)


def test_the_rules_pick_the_lowest_or_the_simplest_within_one_standard_error():
    big = Procedure("trajectory")
    small = Procedure("heading", ("square",), 1.7)
    far = Procedure("umbmark", ("square",))
    folds = {
        big: (0.010, 0.012, 0.008, 0.010),  # mean 10 mm, SE 0.82 mm
        small: (0.011, 0.011, 0.010, 0.0105),  # mean 10.6 mm: within one SE of the lowest
        far: (0.020, 0.021, 0.019, 0.020),
    }
    table = _table(folds, {big: 40, small: 8, far: 20})
    assert choose(table, "lowest")[0].procedure == big
    assert choose(table, "one-se")[0].procedure == small
    # Tibshirani & Tibshirani: the winner's mean plus its mean excess over each fold's minimum
    excess = np.mean(np.subtract(folds[big], np.minimum(folds[big], folds[small])))
    assert selection_corrected(table, choose(table)[0]) == pytest.approx(0.010 + excess)
    assert selection_corrected(table, choose(table)[0]) >= 0.010


def test_a_failed_candidate_is_listed_but_never_chosen():
    ok, bad = Procedure("trajectory"), Procedure("heading", ("square",))
    table = LodoTable(
        ("a", "b"),
        (1, 1),
        ("square", "square"),
        (ScoredProcedure(ok, 4, 2, (0.02, 0.03)), ScoredProcedure(bad, 4, 2, (), "no squares")),
    )
    assert choose(table)[0].procedure == ok
    assert math.isnan(table.candidates[1].mean_m)


@pytest.fixture(scope="module")
def subset(realdata):
    from odocal.io.recordings import load_recordings

    base = realdata / "optiodom_diff"
    return load_recordings([base / p for p in SUBSET])


@pytest.fixture(scope="module")
def auto(subset):
    from odocal.app.fit_runs_auto import fit_runs_auto

    return fit_runs_auto(subset)


def test_candidates_cover_methods_kinds_and_sides_with_two_data_sets_each(subset, realdata):
    from odocal.io.recordings import load_recordings

    labels = [p.label for p in rp.candidate_procedures(subset)]
    # one side only: the per-side candidates are the all-squares ones, listed once
    assert sorted(labels) == sorted(
        [
            "trajectory on every run",
            "trajectory on ivanjko",
            "trajectory on square",
            "heading on square",
            "umbmark on square",
        ]
    )
    june = load_recordings([realdata / "optiodom_diff" / JUNE])
    labels = {p.label for p in rp.candidate_procedures(list(subset) + june)}
    assert {"heading on square 1.7 m", "umbmark on square 1.7 m", "heading on square"} <= labels
    # one 0.75 m data set only: nothing can be left out of it
    assert not any("0.75" in label for label in labels)


def test_the_table_agrees_with_each_candidate_fitted_by_hand_on_one_fold(subset, auto):
    # independent path: the app's fit (with its bands, covariances) and core.odometry.evaluate
    from odocal.app.fit_runs import fit_recordings
    from odocal.core.odometry import evaluate

    nominal = auto.fit.nominal
    fold = auto.table.data_sets.index("231220200048")
    rest = [r for r in subset if r.dataset != "231220200048"]
    left = [r for r in subset if r.dataset == "231220200048"]
    for c in auto.table.scored():
        if c.procedure.label not in ("heading on square", "trajectory on every run"):
            continue
        geo = fit_recordings(c.procedure.runs(rest), c.procedure.method, nominal=nominal).geometry
        by_hand = np.mean([evaluate(r, geo)["final_error_m"] for r in left])
        assert c.fold_errors_m[fold] == pytest.approx(by_hand, rel=1e-6)
    # the mean and its standard error are those of the fold errors
    best = auto.chosen
    assert best.mean_m == pytest.approx(np.mean(best.fold_errors_m))
    assert best.stderr_m == pytest.approx(np.std(best.fold_errors_m, ddof=1) / np.sqrt(4))
    assert best.mean_m == min(c.mean_m for c in auto.table.scored())
    assert auto.fit.fit.method == best.procedure.method
    assert sorted(auto.fit.fit.runs) == sorted(r.name for r in best.procedure.runs(subset))


def test_the_selection_sees_only_the_given_runs_and_never_the_left_out_set(subset, monkeypatch):
    """Every fit of the folds sees given runs outside the left-out data set; every evaluation
    is of the left-out set's runs only."""
    events: list[tuple[str, frozenset[str]]] = []
    fit, errors = rp.fit_procedure, rp.heldout_errors

    def spy_fit(procedure, recordings, nominal, ran_with=None):
        events.append(("fit", frozenset(r.name for r in procedure.runs(recordings))))
        return fit(procedure, recordings, nominal, ran_with)

    def spy_errors(runs, geometry):
        events.append(("eval", frozenset(r.name for r in runs)))
        return errors(runs, geometry)

    monkeypatch.setattr(rp, "heldout_errors", spy_errors)
    cheap = [p for p in rp.candidate_procedures(subset) if p.method != "trajectory"]
    rp.lodo_table(subset, cheap, WheelGeometry(0.084, 0.084, 0.2), fit=spy_fit)
    given = {r.name for r in subset}
    set_of = {r.name: r.dataset for r in subset}
    assert events and all(names <= given for _, names in events)
    evaluated = set()
    for (kind, fitted), (kind2, scored) in zip(events[::2], events[1::2], strict=True):
        assert (kind, kind2) == ("fit", "eval")
        (left_out,) = {set_of[n] for n in scored}  # one data set per evaluation
        assert left_out not in {set_of[n] for n in fitted}
        evaluated.add(left_out)
    assert evaluated == {r.dataset for r in subset}


def test_the_command_prints_the_table_and_writes_json(cli, realdata, tmp_path):
    base = realdata / "optiodom_diff"
    paths = [base / p for p in SUBSET[:3]]
    params = tmp_path / "params.yaml"
    status, out, err = cli("fit", *paths, "--method", "auto", "--json", "--out", params)
    assert status == 0, err
    doc = json.loads(out)
    assert doc["method"] == "auto" and params.exists()
    rows = [r for r in doc["table"] if r["failed"] is None]
    best = min(rows, key=lambda r: r["lodo_mean_error_m"])
    assert doc["choice"]["procedure"] == best["procedure"]
    assert doc["choice"]["selection_corrected_error_m"] >= best["lodo_mean_error_m"]
    assert doc["fit"]["method"] == best["method"]
    assert {f["data_set"] for f in doc["folds"]} == {p.name for p in paths}


def test_one_data_set_cannot_be_left_out(cli, realdata, tmp_path):
    params = tmp_path / "params.yaml"
    one = realdata / "optiodom_diff" / "square" / "231220200045"
    cli("fit", one, "--method", "auto", "--out", params).expect_error(
        "leaving one data set out", "1 data set"
    )
    assert not params.exists()


def test_folders_without_runs_are_refused(cli, tmp_path):
    empty = tmp_path / "empty"
    empty.mkdir()
    (empty / "notes.txt").write_text("nothing here\n")
    params = tmp_path / "params.yaml"
    cli("fit", empty, "--method", "auto", "--out", params).expect_error()
    assert not params.exists()


def test_settings_and_figures_are_refused_for_auto_on_runs(cli, realdata, tmp_path):
    base = realdata / "optiodom_diff" / "square"
    two = [base / "231220200045", base / "231220200048"]
    cli("fit", *two, "--method", "auto", "--heading-weight", "1").expect_error("default settings")
    cli("fit", *two, "--method", "auto", "--plot", tmp_path / "fig").expect_error("--plot")
    assert not (tmp_path / "fig").exists()
