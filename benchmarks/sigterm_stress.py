"""SIGTERM (or SIGINT) to the whole process group of ``odocal reproduce`` at random times.

Each run starts the command in a process group of its own, waits a random time (uniform over
``--max-delay`` seconds, from the start: the imports, the worker processes starting, computing,
drawing, writing), signals the group, and classifies what happened:

- ``clean``: exit 128 + the signal number, stderr exactly one ``odocal: ...`` line, nothing on
  stdout, no output folder or temporary file, no process of the group left;
- ``early``: killed by the signal before odocal's handler was installed (interpreter start-up):
  nothing written, nothing printed;
- ``finished``: the command had already finished (exit 0), or had written every output when
  the signal came (then exit 128 + the signal number, the files those of an undisturbed run);
- ``traceback`` / ``partial`` / ``leftover`` / ``other``: a failure (printed);
- ``hang``: no exit within ``--timeout`` seconds (the group is then killed).

Usage::

    python benchmarks/sigterm_stress.py --runs 40                    # reproduce --trials 5
    python benchmarks/sigterm_stress.py --runs 40 --realdata /work/shared/realdata/optiodom_diff
    python benchmarks/sigterm_stress.py --runs 40 --signal INT

Results of the commit that added this script: see its message (and the report of issue #20).
"""

from __future__ import annotations

import argparse
import collections
import os
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def one_run(
    argv: list[str], delay_s: float, signum: int, timeout_s: float, complete: list[str]
) -> tuple[str, str]:
    """(the class of the outcome, a detail) of one run signalled after ``delay_s``; ``complete``:
    the files of an undisturbed run."""
    work = Path(tempfile.mkdtemp(prefix="odocal-sigterm-"))
    out = work / "out"
    try:
        proc = subprocess.Popen(
            [sys.executable, "-X", "faulthandler", "-m", "odocal", *argv, "--out", str(out)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            cwd=work,
            start_new_session=True,  # its own process group: the workers are in it
        )
        if signum:
            time.sleep(delay_s)
            try:
                os.killpg(proc.pid, signum)
            except ProcessLookupError:
                pass
        try:
            stdout, stderr = proc.communicate(timeout=timeout_s)
        except subprocess.TimeoutExpired:
            ps = subprocess.run(
                ["ps", "-o", "pid,ppid,stat,wchan:20,cmd", "-g", str(proc.pid)],
                capture_output=True,
                text=True,
            ).stdout
            os.killpg(proc.pid, signal.SIGABRT)  # faulthandler: every thread's stack
            try:
                _, stderr = proc.communicate(timeout=10)
            except subprocess.TimeoutExpired:
                os.killpg(proc.pid, signal.SIGKILL)
                _, stderr = proc.communicate()
            return "hang", f"after {delay_s:.2f} s\n{ps}{stderr}"
        time.sleep(0.2)  # let a worker the signal missed notice its parent is gone
        try:
            os.killpg(proc.pid, 0)
            left = True
        except ProcessLookupError:
            left = False
        if left:
            os.killpg(proc.pid, signal.SIGKILL)
        files = sorted(str(p.relative_to(work)) for p in work.rglob("*"))
        code = proc.returncode
        if left:
            return "leftover", f"worker processes alive after exit {code}"
        if "Traceback" in stderr or "Error" in stderr.replace("odocal: error", ""):
            return "traceback", f"exit {code}:\n{stderr.strip()}"
        if code == 0:
            return ("finished", "") if out.is_dir() else ("other", "exit 0, no output")
        if files and files == complete and code in (-signum, 128 + signum):
            return "finished", f"signalled after writing (exit {code})"
        if files:
            return "partial", ", ".join(files)
        if code == -signum and stderr == "" and stdout == "":
            return "early", ""
        one_line = stderr.count("\n") == 1 and stderr.startswith("odocal: ")
        if code == 128 + signum and one_line and stdout == "":
            return "clean", ""
        return "other", f"exit {code}:\n{stderr.strip()}"
    finally:
        shutil.rmtree(work, ignore_errors=True)


def _files_of_one_run(argv: list[str]) -> list[str]:
    """The files an undisturbed run writes (relative to its folder)."""
    with tempfile.TemporaryDirectory(prefix="odocal-sigterm-") as d:
        subprocess.run(
            [sys.executable, "-m", "odocal", *argv, "--out", str(Path(d) / "out")],
            capture_output=True,
            check=True,
        )
        return sorted(str(p.relative_to(d)) for p in Path(d).rglob("*"))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=40)
    parser.add_argument("--min-delay", type=float, default=0.0, help="s")
    parser.add_argument("--max-delay", type=float, default=None, help="s (default: measured)")
    parser.add_argument("--trials", type=int, default=5)
    parser.add_argument("--realdata", default=None, help="an optiodom_diff folder")
    parser.add_argument("--signal", default="TERM", choices=("TERM", "INT"))
    parser.add_argument("--timeout", type=float, default=120.0)
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    import random

    rng = random.Random(args.seed)
    argv = ["reproduce", "--trials", str(args.trials)]
    if args.realdata:
        argv += ["--realdata", args.realdata]
    signum = getattr(signal, f"SIG{args.signal}")
    # a job started in the background inherits SIGINT ignored, and so would the command
    signal.signal(signal.SIGINT, signal.default_int_handler)
    max_delay = args.max_delay
    complete = _files_of_one_run(argv)
    start = time.monotonic()
    kind, detail = one_run(argv, 0.0, 0, args.timeout, complete)
    if max_delay is None:  # the time of one undisturbed run
        max_delay = time.monotonic() - start
        print(f"one undisturbed run: {max_delay:.1f} s ({kind} {detail})", flush=True)
    counts: collections.Counter[str] = collections.Counter()
    for i in range(args.runs):
        delay = rng.uniform(args.min_delay, max_delay)
        kind, detail = one_run(argv, delay, signum, args.timeout, complete)
        counts[kind] += 1
        if kind not in ("clean", "early", "finished"):
            print(f"run {i}: SIG{args.signal} after {delay:.2f} s: {kind}: {detail}", flush=True)
    print(" ".join(f"{k}={v}" for k, v in sorted(counts.items())))


if __name__ == "__main__":
    main()
