"""Figures of the real experiment (``odocal reproduce --realdata``) and of the effective wheelbase
per band of motion (``odocal fit --plot``)."""

from __future__ import annotations

from collections.abc import Callable
from functools import partial
from typing import TYPE_CHECKING, Any

import numpy as np

from ._figure import method_style, new_figure

if TYPE_CHECKING:
    from ..design.real_experiment import RealExperiment
    from ..design.spec import Method

__all__ = ["design_vs_real_figure", "gain_figure", "wheelbase_bands_figure", "real_figures"]

_MM = 1000.0


def design_vs_real_figure(exp: RealExperiment, title: str) -> Any:
    """The design's predicted held-out error per square size (model) against the real
    calibrations' held-out errors (mm)."""
    pred = exp.prediction
    fig = new_figure(7.4, 4.6)
    ax = fig.add_subplot()
    sides = np.array([c.side_m for c in pred.sweep])
    mean = np.array([c.post_error_mean_m for c in pred.sweep]) * _MM
    lo = np.array([c.post_error_ci95_m[0] for c in pred.sweep]) * _MM
    hi = np.array([c.post_error_ci95_m[1] for c in pred.sweep]) * _MM
    ax.fill_between(sides, lo, hi, color="C0", alpha=0.15, label="model: 95 % of experiments")
    ax.plot(
        sides,
        mean,
        "-",
        color="C0",
        lw=2,
        label=f"model: mean ({pred.runs_per_direction} runs per direction)",
    )
    ax.axhline(
        pred.floor.mean_m * _MM, color="C0", ls=":", lw=1, label="model floor (true parameters)"
    )
    for k, (side, cand) in enumerate(pred.real.items()):
        ax.errorbar(
            [side],
            [cand.post_error_mean_m * _MM],
            yerr=[[cand.post_error_std_m * _MM], [cand.post_error_std_m * _MM]],
            fmt="s",
            color="C0",
            mfc="white",
            capsize=4,
            label="model: the real run counts (mean +- std)" if k == 0 else None,
        )
    markers: dict[Method, tuple[str, str]] = {
        "heading": ("o", method_style("heading")[0]),
        "umbmark": ("^", method_style("umbmark")[0]),
    }
    for method, (m, col) in markers.items():
        first = True
        for s in exp.sides_m:
            c = exp.calibration(s, method)
            err = c.heldout_error_m * _MM
            ci = c.heldout_ci95_m
            yerr = (
                None
                if ci is None
                else [[max(err - ci[0] * _MM, 0.0)], [max(ci[1] * _MM - err, 0.0)]]
            )
            ax.errorbar(
                [s],
                [err],
                yerr=yerr,
                fmt=m,
                color=col,
                ms=8,
                capsize=4,
                label=f"real: {method} pooled (95 %)" if first else None,
            )
            first = False
        per = [c for c in exp.calibrations if c.method == method and c.scope != "pooled"]
        ax.plot(
            [c.side_m + (0.03 if method == "umbmark" else -0.03) for c in per],
            [c.heldout_error_m * _MM for c in per],
            m,
            color=col,
            ms=4,
            alpha=0.5,
            label=f"real: {method} per data set",
        )
    ax.set_xlabel("side of the square test track (m)")
    ax.set_ylabel("mean final error on the held-out runs (mm)")
    ax.set_title(title)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper right")
    return fig


def gain_figure(exp: RealExperiment, title: str) -> Any:
    """Held-out error against the turning gain mean(D)/b, with every calibration on it."""
    fig = new_figure(7.4, 4.6)
    ax = fig.add_subplot()
    ax.plot(
        exp.gain_grid,
        exp.gain_curve_m * _MM,
        "-",
        color="0.4",
        lw=1.5,
        label="diameter ratio fixed, gain varied",
    )
    for g in exp.gains:
        # the methods' colours of every figure; the square size by the marker
        method = next(
            (k for k in ("heading", "umbmark", "trajectory") if k in g.label.lower()), None
        )
        colour = method_style(method)[0] if method else "0.25"
        marker = "v" if "0.75 m" in g.label else "o" if "1.7 m" in g.label else "D"
        ax.plot(
            [g.turning_gain],
            [g.heldout_error_m * _MM],
            marker,
            ms=8,
            color=colour,
            mfc="white" if not g.held_out else None,
            label=g.label + ("" if g.held_out else " (fitted with the held-out runs)"),
        )
    ax.set_xlabel("turning gain mean(D) / b")
    ax.set_ylabel("mean final error on the held-out runs (mm)")
    ax.set_title(title)
    ax.set_ylim(bottom=0)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=7, loc="upper center")
    return fig


def wheelbase_bands_figure(
    tables: dict, title: str, single: dict | None = None, fitted: dict | None = None
):
    """Effective wheelbase (mm) per band of motion with 95 % intervals, one series per entry of
    ``tables`` (name -> EffectiveWheelbase); ``single``: name -> a single wheelbase (m) drawn as
    a horizontal line (e.g. the constant fit, the value for a motion mix); ``fitted``: band ->
    wheelbase (m) of a banded model, drawn as crosses."""
    from ..calibration.turning import BANDS

    fig = new_figure(7.4, 4.6)
    ax = fig.add_subplot()
    x = np.arange(len(BANDS))
    n = max(len(tables), 1)
    width = 0.6 / n
    for k, (name, table) in enumerate(tables.items()):
        off = (k - (n - 1) / 2) * width
        for i, b in enumerate(table.bands):
            if b.wheelbase_m is None or not b.excited or b.ci95_m is None:
                continue
            y = b.wheelbase_m * _MM
            lo, hi = b.ci95_m[0] * _MM, b.ci95_m[1] * _MM
            ax.errorbar(
                [i + off],
                [y],
                yerr=[[y - lo], [hi - y]],
                fmt="o",
                color=f"C{k}",
                capsize=3,
                label=name if i == min(j for j, e in enumerate(table.bands) if e.excited) else None,
            )
    if fitted:
        idx = [BANDS.index(b) for b in fitted]
        ax.plot(
            idx,
            [v * _MM for v in fitted.values()],
            "x",
            color="C3",
            ms=10,
            mew=2,
            label="banded model (its gains, at the same diameters)",
        )
    for j, (name, value) in enumerate((single or {}).items()):
        ax.axhline(value * _MM, ls=["--", ":", "-."][j % 3], color="0.3", lw=1, label=name)
    ax.margins(y=0.08)  # a reference line at the edge of the data stays inside the axes
    labels = []
    ref = next(iter(tables.values()), None)
    for i, name in enumerate(BANDS):
        if ref is None:
            labels.append(name)
            continue
        lo, hi = ref.bands[i].radius_range_m
        rng = (
            f"R < {hi:.2g} m"
            if lo == 0
            else (f"R > {lo:.2g} m" if hi is None else f"{lo:.2g}-{hi:.2g} m")
        )
        labels.append(f"{name}\n{rng}")
    ax.set_xticks(x, labels)
    ax.set_xlim(-0.6, len(BANDS) - 0.4)
    ax.set_ylabel("effective wheelbase (mm)")
    ax.set_title(title)
    ax.grid(alpha=0.3, axis="y")
    if ax.get_legend_handles_labels()[0]:
        ax.legend(fontsize=7)
    return fig


def real_figures(exp: RealExperiment) -> dict[str, tuple[str, Callable[[], Any]]]:
    """key -> (file name, a function drawing the figure) for the real experiment (drawn when
    written, several at once)."""
    a, b = exp.sides_m
    return {
        "real_design": (
            "real_design_vs_real.png",
            partial(
                design_vs_real_figure,
                exp,
                f"OptiOdom robot: the design's prediction against the real calibrations\n"
                f"validation: {len(exp.heldout_names)} held-out runs, {exp.prediction.trials} "
                "simulated experiments",
            ),
        ),
        "real_gain": (
            "real_turning_gain.png",
            partial(gain_figure, exp, "Held-out error against the turning gain mean(D)/b"),
        ),
        "real_bands": (
            "real_effective_wheelbase.png",
            partial(
                wheelbase_bands_figure,
                exp.turning.named(),
                "Effective wheelbase per band of motion (at the diameters of odocal's fit)",
            ),
        ),
    }
