"""The figure of ``odocal fit --kinematics skid-steer --plot DIR``: the track multiplier against
the turn rate, with its 95 % band, beside the single multiplier the controller is given (the
skid fit computes; this module only draws)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np

from ._figure import new_figure

__all__ = ["SKID_FIGURE", "multiplier_figure", "skid_figures"]

#: The file name of the figure in ``--plot DIR``.
SKID_FIGURE = "track_multiplier.png"


def multiplier_figure(
    rate_rad_s: np.ndarray,
    multiplier: np.ndarray,
    stderr: np.ndarray,
    exported: tuple[float, float],
    title: str,
) -> Any:
    """The multiplier at each turn-rate knot (``rate_rad_s``, |yaw rate|) with its 95 % band,
    and the exported single multiplier (value, standard error) as a line with its band."""
    fig = new_figure()
    ax = fig.add_subplot()
    r = np.asarray(rate_rad_s, dtype=float)
    m = np.asarray(multiplier, dtype=float)
    se = np.asarray(stderr, dtype=float)
    ax.fill_between(r, m - 1.96 * se, m + 1.96 * se, alpha=0.25, color="C0", lw=0)
    ax.plot(r, m, "o-", color="C0", label="at this turn rate (95 % band)")
    ax.margins(x=0.05)
    value, err = exported
    ax.axhline(value, color="C3", lw=1.5, label=f"exported: {value:.4f} +- {err:.4f}")
    ax.axhspan(value - 1.96 * err, value + 1.96 * err, color="C3", alpha=0.12, lw=0)
    ax.set_xscale("log")
    ax.set_xticks(r, [f"{x:.2g}" for x in r])
    ax.minorticks_off()
    ax.set_xlabel("|yaw rate| (rad/s), at the knots of the fit")
    ax.set_ylabel("wheel_separation_multiplier")
    ax.set_title(title)
    ax.grid(True, which="both", alpha=0.3)
    ax.legend(loc="best")
    return fig


def skid_figures(
    folder: str | Path, rows: Any, exported: tuple[float, float], title: str
) -> dict[Path, Any]:
    """Path -> figure of ``--plot folder`` (the turn-rate table ``rows``: objects with
    ``true_rate_rad_s``, ``multiplier`` and ``stderr``)."""
    r = np.array([x.true_rate_rad_s for x in rows])
    m = np.array([x.multiplier for x in rows])
    se = np.array([x.stderr for x in rows])
    return {Path(folder) / SKID_FIGURE: multiplier_figure(r, m, se, exported, title)}
