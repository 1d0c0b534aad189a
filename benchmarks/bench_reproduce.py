"""Benchmark: the whole ``odocal reproduce`` at full trials, and Monte-Carlo throughput.

Run from the project root:

    .venv/bin/python benchmarks/bench_reproduce.py [--trials 800] [--repeat 3] [--out DIR]

Reports the machine (cores, CPU model), the wall time of the computation (all figures' Monte
Carlo and the experiment prediction), the time of the figures and report, and the throughput in
trial-increments per second: every simulated run counts its increments (segments x increments per
segment), summed over test runs, validation runs, floor and uncalibrated drives. For comparison it
also times the same computation with every segment at 10 increments (no single-increment shortcut
for the heading-method test runs) and extrapolates the 1 cm midpoint reference from a short run.
Target (issue 3): the whole reproduction at 800 trials in under 10 s on 2 cores.
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import odocal.core.simulate as sim
from odocal.design import SimulationSettings
from odocal.design.reproduce import reproduce

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import machine  # noqa: E402  (benchmarks/machine.py, beside this script)


class IncrementCounter:
    """Wraps core.simulate.drive and final_headings to count runs x increments simulated (in
    this process: ODOCAL_THREADS=1 while counting, as worker processes would count their own)."""

    def __init__(self):
        self.increments = 0
        self._orig = {"drive": sim.drive, "final_headings": sim.final_headings}

    def __enter__(self):
        self._threads = os.environ.get("ODOCAL_THREADS")
        os.environ["ODOCAL_THREADS"] = "1"

        def counter(orig):
            def counting(track, true, believed, noise, runs, rng, **kw):
                self._count(track, believed, runs, kw)
                return orig(track, true, believed, noise, runs, rng, **kw)

            return counting

        import odocal.design.sweep as sweep

        self._patched = []
        for name, orig in self._orig.items():
            for mod in (sim, sweep):
                if hasattr(mod, name):
                    self._patched.append((mod, name, getattr(mod, name)))
                    setattr(mod, name, counter(orig))
        return self

    def __exit__(self, *exc):
        for mod, name, orig in self._patched:
            setattr(mod, name, orig)
        if self._threads is None:
            del os.environ["ODOCAL_THREADS"]
        else:
            os.environ["ODOCAL_THREADS"] = self._threads

    def _count(self, track, believed, runs, kw):
        steps = kw.get("steps_per_segment")
        if steps is not None:
            self.increments += runs * steps * len(track.segments)
            return
        max_step = kw.get("max_step_m", 0.01)
        b = np.max(believed.wheelbase_m)
        for seg in track.segments:
            s_r, s_l = seg.wheel_travel(b)
            longest = float(np.max(np.maximum(np.abs(s_r), np.abs(s_l))))
            self.increments += runs * max(1, int(np.ceil(longest / max_step - 1e-9)))


def timed(fn, repeat: int):
    best = float("inf")
    for _ in range(repeat):
        t = time.perf_counter()
        out = fn()
        best = min(best, time.perf_counter() - t)
    return best, out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--trials", type=int, default=800)
    p.add_argument("--repeat", type=int, default=3, help="best of this many runs")
    p.add_argument("--out", help="folder for figures and report (default: a temporary one)")
    args = p.parse_args(argv)

    print(f"machine: {machine()}")
    print(f"trials: {args.trials}, best of {args.repeat}")

    with IncrementCounter() as count:
        reproduce(args.trials, 0)
    increments = count.increments
    t_fast, rep = timed(lambda: reproduce(args.trials, 0), args.repeat)
    print(
        f"reproduce computation (fast setting, on every core): {t_fast:.2f} s, "
        f"{increments / 1e6:.1f} M trial-increments, {increments / t_fast / 1e6:.1f} M/s"
    )

    all10 = SimulationSettings(single_step_heading_tests=False)
    with IncrementCounter() as count:
        reproduce(args.trials, 0, settings=all10)
    inc10 = count.increments
    t10, _ = timed(lambda: reproduce(args.trials, 0, settings=all10), 1)
    print(
        f"reproduce computation, 10 increments on every segment: {t10:.2f} s, "
        f"{inc10 / 1e6:.1f} M trial-increments, {inc10 / t10 / 1e6:.1f} M/s"
    )

    from odocal.app.reproduce import reproduce as reproduce_command

    with tempfile.TemporaryDirectory() as tmp:
        out = args.out or tmp
        t = time.perf_counter()
        res = reproduce_command(out, trials=args.trials, seed=0)
        t_all = time.perf_counter() - t
    print(
        f"whole 'odocal reproduce' (computation + {len(res.figures)} figures + report): "
        f"{t_all:.2f} s"
    )

    # the command itself, in a fresh process (imports, computation, figures, report)
    import subprocess

    with tempfile.TemporaryDirectory() as tmp:
        cmd = [sys.executable, "-m", "odocal", "reproduce", "--out", tmp, "--quiet"]
        cmd += ["--trials", str(args.trials)]
        t = time.perf_counter()
        subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL)
        t_cmd = time.perf_counter() - t
    print(f"'odocal reproduce --trials {args.trials}' as a command (fresh process): {t_cmd:.2f} s")

    # the 1 cm midpoint reference, for scale: the whole reproduction at a few trials, counted and
    # timed, extrapolated linearly in trials (work is proportional to the trials)
    ref_trials = min(args.trials, 20)
    with IncrementCounter() as count:
        t = time.perf_counter()
        reproduce(ref_trials, 0, settings=SimulationSettings.reference())
        t_ref = time.perf_counter() - t
    scale = args.trials / ref_trials
    print(
        f"reproduce at the 1 cm midpoint reference, {ref_trials} trials, one process: "
        f"{t_ref:.2f} s, "
        f"{count.increments / 1e6:.1f} M trial-increments, "
        f"{count.increments / t_ref / 1e6:.1f} M/s; at {args.trials} trials: about "
        f"{count.increments * scale / 1e6:.0f} M trial-increments, {t_ref * scale:.0f} s"
    )
    rec = rep.fig5.recommended
    print(f"Fig. 5 recommendation: side {rec.side_m:g} m ({rec.travel_m:g} m travel)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
