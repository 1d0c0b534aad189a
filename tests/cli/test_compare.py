"""``odocal compare``: the JSON and the table it prints, its figure, bad inputs, the real-data
section."""

from __future__ import annotations

import json

import pytest

import odocal.app.compare as app_compare
from odocal.app.compare import comparison_document
from tests.support.printed import as_printed

NAMES = [
    "heading",
    "umbmark-x",
    "umbmark-y",
    "umbmark-mean",
    "bcpt",
    "ivanjko",
    "linear",
    "trajectory",
]


def test_cli_json_shape(cli):
    status, out, err = cli("compare", "--trials", 6, "--seed", 2, "--json")
    assert status == 0, err
    doc = json.loads(out)
    assert doc["seed"] == 2 and doc["robot"] == "paper-fig5"
    sim = doc["simulated"]
    assert sim["trials"] == 6 and sim["budget"]["runs"] == 10
    assert [m["name"] for m in sim["methods"]] == NAMES
    for m in sim["methods"]:
        assert set(m) >= {
            "name",
            "drives",
            "sizes",
            "runs",
            "travel_m",
            "footprint_m",
            "failed_trials",
            "E_b_error",
            "E_d_error",
            "E_s_error",
            "final_error_m",
            "systematic_final_error_m",
        }
        assert set(m["E_b_error"]) == {"bias", "std"}
        assert set(m["final_error_m"]) == {"mean", "std", "p95"}
    assert "realdata" not in doc
    assert doc["plot"] is None  # no --plot: no figure

    # the figure (into a folder the command creates; the refusal of an unusable one:
    # test_cli_plot_folder_is_created_or_refused) and the same output for the same seed (JSON
    # and figure bytes): test_boundary_outputs.py, test_compare_plot_and_json_are_byte_identical


def test_cli_text_table(cli):
    status, out, err = cli("compare", "--trials", 4)
    assert status == 0, err
    for name in NAMES + ["nominal"]:
        assert name in out


@pytest.mark.parametrize(
    "args, message",
    [
        (["--trials", "1"], "--trials must be >= 2"),
        (["--trials", "0"], "--trials"),
        (["--runs", "2"], "--runs must be >= 3"),
        (["--seed", "-1"], "--seed"),
        (["--travel", "nan"], "--travel"),
        (["--realdata", "MISSING/optiodom"], "MISSING/optiodom"),
        (["--robot", "MISSING/robot.yaml"], "MISSING/robot.yaml"),
    ],
)
def test_cli_bad_input(cli, tmp_path, args, message):
    # MISSING: a folder that certainly does not exist (not a global path another run may create)
    missing = str(tmp_path / "missing")
    args = [a.replace("MISSING", missing) for a in args]
    message = message.replace("MISSING", missing)
    status, out, err = (
        cli("compare", "--trials", 3, *args) if "--trials" not in args else cli("compare", *args)
    )
    assert status == 2
    assert err.startswith("odocal: error:") and err.count("\n") == 1
    assert message in err
    assert "Traceback" not in err


def test_cli_plot_folder_is_created_or_refused(cli, tmp_path):
    blocker = tmp_path / "a-file"
    blocker.write_text("x")
    status, _, err = cli("compare", "--trials", 2, "--plot", blocker / "dir")
    assert status == 2 and err.count("\n") == 1 and str(blocker / "dir") in err
    assert not (blocker.parent / "compare.png").exists()
    # a new folder is created: tests/contracts/test_boundary_outputs.py,
    # test_compare_plot_and_json_are_byte_identical


def test_cli_realdata_folder_without_datasets(cli, tmp_path):
    status, _, err = cli("compare", "--trials", 2, "--realdata", tmp_path)
    assert status == 2 and "no OptiOdom data sets" in err and str(tmp_path) in err


def test_cli_realdata_unknown_circle_set(cli, realdata):
    base = realdata / "optiodom_diff"
    status, _, err = cli("compare", "--trials", 2, "--realdata", base, "--circle-set", "nope")
    assert status == 2 and err.count("\n") == 1
    assert "no circular data set 'nope'" in err and "231220200121" in err


def test_cli_realdata_json(cli, realdata, returned):
    results = returned(app_compare, "compare")
    base = realdata / "optiodom_diff"
    status, out, err = cli("compare", "--trials", 2, "--realdata", base, "--json")
    assert status == 0, err
    doc = json.loads(out)
    # the app's typed result, printed (its numbers: tests/app/test_compare.py)
    assert doc == as_printed(comparison_document(results[0], robot="paper-fig5", seed=0, plot=None))
    real = doc["realdata"]
    assert len(real["heldout_runs"]) == 13
    assert [m["name"] for m in real["methods"]] == NAMES
