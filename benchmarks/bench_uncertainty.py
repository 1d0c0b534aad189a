"""Do the uncertainties odocal prints hold? Checked where the truth is known (synthetic bags)
and where two independent parts of real data must agree (MIT CSAIL halves, OptiOdom
sessions). Prints the tables of docs/uncertainty.md.

    .venv/bin/python benchmarks/bench_uncertainty.py [--trials N] [--only synthetic,mit,optiodom]

(about 3 minutes with the default 40 synthetic trials, on 2 cores.)

1. **Synthetic SLAM bags** (``tests/support/synthetic_robot.py``): a robot 1-4 % off its
   nominal geometry, wheel noise k, a SLAM pose with 5 mm / 0.3 deg noise whose stamps run
   0.1 s late, 2 Hz updates. For each trial: does the 95 % interval (value +- t(0.975, dof)
   x stated error) cover the true D_R, D_L, b and the true 0.1 s offset?
2. **MIT CSAIL halves**: the SLAM route and the scan route on each half; |difference| /
   sqrt(se1^2 + se2^2) per parameter (should be at most about 3), with the formal errors
   beside them.
3. **OptiOdom sessions**: the trajectory fit of the June 2020 runs and of the December 2020 /
   January 2021 runs (squares and Ivanjko), the same statistic; and the fit's own check of its
   data sets (Cochran's Q).
"""

from __future__ import annotations

import argparse
import math
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))
REAL = ROOT.parent / "shared" / "realdata"
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def synthetic(trials: int) -> None:
    """Coverage of the SLAM route's 95 % intervals on bags with a known truth."""
    from odocal.app.fit import fit
    from odocal.core.model import NonSystematicError, WheelGeometry
    from odocal.core.stats import student_t_quantile
    from tests.support.synthetic_robot import (
        Laser,
        default_track,
        repeat_run,
        simulate_robot,
        write_ros2_bag,
    )

    believed = WheelGeometry.symmetric(0.066, 0.160)
    hits = {k: 0 for k in (*KEYS, "offset")}
    z_all = {k: [] for k in (*KEYS, "offset")}
    done = 0
    with tempfile.TemporaryDirectory() as tmp:
        robot = Path(tmp) / "robot.yaml"
        robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
        for i in range(trials):
            rng = np.random.default_rng(1000 + i)
            true = WheelGeometry(
                0.066 * (1 + rng.uniform(-0.02, 0.02)),
                0.066 * (1 + rng.uniform(-0.02, 0.02)),
                0.160 * (1 + rng.uniform(0.0, 0.04)),
            )
            run = simulate_robot(default_track(), true, believed, laser=Laser(n_rays=8),
                                 noise=NonSystematicError(2e-6, 2e-6), rng=rng)  # fmt: skip
            path = Path(tmp) / f"bag{i}"
            write_ros2_bag(path, repeat_run(run, 4), map_odom_every=25, imu=False,
                           slam_delay_s=0.1, slam_noise=(0.005, math.radians(0.3)),
                           rng=rng)  # fmt: skip
            try:
                res = fit(path, truth_frames=("map", "base_link"), robot=robot, force=True)
            except Exception as exc:  # noqa: BLE001 - a trial that fails is counted, not fatal
                print(f"  trial {i}: {exc}")
                continue
            done += 1
            f = res.fit
            t = student_t_quantile(0.975, f.dof) if f.dof else 1.96
            for k, v in zip(KEYS, (true.diameter_right_m, true.diameter_left_m,
                                   true.wheelbase_m), strict=True):  # fmt: skip
                z = (f.geometry.as_dict()[k] - v) / f.stderr[k]
                z_all[k].append(z)
                hits[k] += abs(z) < t
            o = res.time_offsets[0]
            z = (o.offset_s - 0.1) / o.stderr_s
            z_all["offset"].append(z)
            hits["offset"] += abs(z) < 1.96
    print(f"\nSynthetic SLAM bags: {done} of {trials} trials (95 % intervals; binomial sd "
          f"{100 * math.sqrt(0.95 * 0.05 / max(done, 1)):.1f} %)")  # fmt: skip
    print("| quantity | coverage of the 95 % interval | sd of z |")
    print("|---|---|---|")
    for k in (*KEYS, "offset"):
        print(f"| {k} | {100 * hits[k] / max(done, 1):.0f} % | {np.std(z_all[k]):.2f} |")


def _z(a: dict, b: dict, se_a: dict, se_b: dict) -> list[float]:
    return [(a[k] - b[k]) / math.hypot(se_a[k], se_b[k]) for k in KEYS]


def mit() -> None:
    """The halves of the MIT CSAIL log, by the SLAM and the scan route."""
    from odocal.app.fit import fit

    robot = REAL / "mit_csail" / "robot_virtual.yaml"
    print("\nMIT CSAIL halves: (half 1 - half 2) / sqrt(se1^2 + se2^2) for D_R, D_L, b")
    print("| route | half 1 (D_R, D_L, b in mm; offset) | half 2 | z stated | z formal |")
    print("|---|---|---|---|---|")
    for route, kwargs in (
        ("SLAM", {"truth_frames": ("map", "base_link")}),
        ("scan 0.25 s", {"method": "scan", "scan_interval_s": 0.25}),
        ("scan 0.5 s", {"method": "scan", "scan_interval_s": 0.5}),
        ("scan 1 s", {"method": "scan", "scan_interval_s": 1.0}),
    ):
        halves = [
            fit(REAL / "mit_csail" / h, robot=robot, force=True, **kwargs)
            for h in ("csail_half1", "csail_half2")
        ]
        vals = [h.fit.as_dict() for h in halves]
        formal = [h.fit.as_dict().get("stderr_formal") or h.fit.as_dict()["stderr"] for h in halves]
        z = _z(vals[0], vals[1], vals[0]["stderr"], vals[1]["stderr"])
        zf = _z(vals[0], vals[1], formal[0], formal[1])
        cells = [
            ", ".join(f"{1e3 * v[k]:.1f}" for k in KEYS)
            + f"; {next(iter(h.time_offsets_s.values())):+.3f} s"
            for v, h in zip(vals, halves, strict=True)
        ]
        print(f"| {route} | {cells[0]} | {cells[1]} | {', '.join(f'{x:+.1f}' for x in z)} | "
              f"{', '.join(f'{x:+.1f}' for x in zf)} |")  # fmt: skip


def optiodom() -> None:
    """The OptiOdom sessions against each other, and the fit's own check of its data sets."""
    from odocal.app.fit import fit_recordings
    from odocal.io.recordings import load_recordings

    opti = REAL / "optiodom_diff"
    recs = load_recordings([opti / "square", opti / "ivanjko"])
    nominal = recs[0].ran_with
    june = [r for r in recs if r.dataset[2:4] == "06"]
    winter = [r for r in recs if r.dataset[2:4] != "06"]
    fits = [fit_recordings(x, "trajectory", nominal=nominal) for x in (june, winter)]
    vals = [f.as_dict() for f in fits]
    z = _z(vals[0], vals[1], vals[0]["stderr"], vals[1]["stderr"])
    zf = _z(vals[0], vals[1], vals[0]["stderr_formal"], vals[1]["stderr_formal"])
    print("\nOptiOdom sessions (squares + Ivanjko): June 2020 against December 2020 - January 2021")
    print("| session | runs | D_R, D_L, b (mm) | stated se (mm) | formal se (mm) |")
    print("|---|---|---|---|---|")
    for name, x, v in (("June", june, vals[0]), ("winter", winter, vals[1])):

        def mm(d: dict) -> str:
            return ", ".join(f"{1e3 * d[k]:.3f}" for k in KEYS)

        print(f"| {name} | {len(x)} | {mm(v)} | {mm(v['stderr'])} | {mm(v['stderr_formal'])} |")
    print(f"z stated: {', '.join(f'{x:+.1f}' for x in z)}; z formal: "
          f"{', '.join(f'{x:+.1f}' for x in zf)}")  # fmt: skip
    pooled = fit_recordings(recs, "trajectory", nominal=nominal).as_dict()
    c = pooled["consistency"]
    print(
        f"the pooled fit's check of its {len(c['groups'])} data sets: Q = "
        + ", ".join(f"{c['statistic'][k]:.1f}" for k in KEYS)
        + f" on {c['dof']} dof, p = "
        + ", ".join(f"{c['p_value'][k]:.2g}" for k in KEYS)
    )


if __name__ == "__main__":
    ap = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    ap.add_argument("--trials", type=int, default=40)
    ap.add_argument("--only", default="synthetic,mit,optiodom")
    a = ap.parse_args()
    parts = a.only.split(",")
    if "synthetic" in parts:
        synthetic(a.trials)
    if "mit" in parts:
        mit()
    if "optiodom" in parts:
        optiodom()
