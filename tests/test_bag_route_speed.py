"""The bag routes' fast paths give what the plain versions gave (issue 22, item 9; the timings
themselves live in benchmarks/bench_bag_route.py)."""

from __future__ import annotations

import numpy as np

from odocal.calibration.relative_motions import wheel_increments


def _wheel_increments_loop(t, right, left, start_s, end_s):
    """The former implementation: one pass over every wheel sample per interval."""
    rows_r, rows_l = [], []
    for a, b in zip(start_s, end_s, strict=True):
        inside = t[(t > a) & (t < b)]
        tt = np.r_[a, inside, b]
        rows_r.append(np.diff(np.interp(tt, t, right)))
        rows_l.append(np.diff(np.interp(tt, t, left)))
    k = max((len(x) for x in rows_r), default=1)
    out_r, out_l = np.zeros((len(rows_r), k)), np.zeros((len(rows_r), k))
    for i, (x, y) in enumerate(zip(rows_r, rows_l, strict=True)):
        out_r[i, : len(x)], out_l[i, : len(y)] = x, y
    return out_r, out_l


def test_wheel_increments_equal_the_loop_on_random_intervals():
    rng = np.random.default_rng(22)
    for trial in range(30):
        n = int(rng.integers(2, 400))
        t = np.cumsum(rng.uniform(0.001, 0.05, n)) + rng.uniform(-5, 5)
        right = np.cumsum(rng.normal(0, 0.1, n))
        left = np.cumsum(rng.normal(0, 0.1, n))
        m = int(rng.integers(0, 40))
        a = rng.uniform(t[0] - 0.5, t[-1] + 0.5, m)
        b = a + rng.exponential(0.3, m) * (rng.random(m) < 0.9) - (rng.random(m) < 0.05)
        if trial % 3 == 0 and m:  # ends on the samples themselves, and empty intervals
            a[::2] = rng.choice(t, len(a[::2]))
            b[::3] = rng.choice(t, len(b[::3]))
            b[:1] = a[:1]
        want = _wheel_increments_loop(t, right, left, a, b)
        got = wheel_increments(t, right, left, a, b)
        for w, g in zip(want, got, strict=True):
            assert g.shape == w.shape
            np.testing.assert_array_equal(g, w)


def test_wheel_increments_of_no_interval_and_of_nan_ends():
    t = np.arange(10.0)
    r, lft = wheel_increments(t, t, -t, np.zeros(0), np.zeros(0))
    assert r.shape == lft.shape == (0, 1)
    a, b = np.array([np.nan, 1.5, 2.0]), np.array([3.0, np.nan, 5.5])
    want = _wheel_increments_loop(t, t, -t, a, b)
    got = wheel_increments(t, t, -t, a, b)
    for w, g in zip(want, got, strict=True):
        np.testing.assert_array_equal(g, w)
