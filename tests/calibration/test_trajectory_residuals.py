"""The trajectory fit's residual of all runs at once equals the per-run definition bit for bit.

``core.odometry.dead_reckon_rows`` (runs as zero-padded rows) against ``dead_reckon``, and
``calibration.trajectory_residuals.TrajectoryResiduals`` (runs packed into blocks of similar
length) against ``run_residual`` run by run: np.array_equal, not a tolerance, because every
fit, report and figure must stay byte-identical.
"""

from __future__ import annotations

import numpy as np
import pytest

from odocal.calibration import trajectory_residuals
from odocal.calibration.trajectory_residuals import (
    RunResiduals,
    TrajectoryResiduals,
    run_residual,
)
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon, dead_reckon_rows
from odocal.core.recording import Recording

NOMINAL = WheelGeometry(0.07, 0.07, 0.29)
TRUE = WheelGeometry(0.0703, 0.0698, 0.2934)


def _angles(rng, n: int, kind: str) -> np.ndarray:
    """Cumulative wheel angles (K = n, 2): a drive with stops, or a spin."""
    if kind == "spin":
        step = np.outer(rng.uniform(0.05, 0.2, n - 1), [1.0, -1.0])
    else:
        step = rng.uniform(0.0, 0.3, (n - 1, 2)) * [1.0, rng.uniform(0.6, 1.0)]
        step[rng.random(n - 1) < 0.2] = 0.0  # stops: zero-length increments
    return np.vstack([[0.0, 0.0], np.cumsum(step, axis=0)])


def _recordings(rng, lengths=(2, 3, 4, 40, 41, 200, 1500, 1600, 3000), spins=(3, 700)):
    recs = []
    for i, (n, kind) in enumerate([(n, "drive") for n in lengths] + [(n, "spin") for n in spins]):
        a = _angles(rng, n, kind)
        truth = dead_reckon(a[:, 0], a[:, 1], TRUE)
        truth[1:] += rng.normal(0.0, 1e-3, (n - 1, 3))
        recs.append(Recording(f"run{i}", np.arange(n) * 0.1, a[:, 0], a[:, 1], truth))
    order = rng.permutation(len(recs))  # not sorted by length
    return [recs[i] for i in order]


def _per_run(runs, p, kind, w_head, weighted=True):
    return np.concatenate(
        [(r.weight if weighted else 1.0) * run_residual(r, p, kind, w_head) for r in runs]
    )


PARAMETERS = [
    np.array([0.07, 0.07, 0.29]),
    np.array([0.0703, 0.0698, 0.2934]),
    np.array([0.081, 0.062, 0.21]),
]


def test_dead_reckon_rows_is_dead_reckon_bit_for_bit():
    rng = np.random.default_rng(5)
    runs = [_angles(rng, n, "drive") for n in (1, 2, 3, 17, 2500, 4000)]
    runs += [_angles(rng, n, "spin") for n in (2, 900)]
    runs.append(np.zeros((300, 2)))  # standing still: every increment zero
    width = max(len(a) for a in runs) - 1
    inc = np.zeros((2, len(runs), width))
    for i, a in enumerate(runs):
        inc[:, i, : len(a) - 1] = np.diff(a, axis=0).T
    for g in (NOMINAL, TRUE, WheelGeometry.unchecked(0.09, 0.05, 0.17)):
        poses = dead_reckon_rows(inc[0], inc[1], g)
        assert poses.shape == (3, len(runs), width + 1)
        for i, a in enumerate(runs):
            expected = dead_reckon(a[:, 0], a[:, 1], g)
            assert np.array_equal(poses[:, i, : len(a)].T, expected), (g, len(a))


@pytest.mark.parametrize("kind", ["pose", "segment"])
@pytest.mark.parametrize("run_weight", ["travel", "equal"])
def test_residuals_equal_the_per_run_definition(kind, run_weight):
    rng = np.random.default_rng(11)
    recs = _recordings(rng)
    runs = [RunResiduals(r, kind, 60, 0.4, NOMINAL, run_weight) for r in recs]
    for w_head in (0.0, 0.1, 7.3):
        batched = TrajectoryResiduals(runs, kind, w_head)
        assert len(batched.blocks) < len(runs)  # runs do share blocks
        for p in PARAMETERS:
            assert np.array_equal(batched(p), _per_run(runs, p, kind, w_head)), (w_head, p)
    # unweighted, cut per run (the outlier statistic)
    unweighted = TrajectoryResiduals(runs, kind, 0.1, weighted=False)
    parts = unweighted.per_run(unweighted(PARAMETERS[1]))
    assert len(parts) == len(runs)
    for r, part in zip(runs, parts, strict=True):
        assert np.array_equal(part, run_residual(r, PARAMETERS[1], kind, 0.1))


def test_blocks_bound_the_padding(monkeypatch):
    """Every block pads at most MAX_PADDING of its runs' increments (or holds one run), and
    holds at most _MAX_BLOCK increments unless it is one run."""
    rng = np.random.default_rng(2)
    recs = _recordings(rng, lengths=tuple(rng.integers(2, 400, 60)), spins=(5, 9))
    monkeypatch.setattr(trajectory_residuals, "MAX_BLOCK", 2000)
    runs = [RunResiduals(r, "pose", 30, 1.0, NOMINAL) for r in recs]
    batched = TrajectoryResiduals(runs, "pose", 0.1)
    increments = sorted((len(r.phi_r) - 1 for r in runs), reverse=True)
    at = 0
    for inc_r, _, _ in batched.blocks:
        rows, width = inc_r.shape
        used = increments[at : at + rows]
        assert used[0] == width
        if rows > 1:
            assert rows * width <= min(2000, (1 + trajectory_residuals.MAX_PADDING) * sum(used))
        at += rows
    assert at == len(runs)
    assert np.array_equal(batched(PARAMETERS[2]), _per_run(runs, PARAMETERS[2], "pose", 0.1))


def test_residuals_on_the_optiodom_runs(realdata):
    from odocal.io.optiodom import load_optiodom_experiment

    by_side, ivanjko, _, _ = load_optiodom_experiment(realdata / "optiodom_diff")
    recs = [r for runs in by_side.values() for r in runs] + list(ivanjko)
    assert len(recs) == 110
    for kind in ("pose", "segment"):
        runs = [RunResiduals(r, kind, 200, 1.0, NOMINAL) for r in recs]
        batched = TrajectoryResiduals(runs, kind, 0.1)
        for p in PARAMETERS[:2]:
            assert np.array_equal(batched(p), _per_run(runs, p, kind, 0.1)), (kind, p)


def test_a_5e_324_segment_length_is_the_shortest_segments_without_a_numpy_warning():
    """travel / 5e-324 overflowed (a raw RuntimeWarning); such segments are shorter than the
    samples: every sample that moved starts one, as for 1 nm segments."""
    import warnings

    from odocal.calibration.trajectory_residuals import _segment_marks

    travel = np.array([0.0, 0.1, 0.1, 0.3, 0.6])
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        tiny = _segment_marks(travel, 5e-324, len(travel))
    np.testing.assert_array_equal(tiny, _segment_marks(travel, 1e-9, len(travel)))
    np.testing.assert_array_equal(tiny, [0, 1, 3, 4])
