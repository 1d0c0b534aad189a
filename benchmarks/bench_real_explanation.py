"""Why the real experiment came out as it did (docs/real-experiment.md, "Verdict" and "Why
odocal's default fit does worse"): every number of that explanation, with the truth's clock
offset against the wheels estimated per data set (issue 20.11).

1. The truth's clock offset per data set (``truth_offset``; the estimate and its standard error).
2. The effective wheelbase per band of motion (at the diameters of odocal's default fit) per
   kind of run: as recorded, on the wheels' clock (each data set's estimated offset applied), and
   on the wheels' clock shifted by one 50 ms sample either way.
3. The mix of spot and arc turning of the two square sizes, and the share of their turning-gain
   difference it explains (``mixture_gain_ratio``).
4. Who calibrates whom: the heading method and UMBmark from the June 0.75 m and the December
   1.7 m squares, validated on the June circles, the December circles and the free paths.

Usage::

    python benchmarks/bench_real_explanation.py [--data ../shared/realdata/optiodom_diff]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

from odocal.calibration.time_offset import truth_offset
from odocal.calibration.turning import effective_wheelbase
from odocal.core.model import WheelGeometry
from odocal.design.real_experiment import heldout_errors
from odocal.design.real_explanation import mixture_gain_ratio, on_wheel_clock
from odocal.io.recordings import load_recordings

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"
NOMINAL = WheelGeometry(0.084, 0.084, 0.200)
#: odocal fit's default on squares + Ivanjko: the diameters the band wheelbases are taken at.
FIT = WheelGeometry(0.083695, 0.083743, 0.201428)


def june(r) -> bool:
    return str(r.dataset).startswith(("2306", "2506"))


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="optiodom_diff folder")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    sq = load_recordings([args.data / "square"])
    iv = load_recordings([args.data / "ivanjko"])
    ci = load_recordings([args.data / "circular"])
    fr = load_recordings([args.data / "free"])

    def spins(s):
        return [r for r in iv if r.label and r.label.startswith("spin") and june(r) == s]

    groups = {
        "0.75 m squares (June)": [r for r in sq if june(r)],
        "1.7 m squares (December)": [r for r in sq if not june(r)],
        "Ivanjko spins (June)": spins(True),
        "Ivanjko spins (December)": spins(False),
        "circles R 0.375 m (June)": [r for r in ci if june(r)],
        "circles R 0.85 m (December)": [r for r in ci if not june(r)],
        "free paths (January)": fr,
    }
    print("## 1. The truth's clock offset per data set (ms; estimate +- standard error)\n")
    offsets = {}
    by_set: dict[str, list] = {}
    for r in sq + iv + ci + fr:
        by_set.setdefault(r.dataset, []).append(r)
    for name, runs in by_set.items():
        o = truth_offset(runs)
        offsets[name] = float(o.offset_s)
        se = "-" if o.stderr_s is None else f"{1e3 * o.stderr_s:.1f}"
        print(f"- {name}: {1e3 * o.offset_s:+.1f} +- {se}")

    print("\n## 2. Effective wheelbase per band (mm, 95 % interval)\n")
    print("| runs | as recorded | wheels' clock | clock - 50 ms | clock + 50 ms |")
    print("|---|---|---|---|---|")
    tables = {}
    for name, runs in groups.items():
        cells = []
        for label, rr in (
            ("raw", runs),
            ("clock", on_wheel_clock(runs, offsets)),
            ("-50", on_wheel_clock(runs, offsets, -0.05)),
            ("+50", on_wheel_clock(runs, offsets, 0.05)),
        ):
            t = effective_wheelbase(rr, FIT)
            tables[(name, label)] = t
            cells.append(
                ", ".join(
                    f"{b.band} {1e3 * b.wheelbase_m:.2f} ({1e3 * b.ci95_m[0]:.2f}-"
                    f"{1e3 * b.ci95_m[1]:.2f})"
                    for b in t.bands
                    if b.excited and b.wheelbase_m is not None and b.ci95_m is not None
                )
            )
        print(f"| {name} | " + " | ".join(cells) + " |")

    print("\n## 3. The squares' mix of motion and the gain difference it explains\n")
    small = tables[("0.75 m squares (June)", "clock")]
    large = tables[("1.7 m squares (December)", "clock")]
    for label, t in (("0.75 m", small), ("1.7 m", large)):
        mix = ", ".join(f"{k} {100 * v:.1f} %" for k, v in t.motion_mix.items())
        print(f"- {label} squares' rotation: {mix}")
    spot = 0.5 * (small.band("spot").wheelbase_m + large.band("spot").wheelbase_m)
    c_june = tables[("circles R 0.375 m (June)", "clock")].band("tight").wheelbase_m
    c_dec = tables[("circles R 0.85 m (December)", "clock")].band("wide").wheelbase_m
    ends = {}
    for label, runs in (("0.75", groups["0.75 m squares (June)"]),
                        ("1.7", groups["1.7 m squares (December)"])):  # fmt: skip
        from odocal.calibration.squares import fit_recorded_squares

        ends[label] = {
            m: fit_recorded_squares(runs, m, nominal=NOMINAL).geometry
            for m in ("heading", "umbmark")
        }
    g = {k: v["heading"].mean_diameter_m / v["heading"].wheelbase_m for k, v in ends.items()}
    actual = g["0.75"] / g["1.7"] - 1
    print(f"- heading method's turning gains: 0.75 m {g['0.75']:.5f}, 1.7 m {g['1.7']:.5f}: "
          f"{100 * actual:.2f} %")  # fmt: skip
    for arc_label, arc in (("June circles", c_june), ("December circles", c_dec)):
        r = mixture_gain_ratio(small, large, {"spot": spot, "tight": arc, "wide": arc})
        print(
            f"- mixture alone (spot {1e3 * spot:.2f} mm, arcs {1e3 * arc:.2f} mm as the "
            f"{arc_label}): {100 * r:.3f} %, {100 * r / actual:.0f} % of the difference"
        )

    print("\n## 4. Who calibrates whom (mean final error, mm)\n")
    print("| calibrated on | method | June circles | December circles | free paths |")
    print("|---|---|---:|---:|---:|")
    held = {
        "June circles": groups["circles R 0.375 m (June)"],
        "December circles": groups["circles R 0.85 m (December)"],
        "free paths": fr,
    }
    for label, by_method in ends.items():
        for m, geo in by_method.items():
            cells = " | ".join(
                f"{1e3 * float(heldout_errors(runs, geo).mean()):.1f}" for runs in held.values()
            )
            print(f"| {label} m squares | {m} | {cells} |")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
