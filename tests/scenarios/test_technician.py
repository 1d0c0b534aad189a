"""The technician's path (issue 13): a new robot, a tape measure and a protractor, from the run
sheet to a ros2_control file, with honest uncertainty and a stable recommendation.

The robot is TurtleBot3-sized (wheel diameter 0.066 m, wheelbase 0.160 m)."""

from __future__ import annotations

import json
import math
import subprocess
import sys

import numpy as np
import pytest

import odocal
from odocal.calibration.heading import calibrate_heading
from odocal.core.model import Robot
from odocal.core.runs import EndPoseRuns
from odocal.core.simulate import drive, measure
from odocal.core.tracks import polygon
from odocal.design.recommend import recommend
from odocal.design.robust import range_design
from odocal.design.spec import DesignSpec, scaled_sizes
from odocal.design.sweep import run_design
from odocal.io.ros2_export import read_ros2_params
from odocal.presets import PRESETS

TB3 = "wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n"
TB3_TRUE = odocal.make_robot(
    0.066, 0.160, E_b=1.02, E_d=1.004, k_r_m=1e-6, sigma_xy_m=0.01, sigma_theta_deg=1.0
)


@pytest.fixture
def tb3(tmp_path):
    p = tmp_path / "tb3.yaml"
    p.write_text(TB3 + "measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1.0}\n")
    return p


@pytest.fixture
def sheet(tmp_path):
    """5 CW + 5 CCW runs of the true TurtleBot on a 1 m square, track written into the sheet."""
    p = tmp_path / "runs.csv"
    odocal.simulate(TB3_TRUE, sides=4, side_m=1.0, runs=5, seed=3, out=p)
    return p


# --- 1. one export path ----------------------------------------------------------------------


def test_calibrate_writes_the_ros2_file_that_fit_writes(cli, tb3, sheet, tmp_path):
    ros2, params = tmp_path / "dd.yaml", tmp_path / "params.yaml"
    status, out, err = cli(
        "calibrate", sheet, "--robot", tb3, "--ros2", ros2, "--out", params, "--json"
    )
    assert status == 0, err
    data = json.loads(out)
    got = read_ros2_params(ros2)
    for key, v in (
        ("wheel_diameter_right_m", got.diameter_right_m),
        ("wheel_diameter_left_m", got.diameter_left_m),
        ("wheelbase_m", got.wheelbase_m),
    ):
        assert v == pytest.approx(data[key], rel=1e-15)
    text = ros2.read_text()
    # nominal base values, the calibration in the multipliers (as fit writes them)
    assert "wheel_separation: 0.16\n" in text and "wheel_radius: 0.033\n" in text
    assert "# method: heading" in text
    # the Python API writes the same file from the same result
    res = odocal.calibrate(sheet, tb3)
    again = tmp_path / "again.yaml"
    odocal.export(res, ros2=again)
    assert again.read_text() == text


# --- 2. no silent defaults -------------------------------------------------------------------


def test_the_track_comes_from_the_sheet_or_is_required(cli, tb3, sheet, tmp_path):
    res = odocal.calibrate(sheet, tb3)
    assert res.track == "4-gon side 1 m" and res.track_source == "run sheet"
    # the former silent 4 m default would have given E_d 1.0009 instead of about 1.004
    assert res.calibration.E_d == pytest.approx(1.004, abs=0.001)
    cli("calibrate", sheet, "--robot", tb3, "--side-length", 4).expect_error(
        "--side-length 4", "side_m: 1", "line 2"
    )
    bare = tmp_path / "bare.csv"
    bare.write_text("\n".join(sheet.read_text().splitlines()[2:]) + "\n")
    cli("calibrate", bare, "--robot", tb3).expect_error("which track", "--side-length")
    status, _, err = cli("calibrate", bare, "--robot", tb3, "--side-length", 1)
    assert status == 0, err


def test_plan_writes_the_track_as_data_that_calibrate_reads(cli, tb3, tmp_path):
    out = tmp_path / "sheet.csv"
    status, _, err = cli("plan", "--robot", tb3, "--side-length", 1.5, "--out", out, "--quiet")
    assert status == 0, err
    lines = out.read_text().splitlines()
    assert lines[:2] == ["# sides: 4", "# side_m: 1.5"]
    # fill in the headings only (protractor), as the sheet says the heading method allows
    filled = [ln.replace(",,,,", ",,,2.5,") if ln.startswith("cw") else ln for ln in lines]
    filled = [ln.replace(",,,,", ",,,-1.5,") if ln.startswith("ccw") else ln for ln in filled]
    out.write_text("\n".join(filled) + "\n")
    status, text, err = cli("calibrate", out, "--robot", tb3)
    assert status == 0, err
    assert "4-gon side 1.5 m (track from the run sheet)" in text


def test_wrapped_headings_give_the_same_result_in_any_row(tb3, sheet, tmp_path):
    lines = sheet.read_text().splitlines()
    h = next(i for i, ln in enumerate(lines) if ln.startswith("direction")) + 1
    head, rows = lines[:h], lines[h:]

    def typed(k: int, order) -> tuple[float, float, list]:
        r = list(rows)
        f = r[k].split(",")
        f[3] = repr(float(f[3]) - 360)  # the total turn typed instead of the error
        r[k] = ",".join(f)
        p = tmp_path / f"w{k}.csv"
        p.write_text("\n".join(head + [r[i] for i in order]) + "\n")
        res = odocal.calibrate(p, tb3)
        return res.calibration.E_b, res.calibration.E_d, list(res.warnings)

    ref = odocal.calibrate(sheet, tb3).calibration
    n = len(rows)
    for k, order in ((0, range(n)), (7, range(n)), (0, reversed(range(n)))):
        E_b, E_d, warnings = typed(k, list(order))
        assert E_b == pytest.approx(ref.E_b, rel=1e-12)  # float rounding only
        assert E_d == pytest.approx(ref.E_d, rel=1e-12)
        assert any("a full turn removed" in w and "line" in w for w in warnings)


def test_a_heading_that_is_not_a_deviation_is_refused(cli, tb3, tmp_path):
    p = tmp_path / "r.csv"
    p.write_text("# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg\ncw,,,250\nccw,,,-3\n")
    # 250 deg wraps to -110 deg: no square run deviates that much from its commanded turn
    cli("calibrate", p, "--robot", tb3).expect_error("line 4", "theta_deg", "deviation")


# --- 3. unit slips ---------------------------------------------------------------------------


def test_a_robot_file_in_millimetres_cannot_calibrate(cli, sheet, tmp_path):
    mm = tmp_path / "mm.yaml"
    mm.write_text("wheel_diameter_m: 66\nwheelbase_m: 160\n")
    cli("calibrate", sheet, "--robot", mm).expect_error("wheel_diameter_m: 66 m", "millimetres")
    cli("calibrate", sheet, "--robot", mm, "--side-length", 1).expect_error("millimetres")
    mixed = tmp_path / "mixed.yaml"
    mixed.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 160\n")
    cli("calibrate", sheet, "--robot", mixed).expect_error("mixed.yaml", "different units")
    params = tmp_path / "params.yaml"
    params.write_text("wheel_diameter_right_m: 66\nwheel_diameter_left_m: 66\nwheelbase_m: 0.16\n")
    cli("calibrate", sheet, "--robot", TB3_FILE(tmp_path), "--params", params).expect_error(
        "params.yaml", "different units"
    )
    cli("design", "--robot", mm, "--analytic", "--side-lengths", "1:4:1").expect_error(
        "millimetres"
    )


def TB3_FILE(tmp_path):
    p = tmp_path / "tb3-plain.yaml"
    p.write_text(TB3)
    return p


def test_end_errors_in_centimetres_are_refused(cli, tb3, tmp_path):
    p = tmp_path / "r.csv"
    p.write_text(
        "# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg\ncw,-10,-12,12\nccw,-2,2,-2\n"
    )
    cli("calibrate", p, "--robot", tb3, "--method", "umbmark").expect_error(
        "line 4", "x_m", "centimetres"
    )


# --- 4. uncertainty --------------------------------------------------------------------------


def test_calibrate_reports_its_uncertainty_in_text_and_json(cli, tb3, sheet):
    status, out, err = cli("calibrate", sheet, "--robot", tb3, "--json")
    assert status == 0, err
    d = json.loads(out)
    for key in ("E_b", "E_d", "wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        lo, hi = d["ci95"][key]
        assert lo < d[key] < hi and d["stderr"][key] > 0
    assert d["inputs"]["runs_cw"] == 5 and d["inputs"]["side_m"] == 1.0
    assert d["warnings"] == [] and d["track_source"] == "run sheet"
    assert d["nominal"]["wheelbase_m"] == 0.16
    status, text, _ = cli("calibrate", sheet, "--robot", tb3)
    assert "std error" in text and "95 % interval" in text


def test_the_intervals_cover_the_truth_95_percent_of_the_time():
    """Monte Carlo: 400 calibrations of 5 + 5 runs; the t-based delta-method intervals of E_b
    and E_d cover the true values in about 95 % of them (binomial sd 1.1 %: 4 sd bounds)."""
    robot = TB3_TRUE
    m, n, side = 400, 5, 1.0
    rng = np.random.default_rng(13)
    errs = {}
    for d in ("cw", "ccw"):
        res = drive(
            polygon(4, side, d), robot.true_geometry, robot.nominal, robot.nonsystematic,
            m * n, rng, steps_per_segment=1, integration="exact",
        )  # fmt: skip
        errs[d] = measure(res.errors, robot, rng).reshape(m, n, 3)
    truth = (robot.systematic.E_b, robot.systematic.E_d)
    hits = np.zeros(2)
    for i in range(m):
        runs = EndPoseRuns(("cw",) * n + ("ccw",) * n, np.vstack([errs["cw"][i], errs["ccw"][i]]))
        unc = calibrate_heading(runs, 4, side, robot.nominal).uncertainty
        ci = unc.ci95()
        hits += [ci["E_b"][0] <= truth[0] <= ci["E_b"][1], ci["E_d"][0] <= truth[1] <= ci["E_d"][1]]
    rate = hits / m
    assert np.all(np.abs(rate - 0.95) < 4 * math.sqrt(0.95 * 0.05 / m)), rate


# --- 5. a recommendation to trust --------------------------------------------------------------


def test_common_random_numbers_make_the_pick_stable_across_seeds():
    # the paper's conditions; candidates around the answer (the analytic limit picks 1.5 m).
    # Between 1.0 and 1.5 m the pick is a biased coin, not a constant: over seeds 0-11 it is
    # 1.5 m ten times and 1.0 m twice (1.5 m eight times under the random stream before
    # issue 12), never 0.5 or 2 m.
    sides = [0.5, 1.0, 1.5, 2.0, 4.0, 8.0]
    picks = [
        run_design(
            PRESETS["paper-fig5"],
            DesignSpec(side_lengths_m=tuple(sides), trials=800),
            np.random.default_rng(s),
            resamples=0,
        ).recommended.side_m
        for s in range(6)
    ]
    assert set(picks) <= {1.0, 1.5} and picks.count(1.5) >= 4, picks


def test_paired_tests_and_the_bootstrap_spread():
    r = run_design(
        PRESETS["paper-fig5"], DesignSpec(side_lengths_m=(0.5, 1.0, 2.0), trials=300),
        np.random.default_rng(0), resamples=50,
    )  # fmt: skip
    assert r.paired and r.recommendation.test == "paired"
    a, b = (c.post_errors_m for c in r.candidates[1:])
    # common random numbers: trial i of both candidates shares its validation noise
    assert np.corrcoef(a, b)[0, 1] > 0.8
    shares = dict(r.recommendation.spread)
    assert sum(shares.values()) == pytest.approx(1.0) and r.recommendation.resamples == 50
    indep = run_design(
        PRESETS["paper-fig5"], DesignSpec(side_lengths_m=(1.0, 2.0), trials=300),
        np.random.default_rng(0), common_random_numbers=False, resamples=0,
    )  # fmt: skip
    assert not indep.paired and indep.recommendation.test == "welch"
    assert abs(np.corrcoef(*(c.post_errors_m for c in indep.candidates))[0, 1]) < 0.2


def test_the_analytic_rule_compares_expected_values():
    res = odocal.design_track(engine="analytic").result
    assert res.trials is None and all(c.trials is None for c in res.candidates)
    rec = res.recommendation
    assert rec.test == "exact" and res.recommended.side_m == 1.5
    means = [c.post_error_mean_m for c in res.candidates]
    i = rec.index
    assert all(m >= 0.95 * means[i] for m in means[i + 1 :])  # nothing larger beats it by > 5 %
    assert any(m < 0.95 * means[i - 1] for m in means[i:])  # the next smaller one is beaten
    assert recommend(res.candidates).index == i


def test_a_warning_when_calibrating_would_not_help(cli, tmp_path):
    p = tmp_path / "good.yaml"
    p.write_text(
        TB3 + "systematic: {E_b: 1.0005, E_d: 1.00005}\nnonsystematic: {k_r_m: 2e-6, k_l_m: 2e-6}"
        "\nmeasurement: {sigma_xy_m: 0.03, sigma_theta_deg: 3}\n"
    )
    status, out, err = cli("design", "--robot", p, "--analytic", "--json")
    assert status == 0, err
    assert "would not beat the uncalibrated robot" in err
    assert json.loads(out)["warnings"]


# --- 6. a new robot --------------------------------------------------------------------------


def test_sizes_scale_with_the_robot():
    paper, v = scaled_sizes(0.385)
    assert paper[0] == 0.5 and paper[-1] == 10.0 and len(paper) == 20 and v.side_m == 4.0
    tb, v = scaled_sizes(0.16)
    assert tb[0] == 0.2 and tb[-1] == 4.0 and v.side_m == 1.6


def test_unknown_errors_are_designed_over_their_typical_range(cli, tmp_path, monkeypatch):
    import odocal.app.design as app_design

    bare = tmp_path / "bare.yaml"
    bare.write_text(TB3 + "measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1.0}\n")
    real, asked, results = app_design.design, [], []

    def design(*args, **kwargs):
        # what the command asks for (the progress bar aside); the design is computed once
        asked.append((args, {k: v for k, v in kwargs.items() if k != "progress"}))
        if not results:
            results.append(real(*args, **kwargs))
        return results[0]

    monkeypatch.setattr(app_design, "design", design)
    status, out, err = cli("design", "--robot", bare, "--side-lengths", "0.4:2.4:0.4", "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["engine"] == "analytic" and d["validation"]["side_m"] == 1.6
    assert set(d["error_range"]["unknown"]) == {"systematic", "nonsystematic"}
    assert d["recommended"]["within_best"] < 0.06
    # the text report of the same design: the command asks for the same design as with --json
    # and prints the result computed above
    status, out, err = cli("design", "--robot", bare, "--side-lengths", "0.4:2.4:0.4")
    assert status == 0, err
    assert len(asked) == 2 and asked[1] == asked[0]
    assert "Recommended: square" in out and "whatever the robot's errors" in out


def test_the_range_design_holds_for_every_plausible_robot():
    robot = Robot(TB3_TRUE.nominal, measurement=TB3_TRUE.measurement)
    lengths, validation = scaled_sizes(0.16)
    levels = {"E_b": (0.97, 1.03), "E_d": (0.995, 1.005), "k_m": (1e-7, 3e-6)}
    spec = DesignSpec(side_lengths_m=lengths[::2], validation=validation)
    d = range_design(robot, spec, levels=levels)
    assert len(d.scenarios) == 8
    i = d.index
    E = d.errors
    larger = [j for j, c in enumerate(d.candidates) if c.travel_m > d.candidates[i].travel_m]
    assert np.all(E[:, larger] >= 0.95 * E[:, [i]] - 1e-15)  # in every scenario
    # the report's figure is in the rule's measure: how much the best size beats it, as a share
    # of its own error (a regret of 5.1 % is 4.9 % of its error: within a 5 % rule)
    assert d.within == pytest.approx(float(np.max(1 - E.min(axis=1) / E[:, i])))
    best_is_larger = np.all(np.argmin(E, axis=1) >= i)
    assert not best_is_larger or d.within <= d.tolerance
    assert f"no size beats it by more than {100 * d.within:.1f} % of its error" in d.describe()
    if i > 0:  # the next smaller size is beaten for at least one plausible robot
        assert np.any(E[:, i:].min(axis=1) < 0.95 * E[:, i - 1])


# --- 7. progress -----------------------------------------------------------------------------


class _Tty:
    def __init__(self, tty: bool):
        self.tty, self.text = tty, ""

    def isatty(self):
        return self.tty

    def write(self, s):
        self.text += s

    def flush(self):
        pass


def test_progress_bar_only_on_a_terminal():
    from odocal.cli.common import ProgressBar

    for tty, enabled, drawn in ((True, True, True), (False, True, False), (True, False, False)):
        s = _Tty(tty)
        bar = ProgressBar("x", enabled=enabled, stream=s)
        bar(1, 2, "half")
        bar.close()
        assert ("[" in s.text) == drawn


def test_compare_reports_progress(monkeypatch):
    seen = []
    odocal.compare(trials=2, runs=10, progress=lambda d, t, w: seen.append((d, t)))
    assert seen and seen[-1][0] == seen[-1][1] and all(d <= t for d, t in seen)


# --- 9. the Python API -----------------------------------------------------------------------


def test_import_odocal_is_light_and_gives_the_everyday_api():
    code = (
        "import sys, odocal; assert 'numpy' not in sys.modules, 'eager import'; "
        "names = ['simulate', 'calibrate', 'fit', 'design_track', 'validate', 'export', "
        "'make_robot', 'Robot', 'WheelGeometry', 'DesignSpec']; "
        "assert all(callable(getattr(odocal, n)) for n in names); "
        "import odocal.design.sweep as s; assert odocal.design is sys.modules['odocal.design']; "
        "assert callable(odocal.design_track) and s.run_design"
    )
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert proc.returncode == 0, proc.stderr


def test_the_readme_python_example_runs(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    robot = odocal.make_robot(
        0.066, 0.160, E_b=1.02, E_d=1.004, k_r_m=1e-6, sigma_xy_m=0.01, sigma_theta_deg=1.0
    )
    odocal.simulate(robot, sides=4, side_m=1.0, runs=5, seed=1, out="runs.csv")
    cal = odocal.calibrate("runs.csv", robot)
    assert abs(cal.calibration.E_b - 1.02) < 4 * cal.calibration.uncertainty.stderr[0]
    odocal.export(cal, ros2="diff_drive.yaml")
    best = odocal.design_track(robot, odocal.DesignSpec(trials=200)).result.recommended
    assert 0.2 <= best.side_m <= 4.0
    with pytest.raises(odocal.InputError, match="different units"):
        odocal.make_robot(66, 0.16)


# --- numbers in the docs -----------------------------------------------------------------------


def test_the_readme_instrument_table_is_what_the_analytic_design_gives():
    """README's table of the recommended size against the instrument (written by
    benchmarks/bench_design_stability.py) agrees with the code: analytic, so deterministic."""
    from pathlib import Path

    from odocal.design.reproduce import precision_sweep

    readme = (Path(__file__).resolve().parents[2] / "README.md").read_text()
    rows = [line for line in readme.splitlines() if line.startswith("| ") and " deg | " in line]
    sweep = precision_sweep(PRESETS["paper-fig5"])
    heading = sweep.recommended_side_m[("heading", "error")]
    umbmark = sweep.recommended_side_m[("umbmark", "error")]
    assert len(rows) == len(heading) == 6
    for row, h, u in zip(rows, heading, umbmark, strict=True):
        cells = [c.strip() for c in row.strip("|").split("|")]
        assert cells[1:] == [f"{h:g} m", f"{u:g} m"], row
