"""Run sheets as a technician fills them in: the blank rows of a plan's RUNS.csv, in order."""

from __future__ import annotations

import math


def fill(template: str, errors_by_row) -> str:
    """Fill the blank rows of a run sheet in order with (x_m, y_m, theta_rad) per row."""
    out, i = [], 0
    for line in template.splitlines():
        if line.startswith("#") or line.startswith("direction"):
            out.append(line)
            continue
        d, _, _, _, run = line.split(",")
        x, y, th = errors_by_row[i]
        out.append(f"{d},{x:.6f},{y:.6f},{math.degrees(th):.6f},{run}")
        i += 1
    return "\n".join(out) + "\n"
