"""``odocal check`` and the 'Is this log enough?' section of ``fit``: what they print, exit codes
(the check itself, on the real OptiOdom runs: tests/app/test_check.py)."""

from __future__ import annotations

import json

import odocal.app.check as app_check
from odocal.io.generic_csv import write_generic_csv
from tests.support.printed import as_printed
from tests.support.recorded_runs import mixed_runs


def _ivanjko(realdata, runs):
    d = realdata / "optiodom_diff" / "ivanjko" / "250620201738"
    return [d / f"250620201738_run-{i:02d}.csv" for i in runs]


def test_not_enough_is_exit_status_3_also_with_json(cli, realdata):
    status, out, err = cli("check", *_ivanjko(realdata, range(1, 6)), "--json")
    assert status == 3, err
    assert json.loads(out)["ok"] is False


def test_spins_alone_are_not_enough_and_the_text_says_why(cli, realdata):
    status, out, err = cli("check", *_ivanjko(realdata, range(6, 11)))
    assert status == 3, err
    assert "NOT enough" in out and "only spot turns" in out and "suggestion:" in out
    assert "turns only right" in out


def test_fit_reports_the_check(cli, realdata, returned):
    import odocal.app.fit as app_fit

    results = returned(app_fit, "fit")
    status, out, err = cli("fit", *_ivanjko(realdata, range(1, 16)), "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["log_check"]["ok"] is True
    assert set(d["log_check"]["stderr"]) == {
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
    }
    # the text `odocal fit` prints without --json (cli.fit prints res.text()): the same fit,
    # not computed twice
    (res,) = results
    assert "Is this log enough?" in res.text()


def test_check_json_is_the_app_result(cli, tmp_path, returned):
    results = returned(app_check, "check")
    folder = tmp_path / "runs"
    folder.mkdir()
    for r in mixed_runs():
        write_generic_csv(folder / f"{r.name}.csv", r)
    status, out, err = cli("check", folder, "--json")
    assert status == 0, err
    assert json.loads(out) == as_printed(results[0].as_dict())  # its numbers: tests/app
    status, out, err = cli("check", folder)
    assert status == 0 and out.startswith("Is this log enough? 6 run(s)")


def test_check_needs_a_nominal_geometry(cli, tmp_path):
    run = tmp_path / "run.csv"
    run.write_text(
        "time_s,wheel_right_rad,wheel_left_rad\n"
        + "".join(f"{i / 10},{i / 5},{i / 5}\n" for i in range(20))
    )
    cli("check", run).expect_error("--robot")
