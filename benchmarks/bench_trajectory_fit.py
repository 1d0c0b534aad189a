"""Speed of the trajectory fit's residual: all runs at once against run by run (issue 12).

``calibration.trajectory_residuals.TrajectoryResiduals`` (runs packed into blocks of similar
length, dead-reckoned by ``core.odometry.dead_reckon_rows``) against the per-run definition
(``np.concatenate([r.weight * run_residual(r, p, ...) for r in runs])``, which the fit called
before), on the 110 OptiOdom calibration runs (squares + Ivanjko lines and spins, as
``app.reproduce.real_experiment`` loads them) at the nominal geometry they ran with:

- one residual evaluation, 'pose' and 'segment' residuals;
- a whole ``fit_trajectory(runs, nominal=...)`` (what ``app.measured.measure_robot`` runs), the
  old way being the same function with the per-run residual put in place of ``TrajectoryResiduals``;
- the floor: only ``np.cos``, ``np.sin`` and the three running sums of dead reckoning on the
  runs' increments (each run's own arrays; no way around them bit for bit).

In one process, A and B alternating on the same inputs, the minimum of many repeats (the machine
is shared and noisy). Every pair of results is also checked equal (np.array_equal, and the same
fitted geometry). Run from the project root (about 30 s):

    .venv/bin/python benchmarks/bench_trajectory_fit.py [--data ../shared/realdata/optiodom_diff]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import ROOT, machine  # noqa: E402

from odocal.calibration import trajectory  # noqa: E402
from odocal.calibration.trajectory_residuals import RunResiduals, run_residual  # noqa: E402
from odocal.io.optiodom import load_optiodom_experiment  # noqa: E402


class PerRun:
    """The residual as the fit evaluated it before: run by run (the interface of
    TrajectoryResiduals)."""

    def __init__(self, runs, kind, w_head, weighted=True):
        self.runs, self.kind, self.w_head, self.weighted = runs, kind, w_head, weighted

    calls = 0  # evaluations, over all instances

    def __call__(self, p):
        PerRun.calls += 1
        return np.concatenate(
            [
                (r.weight if self.weighted else 1.0) * run_residual(r, p, self.kind, self.w_head)
                for r in self.runs
            ]
        )

    def per_run(self, residual):
        sizes = [3 * (len(r.idx) if self.kind == "pose" else len(r.i0)) for r in self.runs]
        return np.split(residual, np.cumsum(sizes)[:-1])


def interleaved(a, b, repeats: int) -> tuple[float, float]:
    """Minimum time (s) of ``a()`` and of ``b()``, called alternately ``repeats`` times each."""
    ta, tb = [], []
    for _ in range(repeats):
        t = time.perf_counter()
        a()
        ta.append(time.perf_counter() - t)
        t = time.perf_counter()
        b()
        tb.append(time.perf_counter() - t)
    return min(ta), min(tb)


def floor(runs, p) -> None:
    """The unavoidable part of the dead reckoning: cos, sin and three running sums per run."""
    for r in runs:
        inc = np.diff(r.phi_r)
        np.cumsum(inc)
        np.cos(inc)
        np.sin(inc)
        np.cumsum(inc)
        np.cumsum(inc)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", default=str(ROOT.parent / "shared/realdata/optiodom_diff"))
    ap.add_argument("--repeats", type=int, default=200, help="evaluations per variant")
    ap.add_argument("--fits", type=int, default=7, help="whole fits per variant")
    args = ap.parse_args(argv)
    print(machine())
    by_side, ivanjko, _, _ = load_optiodom_experiment(args.data)
    squares = [r for runs in by_side.values() for r in runs]
    recs = squares + list(ivanjko)
    known = [r.ran_with for r in squares if r.ran_with is not None]
    nominal = max(set(known), key=known.count)
    p = np.array([nominal.diameter_right_m, nominal.diameter_left_m, nominal.wheelbase_m])
    print(f"{len(recs)} runs, {sum(len(r.time_s) for r in recs)} samples")

    for kind in trajectory.RESIDUALS:
        runs = [RunResiduals(r, kind, 200, 1.0, nominal) for r in recs]
        old, new = PerRun(runs, kind, 0.1), trajectory.TrajectoryResiduals(runs, kind, 0.1)
        assert np.array_equal(old(p), new(p))
        t_old, t_new = interleaved(lambda o=old: o(p), lambda n=new: n(p), args.repeats)
        t_floor, _ = interleaved(lambda r=runs: floor(r, p), lambda: None, args.repeats)
        print(
            f"residual '{kind}' ({len(new.blocks)} blocks): per run {1e3 * t_old:.2f} ms, "
            f"all at once {1e3 * t_new:.2f} ms ({t_old / t_new:.2f}x); "
            f"floor (cos, sin, cumsum) {1e3 * t_floor:.2f} ms"
        )

    batched = trajectory.TrajectoryResiduals
    results = {}

    def fit(cls):
        trajectory.TrajectoryResiduals = cls
        try:
            results[cls] = trajectory.fit_trajectory(recs, nominal=nominal)
        finally:
            trajectory.TrajectoryResiduals = batched

    t_old, t_new = interleaved(lambda: fit(PerRun), lambda: fit(batched), args.fits)
    evaluations = PerRun.calls // args.fits
    a, b = results[PerRun], results[batched]
    assert a.geometry == b.geometry and a.trajectory == b.trajectory and a.per_run == b.per_run
    print(
        f"fit_trajectory ({evaluations} residual evaluations, {b.trajectory.starts_tried} "
        f"starts): per run {t_old:.3f} s, "
        f"all at once {t_new:.3f} s ({t_old / t_new:.2f}x); the same fit"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
