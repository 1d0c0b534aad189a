"""The README's test command, timed paired against a baseline commit (issue 27 item 21).

Run from the project root (each run is a whole test suite: about 1 to 2 minutes on 2 cores):

    .venv/bin/python benchmarks/bench_suite.py [--baseline REV] [--pairs N] [--no-bytecode]

It runs the README's test command, ``.venv/bin/python -m pytest -q``, on the working tree ("now",
uncommitted changes included) and on a temporary git worktree of ``--baseline`` (default
``HEAD~1``), alternating now, baseline, now, baseline, ... (``--pairs`` pairs, default 3), each in
a fresh state as in a CI clone: no ``__pycache__`` under ``src`` and ``tests`` and no
``.pytest_cache`` before each run. Python writes its bytecode caches during the run as a fresh
clone's would (``PYTHONDONTWRITEBYTECODE`` is removed from the runs' environment, since it may be
set on the machine); ``--no-bytecode`` sets it instead (every process compiles what it imports).

Both trees run with this project's ``.venv`` (its installed dependencies); the baseline's own
``src`` comes first on ``PYTHONPATH``, so that its tests import its ``odocal`` and not the
working tree's editable install (each run prints where ``odocal`` was imported from). The real
data are the ones the working tree's tests find (``$ODOCAL_REALDATA``, else
``../shared/realdata``), given to both runs in ``ODOCAL_REALDATA`` (the baseline worktree is not
beside ``../shared``).

Per run it prints the wall time, the CPU time (user + system of the test command and of every
process it waited for: the xdist workers, the subprocesses and worker processes of the tests;
``os.wait4``'s resource usage), the load average before the run and pytest's last line; then
the medians and the ratios now / baseline.

The machine is shared and noisy (other test suites run on the same 2 cores): the wall time moves
with the load by tens of per cent from one run to the next, the CPU time much less (it counts
what the suite computed, not how long it waited for a core; contention still inflates it a
little). The CPU time, and its ratio now / baseline from alternated runs, is the figure to
trust; the wall time is "on 2 quiet cores" only when the load average before the run is well
under 1.
"""

from __future__ import annotations

import argparse
import os
import shutil
import signal
import statistics
import subprocess
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent))
from machine import ROOT, machine  # noqa: E402  (benchmarks/machine.py, beside this script)

#: the README's test command, run in the tree being measured
TEST_CMD = ("-m", "pytest", "-q")


@dataclass(frozen=True)
class Run:
    label: str
    wall_s: float
    cpu_s: float
    status: int
    load: float
    last_line: str


def fresh_state(tree: Path) -> None:
    """As a fresh clone: no bytecode caches under src and tests, no pytest cache."""
    for top in ("src", "tests"):
        for cache in (tree / top).rglob("__pycache__"):
            shutil.rmtree(cache, ignore_errors=True)
    shutil.rmtree(tree / ".pytest_cache", ignore_errors=True)


def realdata_dir() -> Path | None:
    env = os.environ.get("ODOCAL_REALDATA")
    for c in ([Path(env)] if env else []) + [ROOT.parent / "shared" / "realdata"]:
        if (c / "optiodom_diff").is_dir():
            return c.resolve()
    return None


def run_env(tree: Path, realdata: Path | None, bytecode: bool) -> dict[str, str]:
    env = dict(os.environ)
    env.pop("PYTHONDONTWRITEBYTECODE", None)
    if not bytecode:
        env["PYTHONDONTWRITEBYTECODE"] = "1"
    # this tree's odocal before the editable install's (the working tree's)
    env["PYTHONPATH"] = os.pathsep.join(
        [str(tree / "src"), *filter(None, [os.environ.get("PYTHONPATH")])]
    )
    if realdata is not None:
        env["ODOCAL_REALDATA"] = str(realdata)
    return env


def imported_from(python: str, tree: Path, env: dict[str, str]) -> str:
    code = "import odocal; print(odocal.__file__)"
    return subprocess.run(
        [python, "-c", code], cwd=tree, env=env, capture_output=True, text=True, check=True
    ).stdout.strip()


def _default_sigint() -> None:
    # as from a terminal: a background shell starts its jobs with SIGINT ignored, which the tests
    # of Ctrl-C handling would notice
    signal.signal(signal.SIGINT, signal.SIG_DFL)


def run_suite(label: str, python: str, tree: Path, env: dict[str, str], log: Path) -> Run:
    fresh_state(tree)
    load = os.getloadavg()[0]
    with open(log, "w") as out:
        t = time.perf_counter()
        p = subprocess.Popen(
            [python, *TEST_CMD],
            cwd=tree,
            env=env,
            stdout=out,
            stderr=subprocess.STDOUT,
            stdin=subprocess.DEVNULL,
            preexec_fn=_default_sigint,
        )
        _, status, usage = os.wait4(p.pid, 0)
        wall = time.perf_counter() - t
    lines = [ln.strip() for ln in log.read_text(errors="replace").splitlines() if ln.strip()]
    return Run(
        label,
        wall,
        usage.ru_utime + usage.ru_stime,
        os.waitstatus_to_exitcode(status),
        load,
        lines[-1] if lines else "",
    )


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--baseline", default="HEAD~1", help="the commit to compare with (HEAD~1)")
    p.add_argument("--pairs", type=int, default=3, help="pairs of runs, now then baseline (3)")
    p.add_argument(
        "--no-bytecode",
        action="store_true",
        help="set PYTHONDONTWRITEBYTECODE in the runs (default: unset, as a fresh clone)",
    )
    p.add_argument("--python", default=str(ROOT / ".venv" / "bin" / "python"))
    p.add_argument("--keep-logs", type=Path, help="a folder for each run's pytest output")
    args = p.parse_args(argv)
    if args.pairs < 1:
        p.error("--pairs must be at least 1")

    def git(*a: str) -> str:
        return subprocess.run(
            ["git", *a], cwd=ROOT, capture_output=True, text=True, check=True
        ).stdout.strip()

    sha = git("rev-parse", "--verify", args.baseline + "^{commit}")
    head = git("rev-parse", "--short", "HEAD")
    dirty = " + uncommitted changes" if git("status", "--porcelain", "--", "src", "tests") else ""
    realdata = realdata_dir()
    bytecode = not args.no_bytecode
    print(f"machine: {machine()}")
    print(f"command: {Path(args.python).name} {' '.join(TEST_CMD)} (the README's)")
    print(f"now: working tree (HEAD {head}{dirty}); baseline: {args.baseline} = {sha[:7]}")
    print(
        "fresh state before each run (no __pycache__, no .pytest_cache); bytecode caches "
        + ("written during the run" if bytecode else "not written (PYTHONDONTWRITEBYTECODE=1)")
    )
    print(f"real data: {realdata or 'not found (those tests are skipped)'}")

    tmp = Path(tempfile.mkdtemp(prefix="odocal-bench-suite-"))
    logs = args.keep_logs or tmp / "logs"
    logs.mkdir(parents=True, exist_ok=True)
    base_tree = tmp / "baseline"
    subprocess.run(
        ["git", "worktree", "add", "--detach", "--quiet", str(base_tree), sha], cwd=ROOT, check=True
    )
    runs: list[Run] = []
    try:
        trees = {"now": ROOT, "baseline": base_tree}
        envs = {k: run_env(t, realdata, bytecode) for k, t in trees.items()}
        for k, t in trees.items():
            print(f"  {k}: odocal from {imported_from(args.python, t, envs[k])}")
        print(f"{'run':>4} {'tree':<9} {'wall s':>7} {'CPU s':>7} {'load':>5}  pytest")
        for i in range(args.pairs):
            for k in ("now", "baseline"):
                r = run_suite(k, args.python, trees[k], envs[k], logs / f"{i + 1}-{k}.txt")
                runs.append(r)
                print(
                    f"{i + 1:>4} {k:<9} {r.wall_s:7.1f} {r.cpu_s:7.1f} {r.load:5.2f}  "
                    f"{r.last_line}" + ("" if r.status == 0 else f" (exit status {r.status})"),
                    flush=True,
                )
    finally:
        subprocess.run(["git", "worktree", "remove", "--force", str(base_tree)], cwd=ROOT)
        if args.keep_logs is None:
            shutil.rmtree(tmp, ignore_errors=True)

    def med(k: str, attr: str) -> float:
        return statistics.median(getattr(r, attr) for r in runs if r.label == k)

    print(f"medians over {args.pairs} run(s) each:")
    for k in ("now", "baseline"):
        print(f"  {k:<9} wall {med(k, 'wall_s'):6.1f} s   CPU {med(k, 'cpu_s'):6.1f} s")
    print(
        f"  now / baseline: wall {med('now', 'wall_s') / med('baseline', 'wall_s'):.3f}   "
        f"CPU {med('now', 'cpu_s') / med('baseline', 'cpu_s'):.3f}"
    )
    # the paired view: each now run against the baseline run right after it
    pairs = [(runs[2 * i], runs[2 * i + 1]) for i in range(args.pairs)]
    cpu_ratios = [a.cpu_s / b.cpu_s for a, b in pairs]
    print("  CPU ratio per pair: " + ", ".join(f"{x:.3f}" for x in cpu_ratios))
    failed = [r for r in runs if r.status != 0]
    if failed:
        print(f"{len(failed)} run(s) failed (exit status != 0)")
    if args.keep_logs:
        print(f"pytest output of each run in {args.keep_logs}")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
