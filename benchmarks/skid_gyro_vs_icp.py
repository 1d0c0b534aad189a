"""The skid-steer gyro route checked where the truth is known: on each Norlab recording
(``../shared/realdata/norlab_skid``), the gyro's turning gain (its yaw rate over the nominal
wheels', ``odocal fit --kinematics skid-steer --method gyro``) against the lidar-ICP fit's (each
side's wheel scale over the effective track, their mean), and the gyro's multipliers of the
recordings made on the same day against each other (the robot did not change within a day:
their difference must sit within their combined errors).

    .venv/bin/python benchmarks/skid_gyro_vs_icp.py        # about 1 minute
"""

from __future__ import annotations

import sys
import time
from pathlib import Path

import numpy as np

from odocal.app.fit_skid import EXPORTED, read_skid_bags, read_skid_logs, truth_offsets
from odocal.app.fit_skid_gyro import skid_gyro_fit
from odocal.calibration.skid_steer import fit_skid_logs
from odocal.io.bag_options import BagOptions
from odocal.io.bag_skid import read_skid_gyro_log
from odocal.io.robot_file import load_robot

ROOT = Path(__file__).resolve().parents[1].parent / "shared" / "realdata" / "norlab_skid"
LOGS = [
    ("husky_wheels-deflated_tile_2023_12_12_16h16", "husky", "2023-12-12"),
    ("warthog_wheels_grass", "warthog", "2024-07-18"),
    ("warthog_wheels_grass_2024_7_18_16h59s20", "warthog", "2024-07-18"),
    ("warthog_wheels_grass_2024_7_29_14h46s15", "warthog", "2024-07-29"),
    ("warthog_wheels_grass_2024_8_8_15h56s39", "warthog", "2024-08-08"),
    ("warthog_wheels_grass_2024_8_8_16h19s23", "warthog", "2024-08-08"),
]


def main() -> int:
    root = Path(sys.argv[1]) if len(sys.argv) > 1 else ROOT
    t0 = time.perf_counter()
    opts = BagOptions()
    rows, by_day = [], {}
    print(f"{'recording':44s} {'gyro gain':>17s} {'ICP gain':>17s} {'z':>6s} "
          f"{'gyro multiplier':>17s}")  # fmt: skip
    for name, robot_name, day in LOGS:
        robot = load_robot(root / "robots" / f"{robot_name}.yaml")
        (contents,) = read_skid_bags([next((root / name).glob("*_bag"))], opts)
        gyro = skid_gyro_fit([read_skid_gyro_log(contents, opts, robot.believed_geometry)], robot,
                             opts)  # fmt: skip
        g, g_se = float(gyro.fit.gain[0]), float(gyro.fit.gain_stderr[0])
        logs = read_skid_logs([contents], opts, robot)
        fit, _ = fit_skid_logs(logs, robot.nominal, EXPORTED[0], offsets=truth_offsets(logs),
                               wheel_scales=EXPORTED[1])  # fmt: skip
        i = [fit.names.index(n) for n in ("scale_right", "scale_left", "track_multiplier")]
        v, cov = fit.values[i], fit.covariance[np.ix_(i, i)]
        icp = 0.5 * (v[0] + v[1]) / v[2]
        jac = np.array([0.5 / v[2], 0.5 / v[2], -icp / v[2]])
        icp_se = float(np.sqrt(jac @ cov @ jac))
        z = (g - icp) / np.hypot(g_se, icp_se)
        m, m_se = gyro.track_multiplier
        print(f"{name:44s} {g:.4f} +- {g_se:.4f} {icp:.4f} +- {icp_se:.4f} {z:+6.2f} "
              f"{m:.4f} +- {m_se:.4f}")  # fmt: skip
        rows.append(z)
        by_day.setdefault((robot_name, day), []).append((name, m, m_se))
    print("\nthe gyro's multipliers of recordings made on the same day:")
    for (robot_name, day), found in by_day.items():
        if len(found) == 2:
            (a, ma, sa), (b, mb, sb) = found
            print(f"  {robot_name} {day}: {ma:.4f} +- {sa:.4f} and {mb:.4f} +- {sb:.4f}: "
                  f"z {(ma - mb) / np.hypot(sa, sb):+.2f}")  # fmt: skip
    print(f"\n{time.perf_counter() - t0:.0f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
