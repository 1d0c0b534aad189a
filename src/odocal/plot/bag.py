"""The figures of a bag route (``odocal fit BAG --plot DIR``): the clock-offset profiles and the
held-out check. They draw results; they compute nothing."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.heldout import HeldOut
from ..calibration.time_offset import TimeOffset
from ._figure import new_figure

__all__ = ["OFFSET_FIGURE", "HELDOUT_FIGURE", "offset_figure", "heldout_figure", "bag_figures"]

#: File names in the ``--plot`` folder.
OFFSET_FIGURE = "time_offset.png"
HELDOUT_FIGURE = "heldout.png"


def offset_figure(offsets: Sequence[TimeOffset]) -> Any:
    """The robust loss of each estimated source's clock offset against the offset searched
    (each scaled to its own range), the estimate and its 95 % band."""
    fig = new_figure(7.0, 4.0)
    ax = fig.add_subplot()
    for o in offsets:
        if len(o.grid_s) == 0:
            continue
        loss = np.asarray(o.loss, dtype=float)
        span = float(loss.max() - loss.min()) or 1.0
        (line,) = ax.plot(1e3 * o.grid_s, (loss - loss.min()) / span, label=o.label)
        ax.axvline(1e3 * o.offset_s, color=line.get_color(), lw=1, ls="--")
        if o.stderr_s is not None and np.isfinite(o.stderr_s):
            lo, hi = 1e3 * (o.offset_s - 1.96 * o.stderr_s), 1e3 * (o.offset_s + 1.96 * o.stderr_s)
            ax.axvspan(lo, hi, color=line.get_color(), alpha=0.15)
    ax.set_xlabel("clock offset of the source against the wheels (ms; > 0: its stamps run late)")
    ax.set_ylabel("robust loss (scaled to its range)")
    ax.set_title("Clock offsets: estimate (dashed) and 95 % band")
    ax.grid(alpha=0.3)
    if ax.lines:
        ax.legend(loc="upper center")
    return fig


def heldout_figure(heldout: HeldOut) -> Any:
    """Mean dead-reckoning error over the held-out stretches, nominal against every model; the
    answer's model in a darker colour."""
    fig = new_figure(6.0, 3.8)
    ax = fig.add_subplot()
    names = ["nominal", *(m.model for m in heldout.models)]
    values = [heldout.nominal_final_error_m, *(m.mean_final_error_m for m in heldout.models)]
    colours = ["0.6"] + [
        "tab:blue" if m.model == heldout.preferred else "tab:cyan" for m in heldout.models
    ]
    ax.bar(names, values, color=colours)
    for i, v in enumerate(values):
        ax.annotate(f"{v:.3g} m", (i, v), ha="center", va="bottom", fontsize=9)
    ax.set_ylabel("mean end error of the held-out stretches (m)")
    ax.set_title(
        f"Held out: {heldout.folds} time blocks, {heldout.chains} stretches of median "
        f"{heldout.chain_seconds:.0f} s\n(dark blue: the model of the answer)"
    )
    ax.grid(axis="y", alpha=0.3)
    ax.set_ylim(0, 1.15 * max(values))
    return fig


def bag_figures(
    offsets: Sequence[TimeOffset], heldout: HeldOut | None, folder: str | Path
) -> dict[Path, Any]:
    """Path -> figure of what a bag route has to show."""
    out: dict[Path, Any] = {}
    if any(len(o.grid_s) for o in offsets):
        out[Path(folder) / OFFSET_FIGURE] = offset_figure(offsets)
    if heldout is not None:
        out[Path(folder) / HELDOUT_FIGURE] = heldout_figure(heldout)
    return out
