"""What the speed benchmarks share: the machine, fresh-process timing, and the machine's limits.

Not a benchmark itself: ``bench_speed.py`` (and the other scripts) import it from this folder.

Every figure is reported beside a reference measured in the same run on the same machine, so
that the ratio means something on another machine and under another load (the machines these
run on are shared: wall times move with the load, ratios much less, CPU times least):

- :func:`rng_limit`: numpy's ``Generator.standard_normal`` (PCG64, float64) throughput on 1 and
  on 2 processes at once; the simulator needs two normals per trial-increment (one per wheel),
  so half the 2-process rate is the most increments per second the machine's two cores allow.
- :func:`fresh`: a command in a fresh process: wall time, CPU time (user + system, of that child
  only) and peak resident memory.
"""

from __future__ import annotations

import multiprocessing as mp
import os
import platform
import signal
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent


def machine() -> str:
    model = "unknown CPU"
    try:
        for line in Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    try:
        load = ", load average {:.2f} {:.2f} {:.2f}".format(*os.getloadavg())
    except OSError:
        load = ""
    return (
        f"{os.cpu_count()} logical cores (usable {len(os.sched_getaffinity(0))}), {model}{load}; "
        f"Python {platform.python_version()}, numpy {np.__version__}"
    )


@dataclass(frozen=True)
class Run:
    """One fresh-process run: wall and CPU seconds, peak resident memory (MB), exit status."""

    wall_s: float
    cpu_s: float
    peak_mb: float
    status: int
    stderr: str = ""


def fresh(cmd: list[str], *, cwd: Path | None = None, repeat: int = 1, out: bool = False) -> Run:
    """Run ``cmd`` ``repeat`` times in a fresh process each; the median run by wall time.
    ``out``: keep the end of standard output (in ``stderr``) instead of its standard error."""
    runs = []
    for _ in range(repeat):
        t = time.perf_counter()
        p = subprocess.Popen(
            cmd,
            cwd=cwd or ROOT,
            # as from a terminal: a background shell starts its jobs with SIGINT ignored, which
            # the tests of Ctrl-C handling would notice
            preexec_fn=_default_sigint,
            stdout=subprocess.PIPE if out else subprocess.DEVNULL,
            stderr=subprocess.DEVNULL if out else subprocess.PIPE,
        )
        stream = p.stdout if out else p.stderr
        err = stream.read().decode(errors="replace") if stream else ""
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t
        p.returncode = os.waitstatus_to_exitcode(status)
        runs.append(
            Run(
                wall,
                usage.ru_utime + usage.ru_stime,
                usage.ru_maxrss / 1024.0,  # KiB on Linux
                p.returncode,
                err[-2000:],
            )
        )
    runs.sort(key=lambda r: r.wall_s)
    return runs[len(runs) // 2]


def _default_sigint() -> None:
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def python_cmd(*args: str) -> list[str]:
    return [sys.executable, *args]


def odocal_cmd(*args: str) -> list[str]:
    return [sys.executable, "-m", "odocal", *args]


def _draw(n_blocks: int, block: int, seed: int, out) -> None:
    rng = np.random.default_rng(seed)
    buf = np.empty(block)
    t = time.perf_counter()
    for _ in range(n_blocks):
        rng.standard_normal(out=buf)
    out.put(time.perf_counter() - t)


def rng_limit(normals: int = 200_000_000, block: int = 1 << 20) -> tuple[float, float]:
    """Normals per second (float64, PCG64) on one process, and summed over two processes
    running at once (each drawing ``normals``; spawn start, so no state is shared)."""
    ctx = mp.get_context("spawn")
    n_blocks = max(1, normals // block)
    rates = []
    for procs in (1, 2):
        q = ctx.Queue()
        ps = [ctx.Process(target=_draw, args=(n_blocks, block, i, q)) for i in range(procs)]
        for p in ps:
            p.start()
        times = [q.get() for _ in ps]
        for p in ps:
            p.join()
        # total normals over the slowest process's time: what the processes delivered together
        rates.append(procs * n_blocks * block / max(times))
    return rates[0], rates[1]


def fmt_ratio(x: float) -> str:
    return f"{x:.3g}"
