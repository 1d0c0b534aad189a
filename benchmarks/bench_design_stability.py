"""How stable is the recommendation of ``odocal design``? The source of every design number in the
README and docs/design.md (run from the repo root, about 1 minute on 2 cores):

    .venv/bin/python benchmarks/bench_design_stability.py [--seeds 8] [--out FILE.md]

Prints one Markdown document:

1. the recommended square under the paper's Fig. 5 conditions at seeds 0 .. n-1, for
   - the former default: independent samples per candidate, 800 trials, one-sided Welch tests;
   - the default: common random numbers, 2000 trials, one-sided paired tests, with the bootstrap
     range of each pick;
   - 800 trials with common random numbers (what ``odocal reproduce`` runs, the paper's count);
   and the analytic engine (expected values, no seed);
2. the error line ``odocal design`` prints at seed 0;
3. the recommended size against the instrument's precision (the analytic table of the README);
4. the technician's TurtleBot3 (wheel diameter 0.066 m, wheelbase 0.160 m, tape measure and
   protractor: 1 cm, 1 deg): its design over the typical error ranges, and for one robot with
   errors E_b 1.02, E_d 1.004, k 1e-6 m by Monte Carlo and analytically.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from dataclasses import replace

import numpy as np

from odocal.app.common import make_robot
from odocal.design.analytic import analytic_design_result
from odocal.design.reproduce import INSTRUMENT_LEVELS, precision_sweep
from odocal.design.robust import range_design
from odocal.design.spec import DesignSpec, scaled_sizes
from odocal.design.sweep import run_design
from odocal.presets import PRESETS


def _pick(result) -> str:
    st = result.stability
    side = f"{result.recommended.side_m:g}"
    if st is None or not st.indistinguishable:
        return side
    return f"{side} ({st.range_m[0]:g}-{st.range_m[1]:g})"


def seeds_table(seeds: int) -> list[str]:
    robot = PRESETS["paper-fig5"]
    variants = (
        ("independent, 800 trials, Welch (former default)", dict(trials=800, crn=False)),
        ("common random numbers, 800 trials, paired (reproduce)", dict(trials=800, crn=True)),
        ("common random numbers, 2000 trials, paired (default)", dict(trials=2000, crn=True)),
    )
    rows = [
        "| engine | " + " | ".join(f"seed {s}" for s in range(seeds)) + " | distinct picks |",
        "|---|" + "---|" * (seeds + 1),
    ]
    for label, v in variants:
        t0 = time.perf_counter()
        picks, cells = [], []
        for s in range(seeds):
            res = run_design(
                robot,
                DesignSpec(trials=v["trials"]),
                np.random.default_rng(s),
                common_random_numbers=v["crn"],
                resamples=200,
            )
            picks.append(res.recommended.side_m)
            cells.append(_pick(res))
        dt = (time.perf_counter() - t0) / seeds
        distinct = ", ".join(f"{p:g} m" for p in sorted(set(picks)))
        rows.append(f"| {label} ({dt:.1f} s each) | " + " | ".join(cells) + f" | {distinct} |")
    an = analytic_design_result(robot, DesignSpec()).recommended.side_m
    rows.append(
        "| analytic, expected values (no seed) | "
        + " | ".join(f"{an:g}" for _ in range(seeds))
        + f" | {an:g} m |"
    )
    return rows


def default_line() -> list[str]:
    res = run_design(PRESETS["paper-fig5"], DesignSpec(trials=2000), np.random.default_rng(0))
    r = res.recommended
    gain = res.gain_m
    st = res.stability
    assert st is not None
    return [
        f"Recommended: square, side {r.side_m:g} m ({r.travel_m:g} m travel per run): error "
        f"{r.post_error_mean_m:.4f} m after calibration, residual "
        f"{r.residual_error_mean_m:.4f} m (uncalibrated {res.uncalibrated.mean_m:.4f} m, gain "
        f"{gain:.4f} m; floor {res.floor.mean_m:.4f} m)",
        "bootstrap picks: " + ", ".join(f"{p.side_m:g} m {100 * p.share:.0f} %" for p in st.picks),
    ]


def instrument_table() -> list[str]:
    sweep = precision_sweep(PRESETS["paper-fig5"])
    names = (
        "motion capture, 1 mm, 0.1 deg",
        "2 mm, 0.25 deg",
        "5 mm, 0.5 deg",
        "tape measure and protractor, 1 cm, 1 deg",
        "2 cm, 2 deg",
        "3 cm, 3 deg",
    )
    assert len(names) == len(INSTRUMENT_LEVELS)
    rows = [
        "| instrument (sigma xy, sigma heading) | heading method | UMBmark (mean form) |",
        "|---|---|---|",
    ]
    h = sweep.recommended_side_m[("heading", "error")]
    u = sweep.recommended_side_m[("umbmark", "error")]
    for k, name in enumerate(names):
        rows.append(f"| {name} | {h[k]:g} m | {u[k]:g} m |")
    return rows


def turtlebot() -> list[str]:
    tape = dict(sigma_xy_m=0.01, sigma_theta_deg=1.0)
    bare = make_robot(0.066, 0.160, **tape)
    lengths, validation = scaled_sizes(0.160)
    t0 = time.perf_counter()
    spec = DesignSpec(side_lengths_m=lengths, validation=validation)
    rd = range_design(bare, spec)
    dt = time.perf_counter() - t0
    known = make_robot(0.066, 0.160, E_b=1.02, E_d=1.004, k_r_m=1e-6, **tape)
    an = analytic_design_result(known, spec)
    mc = [run_design(known, replace(spec, trials=800), np.random.default_rng(s)) for s in range(4)]
    perfect = make_robot(0.066, 0.160)
    rp = range_design(perfect, spec)
    return [
        f"- candidates {lengths[0]:g} .. {lengths[-1]:g} m, validation {validation.label}",
        f"- errors unknown, tape measure and protractor ({len(rd.scenarios)} plausible robots, "
        f"{dt:.1f} s): {rd.describe()}; warnings: {len(rd.warnings)}",
        f"- errors unknown, perfect instrument: {rp.describe()}",
        f"- E_b 1.02, E_d 1.004, k 1e-6 m, tape: analytic {an.recommended.side_m:g} m; Monte "
        f"Carlo seeds 0-3: " + ", ".join(_pick(r) + " m" for r in mc),
    ]


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--out", default=None, help="also write the Markdown to this file")
    args = ap.parse_args()
    t0 = time.perf_counter()
    lines = [
        "# Design stability benchmark (benchmarks/bench_design_stability.py)",
        "",
        f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} cores, python "
        f"{platform.python_version()}, numpy {np.__version__}",
        "",
        "## 1. Recommended square side (m) under the paper's Fig. 5 conditions, by seed",
        "(in brackets: the sizes that hold 90 % of the rule's picks on 200 bootstrap resamples of "
        "the trials)",
        "",
        *seeds_table(args.seeds),
        "",
        "## 2. `odocal design` (defaults, seed 0)",
        "",
        *default_line(),
        "",
        "## 3. Recommended square against the instrument (analytic, error criterion)",
        "",
        *instrument_table(),
        "",
        "## 4. The TurtleBot3 of issue 13",
        "",
        *turtlebot(),
        "",
        f"total {time.perf_counter() - t0:.0f} s",
    ]
    text = "\n".join(lines) + "\n"
    sys.stdout.write(text)
    if args.out:
        with open(args.out, "w", encoding="utf-8") as f:
            f.write(text)


if __name__ == "__main__":
    main()
