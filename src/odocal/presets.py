"""Built-in robots: the paper's TETRA-DS II under its stated conditions.

Wheel diameter 0.15 m, wheelbase 0.385 m (paper, section 4). Usable wherever a ROBOT.yaml is
asked for, by name (e.g. ``--robot paper-fig5``).
"""

from __future__ import annotations

from .core.model import NonSystematicError, Robot, SystematicError, WheelGeometry

__all__ = ["PRESETS", "TETRA_DS2", "DEFAULT_ROBOT"]

TETRA_DS2 = WheelGeometry.symmetric(0.15, 0.385)


def _paper(E_b: float, E_d: float, k_m: float) -> Robot:
    return Robot(TETRA_DS2, SystematicError(E_b, E_d), NonSystematicError(k_m, k_m))


PRESETS: dict[str, Robot] = {
    # Figs. 3 and 4: E_b 1.025, E_d 0.999, k_r = k_l = 1e-6 m
    "paper-fig3": _paper(1.025, 0.999, 1.00e-6),
    # Figs. 5 and 6: E_b 1.028, E_d 0.999, k 1.69e-6 m (printed 1.69e6, a typo)
    "paper-fig5": _paper(1.028, 0.999, 1.69e-6),
    # Figs. 8 and 9: the experimental robot, E_b 1.0255, E_d 1.0017, k 2.89e-6 m
    "paper-experiment": _paper(1.0255, 1.0017, 2.89e-6),
}

#: The robot every command uses when none is given: the paper's Fig. 5 conditions.
DEFAULT_ROBOT = "paper-fig5"
