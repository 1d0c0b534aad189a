"""Speed and peak memory of the bag routes against the bag's length (issue 22, item 9).

    .venv/bin/python benchmarks/bench_bag_route.py            # 5, 15, 30 and 60 minutes
    .venv/bin/python benchmarks/bench_bag_route.py --quick    # 5 minutes only (a smoke run)
    .venv/bin/python benchmarks/bench_bag_route.py --minutes 5 60 --repeat 3
    .venv/bin/python benchmarks/bench_bag_route.py --odocal /old/.venv/bin/odocal \\
        --odocal .venv/bin/odocal                                # two versions, interleaved

Writes synthetic ROS 2 bags with tests/synthetic_robot.py: the room tour driven over and over
(``repeat_run``) for the length asked, 50 Hz joint states and ``odom -> base_link``, a 10 Hz
360-beam laser, a 100 Hz IMU (bias 0.002 rad/s, noise 0.003 rad/s per sample) and a 2 Hz
``map -> odom``. The bags are cached under ``--cache`` (default: a folder in the system's temp
folder), so a rerun does not write them again (a 60-minute bag takes a few minutes to write
and 250 MB of disk).

Each command runs as its own process, as a user runs it; its wall time, its CPU time (user +
system, its worker processes included) and its peak resident memory (``ru_maxrss`` of that
child and its workers, the largest one, from ``os.wait4``) are measured:

- ``check``: ``odocal check BAG --truth-frames map:base_link --robot R.yaml``;
- ``slam``: ``odocal fit BAG --truth-frames map:base_link --robot R.yaml --json``;
- ``scan``: ``odocal fit BAG --method scan --robot R.yaml --json`` (default interval, 0.5 s);
- ``scan-every``: the same with ``--scan-interval 0.1`` (every scan matched);
- ``gyro``: ``odocal fit BAG --method gyro --robot R.yaml --json``;
- ``auto``: ``odocal fit BAG --method auto --robot R.yaml --json`` (every route the bag allows:
  SLAM, scan, gyro, with the bag read once, and the log check). Its cost against its slowest
  route is the price of the one command (issue 27: at most that route plus 20 %).

Printed: the machine and its load average, then per route and version the wall time (s), the
CPU time (s) and the peak memory (MB) at each length, and the slope of a straight line through
them (per hour of bag) with its intercept. On a machine shared with other jobs the wall time
follows the load; the CPU time much less so. With
several ``--repeat`` the median is printed. With several ``--odocal`` executables the commands
alternate between them (A B A B ...) and the ratio to the first is printed per length: the
machine's speed drifts, so compare ratios from one run, not absolute times across runs.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from odocal.core.model import WheelGeometry  # noqa: E402
from tests.support.synthetic_robot import (  # noqa: E402
    Gyro,
    Laser,
    default_track,
    repeat_run,
    simulate_robot,
    write_ros2_bag,
)

TRUE = WheelGeometry(0.0655, 0.0662, 0.163)
BELIEVED = WheelGeometry.symmetric(0.066, 0.160)
ROBOT_YAML = "wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n"
SEED = 7
ROUTES = {
    "check": ["check", "{bag}", "--truth-frames", "map:base_link", "--robot", "{robot}"],
    "slam": ["fit", "{bag}", "--truth-frames", "map:base_link", "--robot", "{robot}", "--json"],
    "scan": ["fit", "{bag}", "--method", "scan", "--robot", "{robot}", "--json"],
    "gyro": ["fit", "{bag}", "--method", "gyro", "--robot", "{robot}", "--json"],
    "auto": ["fit", "{bag}", "--method", "auto", "--robot", "{robot}", "--json"],
    "scan-every": [
        "fit",
        "{bag}",
        "--method",
        "scan",
        "--robot",
        "{robot}",
        "--json",
        "--scan-interval",
        "0.1",
    ],  # fmt: skip
}


def write_bag(folder: Path, minutes: float) -> Path:
    """The bag of ``minutes`` of driving in ``folder`` (written unless already there)."""
    path = folder / f"tour_{minutes:g}min_v2"
    if (path / "metadata.yaml").is_file():
        return path
    if path.exists():  # an interrupted write
        import shutil

        shutil.rmtree(path)
    rng = np.random.default_rng(SEED)
    one = simulate_robot(
        default_track(),
        TRUE,
        BELIEVED,
        laser=Laser(every=5, n_rays=360, sigma_m=0.01),
        gyro=Gyro(0.002, 0.0),
        rng=rng,
        dt_s=0.02,
    )
    # a 100 Hz IMU: two gyro samples per 50 Hz increment, at its first and third quarter
    dt_ns = int(one.time_ns[1] - one.time_ns[0])
    ends = one.time_ns[1:]
    rate = one.gyro_z_rad_s - 0.002  # the true rate over each increment (the bias added back)
    one = replace(
        one,
        gyro_time_ns=np.column_stack([ends - 3 * dt_ns // 4, ends - dt_ns // 4]).reshape(-1),
        gyro_z_rad_s=np.repeat(rate, 2) + 0.002 + 0.003 * rng.standard_normal(2 * len(rate)),
    )
    tour_s = float(one.time_s[-1] + 0.02)
    run = repeat_run(one, max(1, math.ceil(minutes * 60.0 / tour_s)))
    t0 = time.perf_counter()
    tmp = path.with_name(path.name + ".part")
    if tmp.exists():
        import shutil

        shutil.rmtree(tmp)
    write_ros2_bag(tmp, run, map_odom_every=25)
    tmp.rename(path)
    size = sum(f.stat().st_size for f in path.rglob("*") if f.is_file())
    print(
        f"# wrote {path} ({run.time_s[-1] / 60:.1f} min, {size / 1e6:.0f} MB) in "
        f"{time.perf_counter() - t0:.0f} s",
        file=sys.stderr,
        flush=True,
    )
    return path


def timed(argv: list[str]) -> tuple[float, float, int, float]:
    """Wall time (s), peak resident memory (MB), exit status and CPU time (s) of one process."""
    t0 = time.perf_counter()
    proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    proc.returncode = os.waitstatus_to_exitcode(status)
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    if proc.stderr:
        proc.stderr.close()
    if proc.returncode not in (0,):
        last = err.strip().splitlines()[-1:] or ["(no message)"]
        print(f"# exit {proc.returncode}: {' '.join(argv)}: {last[0]}", file=sys.stderr)
    return wall, usage.ru_maxrss / 1024.0, proc.returncode, usage.ru_utime + usage.ru_stime


def machine() -> str:
    """The machine, its load and the software, for the record."""
    import platform

    try:
        cpus = len(os.sched_getaffinity(0))
    except AttributeError:
        cpus = os.cpu_count() or 1
    load = " ".join(f"{x:.2f}" for x in os.getloadavg())
    try:
        commit = subprocess.run(
            ["git", "-C", str(ROOT), "rev-parse", "--short", "HEAD"],
            capture_output=True,
            text=True,
        ).stdout.strip()
    except OSError:
        commit = "?"
    return (
        f"\nmachine: {cpus} usable cores, {platform.processor() or platform.machine()}, load "
        f"average {load}; Python {platform.python_version()}, numpy {np.__version__}; commit "
        f"{commit or '?'}"
    )


def slope(hours: list[float], values: list[float]) -> tuple[float, float]:
    """Least-squares (per hour, intercept) of ``values`` against ``hours``."""
    if len(hours) < 2:
        return math.nan, math.nan
    a, b = np.polyfit(np.asarray(hours), np.asarray(values), 1)
    return float(a), float(b)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--minutes", type=float, nargs="+", default=[5, 15, 30, 60])
    ap.add_argument("--quick", action="store_true", help="5 minutes only")
    ap.add_argument("--routes", nargs="+", choices=list(ROUTES), default=list(ROUTES))
    ap.add_argument("--repeat", type=int, default=1, help="runs per command (median printed)")
    ap.add_argument(
        "--odocal",
        action="append",
        help="odocal executable to time (repeat for several versions; default this venv's)",
    )
    ap.add_argument(
        "--cache",
        type=Path,
        default=Path(tempfile.gettempdir()) / "odocal_bench_bag_route",
        help="folder of the cached bags",
    )
    ap.add_argument("--json", type=Path, help="also write every measurement to this file")
    args = ap.parse_args()
    minutes = [5.0] if args.quick else sorted(args.minutes)
    exes = args.odocal or [str(Path(sys.executable).with_name("odocal"))]
    args.cache.mkdir(parents=True, exist_ok=True)
    robot = args.cache / "robot.yaml"
    robot.write_text(ROBOT_YAML)
    bags = {m: write_bag(args.cache, m) for m in minutes}

    # (route, exe, minutes) -> list of (wall, mb, status, cpu)
    runs: dict[tuple[str, int, float], list[tuple[float, float, int, float]]] = {}
    for route in args.routes:
        for m in minutes:
            for _ in range(args.repeat):
                for i, exe in enumerate(exes):
                    argv = [exe] + [a.format(bag=bags[m], robot=robot) for a in ROUTES[route]]
                    runs.setdefault((route, i, m), []).append(timed(argv))
                    w, mb, st, cpu = runs[(route, i, m)][-1]
                    print(
                        f"# {route:<10} v{i} {m:4g} min: {w:7.2f} s ({cpu:6.2f} s CPU) "
                        f"{mb:7.0f} MB exit {st}",
                        file=sys.stderr,
                        flush=True,
                    )

    def med(key, k):
        return statistics.median(r[k] for r in runs[key])

    head = "".join(f"{m:>8g}m" for m in minutes)
    print(machine())
    print(f"bag length (minutes): {', '.join(f'{m:g}' for m in minutes)}; "
          f"median of {args.repeat} run(s); versions: "
          + ", ".join(f"v{i} = {e}" for i, e in enumerate(exes)))  # fmt: skip
    for label, k, unit in (("wall time", 0, "s"), ("CPU time", 3, "s"), ("peak memory", 1, "MB")):
        print(f"\n{label} ({unit})")
        print(f"{'route':<12}{'ver':<4}{head}{'per hour':>10}{'at 0':>8}")
        for route in args.routes:
            for i in range(len(exes)):
                vals = [med((route, i, m), k) for m in minutes]
                a, b = slope([m / 60 for m in minutes], vals)
                fmt = "{:9.0f}" if k == 1 else "{:9.2f}"
                print(
                    f"{route:<12}v{i:<3}"
                    + "".join(fmt.format(v) for v in vals)
                    + f"{a:10.1f}{b:8.1f}"
                )
                if i:
                    ratio = [med((route, i, m), k) / med((route, 0, m), k) for m in minutes]
                    print(f"{'':<12}{'/v0':<4}" + "".join(f"{r:9.2f}" for r in ratio))
    bad = {key: [r[2] for r in v if r[2]] for key, v in runs.items()}
    bad = {k: v for k, v in bad.items() if v}
    if bad:
        print("\nnon-zero exit status: " + ", ".join(f"{k}: {v}" for k, v in bad.items()))
    if args.json:
        args.json.write_text(
            json.dumps(
                {
                    "versions": exes,
                    "minutes": minutes,
                    "runs": [
                        {
                            "route": r,
                            "version": i,
                            "minutes": m,
                            "wall_s": w,
                            "cpu_s": cpu,
                            "peak_mb": mb,
                            "status": st,
                        }
                        for (r, i, m), v in runs.items()
                        for w, mb, st, cpu in v
                    ],
                },
                indent=1,
            )
        )


if __name__ == "__main__":
    main()
