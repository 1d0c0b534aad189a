"""Calibration without motion capture: the accuracy of the three routes on simulated bags.

    .venv/bin/python benchmarks/bench_no_mocap.py [--seeds 5]

A TurtleBot3-sized robot (true D_R 0.0655 m, D_L 0.0662 m, b 0.163 m; it believes 0.066 m and
0.160 m) drives in the synthetic room of tests/support/synthetic_robot.py; every route writes a
ROS 2 bag and runs `odocal fit` on it, as a user would:

- SLAM: the 8.3 m room tour, `map -> odom` updated at 2 Hz from the true pose plus SLAM noise
  (0 and 1 cm / 0.5 deg per update), `fit BAG --truth-frames map:base_link`;
- scan: the same tour, a 2D laser mounted at (0.15 m, 0.05 m, 0.1 rad) with 1 cm range noise,
  `fit BAG --method scan`;
- gyro: 3 CW + 3 CCW 1 m squares with a gyro of 0.002 rad/s bias and 0.003 rad/s noise per
  50 Hz sample, `fit BAGS --method heading --heading-source gyro`.

Reported per route: the mean absolute error over the seeds and the mean standard error the fit
reports, of b and of the diameter ratio (and of the laser mounting for the scan route).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))  # the tests package

from odocal.core.model import WheelGeometry  # noqa: E402
from odocal.core.tracks import polygon  # noqa: E402
from tests.support.synthetic_robot import (  # noqa: E402
    Gyro,
    Laser,
    default_track,
    simulate_robot,
    write_ros2_bag,
)

TRUE = WheelGeometry(0.0655, 0.0662, 0.163)
BELIEVED = WheelGeometry.symmetric(0.066, 0.160)
MOUNT = (0.15, 0.05, 0.1)
ODOCAL = str(Path(sys.executable).with_name("odocal"))


def fit(*args) -> dict:
    res = subprocess.run([ODOCAL, "fit", *map(str, args), "--json"], capture_output=True, text=True)
    if res.returncode != 0:
        raise SystemExit(res.stderr)
    return json.loads(res.stdout)


def errors(d: dict, truth: dict) -> dict:
    out = {}
    for key, value in truth.items():
        out[key] = (abs(d[key] - value), (d.get("stderr") or {}).get(key))
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seeds", type=int, default=5)
    args = ap.parse_args()
    rows: dict[str, list] = {}
    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        robot = tmp / "robot.yaml"
        robot.write_text("wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n")
        for seed in range(args.seeds):
            rng = np.random.default_rng(seed)
            base = {"wheelbase_m": TRUE.wheelbase_m, "ratio": TRUE.diameter_ratio}
            for name, noise in (
                ("SLAM, exact updates", None),
                ("SLAM, 1 cm / 0.5 deg", (0.01, np.radians(0.5))),
            ):
                run = simulate_robot(default_track(), TRUE, BELIEVED)
                path = tmp / f"slam{seed}{noise is None}"
                write_ros2_bag(path, run, map_odom_every=25, imu=False, slam_noise=noise, rng=rng)
                d = fit(path, "--truth-frames", "map:base_link")
                d["ratio"] = d["wheel_diameter_right_m"] / d["wheel_diameter_left_m"]
                rows.setdefault(name, []).append(errors(d, base))
            run = simulate_robot(
                default_track(), TRUE, BELIEVED, laser=Laser(mount=MOUNT, sigma_m=0.01), rng=rng
            )
            write_ros2_bag(tmp / f"scan{seed}", run, imu=False)
            d = fit(tmp / f"scan{seed}", "--method", "scan", "--robot", robot)
            d["ratio"] = d["wheel_diameter_right_m"] / d["wheel_diameter_left_m"]
            truth = {
                **base,
                "sensor_x_m": MOUNT[0],
                "sensor_y_m": MOUNT[1],
                "sensor_yaw_rad": MOUNT[2],
            }
            rows.setdefault("scan, 1 cm range noise", []).append(errors(d, truth))
            bags = []
            for direction in ("cw", "ccw"):
                for i in range(3):
                    run = simulate_robot(
                        polygon(4, 1.0, direction), TRUE, BELIEVED,
                        gyro=Gyro(bias_rad_s=0.002, sigma_rad_s=0.003), rng=rng, still_s=4.0,
                    )  # fmt: skip
                    path = tmp / f"gyro{seed}{direction}{i}"
                    write_ros2_bag(path, run, imu=True)
                    bags.append(path)
            d = fit(*bags, "--method", "heading", "--heading-source", "gyro", "--robot", robot,
                    "--side-length", 1.0)  # fmt: skip
            ds = d["data_sets"][0]
            e_s = TRUE.mean_diameter_m / BELIEVED.mean_diameter_m
            rows.setdefault("gyro + 1 m squares", []).append(
                {
                    "E_b": (abs(ds["E_b"] - TRUE.wheelbase_m / BELIEVED.wheelbase_m / e_s), None),
                    "E_d": (abs(ds["E_d"] - TRUE.diameter_ratio / BELIEVED.diameter_ratio), None),
                }
            )
    print(f"{args.seeds} seeds, {time.perf_counter() - t0:.0f} s")
    print("| route | parameter | mean abs. error | mean reported std. error |")
    print("|---|---|---|---|")
    for name, per_seed in rows.items():
        for key in per_seed[0]:
            err = np.mean([r[key][0] for r in per_seed])
            ses = [r[key][1] for r in per_seed if r[key][1] is not None]
            se = f"{np.mean(ses):.2g}" if ses else "-"
            print(f"| {name} | {key} | {err:.2g} | {se} |")


if __name__ == "__main__":
    main()
