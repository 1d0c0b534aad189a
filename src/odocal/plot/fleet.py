"""The figure of one robot of a fleet (``odocal fleet report``): each parameter's bag estimates
with their standard errors, the filtered level with its 2-sigma band, and the alarms. It draws
results; it computes nothing."""

from __future__ import annotations

import io
from collections.abc import Sequence
from typing import Any

import numpy as np

from ..errors import quote_path
from ._figure import new_figure

__all__ = ["history_figure", "svg_text"]

_LABELS = {
    "wheel_diameter_right_m": "right wheel diameter (mm)",
    "wheel_diameter_left_m": "left wheel diameter (mm)",
    "wheelbase_m": "wheelbase (mm)",
}


def history_figure(robot_id: str, parameters: Sequence[Any]) -> Any:
    """One panel per parameter (a :class:`~odocal.app.fleet_status.ParameterHistory` each:
    ``key``, ``bags``, ``values``, ``std_errors``, ``track``) against the bag's number in the
    robot's history."""
    fig = new_figure(7.5, 1.9 * max(1, len(parameters)) + 0.4, dpi=100)
    axes = fig.subplots(max(1, len(parameters)), 1, sharex=True, squeeze=False)[:, 0]
    for ax, p in zip(axes, parameters, strict=False):
        x = np.asarray(p.bags, float)
        ax.set_ylabel(_LABELS.get(p.key, p.key), fontsize=8)
        if len(x) == 0:
            ax.text(
                0.5,
                0.5,
                "no trustworthy bag estimated it (e.g. the gyro route holds it at nominal)",
                transform=ax.transAxes,
                ha="center",
                fontsize=8,
            )
            ax.set_yticks([])
            continue
        mm = 1e3
        ax.errorbar(
            x,
            mm * p.values,
            yerr=mm * p.std_errors,
            fmt="o",
            ms=3,
            lw=0.8,
            color="tab:blue",
            label="bag estimate ± 1 se",
        )
        t = p.track
        lo, hi = mm * (t.level - 2 * t.level_se), mm * (t.level + 2 * t.level_se)
        ax.fill_between(x, lo, hi, color="tab:orange", alpha=0.25, step="post", lw=0)
        ax.step(x, mm * t.level, where="post", color="tab:orange", label="level ± 2 se")
        for a in t.alarms:
            ax.axvline(x[a.index], color="tab:red", lw=1.2, ls="--")
        ax.tick_params(labelsize=8)
    # the id as it is (a folder's name: no mathtext of its dollar signs), escaped when odd
    axes[0].set_title(
        f"{quote_path(robot_id)}: parameter history (red dashes: drift alarms)",
        fontsize=10,
        parse_math=False,
    )
    drawn = [ax for ax in axes if ax.get_legend_handles_labels()[1]]
    if drawn:  # on the first panel with estimates
        drawn[0].legend(fontsize=7, loc="best")
    last = max((int(max(p.bags)) for p in parameters if len(p.bags)), default=0)
    axes[-1].set_xlim(-0.5, last + 0.5)
    axes[-1].set_xticks(range(0, last + 1, max(1, -(-(last + 1) // 10))))  # whole bags
    axes[-1].set_xlabel("bag (in time order)", fontsize=8)
    return fig


def svg_text(fig: Any) -> str:
    """The figure as SVG text (no date, no software version: the same page each time)."""
    buf = io.StringIO()
    fig.savefig(buf, format="svg", metadata={"Date": None, "Creator": None})
    return buf.getvalue()
