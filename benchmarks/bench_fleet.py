"""The fleet (issue 21): the drift detector's false alarms and detection delays on simulated
estimates, and the ingest's throughput on a simulated fleet of synthetic bags.

    .venv/bin/python benchmarks/bench_fleet.py drift              # the detector (pure numpy)
    .venv/bin/python benchmarks/bench_fleet.py drift --grid       # + the (k, h) choice
    .venv/bin/python benchmarks/bench_fleet.py ingest             # 50 robots x 20 bags
    .venv/bin/python benchmarks/bench_fleet.py ingest --robots 5 --bags 4   # a smoke run

**drift**: a robot-month is 20 bags (one bag per working day). Each simulated robot has a
history of 12 months (240 bags) from its first bag; its three parameters' estimates are drawn
independently around the truth with the stated per-bag standard errors (0.1 % of each value:
what the bag route reports on the synthetic bags of tests/support/fleet.py). Measured:

- false alarms per 100 robot-months at constant parameters (all three parameters);
- bags from a step (after 100 bags) to its alarm: 0.3 % diameter (3 se), 0.5 % wheelbase
  (5 se), and a step of exactly 3 se; median, mean, 90th percentile, share within 5 bags;
- linear wear of one wheel's diameter (0.3 % a month): bags to the alarm and the wear by then.

**ingest**: writes (once, cached under ``--cache``) a fleet of ``--robots`` x ``--bags`` small
synthetic ROS 2 bags (tests/support/fleet.py; per robot one recording and copies of it that
differ in a comment of their metadata, each a bag of its own), then ingests it into a fresh
database with 2 worker processes, on a 2-worker ``dask.distributed.LocalCluster`` and with 1
worker (this process) (``--engines`` chooses); prints bags per minute,
the wall time and the CPU time per bag (this process and its children), and checks that the
three databases hold the same numbers.
"""

from __future__ import annotations

import argparse
import os
import resource
import sqlite3
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from odocal.calibration.drift import DEFAULT_H, DEFAULT_K, track_parameter  # noqa: E402

BAGS_PER_MONTH = 20
MONTHS = 12
STEP_AT = 100
REL_SE = 1e-3  # per-bag standard error, relative


def _alarm_delays(rng, step_rel: float, robots: int, k: float, h: float) -> np.ndarray:
    """Bags from the step to the first alarm at or after it (inf: none in 60 bags)."""
    n = STEP_AT + 60
    out = np.full(robots, np.inf)
    for r in range(robots):
        y = 1.0 + REL_SE * rng.standard_normal(n)
        y[STEP_AT:] += step_rel
        alarms = [a.index for a in track_parameter(y, np.full(n, REL_SE), k=k, h=h).alarms]
        after = [i for i in alarms if i >= STEP_AT]
        if after:
            out[r] = after[0] - STEP_AT + 1
    return out


def _false_alarms(rng, robots: int, k: float, h: float, scatter: float = 1.0) -> float:
    """False alarms per 100 robot-months (three parameters each); ``scatter``: the true
    scatter of the estimates over their stated standard error."""
    n = BAGS_PER_MONTH * MONTHS
    alarms = 0
    for _ in range(robots * 3):
        y = 1.0 + scatter * REL_SE * rng.standard_normal(n)
        alarms += len(track_parameter(y, np.full(n, REL_SE), k=k, h=h).alarms)
    return 100.0 * alarms / (robots * MONTHS)


def _describe(d: np.ndarray) -> str:
    found = d[np.isfinite(d)]
    return (f"median {np.median(found):.0f}, mean {found.mean():.2f}, 90th pct "
            f"{np.percentile(found, 90):.0f}, within 5 bags {100 * np.mean(d <= 5):.1f} %, "
            f"missed (60 bags) {100 * np.mean(~np.isfinite(d)):.2f} %")  # fmt: skip


def drift(args) -> None:
    rng = np.random.default_rng(args.seed)
    settings = [(DEFAULT_K, DEFAULT_H)]
    if args.grid:
        settings += [(1.5, 3.5), (1.5, 4.5), (1.5, 5.0), (1.0, 5.0)]
    for k, h in settings:
        t = time.process_time()
        fa = _false_alarms(rng, args.robots, k, h)
        print(f"k = {k}, h = {h}: {fa:.2f} false alarms per 100 robot-months "
              f"({args.robots} robots x {MONTHS} months, {BAGS_PER_MONTH} bags/month, 3 "
              "parameters, se 0.1 %)")  # fmt: skip
        for name, step in (("0.3 % diameter step (3 se)", 0.003),
                           ("0.5 % wheelbase step (5 se)", 0.005),
                           ("3 se step", 3 * REL_SE)):  # fmt: skip
            print(f"  {name}: bags to the alarm: "
                  f"{_describe(_alarm_delays(rng, step, args.steps, k, h))}")  # fmt: skip
        n = BAGS_PER_MONTH * MONTHS
        rate = 0.003 / BAGS_PER_MONTH  # 0.3 % a month
        first = []
        for _ in range(args.steps):
            y = 1.0 - rate * np.arange(n) + REL_SE * rng.standard_normal(n)
            a = track_parameter(y, np.full(n, REL_SE), k=k, h=h).alarms
            first.append(a[0].index if a else np.inf)
        f = np.asarray(first, float)
        print(f"  wear 0.3 %/month ({rate / REL_SE:.2f} se per bag): first alarm after "
              f"{np.median(f):.0f} bags (median; 90th pct {np.percentile(f, 90):.0f}), wear by "
              f"then {100 * rate * np.median(f):.2f} %")  # fmt: skip
        fa = _false_alarms(rng, args.robots // 4, k, h, scatter=1.2)
        print(
            f"  if the stated standard errors are 20 % too small: {fa:.2f} false alarms per "
            "100 robot-months"
        )
        print(f"  ({time.process_time() - t:.1f} s CPU)")


def _write_fleet(folder: Path, robots: int, bags: int, seed: int) -> Path:
    """Each robot: one synthetic bag written, and ``bags - 1`` copies of it whose
    metadata.yaml ends with a different comment (each copy its own content hash, so a bag of
    its own for the ingest, and calibrated in full). Writing a bag costs 0.17 s of CPU; 1,000
    of them would take longer than the ingest on a busy machine."""
    import shutil

    from odocal.core.model import WheelGeometry
    from tests.support.fleet import NOMINAL, robot_yaml, write_bag

    root = folder / f"fleet_{robots}x{bags}_{seed}"
    done = root / ".complete"
    if done.exists():
        return root
    rng = np.random.default_rng(seed)
    for r in range(robots):
        rid = f"robot{r:03d}"
        robot_yaml(root / rid)
        true = WheelGeometry(NOMINAL.diameter_right_m * (1 + 0.01 * rng.uniform(-1, 1)),
                             NOMINAL.diameter_left_m * (1 + 0.01 * rng.uniform(-1, 1)),
                             NOMINAL.wheelbase_m * (1 + 0.03 * rng.uniform(-1, 1)))  # fmt: skip
        first = root / rid / "day000"
        if not first.exists():
            write_bag(first, true, 0, rng)
        for b in range(1, bags):
            copy = root / rid / f"day{b:03d}"
            if copy.exists():
                shutil.rmtree(copy)
            shutil.copytree(first, copy)
            with (copy / "metadata.yaml").open("a") as f:
                f.write(f"# copy {b} of day000 (benchmarks/bench_fleet.py)\n")
    done.write_text("")
    return root


def _children_cpu() -> float:
    ru = resource.getrusage(resource.RUSAGE_CHILDREN)
    return ru.ru_utime + ru.ru_stime


def _numbers(db: Path) -> list[tuple]:
    with sqlite3.connect(db) as con:
        return con.execute("SELECT content_hash, d_right_m, d_right_se_m, d_left_m, wheelbase_m, "
                           "wheelbase_se_m, result_json FROM calibrations "
                           "ORDER BY content_hash").fetchall()  # fmt: skip


def ingest(args) -> None:
    from odocal.app.fleet import fleet_ingest

    cache = Path(args.cache)
    cache.mkdir(parents=True, exist_ok=True)
    t = time.perf_counter()
    root = _write_fleet(cache, args.robots, args.bags, args.seed)
    n = args.robots * args.bags
    print(f"fleet: {args.robots} robots x {args.bags} bags under {root} "
          f"({time.perf_counter() - t:.0f} s to write or find)")  # fmt: skip
    print(f"machine: {os.cpu_count()} CPUs, load average {os.getloadavg()[0]:.1f}")
    dbs = {}
    every = [
        ("2 workers", {"workers": 2}),
        ("LocalCluster 2 workers", None),
        ("1 worker", {"workers": 1}),
    ]
    engines = [e for e in every if e[0].split()[0] in args.engines]
    with tempfile.TemporaryDirectory() as tmp:
        for name, kw in engines:
            db = Path(tmp) / f"{name.replace(' ', '_')}.db"
            cluster = None
            if kw is None:
                from dask.distributed import LocalCluster

                cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True)
                kw = {"dask": cluster.scheduler_address}
            cpu0, child0, t0 = time.process_time(), _children_cpu(), time.perf_counter()
            res = fleet_ingest(root, db, **kw)
            wall = time.perf_counter() - t0
            cpu = time.process_time() - cpu0 + _children_cpu() - child0
            if cluster is not None:
                cluster.close()
                cpu_note = " (the cluster's workers' CPU not counted)"
            else:
                cpu_note = ""
            assert res.bags_new == n, res.as_dict()
            print(f"{name}: {n} bags in {wall:.1f} s: {60 * n / wall:.1f} bags/minute, "
                  f"{wall / n:.3f} s wall per bag, {cpu / n:.3f} s CPU per bag{cpu_note}; "
                  f"load {os.getloadavg()[0]:.1f}", flush=True)  # fmt: skip
            dbs[name] = _numbers(db)
        first = next(iter(dbs.values()))
        same = all(v == first for v in dbs.values())
        print(f"the same numbers, bit for bit, in the {len(dbs)} databases: {same}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    sub = p.add_subparsers(dest="what", required=True)
    d = sub.add_parser("drift")
    d.add_argument("--robots", type=int, default=1000, help="robots of 12 months (false alarms)")
    d.add_argument("--steps", type=int, default=2000, help="simulated steps per case")
    d.add_argument("--grid", action="store_true")
    d.add_argument("--seed", type=int, default=1)
    i = sub.add_parser("ingest")
    i.add_argument("--robots", type=int, default=50)
    i.add_argument("--bags", type=int, default=20)
    i.add_argument("--seed", type=int, default=1)
    i.add_argument(
        "--engines",
        nargs="+",
        default=["1", "2", "LocalCluster"],
        help="which of: 1 (worker), 2 (workers), LocalCluster",
    )
    i.add_argument("--cache", default=str(Path(tempfile.gettempdir()) / "odocal_bench_fleet"))
    args = p.parse_args()
    (drift if args.what == "drift" else ingest)(args)


if __name__ == "__main__":
    main()
