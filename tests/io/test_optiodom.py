"""The OptiOdom reader (io.optiodom): the split into calibration data sets and held-out runs."""

from __future__ import annotations


def test_optiodom_split(realdata):
    # the held-out runs: OptiOdom free/ (7 runs) + circular/250620202104 (6 runs)
    from odocal.io.optiodom import load_optiodom_split

    datasets, heldout = load_optiodom_split(realdata / "optiodom_diff")
    assert len(heldout) == 13
    assert [len(datasets[k]) for k in ("square", "ivanjko", "circular-calibration")] == [8, 8, 1]
