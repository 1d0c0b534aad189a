"""Husky bag: gyro-vs-odometry rotation ratio, cross-checked against the GPS track.

    python benchmarks/husky_gyro_gps.py [BAG]
    (default BAG: ../shared/realdata/husky/husky_test1.bag; a ROS 2 bag works too)

1. The gyro calibration (odocal.app.fit_gyro.fit_gyro_bag) with bias 'auto', 'still' and 'none'.
2. An independent heading scale from GPS: dead-reckon the wheel odometry's speed with its heading
   change scaled by k, fit the track to the GPS fixes (best rotation, translation and distance
   scale, closed form), and find the k with the smallest RMS residual. If the gyro is right, k is
   close to the gyro rotation ratio.
"""

from __future__ import annotations

import math
import sys
from pathlib import Path

import numpy as np
from scipy.optimize import minimize_scalar

from odocal.app.fit_gyro import fit_gyro_bag
from odocal.io.bags import pose_series, read_bag

ROOT = Path(__file__).resolve().parents[1]
DEFAULT = ROOT.parent / "shared" / "realdata" / "husky" / "husky_test1.bag"
ODOM, FIX = "/husky_velocity_controller/odom", "/fix"


def gps_residual(k, t_o, speed, yaw, t_g, gps_xy):
    """RMS residual (m) of the odometry track with heading scale k fitted to the GPS fixes."""
    th = k * (yaw - yaw[0])
    ds = 0.5 * (speed[1:] + speed[:-1]) * np.diff(t_o)
    mid = 0.5 * (th[1:] + th[:-1])
    x = np.concatenate([[0.0], np.cumsum(ds * np.cos(mid))])
    y = np.concatenate([[0.0], np.cumsum(ds * np.sin(mid))])
    q = np.column_stack([np.interp(t_g, t_o, x), np.interp(t_g, t_o, y)])
    a, b = q - q.mean(0), gps_xy - gps_xy.mean(0)
    u, s, vt = np.linalg.svd(a.T @ b)
    d = np.diag([1.0, np.sign(np.linalg.det(u @ vt))])
    rot = (u @ d @ vt).T
    scale = np.trace(np.diag(s) @ d) / np.sum(a * a)
    res = b - scale * a @ rot.T
    return math.sqrt(np.mean(np.sum(res * res, axis=1))), scale


def main(path: Path) -> None:
    for bias in ("auto", "still", "none"):
        r = fit_gyro_bag(path, bias=bias)
        print(
            f"gyro, bias {bias:5s}: rotation_ratio {r.rotation_ratio:.4f} "
            f"(bias removed {r.bias_rad_s:+.2e} rad/s, {r.bias_source}; "
            f"ratio stderr (bias, noise, drift) {r.rotation_ratio_stderr:.3f})"
        )
    bag = read_bag(path, [ODOM, FIX])
    od = pose_series(bag, ODOM)
    fixes = bag.messages[FIX]
    t_g = np.array([m.header.stamp.sec + 1e-9 * m.header.stamp.nanosec for _, m in fixes])
    t_g -= bag.start_ns * 1e-9
    lat = np.radians([m.latitude for _, m in fixes])
    lon = np.radians([m.longitude for _, m in fixes])
    r_earth = 6378137.0
    gps = np.column_stack([r_earth * math.cos(lat[0]) * (lon - lon[0]), r_earth * (lat - lat[0])])
    inside = (t_g >= od.time_s[0]) & (t_g <= od.time_s[-1])
    args = (od.time_s, od.values["speed"], od.values["yaw"], t_g[inside], gps[inside])
    for k in (1.0, 1.02, 1.04, 1.06):
        print(f"GPS fit, heading scale k = {k:.2f}: RMS {gps_residual(k, *args)[0]:.2f} m")
    best = minimize_scalar(lambda k: gps_residual(k, *args)[0], bounds=(0.9, 1.2), method="bounded")
    rms, scale = gps_residual(best.x, *args)
    print(
        f"GPS fit, best heading scale k = {best.x:.4f} "
        f"(RMS {rms:.2f} m, distance scale {scale:.4f})"
    )


if __name__ == "__main__":
    main(Path(sys.argv[1]) if len(sys.argv) > 1 else DEFAULT)
