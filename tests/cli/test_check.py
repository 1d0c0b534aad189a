"""`odocal check` and the 'Is this log enough?' section of `fit`, on the real OptiOdom runs."""

from __future__ import annotations

import json


def _ivanjko(realdata, runs):
    d = realdata / "optiodom_diff" / "ivanjko" / "250620201738"
    return [d / f"250620201738_run-{i:02d}.csv" for i in runs]


def test_straight_runs_alone_are_not_enough(cli, realdata):
    status, out, err = cli("check", *_ivanjko(realdata, range(1, 6)), "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["ok"] is False
    codes = {g["code"] for g in d["degeneracies"]}
    assert "straight-only" in codes
    assert any("turns in both directions" in s for s in d["suggestions"])
    # the wheelbase is the parameter a straight line cannot see
    assert d["stderr"]["wheelbase_m"] > 100 * d["stderr"]["wheel_diameter_right_m"]


def test_spins_alone_are_not_enough_and_the_text_says_why(cli, realdata):
    status, out, err = cli("check", *_ivanjko(realdata, range(6, 11)))
    assert status == 0, err
    assert "NOT enough" in out and "only spot turns" in out and "suggestion:" in out
    assert "turns only right" in out


def test_a_whole_data_set_is_enough(cli, realdata):
    status, out, err = cli("check", *_ivanjko(realdata, range(1, 16)), "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["ok"] is True and d["condition_number"] < 100
    assert d["noise_source"].startswith("default")


def test_fit_reports_the_check(cli, realdata):
    status, out, err = cli("fit", *_ivanjko(realdata, range(1, 16)), "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["log_check"]["ok"] is True
    assert set(d["log_check"]["stderr"]) == {
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
    }
    status, out, _ = cli("fit", *_ivanjko(realdata, range(1, 16)))
    assert status == 0 and "Is this log enough?" in out


def test_check_needs_a_nominal_geometry(cli, tmp_path):
    run = tmp_path / "run.csv"
    run.write_text(
        "time_s,wheel_right_rad,wheel_left_rad\n"
        + "".join(f"{i / 10},{i / 5},{i / 5}\n" for i in range(20))
    )
    cli("check", run).expect_error("--robot")
