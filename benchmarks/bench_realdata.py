"""Real-data benchmark: calibrate on OptiOdom squares + Ivanjko runs, validate on held-out runs.

Calibration runs: ``square/`` (44 UMBmark squares, CW and CCW) and ``ivanjko/`` (66 straight lines
and 180 deg spins). Held-out runs: ``circular/`` (12) and ``free/`` (7); none is used by any
calibration here, except the published OptiOdom row (see below).

Metric: mean over the 19 held-out runs of the final position error (m) of dead reckoning with the
calibrated parameters against the motion-capture ground truth (``odocal.core.odometry.evaluate``).

UMBmark and the heading method use the square runs only (they need CW/CCW squares); each data set
is calibrated with the firmware parameters it ran with and the results are pooled
(``calibration/squares.py``). ``linear`` and ``trajectory`` use squares and Ivanjko runs.

Published row: ``reference_results_diff.csv``, method Sousa, ALL_DATASETS_COMBINED (171 runs, all
categories INCLUDING the held-out circles and free paths, so it is not a held-out result).

Usage::

    python benchmarks/bench_realdata.py [--data ../shared/realdata/optiodom_diff] [--json]

Also: the turning gain each kind of run implies (per recording session), and the trajectory fit's
settings (residual, run weight, heading weight) on the same runs and on the 1.7 m squares alone.
"""

from __future__ import annotations

import argparse
import csv
import json
import sys
import time
from pathlib import Path

import numpy as np

from odocal.app.fit import fit_recordings
from odocal.calibration.fit_settings import TrajectorySettings
from odocal.core.model import WheelGeometry
from odocal.core.odometry import evaluate
from odocal.design.real_experiment import heldout_floor
from odocal.io.recordings import load_recordings

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"


def published(data: Path) -> list[tuple[str, WheelGeometry]]:
    out = []
    with open(data / "reference_results_diff.csv", encoding="utf-8") as fh:
        for row in csv.DictReader(fh):
            if row["method"] == "Sousa" and row["dataset"] == "ALL_DATASETS_COMBINED":
                label = "published OptiOdom, ALL_DATASETS_COMBINED"
                if row["note"]:
                    label += f" {row['note']}"
                geo = WheelGeometry(
                    float(row["cal_Dr_m"]), float(row["cal_Dl_m"]), float(row["cal_b_m"])
                )
                out.append((label, geo))
    return out


def errors(runs, geometry) -> dict:
    ev = [evaluate(r, geometry) for r in runs]
    return {
        "final": float(np.mean([e["final_error_m"] for e in ev])),
        "max": float(np.mean([e["max_error_m"] for e in ev])),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="optiodom_diff folder")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    data = args.data
    t0 = time.perf_counter()
    squares = load_recordings([data / "square"])
    ivanjko = load_recordings([data / "ivanjko"])
    circular = load_recordings([data / "circular"])
    free = load_recordings([data / "free"])
    train = squares + ivanjko
    held = circular + free
    nominal = WheelGeometry(0.084, 0.084, 0.200)

    rows = []

    def add(name, trained_on, geometry, note=""):
        rows.append(
            {
                "method": name,
                "calibrated_on": trained_on,
                **geometry.as_dict(),
                "held_out_mean_final_error_m": errors(held, geometry)["final"],
                "held_out_mean_max_error_m": errors(held, geometry)["max"],
                "circular_mean_final_error_m": errors(circular, geometry)["final"],
                "free_mean_final_error_m": errors(free, geometry)["final"],
                "note": note,
            }
        )

    add("nominal (firmware)", "-", nominal)
    for method in ("umbmark", "heading"):
        fit = fit_recordings(squares, method, nominal=nominal)
        add(method, "square", fit.geometry, "per data set, pooled")
        for side in (0.75, 1.7):
            runs = [r for r in squares if r.meta.get("side_m") == side]
            fit = fit_recordings(runs, method, nominal=nominal)
            add(
                f"{method}, {side:g} m squares only",
                f"square {side:g} m",
                fit.geometry,
                "per data set, pooled",
            )
    fit = fit_recordings(train, "linear", nominal=nominal)
    add("linear (Antonelli)", "square + ivanjko", fit.geometry)
    variants = [
        ("trajectory (default: pose residual, travel weights)", {}),
        ("trajectory --run-weight equal", {"run_weight": "equal"}),
        ("trajectory --drop-outliers", {"drop_outliers": True}),
        ("trajectory --residual segment", {"residual": "segment"}),
    ]
    for name, kw in variants:
        fit = fit_recordings(
            train, "trajectory", nominal=nominal, settings=TrajectorySettings(**kw)
        )
        note = ""
        if fit.outliers:
            note = "outliers: " + ", ".join(Path(n).stem for n in fit.outliers)
            if kw.get("drop_outliers"):
                note = "dropped " + note[len("outliers: ") :]
        add(name, "square + ivanjko", fit.geometry, note)
    for label, geo in published(data):
        add(label, "all 171 runs (incl. held-out)", geo, "not held-out")
    fit = fit_recordings(held, "trajectory", nominal=nominal)
    add(
        "trajectory fitted ON the held-out runs",
        "circular + free",
        fit.geometry,
        "in-sample reference, not held-out",
    )
    add(
        "best possible: D_R, D_L, b minimising the mean held-out final error",
        "circular + free",
        heldout_floor(held, nominal),
        "floor of the mean final error for ANY parameters",
    )

    # diagnostic: the effective turning gain mean(D)/b each kind of motion implies
    def june(r):
        return str(r.meta.get("dataset", "")).startswith(("2306", "2506"))

    spins = [r for r in ivanjko if r.label and r.label.startswith("spin")]
    gains = {}
    for name, runs in (
        ("ivanjko spins", spins),
        ("ivanjko spins, June", [r for r in spins if june(r)]),
        ("ivanjko spins, December", [r for r in spins if not june(r)]),
        ("squares", squares),
        ("0.75 m squares (June)", [r for r in squares if june(r)]),
        ("1.7 m squares (December)", [r for r in squares if not june(r)]),
        ("circles", circular),
        ("circles R 0.85 m (December)", [r for r in circular if not june(r)]),
        ("circles R 0.375 m (June)", [r for r in circular if june(r)]),
        ("free paths", free),
    ):
        g = fit_recordings(runs, "trajectory", nominal=nominal).geometry
        gains[name] = float(g.mean_diameter_m / g.wheelbase_m)

    # the default's estimator settings on the same runs, and the December squares alone
    sweep = []
    dec_squares = [r for r in squares if not june(r)]
    settings = [
        (hw, res, w)
        for hw in (0.1, 1.0, 10.0)
        for res in ("pose", "segment")
        for w in ("travel", "equal")
    ]
    for on, runs, grid in (
        ("square + ivanjko", train, settings),
        ("1.7 m squares", dec_squares, [(hw, "pose", "travel") for hw in (0.1, 1.0, 10.0)]),
    ):
        for hw, residual, weight in grid:
            g = fit_recordings(
                runs,
                "trajectory",
                nominal=nominal,
                settings=TrajectorySettings(
                    heading_weight_m=hw, residual=residual, run_weight=weight
                ),
            ).geometry
            sweep.append(
                {
                    "calibrated_on": on,
                    "heading_weight_m": hw,
                    "residual": residual,
                    "run_weight": weight,
                    "turning_gain": float(g.mean_diameter_m / g.wheelbase_m),
                    "held_out_mean_final_error_m": errors(held, g)["final"],
                }
            )
    elapsed = time.perf_counter() - t0

    if args.json:
        json.dump(
            {
                "rows": rows,
                "turning_gain_D_over_b": gains,
                "estimator_sweep": sweep,
                "seconds": elapsed,
            },
            sys.stdout,
            indent=2,
        )
        print()
        return 0
    print(
        f"Held-out: {len(circular)} circular + {len(free)} free runs; calibration runs: "
        f"{len(squares)} square + {len(ivanjko)} ivanjko.\n"
    )
    print(
        "| method | calibrated on | D_R (m) | D_L (m) | b (m) | gain mean(D)/b | held-out mean "
        "final error (mm) | mean max error (mm) | circular / free (mm) | note |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        gain = 0.5 * (r["wheel_diameter_right_m"] + r["wheel_diameter_left_m"]) / r["wheelbase_m"]
        print(
            f"| {r['method']} | {r['calibrated_on']} | {r['wheel_diameter_right_m']:.6f} | "
            f"{r['wheel_diameter_left_m']:.6f} | {r['wheelbase_m']:.6f} | {gain:.5f} | "
            f"{1000 * r['held_out_mean_final_error_m']:.1f} | "
            f"{1000 * r['held_out_mean_max_error_m']:.1f} | "
            f"{1000 * r['circular_mean_final_error_m']:.1f} / "
            f"{1000 * r['free_mean_final_error_m']:.1f} | {r['note']} |"
        )
    print("\nEffective turning gain mean(D)/b fitted per kind of motion (trajectory, in-sample):")
    for k, v in gains.items():
        print(f"- {k}: {v:.5f}")
    print("\nTrajectory-fit settings (held-out mean final error, mm; turning gain):\n")
    print("| calibrated on | residual | run weight | heading weight (m/rad) | gain | error (mm) |")
    print("|---|---|---|---:|---:|---:|")
    for r in sweep:
        print(
            f"| {r['calibrated_on']} | {r['residual']} | {r['run_weight']} | "
            f"{r['heading_weight_m']:g} | {r['turning_gain']:.5f} | "
            f"{1000 * r['held_out_mean_final_error_m']:.1f} |"
        )
    print(f"\n({elapsed:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
