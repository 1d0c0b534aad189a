"""Speed and memory of ``odocal calibrate`` on a large RUNS.csv: this tree against an older one.

Writes a synthetic run sheet of N rows (``direction,x_m,y_m,theta_deg,run``, alternate CW and
CCW runs of ``paper-fig5`` on a 1 m square with measurement noise, six decimals), then times
``odocal.app.calibrate.calibrate`` on it (heading method, ``paper-fig5``) in a fresh child
process per tree and size, recording the wall time and the child's peak resident memory
(``resource.getrusage``, ru_maxrss). The older tree (default: dc0f233, the commit before the
vectorised reader) is extracted with ``git archive`` and run from its own ``src``; both run in
the same invocation, so that their ratio holds on a shared machine whose speed varies.

Usage::

    .venv/bin/python benchmarks/bench_runs_csv.py [--rows 100000,1000000,5000000] [--old dc0f233]
        [--new COMMIT]

Results (2 shared cores under a load average of about 10, 2026-11-26; old = dc0f233, new =
the vectorised reader with the heading-sign check of calibrate; E_b and E_d equal in every row):

========= ============ ============ ============= =============
rows      old time (s) new time (s) old peak (MB) new peak (MB)
========= ============ ============ ============= =============
100 000   2.94         0.74         132           74
1 000 000 29.90        6.40         1030          225
5 000 000 159.37       35.69        4973          1192
========= ============ ============ ============= =============

The old tree took 159 s here against the issue's 85 s (the machine ran at about half speed):
the new reader's 35.7 s and 1.2 GB are under the issue's figures of a week before (39 s,
2.6 GB) even so, and 4.5 times faster than the old tree in the same run. What remains is numpy's
string-to-float conversion and the vectorised split (about 60 %), the repeated-row check and
the heading-sign check (calibrate_heading twice more).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]

CHILD = """
import json, resource, sys, time
from odocal.app.calibrate import calibrate
start = time.perf_counter()
res = calibrate(sys.argv[1], "paper-fig5")
wall = time.perf_counter() - start
peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
c = res.calibration
print(json.dumps({"wall_s": wall, "peak_mb": peak_mb, "E_b": c.E_b, "E_d": c.E_d}))
"""


def _mean_ends() -> dict[str, np.ndarray]:
    """Noise-free final pose errors of paper-fig5 on a 1 m square, per direction (so that the
    synthetic runs are honest: their headings agree with their positions)."""
    from odocal.core.model import NonSystematicError
    from odocal.core.simulate import drive
    from odocal.core.tracks import polygon
    from odocal.presets import PRESETS

    r, still = PRESETS["paper-fig5"], NonSystematicError(0.0, 0.0)
    return {
        d: drive(polygon(4, 1.0, d), r.true_geometry, r.nominal, still, 1, None).errors[0]
        for d in ("cw", "ccw")
    }


def write_sheet(path: Path, rows: int, seed: int = 0) -> None:
    """A RUNS.csv of ``rows`` runs of paper-fig5 on a 1 m square, alternately CW and CCW: the
    noise-free ends plus a tape's 2 mm and a protractor's 0.3 deg (written in blocks)."""
    rng = np.random.default_rng(seed)
    ends = _mean_ends()
    with open(path, "w", encoding="utf-8") as fh:
        fh.write("# sides: 4\n# side_m: 1\ndirection,x_m,y_m,theta_deg,run\n")
        block = 200_000
        for first in range(0, rows, block):
            n = min(block, rows - first)
            k = np.arange(first, first + n)
            cw = k % 2 == 0
            v = np.where(cw[:, None], ends["cw"], ends["ccw"])
            v[:, 2] = np.degrees(v[:, 2])
            v += rng.normal(0.0, [0.002, 0.002, 0.3], size=(n, 3))
            fh.writelines(
                f"{'cw' if c else 'ccw'},{a:.6f},{b:.6f},{t:.4f},{i + 1}\n"
                for c, (a, b, t), i in zip(cw, v.tolist(), k.tolist(), strict=True)
            )


def run(src: Path, sheet: Path) -> dict:
    """``calibrate`` on ``sheet`` in a fresh interpreter importing odocal from ``src``."""
    env = dict(os.environ, PYTHONPATH=str(src), ODOCAL_THREADS="1")
    out = subprocess.run(
        [sys.executable, "-c", CHILD, str(sheet)], env=env, capture_output=True, text=True
    )
    if out.returncode != 0:
        return {"error": out.stderr.strip().splitlines()[-1:]}
    return json.loads(out.stdout)


def extract(commit: str, folder: Path) -> Path:
    """The ``src`` tree of ``commit`` extracted into ``folder`` (``git archive``)."""
    folder.mkdir()
    archive = subprocess.run(
        ["git", "-C", str(ROOT), "archive", commit, "src"], check=True, capture_output=True
    ).stdout
    subprocess.run(["tar", "-x", "-C", str(folder)], input=archive, check=True)
    return folder


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--rows", default="100000,1000000,5000000")
    ap.add_argument("--old", default="dc0f233", help="the older commit (default dc0f233)")
    ap.add_argument("--new", default=None, help="the newer commit (default: this working tree)")
    args = ap.parse_args()
    with tempfile.TemporaryDirectory() as tmp:
        old, new = extract(args.old, Path(tmp, "old")), ROOT
        if args.new is not None:
            new = extract(args.new, Path(tmp, "new"))
        print("| rows | old s | new s | old/new time | old peak MB | new peak MB | E_b equal |")
        print("|---:|---:|---:|---:|---:|---:|---|")
        for rows in (int(float(r)) for r in args.rows.split(",")):
            sheet = Path(tmp, f"runs-{rows}.csv")
            write_sheet(sheet, rows)
            a = run(old / "src", sheet)
            b = run(new / "src", sheet)
            if "error" in a or "error" in b:
                print(f"| {rows} | {a} | {b} |")
                continue
            same = abs(a["E_b"] - b["E_b"]) < 1e-12 and abs(a["E_d"] - b["E_d"]) < 1e-12
            print(
                f"| {rows} | {a['wall_s']:.2f} | {b['wall_s']:.2f} | "
                f"{a['wall_s'] / b['wall_s']:.1f} | {a['peak_mb']:.0f} | {b['peak_mb']:.0f} | "
                f"{same} |",
                flush=True,
            )
            sheet.unlink()


if __name__ == "__main__":
    main()
