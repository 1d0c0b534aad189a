"""odocal fit: linear and trajectory least squares, UMBmark/heading on recorded squares, exports."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
import yaml

from odocal.calibration.fit_settings import TrajectorySettings
from odocal.calibration.linear import fit_linear, linear_geometry_trials
from odocal.calibration.squares import fit_recorded_squares
from odocal.calibration.trajectory import fit_trajectory, fit_trajectory_trials
from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.errors import CalibrationError
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import load_params
from odocal.io.ros2_export import read_ros2_params, ros2_params_yaml

NOMINAL = WheelGeometry(0.15, 0.15, 0.385)
TRUE = NOMINAL.with_systematic(SystematicError(E_b=1.02, E_d=1.004, E_s=0.99))


def wheel_angles(primitives, believed: WheelGeometry, step_m=0.01):
    """Cumulative wheel angles (rad) of an open-loop run of (kind, a, b) primitives as the
    controller with ``believed`` geometry commands them: ('straight', d), ('spin', psi),
    ('arc', rho, psi)."""
    r_list, l_list = [np.zeros(1)], [np.zeros(1)]
    b = believed.wheelbase_m
    for p in primitives:
        if p[0] == "straight":
            s_r = s_l = p[1]
        elif p[0] == "spin":
            s_r, s_l = p[1] * b / 2, -p[1] * b / 2
        else:
            rho, psi = p[1], p[2]
            s_r, s_l = (rho + b / 2) * psi, (rho - b / 2) * psi
        n = max(2, int(math.ceil(max(abs(s_r), abs(s_l)) / step_m)))
        f = np.arange(1, n + 1) / n
        r_list.append(r_list[-1][-1] + f * 2 * s_r / believed.diameter_right_m)
        l_list.append(l_list[-1][-1] + f * 2 * s_l / believed.diameter_left_m)
    return np.concatenate(r_list), np.concatenate(l_list)


def make_run(name, primitives, true=TRUE, believed=NOMINAL, label=None, noise=None, side=None):
    right, left = wheel_angles(primitives, believed)
    gt = dead_reckon(right, left, true)
    if noise is not None:
        gt = gt + noise
    return Recording(
        name=name,
        time_s=np.arange(len(right)) * 0.05,
        wheel_angle_right_rad=right,
        wheel_angle_left_rad=left,
        ground_truth=gt,
        ran_with=believed,
        label=label,
        meta={"side_m": side} if side else {},
    )


def square(direction, side=2.0):
    s = 1 if direction == "ccw" else -1
    return [p for _ in range(4) for p in (("straight", side), ("spin", s * math.pi / 2))]


def mixed_runs(true=TRUE):
    return [
        make_run("straight", [("straight", 3.0)], true),
        make_run("spin-ccw", [("spin", math.pi)], true),
        make_run("arc-cw", [("arc", 1.0, -math.pi)], true),
        make_run("arc-ccw", [("arc", 0.7, 1.5 * math.pi), ("straight", 1.0)], true),
        make_run("sq-cw", square("cw"), true),
        make_run("sq-ccw", square("ccw"), true),
    ]


def values(g):
    return np.array([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m], dtype=float)


def test_linear_is_exact_on_noise_free_data():
    fit = fit_linear(mixed_runs(), NOMINAL)
    # exact up to floating point: the estimator is linear and the data noise-free
    np.testing.assert_allclose(values(fit.geometry), values(TRUE), rtol=1e-9)
    assert fit.linear.wheelbase_from_right_m == pytest.approx(TRUE.wheelbase_m, rel=1e-9)
    assert fit.linear.wheelbase_from_left_m == pytest.approx(TRUE.wheelbase_m, rel=1e-9)


def test_linear_needs_independent_runs():
    runs = [make_run("a", [("straight", 2.0)]), make_run("b", [("straight", 3.0)])]
    with pytest.raises(CalibrationError, match="independent"):
        fit_linear(runs, NOMINAL)


@pytest.mark.parametrize("residual", ["pose", "segment"])
def test_trajectory_is_exact_on_noise_free_data(residual):
    fit = fit_trajectory(
        mixed_runs(), nominal=NOMINAL, settings=TrajectorySettings(residual=residual)
    )
    # the optimiser stops at xtol 1e-12 relative; the fit is exact
    np.testing.assert_allclose(values(fit.geometry), values(TRUE), rtol=1e-8)
    assert not fit.outliers


def test_trajectory_reports_every_residual_evaluation(monkeypatch):
    """The fit's optimizer report counts the residual's evaluations, its finite-difference
    Jacobian's too (scipy's nfev leaves those out for Levenberg-Marquardt)."""
    import scipy.optimize

    calls = []
    real = scipy.optimize.least_squares

    def spy(fun, x0, **options):
        return real(lambda p: calls.append(1) or fun(p), x0, **options)

    monkeypatch.setattr(scipy.optimize, "least_squares", spy)
    fit = fit_trajectory(mixed_runs(), NOMINAL, nominal=NOMINAL)  # one start: one solve
    report = fit.trajectory.optimizer
    assert fit.trajectory.starts_tried == 1
    assert report.evaluations == len(calls) > report.nfev


def test_trajectory_noise_stderr_and_outlier():
    rng = np.random.default_rng(7)
    runs = []
    for i in range(8):
        base = make_run(f"run{i}", square("cw" if i % 2 else "ccw") + [("arc", 1.0, 2.0)])
        n = len(base.time_s)
        # 2 mm / 0.2 deg white measurement noise on the ground truth
        noise = np.column_stack(
            [rng.normal(0, 2e-3, n), rng.normal(0, 2e-3, n), rng.normal(0, 3.5e-3, n)]
        )
        noise[0] = 0
        runs.append(
            make_run(base.name, square("cw" if i % 2 else "ccw") + [("arc", 1.0, 2.0)], noise=noise)
        )
    fit = fit_trajectory(runs, nominal=NOMINAL)
    err = values(fit.geometry) - values(TRUE)
    se = np.array(
        [fit.stderr[k] for k in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")]
    )
    # white noise on 8 long runs: the estimate lies within 5 formal standard errors (the formal
    # errors assume exactly this independent noise), and those are below 0.1 % of the values
    assert np.all(np.abs(err) < 5 * se)
    assert np.all(se < 1e-3 * values(TRUE))
    # one run whose right wheel slips by 3 % over its second half: flagged, and refitting
    # without it recovers the truth as well as before
    bad = runs[3]
    right = bad.wheel_angle_right_rad.copy()
    k = len(right) // 2
    right[k:] = right[k] + 1.03 * (right[k:] - right[k])
    runs[3] = Recording(
        bad.name, bad.time_s, right, bad.wheel_angle_left_rad, bad.ground_truth, ran_with=NOMINAL
    )
    flagged = fit_trajectory(runs, nominal=NOMINAL)
    assert flagged.outliers == ["run3"] and flagged.warnings
    dropped = fit_trajectory(runs, nominal=NOMINAL, settings=TrajectorySettings(drop_outliers=True))
    assert dropped.excluded == ["run3"] and "run3" not in dropped.runs
    assert np.all(np.abs(values(dropped.geometry) - values(TRUE)) < 5 * se)
    excluded = fit_trajectory(runs, nominal=NOMINAL, settings=TrajectorySettings(exclude=["run3"]))
    np.testing.assert_allclose(values(excluded.geometry), values(dropped.geometry), rtol=1e-9)
    with pytest.raises(CalibrationError, match="matches no run"):
        fit_trajectory(runs, nominal=NOMINAL, settings=TrajectorySettings(exclude=["nope"]))


def test_batched_fits_of_many_trials_match_the_fits_of_each_trial():
    # Two groups of runs that share their wheel angles (as the simulated comparison's runs do),
    # 3 trials x 2 runs each, 3 mm / 0.3 deg white noise on the ground truth.
    rng = np.random.default_rng(3)
    tracks = (square("cw") + [("arc", 1.0, 2.0)], square("ccw") + [("arc", 1.5, -1.0)])
    base = [make_run(f"g{i}", t) for i, t in enumerate(tracks)]
    angles = [np.column_stack([r.wheel_angle_right_rad, r.wheel_angle_left_rad]) for r in base]
    sigma = np.array([3e-3, 3e-3, 5e-3])
    truth = [r.ground_truth + sigma * rng.standard_normal((3, 2, len(r.time_s), 3)) for r in base]
    batched = fit_trajectory_trials(angles, truth, NOMINAL)
    lin = linear_geometry_trials([a for a in angles for _ in range(2)],
                                 np.concatenate([t[:, :, -1] for t in truth], axis=1))  # fmt: skip
    for m in range(3):
        recs = [
            Recording(f"{i}-{j}", r.time_s, *angles[i].T, truth[i][m, j])
            for i, r in enumerate(base)
            for j in range(2)
        ]
        # the same minimum from the same start (scipy stops when the cost changes by less than
        # 1e-12 relative, which pins the parameters to about 1e-9)
        single = fit_trajectory(recs, NOMINAL, nominal=NOMINAL).geometry
        np.testing.assert_allclose(batched[m], values(single), rtol=1e-8)
        np.testing.assert_allclose(lin[m], values(fit_linear(recs).geometry), rtol=1e-10)
    # noise free: exact
    exact = fit_trajectory_trials(angles, [r.ground_truth[None, None] for r in base], NOMINAL)
    np.testing.assert_allclose(exact[0], values(TRUE), rtol=1e-10)


def test_swapped_wheels_are_reported():
    runs = mixed_runs()
    swapped = [
        Recording(
            r.name,
            r.time_s,
            r.wheel_angle_left_rad,
            r.wheel_angle_right_rad,
            r.ground_truth,
            ran_with=NOMINAL,
        )
        for r in runs
    ]
    with pytest.raises(CalibrationError, match="swapped"):
        fit_linear(swapped, NOMINAL)
    # the trajectory fit lands in a positive but absurd minimum (b 68 % below nominal): warned
    fit = fit_trajectory(swapped, nominal=NOMINAL)
    assert any("absurd" in w and "swapped" in w for w in fit.warnings)


def test_heading_and_umbmark_on_recorded_squares_directions_from_the_data():
    side = 3.0
    # labels deliberately wrong on one run: the direction comes from the total rotation
    runs = [make_run(f"cw{i}", square("cw", side), label="cw", side=side) for i in range(2)]
    runs += [make_run("ccw0", square("ccw", side), label="cw", side=side)]
    runs += [make_run("ccw1", square("ccw", side), label="ccw", side=side)]
    true_ratio = TRUE.diameter_ratio
    fit = fit_recorded_squares(runs, "heading", nominal=NOMINAL)
    # the heading method is exact under the model (model.md); it keeps the nominal mean
    # diameter, so compare the scale-free quantities
    assert fit.geometry.diameter_ratio == pytest.approx(true_ratio, rel=1e-9)
    assert fit.geometry.wheelbase_m / fit.geometry.mean_diameter_m == pytest.approx(
        TRUE.wheelbase_m / TRUE.mean_diameter_m, rel=1e-9
    )
    assert fit.geometry.mean_diameter_m == pytest.approx(NOMINAL.mean_diameter_m)
    assert any("ccw0" in w and "CCW" in w for w in fit.warnings)
    um = fit_recorded_squares(runs, "umbmark", nominal=NOMINAL)
    # UMBmark is small-angle: E_b 2 %, E_d 0.4 % on a 3 m square are reproduced to ~1e-3
    assert um.geometry.diameter_ratio == pytest.approx(true_ratio, rel=1e-3)
    with pytest.raises(CalibrationError, match="not a closed square"):
        fit_recorded_squares(runs + [make_run("line", [("straight", 2.0)], side=side)], "heading")


def test_ros2_export_reproduces_the_geometry_exactly(tmp_path):
    cal = WheelGeometry(0.1497, 0.1503, 0.3911)
    path = tmp_path / "ros2.yaml"
    path.write_text(ros2_params_yaml(cal, NOMINAL, "my_ctrl"))
    doc = yaml.safe_load(path.read_text())["my_ctrl"]["ros__parameters"]
    assert doc["wheel_separation"] == NOMINAL.wheelbase_m
    assert doc["wheel_radius"] == NOMINAL.mean_diameter_m / 2
    # effective radius = wheel_radius x multiplier, separation = wheel_separation x multiplier;
    # values are written with repr (round-trip), so the products agree to an ulp or two
    eff = read_ros2_params(path, "my_ctrl")
    np.testing.assert_allclose(values(eff), values(cal), rtol=1e-15, atol=0)
    assert 2 * doc["wheel_radius"] * doc["right_wheel_radius_multiplier"] == pytest.approx(
        cal.diameter_right_m, rel=1e-15
    )


def _write_runs(folder, runs):
    folder.mkdir()
    for r in runs:
        write_generic_csv(folder / f"{r.name}.csv", r)
    return folder


def test_fit_cli_json_out_and_ros2(tmp_path, cli):
    folder = _write_runs(tmp_path / "runs", mixed_runs())
    robot = tmp_path / "robot.yaml"
    robot.write_text("wheel_diameter_m: 0.15\nwheelbase_m: 0.385\n")
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    status, stdout, err = cli(
        "fit", folder, "--robot", robot, "--json", "--out", out, "--ros2", ros2
    )
    assert status == 0, err
    d = json.loads(stdout)
    for key in (
        "method",
        "wheel_diameter_right_m",
        "wheel_diameter_left_m",
        "wheelbase_m",
        "stderr",
        "runs",
    ):
        assert key in d
    assert d["method"] == "trajectory" and len(d["runs"]) == 6
    # the CSV stores 10 significant digits, so the fit is exact to about 1e-8
    np.testing.assert_allclose(values(load_params(out)), values(TRUE), rtol=1e-7)
    np.testing.assert_allclose(values(read_ros2_params(ros2)), values(load_params(out)), rtol=1e-8)
    status, stdout, _ = cli("fit", folder, "--robot", robot, "--method", "linear")
    assert status == 0 and "linear fit from 6 run(s)" in stdout


def test_fit_cli_errors(tmp_path, cli):
    # runs without metadata (no 'ran with' parameters): the nominal geometry is unknown
    runs = [
        Recording(r.name, r.time_s, r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.ground_truth)
        for r in mixed_runs()
    ]
    swapped = [
        Recording(r.name, r.time_s, r.wheel_angle_left_rad, r.wheel_angle_right_rad, r.ground_truth)
        for r in runs
    ]
    folder = _write_runs(tmp_path / "swapped", swapped)
    out = tmp_path / "p.yaml"
    status, _, err = cli("fit", folder, "--method", "linear", "--out", out)
    assert status == 2 and "swapped" in err and err.count("\n") == 1 and not out.exists()
    good = _write_runs(tmp_path / "good", runs)
    status, _, err = cli("fit", good, "--ros2", tmp_path / "r.yaml")
    # no nominal geometry known (no metadata in the CSVs, no --robot): needed for --ros2
    assert status == 2 and "--robot" in err and not (tmp_path / "r.yaml").exists()
    status, _, err = cli("fit", good, "--exclude", "zzz")
    assert status == 2 and "'zzz' matches no run" in err
    status, _, err = cli(
        "fit",
        good,
        "--robot",
        "paper-fig5",
        "--ros2",
        tmp_path / "r.yaml",
        "--controller-name",
        "1bad name",
    )
    assert status == 2 and "controller name" in err and not (tmp_path / "r.yaml").exists()


def test_real_data_umbmark_reproduces_the_published_values(realdata, cli):
    # reference_results_diff.csv, UMBmark row of square/230620202042 (x-form)
    path = realdata / "optiodom_diff" / "square" / "230620202042"
    status, out, err = cli("fit", path, "--method", "umbmark", "--umbmark-form", "x", "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["wheelbase_m"] == pytest.approx(0.201458, abs=1e-6)
    assert d["wheel_diameter_right_m"] == pytest.approx(0.083954, abs=1e-6)
    assert d["wheel_diameter_left_m"] == pytest.approx(0.084046, abs=1e-6)


def test_real_data_trajectory_golden(realdata, cli):
    base = realdata / "optiodom_diff"
    status, out, err = cli(
        "fit", base / "square" / "231220200048", base / "ivanjko" / "231220200104", "--json"
    )
    assert status == 0, err
    d = json.loads(out)
    # golden values of this commit (5 runs); the published OptiOdom fits of these categories
    # give D 0.0834-0.0840 m and b 0.2000-0.2025 m
    assert d["wheel_diameter_right_m"] == pytest.approx(GOLDEN[0], abs=2e-6)
    assert d["wheel_diameter_left_m"] == pytest.approx(GOLDEN[1], abs=2e-6)
    assert d["wheelbase_m"] == pytest.approx(GOLDEN[2], abs=5e-6)
    assert len(d["runs"]) == 5


GOLDEN = (0.083884, 0.083923, 0.201740)


def test_list_topics_needs_a_bag(tmp_path, cli):
    path = tmp_path / "run.csv"
    path.write_text("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n1,1,1\n")
    status, _, err = cli("fit", path, "--list-topics")
    assert status == 2 and "run.csv" in err and "needs a ROS bag" in err


def test_real_data_square_methods_refuse_non_square_runs(realdata, cli):
    path = realdata / "optiodom_diff" / "ivanjko" / "231220200104"
    status, _, err = cli("fit", path, "--method", "heading")
    assert status == 2 and "231220200104_run-01.csv" in err and "not a closed square" in err
