"""The simulator's speed per CPU second, as a share of the random-number limit, against a baseline.

Run from the project root (about 2 minutes on a loaded 2-core machine):

    .venv/bin/python benchmarks/bench_sim_speed.py [--baseline COMMIT] [--rounds N] [--split]

Everything runs in this one process on one thread (``ODOCAL_THREADS=1``) and is timed in CPU
seconds (``time.process_time``), so the load of a shared machine moves it much less than wall
time. The limit is numpy's ``Generator.standard_normal`` (PCG64, float64) in blocks of 2^20,
halved: the simulator draws two normals per trial-increment (one per wheel), so half the
normals per CPU second is the most trial-increments per CPU second it could reach.

Cases (the paper-fig5 robot):

- ``exact10``: ``drive`` of a 4 m square, 10 exact-arc increments per segment, 100 000 runs
  (the design's validation drives);
- ``mid1cm``: the same with the 1 cm midpoint update, 5 000 runs (``odocal simulate``);
- ``heading1``: ``final_headings`` of squares, one increment per segment, 400 000 runs (the
  design's heading-method test runs);
- ``exact10 x 800 runs`` and ``heading1 x 4000 runs``: the same in the sizes of the design's
  own calls (800 validation drives; 5 test runs x 800 trials of one square), 100 calls each:
  there the work of a call around its passes counts;
- ``design``: ``run_design`` (20 squares x 800 trials, heading method) in process, and the plain
  numpy loop of ``reference_design.py`` on the same work (20 trials, scaled), as in
  ``bench_speed.py``.

With ``--baseline COMMIT`` that commit's ``src/odocal/core/simulate.py`` is loaded beside the
current one (``git show``; the rest of the package is the current one) and every case is timed
with both, one after the other within each round (who goes first alternates from round to
round); the design swaps the baseline's ``drive`` and ``final_headings`` into the sweep. The
two simulators' outputs on the same seed are compared too (the random stream is part of the
contract: the same seed gives the same runs).
Each round measures the limit just before the simulators; the medians over the rounds and the
round-by-round shares are printed. ``--split`` adds where the current simulator's time goes:
ns per trial-increment in all, with its generators handing back their buffers undrawn (its own
work), and two normals drawn alone.
"""

from __future__ import annotations

import argparse
import importlib.util
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

os.environ["ODOCAL_THREADS"] = "1"

import numpy as np  # noqa: E402

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import ROOT, machine  # noqa: E402


def limit_per_cpu_s(blocks: int = 24, block: int = 1 << 20) -> float:
    """Standard normals per CPU second on this thread."""
    g = np.random.default_rng(1)
    buf = np.empty(block)
    t = time.process_time()
    for _ in range(blocks):
        g.standard_normal(out=buf)
    return blocks * block / (time.process_time() - t)


def load_baseline(commit: str):
    """The simulator module of ``commit``, loaded as a sibling of the current one."""
    text = subprocess.run(
        ["git", "-C", str(ROOT), "show", f"{commit}:src/odocal/core/simulate.py"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout
    path = Path(tempfile.mkdtemp(prefix="odocal-sim-baseline-")) / "simulate.py"
    path.write_text(text)
    spec = importlib.util.spec_from_file_location("odocal.core._baseline_simulate", path)
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def cases():
    from odocal.core.simulate import increments_per_segment
    from odocal.core.tracks import polygon
    from odocal.presets import PRESETS

    robot = PRESETS["paper-fig5"]
    true, bel, noise = robot.true_geometry, robot.believed_geometry, robot.nonsystematic
    square = polygon(4, 4.0, "ccw")
    sides = np.repeat(np.arange(1, 21) * 0.5, 20_000)  # the design's 20 squares

    def work(track, runs, opts):
        steps = 0
        for seg in track.segments:
            s_r, s_l = seg.wheel_travel(bel.wheelbase_m)
            steps += increments_per_segment(
                np.max(s_r * true.diameter_right_m / bel.diameter_right_m),
                np.max(s_l * true.diameter_left_m / bel.diameter_left_m),
                opts.get("max_step_m"),
                opts.get("steps_per_segment"),
            )
        return runs * steps

    def run(name, track, runs, opts, calls=1):
        def go(module, seed=0):
            heading = name.startswith("heading1")
            fn = module.final_headings if heading else module.drive
            rng = np.random.default_rng(seed)
            for _ in range(calls):
                out = fn(track, true, bel, noise, runs, rng, **opts)
            return out if heading else out.true_final

        return name, calls * work(track, runs, opts), go

    exact = {"steps_per_segment": 10, "integration": "exact"}
    return [
        run("exact10", square, 100_000, exact),
        run("mid1cm", square, 5_000, {"max_step_m": 0.01}),
        run("heading1", polygon(4, sides, "ccw"), sides.size, {**exact, "steps_per_segment": 1}),
        # the calls the design makes: 800 validation drives, 5 x 800 test runs of one square
        run("exact10 x 800 runs", square, 800, exact, calls=100),
        run(
            "heading1 x 4000 runs",
            polygon(4, np.full(4000, 2.0), "cw"),
            4000,
            {**exact, "steps_per_segment": 1},
            calls=100,
        ),
    ]


class _NoDraws:
    """Stands in for the simulator's per-block generators: hands back its buffer undrawn (what
    is left is the simulator's own work)."""

    def __init__(self, *_args) -> None:
        pass

    def standard_normal(self, size=None, out=None):
        return np.zeros(size) if out is None else out


def split(all_cases, rounds: int) -> None:
    """Where the time of the current simulator goes: ns per trial-increment in all, without the
    drawing of the normals (the generators replaced by :class:`_NoDraws`), and two normals
    drawn alone (the limit), medians over the rounds."""
    import odocal.core.simulate as current

    print("\nwhere the time goes (current simulator, ns per trial-increment, medians):")
    print("| case | in all | without drawing the normals | two normals drawn alone |")
    print("|---|---|---|---|")
    for name, work, go in all_cases:
        total, rest, rng = [], [], []
        for _ in range(rounds):
            rng.append(2e9 / limit_per_cpu_s(8))
            total.append(cpu_time(lambda go=go: go(current)) / work * 1e9)
            real = np.random.Generator
            np.random.Generator = _NoDraws  # type: ignore[misc]
            try:
                rest.append(cpu_time(lambda go=go: go(current)) / work * 1e9)
            finally:
                np.random.Generator = real  # type: ignore[misc]
        print(f"| {name} | {median(total):.1f} | {median(rest):.1f} | {median(rng):.1f} |")


def cpu_time(fn) -> float:
    t = time.process_time()
    fn()
    return time.process_time() - t


def median(values):
    v = sorted(values)
    return v[len(v) // 2] if len(v) % 2 else 0.5 * (v[len(v) // 2 - 1] + v[len(v) // 2])


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline", help="a commit whose simulator is timed beside the current one")
    p.add_argument("--rounds", type=int, default=5)
    p.add_argument("--ref-trials", type=int, default=10, help="reference design-loop trials")
    p.add_argument(
        "--split", action="store_true", help="also: the time without drawing the normals"
    )
    args = p.parse_args(argv)

    import odocal.core.simulate as current

    print(f"machine: {machine()}")
    head = os.popen(f"git -C {ROOT} rev-parse --short HEAD 2>/dev/null").read().strip()
    dirty = os.popen(f"git -C {ROOT} status --porcelain src 2>/dev/null").read().strip()
    print(f"commit: {head}{' (with uncommitted changes in src)' if dirty else ''}")
    modules = {"current": current}
    if args.baseline:
        modules = {"baseline": load_baseline(args.baseline), "current": current}
        print(f"baseline: {args.baseline}")
    print("one thread (ODOCAL_THREADS=1), CPU seconds; limit = normals per CPU second / 2")

    all_cases = cases()
    if "baseline" in modules:
        for name, _, go in all_cases:
            a, b = go(modules["baseline"], 7), go(modules["current"], 7)
            same = np.array_equal(a, b)
            diff = float(np.max(np.abs(a - b)))
            print(f"  {name}: same seed, outputs identical: {same} (largest difference {diff:.1e})")

    shares: dict[tuple[str, str], list[float]] = {}
    ratios: dict[str, list[float]] = {}
    for _name, _, go in all_cases:  # warm up
        for m in modules.values():
            go(m)
    for r in range(args.rounds):
        limit = limit_per_cpu_s() / 2.0
        line = []
        for name, work, go in all_cases:
            order = list(modules.items())[:: -1 if r % 2 else 1]  # who goes first alternates
            t = {label: cpu_time(lambda m=m: go(m)) for label, m in order}  # noqa: B023
            for label, dt in t.items():
                shares.setdefault((name, label), []).append(work / dt / limit)
            if "baseline" in t:
                ratios.setdefault(name, []).append(t["baseline"] / t["current"])
            line.append(
                f"{name} " + "/".join(f"{shares[name, label][-1]:.0%}" for label in modules)
            )
        print(f"  round {r + 1}: limit {limit / 1e6:.1f} M/CPU s; " + ", ".join(line), flush=True)

    if args.split:
        split(all_cases, args.rounds)

    # the design, against the plain numpy loop (and the baseline's simulator swapped in)
    from reference_design import design_loop

    import odocal.design.sweep as sweep
    from odocal.design.spec import DesignSpec
    from odocal.presets import PRESETS

    robot = PRESETS["paper-fig5"]
    design_t: dict[str, list[float]] = {}

    def design(m):
        sweep.drive, sweep.final_headings = m.drive, m.final_headings
        try:
            return sweep.run_design(robot, DesignSpec(trials=800), np.random.default_rng(0))
        finally:
            sweep.drive, sweep.final_headings = current.drive, current.final_headings

    for m in modules.values():
        design(m)
    for r in range(args.rounds):
        for label, m in list(modules.items())[:: -1 if r % 2 else 1]:
            design_t.setdefault(label, []).append(cpu_time(lambda m=m: design(m)))  # noqa: B023
    t_ref = cpu_time(lambda: design_loop(robot, np.arange(1, 21) * 0.5, args.ref_trials, seed=1))
    t_ref *= 800 / args.ref_trials

    print(f"\nmachine at the end: {machine()}\n")
    print("| case | trial-increments | " + " | ".join(f"{lb}: share of the limit" for lb in modules)
          + (" | current / baseline speed |" if "baseline" in modules else " |"))  # fmt: skip
    print("|---" * (2 + len(modules) + ("baseline" in modules)) + "|")
    for name, work, _ in all_cases:
        cells = [
            f"{median(shares[name, lb]):.0%} (rounds {min(shares[name, lb]):.0%}-"
            f"{max(shares[name, lb]):.0%})"
            for lb in modules
        ]
        if name in ratios:
            cells.append(f"{median(ratios[name]):.2f}x")
        print(f"| {name} | {work / 1e6:.1f} M | " + " | ".join(cells) + " |")
    cells = [
        f"{median(design_t[lb]):.3f} CPU s: {t_ref / median(design_t[lb]):.0f}x the numpy loop"
        for lb in modules
    ]
    if "baseline" in modules:
        cells.append(f"{median(design_t['baseline']) / median(design_t['current']):.2f}x")
    print(
        f"| design, 20 squares x 800 trials (numpy loop: {t_ref:.1f} CPU s, scaled from "
        f"{args.ref_trials} trials) | | " + " | ".join(cells) + " |"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
