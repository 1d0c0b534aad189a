"""Valid input files of every format odocal reads, small and synthetic (no real data needed).

The boundary tests and the fuzz test start from these and break them.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from odocal.core.model import SystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import params_yaml

NOMINAL = WheelGeometry(0.15, 0.15, 0.385)
TRUE = NOMINAL.with_systematic(SystematicError(E_b=1.02, E_d=1.004))

ROBOT_YAML = """\
# a TETRA-DS II-like robot
name: tetra
wheel_diameter_m: 0.15
wheelbase_m: 0.385
systematic: {E_b: 1.028, E_d: 0.999}
nonsystematic:
  k_r_m: 1.69e-6
  k_l_m: 1.69e-6
measurement: {sigma_xy_m: 0.005, sigma_theta_deg: 0.2}
believed:
  wheel_diameter_right_m: 0.15
  wheel_diameter_left_m: 0.15
  wheelbase_m: 0.385
"""

PARAMS_YAML = params_yaml(TRUE, method="test")

TRACK_YAML = """\
name: L-shape
direction: ccw
segments:
  - straight_m: 2.0
  - turn_deg: 90
  - arc: {radius_m: 1.0, angle_deg: 180}
  - straight_m: 1.0
"""

RUNS_CSV = """\
# measured on the floor
direction,x_m,y_m,theta_deg,run
cw,-0.2531,-0.2770,7.49,1
ccw,-0.3958,0.4690,-12.12,2
cw,-0.2401,-0.2652,7.21,3
ccw,-0.3830,0.4512,-12.31,4
cw,-0.2455,-0.2807,7.36,5
ccw,-0.4012,0.4471,-11.98,6
"""

TTEST_A = "error_m\n0.061\n0.058\n0.066\n0.071\n0.059\n"
TTEST_B = "error_m\n0.081\n0.077\n0.079\n0.090\n0.085\n"


def wheel_run(name: str = "run", turn: float = math.pi / 2, n: int = 60) -> Recording:
    """Straight 2 m, a spot turn of ``turn`` rad, straight 1 m, commanded with NOMINAL; the
    ground truth is what the TRUE robot does."""
    f = np.linspace(0, 1, n)[1:]
    legs = [(2.0, 0.0), (0.0, turn), (1.0, 0.0)]
    r, lft = [0.0], [0.0]
    for d, psi in legs:
        s_r, s_l = d + psi * NOMINAL.wheelbase_m / 2, d - psi * NOMINAL.wheelbase_m / 2
        r += list(r[-1] + f * 2 * s_r / NOMINAL.diameter_right_m)
        lft += list(lft[-1] + f * 2 * s_l / NOMINAL.diameter_left_m)
    right, left = np.array(r), np.array(lft)
    return Recording(
        name=name,
        time_s=np.arange(len(right)) * 0.05,
        wheel_angle_right_rad=right,
        wheel_angle_left_rad=left,
        ground_truth=dead_reckon(right, left, TRUE),
        ran_with=NOMINAL,
        label="ccw" if turn > 0 else "cw",
    )


def generic_csv_text(turn: float = math.pi / 2, tmp: Path | None = None) -> str:
    """A generic run CSV (wheel angles, ground truth, the ran-with parameters in its header)."""
    import tempfile

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "run.csv"
        write_generic_csv(path, wheel_run(turn=turn))
        return path.read_text()


OPTI_ID = "111"
OPTI_TICKS_PER_REV = 43.7 * 64
OPTI_GEOMETRY = WheelGeometry(0.084, 0.084, 0.2)
OPTI_METADATA = """\
type,diff,,,,,
ngear,43.7,,,,,
encRes,64,,,,,
Li,0.2,,,,,
Di,0.084,0.084,,,,
Thi,,,,,,
N,2,,,,,
L,0.75,,,,,
"""


def optiodom_run_text(direction: int) -> str:
    """An OptiOdom run file: a 0.75 m square (+1 CCW, -1 CW) as tick increments per 50 ms."""
    b, d = OPTI_GEOMETRY.wheelbase_m, OPTI_GEOMETRY.diameter_right_m
    scale = OPTI_TICKS_PER_REV / (math.pi * d)  # ticks per metre of wheel travel
    incs = []
    for _ in range(4):
        incs += [(0.0375 * scale, 0.0375 * scale)] * 20  # 0.75 m in 20 steps
        turn = direction * math.pi / 2 * b / 2
        incs += [(turn / 10 * scale, -turn / 10 * scale)] * 10
    ticks = np.round(np.array([(0.0, 0.0), *incs]))
    angles = np.cumsum(ticks, axis=0) * 2 * math.pi / OPTI_TICKS_PER_REV
    true = WheelGeometry(0.0838, 0.0842, 0.201)
    gt = dead_reckon(angles[:, 0], angles[:, 1], true)
    rows = [
        f"{0.05 * i:.2f},{gt[i, 0]:.6g},{gt[i, 1]:.6g},{gt[i, 2]:.6g},{t[0]:.0f},{t[1]:.0f}"
        for i, t in enumerate(ticks)
    ]
    return "\n".join(rows) + "\n"


def write_optiodom(folder: Path) -> Path:
    """An OptiOdom data set folder ``folder/square/111`` (one CW and one CCW square)."""
    ds = folder / "square" / OPTI_ID
    ds.mkdir(parents=True)
    (ds / f"{OPTI_ID}_metadata.csv").write_text(OPTI_METADATA)
    (ds / f"{OPTI_ID}_run-01.csv").write_text(optiodom_run_text(-1))
    (ds / f"{OPTI_ID}_run-02.csv").write_text(optiodom_run_text(+1))
    return ds


def tuples_text(n: int = 60, seed: int = 3) -> str:
    """Relative-motion tuples of a robot with D 0.2 m, b 0.4 m and the sensor at its centre."""
    rng = np.random.default_rng(seed)
    r, b = 0.1, 0.4
    lines = []
    for _ in range(n):
        t = float(rng.uniform(0.3, 1.0))
        w_l, w_r = (float(v) for v in rng.uniform(-3, 3, 2))
        v, w = r * (w_r + w_l) / 2, r * (w_r - w_l) / b
        th = w * t
        if abs(w) > 1e-9:
            x, y = v / w * math.sin(th), v / w * (1 - math.cos(th))
        else:
            x, y = v * t, 0.0
        lines.append(json.dumps({"T": t, "phi_l": w_l, "phi_r": w_r, "sm": [x, y, th]}))
    return "\n".join(lines) + "\n"
