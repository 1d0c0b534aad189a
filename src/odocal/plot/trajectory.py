"""A run's trajectory: ground truth against dead reckoning with nominal and calibrated
parameters."""

from __future__ import annotations

from typing import Any

import numpy as np

from ._figure import new_figure

__all__ = ["run_figure"]


def run_figure(
    title: str,
    ground_truth: np.ndarray,
    trajectories: dict[str, np.ndarray],
    truth_marker: str | None = None,
) -> Any:
    """One figure: ``ground_truth`` (K, 3) and each named dead-reckoned trajectory (K, 3).

    Metres on both axes, equal aspect, start marked, legend with each curve's final position
    error. ``truth_marker``: draw the truth as markers (truth known only at those samples)."""
    fig = new_figure(6.4, 6.0, dpi=110)
    ax = fig.add_subplot()
    ax.plot(
        ground_truth[:, 0],
        ground_truth[:, 1],
        color="black",
        lw=2.0 if truth_marker is None else 0.8,
        marker=truth_marker,
        ms=3,
        label="ground truth" if truth_marker is None else "ground truth (at SLAM updates)",
    )
    styles = [("tab:red", "--"), ("tab:blue", "-"), ("tab:green", "-."), ("tab:purple", ":")]
    for (name, traj), (color, ls) in zip(trajectories.items(), styles, strict=False):
        err = float(np.hypot(*(ground_truth[-1, :2] - traj[-1, :2])))
        ax.plot(
            traj[:, 0],
            traj[:, 1],
            color=color,
            ls=ls,
            lw=1.4,
            label=f"{name} (final error {1000 * err:.1f} mm)",
        )
        ax.plot(traj[-1, 0], traj[-1, 1], "o", color=color, ms=5)
    ax.plot(ground_truth[-1, 0], ground_truth[-1, 1], "o", color="black", ms=5)
    ax.plot(0, 0, marker="s", color="gray", ms=7, ls="none", label="start")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x (m, start frame)")
    ax.set_ylabel("y (m, start frame)")
    ax.set_title(title, fontsize=10)
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
    return fig
