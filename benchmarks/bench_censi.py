"""Censi et al. (2013) real data: the authors' published calibration vs odocal, per tuple file.

Data: ``censi_calibration/`` in the shared real-data folder (``$ODOCAL_REALDATA`` or
``../shared/realdata``): 12 tuple files (l90, lmov, lstraight and their three disjoint subsets
_0/_1/_2) and the authors' ``X_results.json`` (axle, l_diam, r_diam, l_x, l_y, l_theta and a 6x6
covariance of (r_L, r_R, axle, l_x, l_y, l_theta), radii).

For every file and parameter the table gives the published value, odocal's value and
|difference| / published standard deviation (z; for a diameter D = 2 r the std is 2 sqrt(C_rr),
so z is the same for the radius). Rows:

- ``odocal``: ``fit_censi`` defaults (closed form, 4 trimming rounds of 1 %, ML refinement);
- ``closed``: the closed-form estimate on the same tuples (the authors' estimator);
- ``cov``: max over the six parameters of |std_paper / std_published - 1| for odocal's
  recomputation of the authors' covariance (verifies its order and units), and odocal's own
  standard error / published std (median over the six parameters).

Usage::

    python benchmarks/bench_censi.py [--data DIR] [--json]
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np

from odocal.calibration.censi import PARAMETERS, fit_censi
from odocal.io.tuples import read_tuples

ROOT = Path(__file__).resolve().parents[1]
FILES = [f"{s}{k}" for s in ("l90", "lmov", "lstraight") for k in ("", "_0", "_1", "_2")]
# Column order of the table: the authors' names and the index into odocal's PARAMETERS
COLUMNS = [
    ("axle", 2),
    ("r_diam", 0),
    ("l_diam", 1),
    ("l_x", 3),
    ("l_y", 4),
    ("l_theta", 5),
]


def default_folder() -> Path:
    env = os.environ.get("ODOCAL_REALDATA")
    base = Path(env) if env else ROOT.parent / "shared" / "realdata"
    return base / "censi_calibration"


def published(folder: Path, name: str) -> tuple[np.ndarray, np.ndarray]:
    """Published values and covariance in odocal's PARAMETERS order (diameters, SI)."""
    pub = json.loads((folder / f"{name}_results.json").read_text())
    values = np.array(
        [pub["r_diam"], pub["l_diam"], pub["axle"], pub["l_x"], pub["l_y"], pub["l_theta"]]
    )
    to_ours = np.zeros((6, 6))
    to_ours[0, 1] = to_ours[1, 0] = 2.0  # (r_L, r_R) -> (D_R, D_L)
    for i in (2, 3, 4, 5):
        to_ours[i, i] = 1.0
    return values, to_ours @ np.array(pub["covariance"]) @ to_ours.T


def run(folder: Path) -> list[dict]:
    rows = []
    for name in FILES:
        t0 = time.perf_counter()
        data = read_tuples(folder / f"{name}.tuple")
        t1 = time.perf_counter()
        fit = fit_censi(data.phi_right_rad, data.phi_left_rad, data.sensor_motion)
        t2 = time.perf_counter()
        values, cov = published(folder, name)
        std = np.sqrt(np.diag(cov))
        rows.append(
            {
                "file": name,
                "tuples": fit.tuples_total,
                "used": fit.tuples_used,
                "published": values.tolist(),
                "published_std": std.tolist(),
                "odocal": fit.parameters.tolist(),
                "closed_form": fit.closed_form.tolist(),
                "z": (np.abs(fit.parameters - values) / std).tolist(),
                "z_closed_form": (np.abs(fit.closed_form - values) / std).tolist(),
                "paper_cov_std_error": float(
                    np.max(np.abs(np.sqrt(np.diag(fit.covariance_paper)) / std - 1))
                ),
                "own_std_over_published": float(np.median(np.sqrt(np.diag(fit.covariance)) / std)),
                "read_s": t1 - t0,
                "fit_s": t2 - t1,
                "warnings": list(fit.warnings),
            }
        )
    return rows


def _fmt(v: float, j: int) -> str:
    return f"{v:.6f}" if j == 5 else f"{1000 * v:.4f}"


def table(rows: list[dict]) -> str:
    head = " | ".join(f"{c} (z)" for c, _ in COLUMNS)
    out = [
        "lengths in mm, l_theta in rad; z = |odocal - published| / published std",
        "",
        f"| file | row | {head} |",
        "|" + "---|" * (len(COLUMNS) + 2),
    ]
    for r in rows:
        pub = " | ".join(_fmt(r["published"][j], j) for _, j in COLUMNS)
        std = " | ".join(_fmt(r["published_std"][j], j) for _, j in COLUMNS)
        ours = " | ".join(f"{_fmt(r['odocal'][j], j)} ({r['z'][j]:.3f})" for _, j in COLUMNS)
        closed = " | ".join(
            f"{_fmt(r['closed_form'][j], j)} ({r['z_closed_form'][j]:.4f})" for _, j in COLUMNS
        )
        out.append(f"| {r['file']} | published | {pub} |")
        out.append(f"| | published std | {std} |")
        out.append(f"| | odocal | {ours} |")
        out.append(f"| | closed form | {closed} |")
    out.append("")
    out.append(
        "| file | tuples | used | worst z odocal | worst z closed form | paper cov. std error | "
        "own std / published | read (s) | fit (s) |"
    )
    out.append("|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        out.append(
            f"| {r['file']} | {r['tuples']} | {r['used']} | {max(r['z']):.3f} | "
            f"{max(r['z_closed_form']):.4f} | {r['paper_cov_std_error']:.1e} | "
            f"{r['own_std_over_published']:.2f} | {r['read_s']:.3f} | {r['fit_s']:.3f} |"
        )
    worst = np.max([r["z"] for r in rows], axis=0)
    out.append("")
    out.append(
        "worst z per parameter over the 12 files (odocal): "
        + ", ".join(f"{c} {worst[j]:.3f}" for c, j in COLUMNS)
    )
    total_read = sum(r["read_s"] for r in rows)
    total_fit = sum(r["fit_s"] for r in rows)
    out.append(f"run time: read {total_read:.2f} s, fit {total_fit:.2f} s (12 files)")
    return "\n".join(out)


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data", type=Path, default=None, help="censi_calibration folder")
    parser.add_argument("--json", action="store_true", help="print JSON instead of the table")
    args = parser.parse_args(argv)
    folder = args.data or default_folder()
    if not folder.is_dir():
        print(f"bench_censi: data folder not found: {folder}", file=sys.stderr)
        return 2
    t0 = time.perf_counter()
    rows = run(folder)
    elapsed = time.perf_counter() - t0
    if args.json:
        print(json.dumps({"parameters": list(PARAMETERS), "rows": rows, "elapsed_s": elapsed}))
    else:
        print(table(rows))
        print(f"total wall time {elapsed:.2f} s")
    return 0


if __name__ == "__main__":
    sys.exit(main())
