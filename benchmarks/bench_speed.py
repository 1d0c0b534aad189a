"""Speed benchmark: every figure of issue 12, each beside a reference measured in the same run.

Run from the project root (about 3 to 6 minutes on 2 cores; ``--only`` picks sections):

    .venv/bin/python benchmarks/bench_speed.py [--only SECTION,...]

with SECTION among limit, sim, design, startup, compare, reproduce, csv, bags, suite (default:
all).

Sections and their references (see machine.py for the measuring tools):

- ``limit``: numpy's normal generator on 1 and 2 processes; the two-core limit of the simulator
  is half the 2-process rate (two normals per trial-increment). The "machine unit" is the time
  one process needs for 10^8 normals: long commands are also given in machine units.
- ``sim``: ``core.simulate.drive`` throughput (trial-increments per second) on the design's
  setting (10 exact increments per segment) and on ``odocal simulate``'s (1 cm midpoint), as a
  share of the two-core limit (target: >= 50 %): 5 rounds of (the limit, then the simulator),
  the best of each (the load of a shared machine drifts within a minute), every round's share
  printed too.
- ``design``: the default Monte-Carlo design (paper-fig5, 20 squares, 800 trials) in process,
  against the plain numpy loop of ``reference_design.py`` on the same Monte-Carlo work (timed on
  ``--ref-trials`` trials per candidate and scaled; target: >= 10x); its errors are checked
  against the design's (largest |z| over the candidates); and ``odocal design`` as a command.
- ``startup``: fresh-process times (median of 5) of ``odocal --help``, ``design --analytic`` and
  other short commands against ``python -c 'import numpy'``, and which heavy packages each one
  imports (target: ``design --analytic`` under 0.3 s).
- ``compare``: ``odocal compare --trials 500`` with and without ``--realdata`` (wall, CPU, peak
  memory; target: under 10 s and 200 MB).
- ``reproduce``: ``odocal reproduce`` at 800 trials as a command (target: under 2 s).
- ``csv``: reading a 5-million-row generic run CSV (``io.generic_csv.load_generic_csv``) against
  ``numpy.loadtxt`` of the same file (time; peak memory against the file size).
- ``bags``: reading the Husky bag's IMU and odometry (ROS 1 ``.bag`` and ROS 2 ``.mcap``,
  15 817 messages) into series (``io.bags.read_bag`` + ``imu_series`` + ``pose_series``) with the
  fast Imu/Odometry decoder, against the rosbags-only path (``read_bag(..., fast=False)``) and
  against rosbags' messages kept as objects (how ``read_bag`` read before), interleaved, best of
  5; and ``odocal fit husky_test1.bag --method gyro --json`` (median of 5) against importing
  what it imports.
- ``suite``: the whole test suite (``pytest -q``) in a fresh process (target: under 60 s of wall
  time on 2 quiet cores, about 100 s of CPU, issue 27 item 21; ``bench_suite.py`` times the
  README's test command from a fresh state, paired against a baseline commit).
"""

from __future__ import annotations

import argparse
import compileall
import math
import os
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))

from machine import ROOT, fresh, machine, odocal_cmd, python_cmd, rng_limit  # noqa: E402

SECTIONS = ("limit", "sim", "design", "startup", "compare", "reproduce", "csv", "bags", "suite")
REALDATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"
HUSKY = ROOT.parent / "shared" / "realdata" / "husky"

rows: list[tuple[str, str, str, str, str]] = []  # figure, value, reference, ratio, target


def row(figure: str, value: str, reference: str = "", ratio: str = "", target: str = "") -> None:
    rows.append((figure, value, reference, ratio, target))
    print(f"  {figure}: {value}" + (f"  | ref {reference}" if reference else "")
          + (f"  | ratio {ratio}" if ratio else ""), flush=True)  # fmt: skip


def best_of(fn, repeat: int = 3) -> float:
    best = math.inf
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        best = min(best, time.perf_counter() - t)
    return best


# --- limit ----------------------------------------------------------------------------------
state: dict = {}


def section_limit() -> None:
    one, two = rng_limit()
    state["rate1"], state["rate2"] = one, two
    state["unit_s"] = 1e8 / one
    row("normals/s, 1 process", f"{one / 1e6:.1f} M/s")
    row("normals/s, 2 processes together", f"{two / 1e6:.1f} M/s", ratio=f"{two / one:.2f}x")
    row(
        "two-core limit of the simulator (2 normals per trial-increment)",
        f"{two / 2e6:.1f} M trial-increments/s",
    )
    row("machine unit (10^8 normals on one process)", f"{state['unit_s']:.2f} s")


def _unit() -> float:
    if "unit_s" not in state:
        section_limit()
    return state["unit_s"]


# --- sim ------------------------------------------------------------------------------------
def section_sim() -> None:
    from odocal.core.simulate import drive, increments_per_segment
    from odocal.core.tracks import polygon
    from odocal.presets import PRESETS

    robot = PRESETS["paper-fig5"]
    track = polygon(4, 4.0, "ccw")
    true, bel, noise = robot.true_geometry, robot.believed_geometry, robot.nonsystematic
    cases = [
        ("design setting (10 exact increments per segment)", 100_000, {
            "steps_per_segment": 10, "integration": "exact"}),
        ("odocal simulate setting (1 cm midpoint)", 5_000, {"max_step_m": 0.01}),
    ]  # fmt: skip
    for label, runs, opts in cases:
        steps = 0
        for seg in track.segments:
            s_r, s_l = seg.wheel_travel(bel.wheelbase_m)
            steps += increments_per_segment(
                s_r * true.diameter_right_m / bel.diameter_right_m,
                s_l * true.diameter_left_m / bel.diameter_left_m,
                opts.get("max_step_m"),
                opts.get("steps_per_segment"),
            )
        work = runs * steps
        rng = np.random.default_rng(0)
        drive(track, true, bel, noise, runs, rng, **opts)  # warm up
        # the machine's load drifts (shared machines): rounds of (the limit, then the simulator),
        # and the best of each, as for every other timing here
        rounds = []
        for _ in range(5):
            two = rng_limit(60_000_000)[1] / 2.0
            t = best_of(lambda: drive(track, true, bel, noise, runs, rng, **opts), 2)  # noqa: B023
            rounds.append((work / t, two))
        rate, two = max(r for r, _ in rounds), max(lim for _, lim in rounds)
        row(
            f"simulator, {label}, 4 m square x {runs} runs",
            f"{rate / 1e6:.1f} M trial-increments/s",
            f"limit {two / 1e6:.1f} M/s (best of 5 rounds, each measured just before)",
            f"{rate / two:.0%} of the two-core limit (round by round: "
            + ", ".join(f"{r / lim:.0%}" for r, lim in rounds)
            + ")",
            ">= 50 %",
        )


# --- design ---------------------------------------------------------------------------------
def section_design(ref_trials: int) -> None:
    from reference_design import design_loop

    from odocal.design.spec import DesignSpec
    from odocal.design.sweep import run_design
    from odocal.presets import PRESETS

    robot = PRESETS["paper-fig5"]
    sides = np.arange(1, 21) * 0.5
    res = {}

    def ours():
        res["r"] = run_design(robot, DesignSpec(trials=800), np.random.default_rng(0))

    ours()  # warm up
    t_ours = best_of(ours)
    t = time.perf_counter()
    ref = design_loop(robot, sides, ref_trials, seed=1)
    t_ref = (time.perf_counter() - t) * 800 / ref_trials
    z = []
    for c, r in zip(res["r"].candidates, ref, strict=True):
        se = math.sqrt(c.post_error_std_m**2 / c.trials + r.var(ddof=1) / r.size)
        z.append(abs(c.post_error_mean_m - r.mean()) / se)
    row(
        "design computation (paper-fig5, 20 squares x 800 trials, in process)",
        f"{t_ours:.3f} s",
        f"numpy loop {t_ref:.1f} s (scaled from {ref_trials} trials; largest |z| of the "
        f"mean errors {max(z):.1f})",
        f"{t_ref / t_ours:.0f}x faster",
        ">= 10x",
    )
    run = fresh(odocal_cmd("design", "--quiet"), repeat=3)
    row(
        "'odocal design' as a command",
        f"{run.wall_s:.2f} s wall, {run.cpu_s:.2f} s CPU",
        f"machine unit {_unit():.2f} s",
        f"{run.wall_s / _unit():.2f} units",
    )


# --- startup --------------------------------------------------------------------------------
def _heavy_imports(cmd: list[str], cwd: Path) -> str:
    import subprocess

    p = subprocess.run(
        [cmd[0], "-X", "importtime", *cmd[1:]], cwd=cwd, capture_output=True, text=True
    )
    names = {ln.split("|")[-1].strip() for ln in p.stderr.splitlines() if "|" in ln}
    heavy = [m for m in ("numpy", "scipy", "matplotlib", "yaml", "rosbags") if m in names]
    return ", ".join(heavy) or "none of numpy, scipy, matplotlib, yaml"


def section_startup() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        a, b = Path(tmp, "a.csv"), Path(tmp, "b.csv")
        a.write_text("e\n1\n2\n3\n4\n")
        b.write_text("e\n2\n3\n4\n6\n")
        runs = Path(tmp, "runs.csv")
        base = python_cmd("-c", "import numpy")
        ref = fresh(base, repeat=5)
        bare = fresh(python_cmd("-c", "pass"), repeat=5)
        row("python -c pass", f"{bare.wall_s:.3f} s wall, {bare.cpu_s:.3f} s CPU")
        row(
            "python -c 'import numpy' (reference)",
            f"{ref.wall_s:.3f} s wall, {ref.cpu_s:.3f} s CPU",
        )
        cmds = {
            "odocal --help": odocal_cmd("--help"),
            "odocal design --analytic": odocal_cmd("design", "--analytic"),
            "odocal simulate (5 runs, 1 cm)": odocal_cmd(
                "simulate", "--runs", "5", "--seed", "1", "--out", str(runs)
            ),
            "odocal calibrate (heading)": odocal_cmd(
                "calibrate", str(runs), "--robot", "paper-fig5"
            ),
            "odocal plan": odocal_cmd("plan"),
            "odocal ttest": odocal_cmd("ttest", str(a), str(b)),
        }
        for label, cmd in cmds.items():
            run = fresh(cmd, cwd=Path(tmp), repeat=5)
            if run.status != 0:
                row(label, f"FAILED ({run.status}): {run.stderr.strip()[-200:]}")
                continue
            target = "< 0.3 s" if "analytic" in label else ""
            row(
                label,
                f"{run.wall_s:.3f} s wall, {run.cpu_s:.3f} s CPU; "
                f"imports {_heavy_imports(cmd, Path(tmp))}",
                f"import numpy {ref.wall_s:.3f} s",
                f"{run.wall_s / ref.wall_s:.2f}x",
                target,
            )


# --- compare --------------------------------------------------------------------------------
def section_compare(trials: int) -> None:
    cases = [("", [])]
    if REALDATA.is_dir():
        cases.append((" --realdata", ["--realdata", str(REALDATA)]))
    for label, extra in cases:
        cmd = odocal_cmd("compare", "--trials", str(trials), "--seed", "0", "--json", *extra)
        run = fresh(cmd)
        if run.status != 0:
            row(f"odocal compare --trials {trials}{label}", f"FAILED: {run.stderr[-300:]}")
            continue
        row(
            f"odocal compare --trials {trials}{label}",
            f"{run.wall_s:.1f} s wall, {run.cpu_s:.1f} s CPU, {run.peak_mb:.0f} MB peak",
            f"machine unit {_unit():.2f} s",
            f"{run.wall_s / _unit():.1f} units",
            "< 10 s, < 200 MB",
        )


# --- reproduce ------------------------------------------------------------------------------
def section_reproduce() -> None:
    with tempfile.TemporaryDirectory() as tmp:
        run = fresh(odocal_cmd("reproduce", "--out", tmp, "--quiet"), repeat=5)
    row(
        "odocal reproduce (800 trials)",
        f"{run.wall_s:.2f} s wall, {run.cpu_s:.2f} s CPU, {run.peak_mb:.0f} MB peak",
        f"machine unit {_unit():.2f} s",
        f"{run.wall_s / _unit():.2f} units",
        "< 2 s",
    )


# --- csv ------------------------------------------------------------------------------------
def _fixed(v: np.ndarray, width: int, decimals: int) -> np.ndarray:
    """Fixed-width decimal text of ``v`` (sign, zero-padded), uint8 array (len, width)."""
    n = np.rint(np.abs(v) * 10**decimals).astype(np.int64)
    out = np.empty((v.size, width), np.uint8)
    out[:, 0] = np.where(v < 0, ord("-"), ord("+"))
    pos = width - 1
    for k in range(width - 2):
        if k == decimals:
            out[:, pos] = ord(".")
            pos -= 1
        out[:, pos] = 48 + n % 10
        n //= 10
        pos -= 1
    return out


def big_run_csv(rows_n: int) -> Path:
    """A generic run CSV of ``rows_n`` samples (a robot circling for hours at 100 Hz), cached in
    the temporary folder."""
    path = Path(tempfile.gettempdir(), f"odocal-bench-run-{rows_n}.csv")
    if path.exists():
        return path
    t = np.arange(rows_n) * 0.01
    phi_r, phi_l = 4.1 * t, 3.9 * t
    theta = (0.075 * (phi_r - phi_l)) / 0.385
    x, y = 2.0 * np.sin(theta), 2.0 * (1 - np.cos(theta))
    cols = [_fixed(c, 14, 6) for c in (t, phi_r, phi_l, x, y, theta)]
    sep = np.full((rows_n, 1), ord(","), np.uint8)
    nl = np.full((rows_n, 1), ord("\n"), np.uint8)
    parts = []
    for c in cols:
        parts += [c, sep]
    parts[-1] = nl
    body = np.hstack(parts)
    tmp = path.with_suffix(".tmp")
    with open(tmp, "wb") as f:
        f.write(b"time_s,wheel_right_rad,wheel_left_rad,x_m,y_m,theta_rad\n")
        f.write(body.tobytes())
    os.replace(tmp, path)
    return path


def section_csv(rows_n: int) -> None:
    path = big_run_csv(rows_n)
    size_mb = path.stat().st_size / 2**20
    ours = fresh(
        python_cmd(
            "-c",
            "import sys; from odocal.io.generic_csv import load_generic_csv; "
            "r = load_generic_csv(sys.argv[1]); assert len(r) == int(sys.argv[2])",
            str(path),
            str(rows_n),
        )
    )
    ref = fresh(
        python_cmd(
            "-c",
            "import sys, numpy as np; "
            "d = np.loadtxt(sys.argv[1], delimiter=',', skiprows=1); "
            "assert len(d) == int(sys.argv[2])",
            str(path),
            str(rows_n),
        )
    )
    if ours.status != 0:
        row(f"read a {rows_n}-row run CSV", f"FAILED: {ours.stderr[-300:]}")
        return
    row(
        f"read a {rows_n / 1e6:g}-million-row run CSV ({size_mb:.0f} MB)",
        f"{ours.wall_s:.1f} s wall, {ours.peak_mb:.0f} MB peak",
        f"numpy.loadtxt {ref.wall_s:.1f} s, {ref.peak_mb:.0f} MB",
        f"{ours.wall_s / ref.wall_s:.2f}x loadtxt's time; peak {ours.peak_mb / size_mb:.1f}x the "
        "file size",
        "memory a few times the file",
    )


# --- bags -----------------------------------------------------------------------------------
def _rosbags_objects(path: Path, topics: list[str]) -> int:
    """The former read: every message deserialised by rosbags and kept as its object."""
    from rosbags.highlevel import AnyReader
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.ROS1_NOETIC if path.suffix == ".bag" else Stores.ROS2_HUMBLE)
    with AnyReader([path], default_typestore=store) as r:
        conns = [c for c in r.connections if c.topic in topics]
        kept = [(t, r.deserialize(raw, c.msgtype)) for c, t, raw in r.messages(conns)]
    return len(kept)


def section_bags() -> None:
    from odocal.io.bags import imu_series, pose_series, read_bag

    imu, odom = "/imu/data", "/husky_velocity_controller/odom"
    for label, path in (("ROS 1 .bag", "husky_test1.bag"), ("ROS 2 .mcap", "husky_test1_ros2")):
        path = HUSKY / path
        if not path.exists():
            row(f"read the Husky bag ({label})", f"SKIPPED: no {path}")
            continue

        def series(fast: bool, path=path) -> None:
            bag = read_bag(path, [imu, odom], fast=fast)
            imu_series(bag, imu), pose_series(bag, odom)

        ways = {
            "fast": lambda: series(True),
            "rosbags": lambda: series(False),
            "objects": lambda path=path: _rosbags_objects(path, [imu, odom]),
        }
        best = dict.fromkeys(ways, math.inf)
        for _ in range(5):  # interleaved: the load moves all three alike
            for name, fn in ways.items():
                best[name] = min(best[name], best_of(fn, 1))
        row(
            f"read the Husky bag's IMU + odometry into series ({label}, 15817 messages)",
            f"{best['fast']:.3f} s ({1e6 * best['fast'] / 15817:.1f} us/message)",
            f"rosbags-only path {best['rosbags']:.3f} s; rosbags objects kept (the former "
            f"read, without series) {best['objects']:.3f} s",
            f"{best['rosbags'] / best['fast']:.2f}x faster than rosbags-only, "
            f"{best['objects'] / best['fast']:.2f}x than the former read",
        )
    bag = HUSKY / "husky_test1.bag"
    if bag.exists():
        cmd = odocal_cmd("fit", str(bag), "--method", "gyro", "--json")
        run = fresh(cmd, repeat=5)
        ref = fresh(python_cmd("-c", "import rosbags.highlevel, odocal.app.fit"), repeat=5)
        row(
            "odocal fit husky_test1.bag --method gyro --json",
            f"{run.wall_s:.3f} s wall, {run.cpu_s:.3f} s CPU (status {run.status})",
            f"importing odocal.app.fit + rosbags {ref.wall_s:.3f} s",
            f"{run.wall_s - ref.wall_s:.3f} s beyond the imports",
        )


# --- suite ----------------------------------------------------------------------------------
def section_suite() -> None:
    run = fresh(python_cmd("-m", "pytest", "-q", "-p", "no:cacheprovider"), out=True)
    for line in run.stderr.splitlines():
        if line.startswith(("FAILED", "ERROR")):
            print(f"  {line}", flush=True)
    row(
        "test suite (pytest -q)",
        f"{run.wall_s:.1f} s wall, {run.cpu_s:.1f} s CPU (status {run.status})",
        f"machine unit {_unit():.2f} s",
        f"{run.wall_s / _unit():.1f} units",
        "< 60 s (about 100 s CPU)",
    )


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default=",".join(SECTIONS), help="comma-separated sections")
    p.add_argument("--trials", type=int, default=500, help="compare trials (default 500)")
    p.add_argument("--ref-trials", type=int, default=20, help="reference design-loop trials")
    p.add_argument("--csv-rows", type=int, default=5_000_000)
    args = p.parse_args(argv)
    only = [s.strip() for s in args.only.split(",") if s.strip()]
    unknown = set(only) - set(SECTIONS)
    if unknown:
        p.error(f"unknown section(s): {', '.join(sorted(unknown))}")
    print(f"machine: {machine()}")
    # as an installation does (pip compiles a package's bytecode; an editable one writes it on
    # first import): compiled once here, so that every fresh process below does not compile
    # odocal again where PYTHONDONTWRITEBYTECODE is set (as on the machine these figures are from)
    compileall.compile_dir(str(ROOT / "src"), quiet=1)
    flag = os.environ.get("PYTHONDONTWRITEBYTECODE", "")
    print(f"PYTHONDONTWRITEBYTECODE={flag!r}; odocal's sources compiled")
    git = os.popen(f"git -C {ROOT} rev-parse --short HEAD 2>/dev/null").read().strip()
    print(f"commit: {git or 'unknown'}", flush=True)
    for name in SECTIONS:
        if name not in only:
            continue
        print(f"[{name}]", flush=True)
        {
            "limit": section_limit,
            "sim": section_sim,
            "design": lambda: section_design(args.ref_trials),
            "startup": section_startup,
            "compare": lambda: section_compare(args.trials),
            "reproduce": section_reproduce,
            "csv": lambda: section_csv(args.csv_rows),
            "bags": section_bags,
            "suite": section_suite,
        }[name]()
    print(f"\nmachine at the end: {machine()}\n")
    print("| figure | measured | reference (same run) | ratio | target |")
    print("|---|---|---|---|---|")
    for r in rows:
        print("| " + " | ".join(r) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
