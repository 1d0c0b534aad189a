"""An independent check of a skid-steer fit (a helper for tests; not a test module): the heading
change over 1 s of ICP truth regressed on the two sides' wheel rotations, by plain least squares
(5-MAD outliers dropped: ICP jumps), from the recordings' CSV copies (their own reader) and
without a clock offset. Its two coefficients are the turning gains r_R / track and r_L / track
that any skid-steer answer must reproduce."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

import numpy as np

from odocal.io.norlab_csv import read_norlab_csv


def plain_turning_gains(csvs: Sequence[Path], interval_s: float = 1.0) -> tuple[float, float]:
    """(right, left) turning gains (rad of heading per rad of wheel) over every CSV pooled."""
    rows, ys = [], []
    for path in csvs:
        c = read_norlab_csv(path)
        t, yaw = c.icp_time_s, c.icp_pose[:, 2]
        idx = [0]
        for i in range(1, len(t)):
            if t[i] - t[idx[-1]] >= interval_s:
                idx.append(i)
        a, e = np.array(idx[:-1]), np.array(idx[1:])
        ok = (t[e] - t[a]) < 1.5 * interval_s
        right = np.interp(t, c.time_s, c.angle_right_rad)
        left = np.interp(t, c.time_s, c.angle_left_rad)
        rows.append(np.column_stack([(right[e] - right[a])[ok], -(left[e] - left[a])[ok]]))
        ys.append((yaw[e] - yaw[a])[ok])
    x, y = np.concatenate(rows), np.concatenate(ys)
    keep = np.ones(len(y), dtype=bool)
    for _ in range(4):
        coef = np.linalg.lstsq(x[keep], y[keep], rcond=None)[0]
        r = y - x @ coef
        keep = np.abs(r) < 5 * 1.4826 * np.median(np.abs(r))
    return float(coef[0]), float(coef[1])
