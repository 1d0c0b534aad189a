"""The paper's procedure on the real OptiOdom robot, end to end: every number of the README's
"The paper's experiment on a real robot" and of docs/real-experiment.md.

1. Steps 2-3 from recordings (``odocal noise RUN_OR_DIR...``): k_r + k_l from the run-to-run
   spread of repeated runs, per kind of run and pooled; the tracker's jitter; the measured robot.
2. The experiment (``odocal reproduce --realdata``, seed 0, 800 trials): heading and UMBmark on
   the 0.75 m and 1.7 m squares, pooled, validated on the 19 held-out circle and free runs, with
   the held-out error's 95 % interval and its coverage in 200 simulated experiments drawn from
   the recorded runs (``heldout_interval_coverage``; the percentile interval's beside it); the
   t-tests; the design's prediction; the verdict.
3. The covariances ``odocal noise --ros2`` writes at the squares' cruise speed.

Usage::

    python benchmarks/bench_real_experiment.py [--data ../shared/realdata/optiodom_diff]
        [--trials 800] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from odocal.app.noise import cruise_speed_m_s, noise_recordings
from odocal.app.reproduce import real_experiment
from odocal.calibration.noise import estimate_k_from_recordings, tracker_noise
from odocal.core.covariance import odometry_covariance
from odocal.design.real_experiment import heldout_interval_coverage, square_end_errors
from odocal.design.verdict import judge_experiment
from odocal.io.real_experiment_report import experiment_dict
from odocal.io.recordings import load_recordings

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"


def noise_by_kind(data: Path) -> dict:
    """k_r + k_l (95 %) per kind of run, with the squares' trajectory geometry."""
    measured = noise_recordings([data / "square"]).measured
    g = measured.fit.geometry
    tracker = tracker_noise(load_recordings([data / "square"]))
    out = {}
    for kind in ("square", "ivanjko", "circular"):
        runs = load_recordings([data / kind])
        est = estimate_k_from_recordings(runs, g, tracker, strict=False)
        out[kind] = {
            "k_sum_m": est.k_sum_m,
            "k_sum_ci95_m": list(est.k_sum_ci95_m),
            "runs": est.runs,
            "dof": est.dof,
            "groups": len(est.groups),
        }
    spins = [
        r for r in load_recordings([data / "ivanjko"]) if r.label and r.label.startswith("spin")
    ]
    lines = [r for r in load_recordings([data / "ivanjko"]) if r.label == "straight"]
    for name, runs in (("ivanjko spins", spins), ("ivanjko straight lines", lines)):
        est = estimate_k_from_recordings(runs, g, tracker, strict=False)
        out[name] = {
            "k_sum_m": est.k_sum_m,
            "k_sum_ci95_m": list(est.k_sum_ci95_m),
            "runs": est.runs,
            "dof": est.dof,
            "groups": len(est.groups),
        }
    return {"by_kind": out, "measured": measured.as_dict(), "tracker": tracker}


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="optiodom_diff folder")
    ap.add_argument("--trials", type=int, default=800)
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    noise = noise_by_kind(args.data)
    t_noise = time.perf_counter() - t0
    t1 = time.perf_counter()
    exp = real_experiment(args.data, trials=args.trials, seed=0)
    t_exp = time.perf_counter() - t1
    squares = load_recordings([args.data / "square"])
    m = noise["measured"]
    k = m["nonsystematic"]
    speed = cruise_speed_m_s(squares, exp.turning.reference)
    cov = odometry_covariance(
        k["k_r_m"], k["k_l_m"], m["calibrated"]["wheelbase_m"], speed_m_s=speed
    )
    if args.json:
        out = {
            "noise": {"by_kind": noise["by_kind"], "measured": m},
            "real_experiment": experiment_dict(exp),
            "ros2_covariance": cov.as_dict(),
            "seconds": {"noise": t_noise, "experiment": t_exp},
        }
        json.dump(out, sys.stdout, indent=2)
        print()
        return 0
    v = judge_experiment(exp)
    print(
        f"machine: {platform.processor() or platform.machine()}, python {platform.python_version()}"
    )
    print(f"\n## Steps 2-3 from recordings ({t_noise:.1f} s)\n")
    tr = noise["tracker"]
    print(
        f"tracker jitter per sample: {tr.sigma_xy_m * 1000:.3f} mm, "
        f"{math.degrees(tr.sigma_theta_rad):.3f} deg (second differences, MAD)"
    )
    print("\n| runs | k_r + k_l (m) | 95 % interval (m) | repeated runs | dof |")
    print("|---|---:|---|---:|---:|")
    for name, e in noise["by_kind"].items():
        lo, hi = e["k_sum_ci95_m"]
        print(f"| {name} | {e['k_sum_m']:.3g} | {lo:.3g}-{hi:.3g} | {e['runs']} | {e['dof']} |")
    s = m["systematic"]
    print(
        f"\nmeasured robot (odocal noise square/): E_b {s['E_b']:.6f}, E_d {s['E_d']:.6f}, "
        f"E_s {s['E_s']:.6f}; k_r = k_l = {k['k_r_m']:.3g} m; instrument "
        f"{m['measurement']['sigma_xy_m'] * 1000:.3f} mm / "
        f"{m['measurement']['sigma_theta_deg']:.3f} deg"
    )
    print(f"\n## The experiment ({t_exp:.1f} s, {args.trials} trials, seed 0)\n")
    print(f"held-out: {exp.heldout_split}\n")
    print(
        "| square | method | runs CW + CCW | E_b | E_d | b (m) | held-out error (mm) | "
        "95 % (mm) | coverage: this interval, percentile | predicted (mm) |"
    )
    print("|---:|---|---|---:|---:|---:|---:|---|---|---:|")
    squares = load_recordings([args.data / "square"])
    heldout = load_recordings([args.data / "circular", args.data / "free"])
    for side in exp.sides_m:
        ends = square_end_errors(
            [r for r in squares if r.meta.get("side_m") == side], exp.reference
        )
        for method in ("heading", "umbmark"):
            c = exp.calibration(side, method)
            cover = heldout_interval_coverage(
                method, ends, side, exp.reference, heldout, np.random.default_rng(1), 200
            )
            p = exp.prediction.real[side].post_error_mean_m * 1000 if method == "heading" else None
            lo, hi = c.heldout_ci95_m
            print(
                f"| {side:g} m | {method} | {c.runs_cw} + {c.runs_ccw} | {c.E_b:.5f} | "
                f"{c.E_d:.6f} | {float(c.geometry.wheelbase_m):.6f} | "
                f"{c.heldout_error_m * 1000:.1f} | {lo * 1000:.1f}-{hi * 1000:.1f} | "
                f"{100 * cover['projected']:.1f} %, {100 * cover['percentile']:.1f} % | "
                + ("-" if p is None else f"{p:.1f}")
                + " |"
            )
    for method, tests in exp.ttests.items():
        t = tests.paired
        st = tests.student
        print(
            f"\n{method}: paired t = {t.t:.2f} (df {t.df:.0f}), p = {t.p_two_sided:.2g}, mean "
            f"difference {t.mean_difference * 1000:+.1f} mm; Student t = {st.t:.2f}, p = "
            f"{st.p_two_sided:.2g}"
        )
    pt = exp.prediction.ttest
    print(
        f"\ndesign: prefers {v.preferred_side_m:g} m; predicted difference "
        f"{pt.mean_difference_m * 1000:+.1f} mm (95 %: {pt.difference_ci95_m[0] * 1000:+.1f} "
        f"to {pt.difference_ci95_m[1] * 1000:+.1f}), significant in "
        f"{100 * pt.fraction_significant:.0f} %; floor {exp.prediction.floor.mean_m * 1000:.1f}"
        f" mm, uncalibrated {exp.prediction.uncalibrated.mean_m * 1000:.1f} mm"
    )
    print(
        f"verdict: ordering predicted {v.ordering_predicted}, difference within the "
        f"prediction {v.difference_within_prediction}"
    )
    print("\nturning gain and held-out error:")
    for g in sorted(exp.gains, key=lambda g: g.heldout_error_m):
        print(f"- {g.label}: {g.turning_gain:.5f}, {g.heldout_error_m * 1000:.1f} mm")
    print(f"\n## ros2 covariances at the squares' cruise speed {speed:.3f} m/s\n")
    print(f"pose_covariance_diagonal: {list(cov.pose_diagonal)}")
    print(f"twist_covariance_diagonal: {list(cov.twist_diagonal)}")
    print(f"process noise per s: {cov.process_noise_per_s}")
    print(f"\n({time.perf_counter() - t0:.1f} s)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
