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

    Left, the path: metres on both axes, equal aspect, start marked, legend with each curve's
    final position error. Right, the heading along the run (unwrapped, degrees): a spin in place
    shows there what its path (millimetres of tracker jitter) cannot. ``truth_marker``: draw the
    truth as markers (truth known only at those samples)."""
    fig = new_figure(11.0, 5.2, dpi=100)
    ax, hx = fig.subplots(1, 2, gridspec_kw={"width_ratios": [1.15, 1.0]})
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
    _headings(hx, ground_truth, trajectories, styles, truth_marker)
    return fig


def _headings(
    ax: Any,
    ground_truth: np.ndarray,
    trajectories: dict[str, np.ndarray],
    styles: list[tuple[str, str]],
    truth_marker: str | None,
) -> None:
    """Each curve's unwrapped heading (deg) against its progress through the run (0 to 1), with
    the final heading error in the legend."""

    def heading_deg(poses: np.ndarray) -> np.ndarray:
        return np.degrees(np.unwrap(poses[:, 2]))

    def progress(poses: np.ndarray) -> np.ndarray:
        return np.linspace(0.0, 1.0, len(poses))

    truth = heading_deg(ground_truth)
    ax.plot(
        progress(ground_truth),
        truth,
        color="black",
        lw=2.0 if truth_marker is None else 0.8,
        marker=truth_marker,
        ms=3,
        label="ground truth",
    )
    for (name, traj), (color, ls) in zip(trajectories.items(), styles, strict=False):
        h = heading_deg(traj)
        ax.plot(
            progress(traj),
            h,
            color=color,
            ls=ls,
            lw=1.4,
            label=f"{name} (final heading error {h[-1] - truth[-1]:+.2f} deg)",
        )
    ax.set_xlabel("progress through the run (samples, 0 to 1)")
    ax.set_ylabel("heading (deg, unwrapped)")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize=8, loc="best")
