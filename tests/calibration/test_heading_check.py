"""``odocal.calibration.heading_check``: headings held against the positions of the same runs."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.app.common import make_robot
from odocal.app.simulate import simulate_runs
from odocal.calibration.heading import calibrate_heading
from odocal.calibration.heading_check import HeadingCheck, _mean_ends, check_heading_sign
from odocal.core.runs import EndPoseRuns
from odocal.core.stats import student_t_quantile
from odocal.core.tracks import polygon

# a TurtleBot3-sized robot as the trial: E_b 1.019, tape to 2 mm, protractor to 0.3 deg
TB3 = make_robot(
    0.066, 0.16, E_b=1.019, E_d=1.003, k_r_m=2e-6, sigma_xy_m=0.002, sigma_theta_deg=0.3
)
FLIP = np.array([1.0, 1.0, -1.0])


def _runs(robot, seed: int, n: int = 5, sides: int = 4, side_m: float = 1.0) -> EndPoseRuns:
    return simulate_runs(robot, lambda d: polygon(sides, side_m, d), ("cw", "ccw"), n, seed, 0.05)


@pytest.mark.parametrize("sides, side_m", [(4, 1.0), (3, 1.5)])
def test_honest_sheets_pass_and_a_flipped_heading_is_caught(sides, side_m):
    # issue 20.2: theta read with the wrong sign gave the inverse correction without a word
    for seed in range(12):
        runs = _runs(TB3, seed, sides=sides, side_m=side_m)
        honest = check_heading_sign(runs, sides, side_m, TB3.believed_geometry)
        assert honest is not None and not honest.contradicted
        assert abs(honest.t) < honest.threshold / 2
        flipped = EndPoseRuns(runs.directions, runs.errors * FLIP)
        caught = check_heading_sign(flipped, sides, side_m, TB3.believed_geometry)
        assert caught is not None and caught.contradicted, (seed, caught)
        # the written answer is the inverse correction; the flipped one is the truth's
        assert caught.E_b_written < 1.0 < caught.E_b_flipped
        assert caught.E_b_flipped == pytest.approx(1.019, abs=0.004)


def test_no_check_without_positions_or_scatter():
    runs = _runs(TB3, 0)
    err = runs.errors.copy()
    err[:, :2] = np.nan  # headings only (a protractor, no tape)
    assert check_heading_sign(EndPoseRuns(runs.directions, err), 4, 1.0, TB3.nominal) is None
    one = EndPoseRuns(("cw", "ccw"), runs.errors[[0, 5]])
    assert check_heading_sign(one, 4, 1.0, TB3.nominal) is None


def test_an_almost_perfect_robot_is_not_flagged():
    # tiny headings (mostly the runs' noise): the honest sheet passes; the check judges the
    # noise by the runs' own scatter
    good = make_robot(0.066, 0.16, E_b=1.0003, k_r_m=2e-6, sigma_xy_m=0.002, sigma_theta_deg=0.3)
    for seed in range(8):
        c = check_heading_sign(_runs(good, seed), 4, 1.0, good.nominal)
        assert c is not None and not c.contradicted


def test_the_rule_needs_both_conditions():
    def check(t: float, separation: float) -> HeadingCheck:
        return HeadingCheck(t, separation, 5.0, 0.98, 1.0, 1.02, 1.0, 10)

    assert check(6.0, 10.0).contradicted
    assert not check(6.0, 20.0).contradicted  # beyond T, but nearer the written prediction
    assert not check(3.0, 4.0).contradicted  # nearer the flipped one, but within the noise


def test_two_runs_per_direction_suffice_and_incomplete_runs_are_left_out():
    runs = _runs(TB3, 1)
    geo = TB3.believed_geometry
    two = EndPoseRuns(("cw", "cw", "ccw", "ccw"), runs.errors[[0, 1, 5, 6]])
    assert check_heading_sign(two, 4, 1.0, geo) is not None
    # runs with a heading but no position are not part of the check
    err = runs.errors.copy()
    err[[2, 7], :2] = np.nan
    partial = check_heading_sign(EndPoseRuns(runs.directions, err), 4, 1.0, geo)
    keep = [0, 1, 3, 4, 5, 6, 8, 9]
    directions = tuple(runs.directions[i] for i in keep)
    alone = check_heading_sign(EndPoseRuns(directions, runs.errors[keep]), 4, 1.0, geo)
    assert partial is not None and alone is not None and partial.runs == alone.runs == 8
    assert (partial.t, partial.separation, partial.threshold) == pytest.approx(
        (alone.t, alone.separation, alone.threshold), rel=1e-12
    )


def test_the_statistic_is_the_documented_one():
    """t, D and T recomputed from the module docstring: S = each mean's squared standard error
    (scatter / n) + what the headings' scatter does to p (central differences here, so D agrees
    to 1e-4), Welch-Satterthwaite degrees of freedom (n - 1 per mean, the headings' own), T the
    Student t quantile at 1 - ALPHA = 1 - 1e-5."""
    runs = _runs(TB3, 2, n=4)
    geo = TB3.believed_geometry
    check = check_heading_sign(runs, 4, 1.0, geo)
    written = calibrate_heading(runs, 4, 1.0, geo)
    flipped = calibrate_heading(EndPoseRuns(runs.directions, runs.errors * FLIP), 4, 1.0, geo)
    assert check is not None and written.uncertainty is not None
    e_b, e_d, h = written.E_b, written.E_d, 1e-5
    ends = _mean_ends(
        lambda d: polygon(4, 1.0, d),
        [
            written.corrected,
            flipped.corrected,
            geo.corrected(e_b + h, e_d),
            geo.corrected(e_b - h, e_d),
            geo.corrected(e_b, e_d + h),
            geo.corrected(e_b, e_d - h),
        ],
        geo,
    )
    p, q = ends[0], ends[1]
    jac = np.column_stack([ends[2] - ends[3], ends[4] - ends[5]]) / (2 * h)
    from_headings = jac @ written.uncertainty.covariance[:2, :2] @ jac.T
    var = np.concatenate([runs.select(d)[:, :2].var(axis=0, ddof=1) / 4 for d in ("cw", "ccw")])
    s_inv_d = np.linalg.solve(np.diag(var) + from_headings, q - p)
    sep = float(np.sqrt((q - p) @ s_inv_d))
    m = np.concatenate([runs.mean("cw")[:2], runs.mean("ccw")[:2]])
    parts = np.append(s_inv_d**2 * var, s_inv_d @ from_headings @ s_inv_d)
    nus = np.append(np.full(4, 3.0), min(written.uncertainty.dof[:2]))
    dof = sep**4 / float(np.sum(parts**2 / nus))
    assert check.separation == pytest.approx(sep, rel=1e-4)
    assert check.t == pytest.approx(float((m - p) @ s_inv_d) / sep, abs=1e-4 * sep)
    assert check.threshold == pytest.approx(student_t_quantile(1.0 - 1e-5, dof), rel=1e-5)
