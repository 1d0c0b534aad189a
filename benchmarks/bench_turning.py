"""The effective wheelbase as a function of the motion, on the real OptiOdom robot, and an honest
held-out evaluation of the curvature-dependent model (docs/real-robots.md).

1. Effective wheelbase per band of motion (spot turns, tight arcs, wide arcs, near-straight)
   per kind of run, with 95 % intervals (``odocal.calibration.turning``), at the diameters of
   odocal's default fit (squares + Ivanjko).
2. Held-out evaluation across data sets: every procedure is calibrated on some data sets and
   validated on others (never on the runs fitted); the metric is the mean final position error
   of the validation runs. Procedures:

   - constant: ``odocal fit`` (trajectory, one wheelbase);
   - banded: ``--wheelbase-model banded``, the validation runs dead-reckoned with the band
     model (refused when the calibration runs excite fewer than two bands);
   - banded, mix of the calibration runs: the single wheelbase for the calibration runs' own
     motion mix;
   - banded, mix of the validation runs: the single wheelbase for the motion mix of the
     validation runs, read from their WHEEL data only (what a user knows from logs of normal
     driving, without ground truth);
   - heading / UMBmark on the squares of each size (the paper's methods).

Usage::

    python benchmarks/bench_turning.py [--data ../shared/realdata/optiodom_diff] [--json]
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from odocal.calibration.banded import fit_banded
from odocal.calibration.squares import fit_recorded_squares
from odocal.calibration.trajectory import fit_trajectory
from odocal.calibration.turning import (
    BANDS,
    band_of_increments,
    effective_wheelbase,
    wheelbase_for_mix,
    wheelbase_per_increment,
)
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.errors import CalibrationError
from odocal.io.optiodom import load_optiodom_dataset

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"
NOMINAL = WheelGeometry(0.084, 0.084, 0.200)
CIRCLE_DEC, CIRCLE_JUN = "231220200121", "250620202104"


def load(data: Path) -> dict:
    """(kind, data set id) -> runs."""
    out = {}
    for kind in ("square", "ivanjko", "circular", "free"):
        for d in sorted((data / kind).iterdir()):
            out[(kind, d.name)] = load_optiodom_dataset(d)
    return out


def runs_of(sets: dict, pred) -> list:
    return [r for k, v in sets.items() if pred(k) for r in v]


def mean_error(runs, geometry: WheelGeometry) -> float:
    return float(
        np.mean(
            [
                np.hypot(
                    *(
                        r.ground_truth[-1, :2]
                        - dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, geometry)[
                            -1, :2
                        ]
                    )
                )
                for r in runs
            ]
        )
    )


def banded_error(runs, fit) -> float:
    g, bands = fit.geometry, fit.banded.band_wheelbase_m
    errs = []
    for r in runs:
        b = wheelbase_per_increment(r, bands, g)
        odo = dead_reckon(
            r.wheel_angle_right_rad,
            r.wheel_angle_left_rad,
            WheelGeometry.unchecked(g.diameter_right_m, g.diameter_left_m, b),
        )
        errs.append(np.hypot(*(r.ground_truth[-1, :2] - odo[-1, :2])))
    return float(np.mean(errs))


def rotation_mix(runs, geometry: WheelGeometry) -> dict[str, float]:
    """Share of the odometric rotation per band, from the wheel data only."""
    rot = np.zeros(len(BANDS))
    for r in runs:
        band = band_of_increments(
            r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.time_s, geometry
        )
        dth = (
            np.diff(r.wheel_angle_right_rad) * geometry.diameter_right_m
            - np.diff(r.wheel_angle_left_rad) * geometry.diameter_left_m
        ) / (2 * geometry.wheelbase_m)
        for i in range(len(BANDS)):
            rot[i] += np.abs(dth[band == i]).sum()
    return {n: float(v / rot.sum()) for n, v in zip(BANDS, rot, strict=True)}


SPLITS = {
    "squares + Ivanjko -> circles + free (the 19 held-out runs)": (
        lambda k: k[0] in ("square", "ivanjko"),
        lambda k: k[0] in ("circular", "free"),
    ),
    "+ December circles -> June circles + free": (
        lambda k: k[0] in ("square", "ivanjko") or k[1] == CIRCLE_DEC,
        lambda k: k[0] == "free" or k[1] == CIRCLE_JUN,
    ),
    "+ June circles -> December circles + free": (
        lambda k: k[0] in ("square", "ivanjko") or k[1] == CIRCLE_JUN,
        lambda k: k[0] == "free" or k[1] == CIRCLE_DEC,
    ),
    "+ all circles -> free": (
        lambda k: k[0] in ("square", "ivanjko", "circular"),
        lambda k: k[0] == "free",
    ),
    "+ free -> circles": (
        lambda k: k[0] in ("square", "ivanjko", "free"),
        lambda k: k[0] == "circular",
    ),
}


def evaluate_split(sets, train_pred, test_pred) -> dict:
    train, test = runs_of(sets, train_pred), runs_of(sets, test_pred)
    out = {"train_runs": len(train), "test_runs": len(test)}
    const = fit_trajectory(train, nominal=NOMINAL)
    out["constant"] = mean_error(test, const.geometry)
    try:
        banded = fit_banded(train, const.geometry, nominal=NOMINAL)
        out["banded"] = banded_error(test, banded)
        out["banded, mix of the calibration runs"] = mean_error(test, banded.geometry)
        per_band = {n: banded.banded.band_wheelbase_m[banded.banded.band_uses[n]] for n in BANDS}
        mix = rotation_mix(test, const.geometry)
        b = wheelbase_for_mix(per_band, mix).wheelbase_m
        g = banded.geometry
        out["banded, mix of the validation runs"] = mean_error(
            test, WheelGeometry(g.diameter_right_m, g.diameter_left_m, b)
        )
        out["band_wheelbase_m"] = banded.banded.band_wheelbase_m
    except CalibrationError as exc:
        out["banded"] = f"refused: {str(exc)[:90]}..."
    for side in (0.75, 1.7):
        sq = [r for r in train if r.meta.get("kind") == "square" and r.meta["side_m"] == side]
        for method in ("heading", "umbmark"):
            g = fit_recorded_squares(sq, method, nominal=NOMINAL).geometry
            out[f"{method} {side:g} m squares"] = mean_error(test, g)
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="optiodom_diff folder")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    sets = load(args.data)
    ref = fit_trajectory(
        runs_of(sets, lambda k: k[0] in ("square", "ivanjko")), nominal=NOMINAL
    ).geometry
    tables = {}
    for name, pred in (
        ("0.75 m squares (June)", lambda k: k[0] == "square" and k[1].startswith("2306")),
        ("1.7 m squares (December)", lambda k: k[0] == "square" and k[1].startswith("2312")),
        ("Ivanjko spins + lines", lambda k: k[0] == "ivanjko"),
        ("circles R 0.85 m (December)", lambda k: k[1] == CIRCLE_DEC),
        ("circles R 0.375 m (June)", lambda k: k[1] == CIRCLE_JUN),
        ("free paths (January)", lambda k: k[0] == "free"),
    ):
        tables[name] = effective_wheelbase(runs_of(sets, pred), ref)
    splits = {name: evaluate_split(sets, tr, te) for name, (tr, te) in SPLITS.items()}
    elapsed = time.perf_counter() - t0
    if args.json:
        json.dump(
            {
                "reference": ref.as_dict(),
                "effective_wheelbase": {k: v.as_dict() for k, v in tables.items()},
                "splits": splits,
                "seconds": elapsed,
            },
            sys.stdout,
            indent=2,
        )
        print()
        return 0
    print(
        f"Effective wheelbase per band of motion (mm, 95 % interval over runs) at the diameters "
        f"of odocal's default fit (D_R {ref.diameter_right_m:.6f}, D_L {ref.diameter_left_m:.6f} "
        "m):\n"
    )
    print("| runs | " + " | ".join(BANDS) + " |")
    print("|---|" + "---|" * len(BANDS))
    for name, t in tables.items():
        cells = []
        for b in t.bands:
            if b.excited:
                cells.append(
                    f"{1000 * b.wheelbase_m:.2f} ({1000 * b.ci95_m[0]:.2f}-"
                    f"{1000 * b.ci95_m[1]:.2f})"
                )
            else:
                cells.append("-")
        print(f"| {name} | " + " | ".join(cells) + " |")
    procs = [
        "constant",
        "banded",
        "banded, mix of the calibration runs",
        "banded, mix of the validation runs",
        "heading 0.75 m squares",
        "heading 1.7 m squares",
        "umbmark 0.75 m squares",
        "umbmark 1.7 m squares",
    ]
    print("\nHeld-out mean final error (mm), calibrated on some data sets, validated on others:\n")
    print("| calibrated on -> validated on | runs | " + " | ".join(procs) + " |")
    print("|---|---|" + "---:|" * len(procs))
    for name, row in splits.items():
        cells = []
        for p in procs:
            v = row.get(p)
            cells.append(
                "refused" if isinstance(v, str) else ("-" if v is None else f"{1000 * v:.1f}")
            )
        print(f"| {name} | {row['train_runs']} / {row['test_runs']} | " + " | ".join(cells) + " |")
    for name, row in splits.items():
        if "band_wheelbase_m" in row:
            bw = ", ".join(f"{k} {1000 * v:.2f}" for k, v in row["band_wheelbase_m"].items())
            print(f"- {name}: banded fit {bw} mm")
    print(f"\n({elapsed:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
