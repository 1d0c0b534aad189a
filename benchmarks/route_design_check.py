"""Predicted standard errors of design --route against their own Monte Carlo (docs/design.md).

Run: python benchmarks/route_design_check.py  (about a minute on one core)
For every route and two durations: the recommended candidate's predicted standard error and
the spread of 400 simulated calibrations (ratio realised / predicted)."""

from __future__ import annotations

import numpy as np

from odocal.core.model import NonSystematicError, Robot, SystematicError, WheelGeometry
from odocal.design.route import RouteSpec, default_noise, design_route

ROBOT = Robot(
    WheelGeometry(0.15, 0.15, 0.4),
    systematic=SystematicError(E_b=1.02, E_d=1.003),
    nonsystematic=NonSystematicError(2e-6, 2e-6),
)


def main() -> None:
    print(
        "route       duration_s  mix                     parameter       predicted   realised"
        "  ratio"
    )
    for route in ("trajectory", "slam", "scan", "gyro"):
        for duration in (60.0, 240.0):
            spec = RouteSpec(route=route, durations_s=(duration,), trials=400, confirm=1)
            d = design_route(ROBOT, spec, default_noise(route, ROBOT), np.random.default_rng(7))
            rec = d.recommended
            assert rec.monte_carlo is not None
            for k, real in rec.monte_carlo.realised_std_error.items():
                pred = rec.predicted_std_error[k]
                print(
                    f"{route:11s} {rec.duration_s:10.0f}  {rec.label:22s}  {k:14s}  "
                    f"{pred:9.3g}  {real:9.3g}  {real / pred:5.2f}"
                )


if __name__ == "__main__":
    main()
