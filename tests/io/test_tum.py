"""``odocal.io.tum``: planar trajectories in the TUM format (timestamp x y z qx qy qz qw)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.errors import InputError, ModelError
from odocal.io.tum import read_tum, tum_text, write_tum


def test_a_planar_pose_is_a_rotation_about_z():
    text = tum_text([1.5], [[1.0, -2.0, math.pi / 2]], comment="truth\nICP")
    lines = text.splitlines()
    assert lines[:3] == ["# truth", "# ICP", "# timestamp x y z qx qy qz qw"]
    t, x, y, z, qx, qy, qz, qw = (float(v) for v in lines[3].split())
    assert (t, x, y, z, qx, qy) == (1.5, 1.0, -2.0, 0.0, 0.0, 0.0)
    assert (qz, qw) == pytest.approx((math.sqrt(0.5), math.sqrt(0.5)))


def test_written_and_read_back(tmp_path):
    rng = np.random.default_rng(0)
    t = np.cumsum(rng.uniform(0.05, 0.15, 50)) + 1.7e9
    poses = np.column_stack(
        [rng.normal(size=50), rng.normal(size=50), np.cumsum(rng.normal(size=50))]
    )
    write_tum(tmp_path / "a.tum", t, poses)
    t2, p2 = read_tum(tmp_path / "a.tum")
    assert t2 == pytest.approx(t, abs=1e-6)
    assert p2[:, :2] == pytest.approx(poses[:, :2], rel=1e-8)
    # headings come back unwrapped, so equal up to one whole turn at the start
    assert p2[:, 2] - p2[0, 2] == pytest.approx(poses[:, 2] - poses[0, 2], abs=1e-9)


def test_bad_input(tmp_path):
    with pytest.raises(ModelError):
        tum_text([0.0, 1.0], [[0, 0, 0]])
    p = tmp_path / "b.tum"
    p.write_text("0 1 2 3\n")
    with pytest.raises(InputError, match="8 numbers"):
        read_tum(p)
