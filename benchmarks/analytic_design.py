"""Time the analytic design and compare it with a direct Monte Carlo (run from the repo root).

    .venv/bin/python benchmarks/analytic_design.py [--trials 4000]

Prints: the time of a whole analytic sweep (20 side lengths, square and octagon), the analytic vs
Monte-Carlo agreement per robot (the robots of tests/design/test_analytic.py), and how the post-
calibration error depends on the ground-truth instrument (motion capture vs tape measure).
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from dataclasses import replace

import numpy as np

sys.path.insert(0, os.path.join(os.path.dirname(__file__), ".."))  # the tests package

from odocal.core.model import MeasurementNoise  # noqa: E402
from odocal.design.analytic import analytic_design, analytic_reference  # noqa: E402
from odocal.presets import PRESETS  # noqa: E402
from tests.design.test_analytic import SLOPPY, SMALL, TAPE, VALIDATE, monte_carlo  # noqa: E402


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--trials", type=int, default=4000)
    args = ap.parse_args()
    print(
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
        f"python {platform.python_version()}, numpy {np.__version__}"
    )
    robot = PRESETS["paper-fig5"]
    sizes = np.arange(0.5, 10.01, 0.5)
    analytic_design(robot, 4, sizes, 5)  # warm up (the fixed normal sample)
    for sides in (4, [4, 8]):
        t = time.perf_counter()
        reps = 20
        for _ in range(reps):
            analytic_design(robot, sides, sizes, 5)
        dt = (time.perf_counter() - t) / reps
        n = len(sizes) * (1 if np.ndim(sides) == 0 else len(sides))
        print(f"analytic sweep, {n} candidates: {1e3 * dt:.1f} ms")
    t = time.perf_counter()
    analytic_reference(robot, VALIDATE)
    print(f"analytic_reference: {1e3 * (time.perf_counter() - t):.1f} ms")

    print(f"\nanalytic vs direct Monte Carlo ({args.trials} trials), relative difference:")
    cases = [
        ("paper-fig5", robot, 4, "heading", [0.5, 1.0, 2.0, 4.0, 8.0]),
        ("small-mocap (octagon)", SMALL, 8, "heading", [0.5, 1.0, 2.0]),
        ("tape-umbmark", TAPE, 4, "umbmark", [1.0, 2.0, 4.0]),
        ("sloppy k=1e-3", SLOPPY, 4, "heading", [0.25, 0.5, 1.0, 2.0]),
    ]
    print(
        f"  {'robot':24s} {'L_m':>5s} {'mean_m':>8s} {'MC_m':>8s} {'d_mean':>7s} {'d_std':>7s} "
        f"{'d_Eb_sd':>7s} {'d_Ed_sd':>7s} {'MC_s':>5s}"
    )
    for name, rob, sides, method, Ls in cases:
        cands = analytic_design(rob, sides, Ls, 5, method, VALIDATE)
        for c, L in zip(cands, Ls, strict=True):
            t = time.perf_counter()
            mc = monte_carlo(rob, sides, L, 5, method, args.trials, seed=1)
            dt = time.perf_counter() - t
            rel = {k: getattr(c, k) / v - 1 for k, v in mc.items()}
            print(
                f"  {name:24s} {L:5.2f} {c.post_error_mean_m:8.4f} "
                f"{mc['post_error_mean_m']:8.4f} {rel['post_error_mean_m']:+7.3f} "
                f"{rel['post_error_std_m']:+7.3f} {rel['E_b_std']:+7.3f} "
                f"{rel['E_d_std']:+7.3f} {dt:5.2f}"
            )

    print("\npost-calibration error on the 4 m CCW square (paper-fig5 robot) vs instrument:")
    instruments = {
        "none": MeasurementNoise(),
        "mocap 1 mm, 0.1 deg": MeasurementNoise.from_degrees(0.001, 0.1),
        "tape 1 cm, 1 deg": MeasurementNoise.from_degrees(0.01, 1.0),
        "rough 2 cm, 3 deg": MeasurementNoise.from_degrees(0.02, 3.0),
    }
    sizes = np.array([0.5, 1.0, 1.5, 2.0, 3.0, 4.0, 6.0, 8.0, 10.0])
    print("  " + f"{'side_m':20s}" + "".join(f"{s:7.1f}" for s in sizes))
    for label, m in instruments.items():
        for method in ("heading", "umbmark"):
            cands = analytic_design(replace(robot, measurement=m), 4, sizes, 5, method)
            row = "".join(f"{c.post_error_mean_m:7.3f}" for c in cands)
            print(f"  {label + ' ' + method[:4]:20s}{row}")


if __name__ == "__main__":
    main()
