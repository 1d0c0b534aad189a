"""The trajectory least-squares fit (calibration.trajectory): exact without noise, every residual
evaluation reported, standard errors and outliers, batched trials, swapped wheels."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from odocal.calibration.fit_settings import TrajectorySettings
from odocal.calibration.linear import fit_linear, linear_geometry_trials
from odocal.calibration.trajectory import fit_trajectory, fit_trajectory_trials
from odocal.core.recording import Recording
from odocal.errors import CalibrationError
from tests.support.recorded_runs import (
    NOMINAL,
    TRUE,
    make_run,
    mixed_runs,
    square,
    values,
)


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


def test_the_consistency_pools_the_dispersion_only_over_runs(monkeypatch):
    # data sets of two runs each: runs are the subclusters, their dispersion pooled; a data set
    # of one run: its time blocks are, and each group keeps its own covariance
    import odocal.calibration.trajectory as trajectory
    from tests.support.recorded_runs import NOMINAL, make_run, square

    seen = []
    real = trajectory.group_consistency

    def spy(*args, **kwargs):
        seen.append(kwargs["pooled"])
        return real(*args, **kwargs)

    monkeypatch.setattr(trajectory, "group_consistency", spy)
    runs = [
        replace(make_run(f"{d}{k}", square("cw" if k else "ccw", 1.0)), meta={"dataset": d})
        for d in ("a", "b")
        for k in (0, 1)
    ]
    trajectory.fit_trajectory(runs, nominal=NOMINAL)
    trajectory.fit_trajectory([runs[0], runs[2]], nominal=NOMINAL)
    assert seen == [True, False]
