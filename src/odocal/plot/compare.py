"""The figure of ``odocal compare``: every method's validation error and calibration spread."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..comparison.real import RealComparison
from ..comparison.simulated import SimulatedComparison
from ._figure import method_style, new_figure

__all__ = ["comparison_figure"]

# A method whose spread is this many times the typical one would squash the others on a linear
# axis: it is listed in a note (its numbers in full) instead of drawn.
_OFF_SCALE = 8.0


def _off_scale(values: dict[str, float]) -> set[str]:
    typical = float(np.median(list(values.values()))) if values else 0.0
    return {k for k, v in values.items() if typical > 0 and v > _OFF_SCALE * typical}


def _note(ax: Any, lines: list[str]) -> None:
    for k, text in enumerate(lines):
        ax.text(
            0.02, 0.97 - 0.06 * k, text, transform=ax.transAxes, fontsize=7, color="0.3",
            va="top",
        )  # fmt: skip


def _error_panel(ax: Any, sim: SimulatedComparison, legend: dict[str, Any]) -> None:
    """Simulated validation error per method (box plot) and the noise-free residual."""
    data = {m.name: 1e3 * m.final_error_m[np.isfinite(m.final_error_m)] for m in sim.methods}
    p95 = {k: float(np.percentile(v, 95)) for k, v in data.items() if v.size}
    off = _off_scale(p95)
    shown = [m for m in sim.methods if m.name in p95 and m.name not in off]
    pos = np.arange(1, len(shown) + 1)
    boxes = ax.boxplot(
        [data[m.name] for m in shown],
        positions=pos,
        whis=(5, 95),
        showfliers=False,
        patch_artist=True,
        medianprops={"color": "k"},
    )
    for patch, m in zip(boxes["boxes"], shown, strict=True):
        colour, name = method_style(m.name)
        patch.set_facecolor(colour)
        patch.set_alpha(0.8)
        legend.setdefault(name, patch)
    sys_err = [1e3 * float(np.nanmean(m.systematic_error_m)) for m in shown]
    legend["noise-free residual (mean)"] = ax.plot(pos, sys_err, "kD", ms=5)[0]
    ax.set_xticks(pos, [method_style(m.name)[1] for m in shown], rotation=35, ha="right")
    top = max((p95[m.name] for m in shown), default=1.0)
    ax.set_ylim(0, top * (1.1 + 0.08 * len(off)))  # room for the notes above the whiskers
    ax.set_ylabel("validation final position error (mm)")
    nom = 1e3 * float(np.mean(sim.nominal_final_error_m))
    ax.set_title(
        f"Simulated: {sim.validation}, {sim.trials} trials\n(box: quartiles, whiskers: "
        f"5-95 %; uncalibrated: {nom:.0f} mm)",
        fontsize=10,
    )
    _note(
        ax,
        [
            f"{method_style(k)[1]}: median {np.median(data[k]):.0f} mm, 95th percentile "
            f"{p95[k]:.0f} mm (off scale)"
            for k in sorted(off)
        ],
    )
    ax.grid(alpha=0.3, axis="y")


def _factor_panel(ax: Any, sim: SimulatedComparison, legend: dict[str, Any]) -> None:
    """Bias and spread of the calibrated E_b, E_d errors per method."""
    stats = []
    for m in sim.methods:
        eb = 1e2 * m.E_b_error[np.isfinite(m.E_b_error)]
        ed = 1e2 * m.E_d_error[np.isfinite(m.E_d_error)]
        if len(eb) > 1:
            stats.append((m.name, eb, ed))
    spread = {n: max(eb.std(ddof=1) / 0.1, ed.std(ddof=1) / 0.01) for n, eb, ed in stats}
    off = _off_scale(spread)
    for name, eb, ed in stats:
        if name in off:
            continue
        colour, label = method_style(name)
        h = ax.errorbar(
            eb.mean(), ed.mean(), xerr=eb.std(ddof=1), yerr=ed.std(ddof=1), fmt="o",
            capsize=3, color=colour,
        )  # fmt: skip
        legend.setdefault(label, h)
    _note(
        ax,
        [
            f"{method_style(n)[1]}: E_b {eb.mean():+.2f} +- {eb.std(ddof=1):.2f} %, "
            f"E_d {ed.mean():+.3f} +- {ed.std(ddof=1):.3f} % (off scale)"
            for n, eb, ed in stats
            if n in off
        ],
    )
    ax.axhline(0, color="gray", lw=0.8)
    ax.axvline(0, color="gray", lw=0.8)
    ax.margins(0.15)
    ax.set_xlabel("E_b error (%): bias +- std")
    ax.set_ylabel("E_d error (%): bias +- std")
    ax.set_title("Calibrated vs true geometry\n(0, 0 = the truth)", fontsize=10)
    ax.grid(alpha=0.3)


def _real_panel(ax: Any, real: RealComparison, legend: dict[str, Any]) -> None:
    """The real held-out error per method (bars: mean over data sets, whiskers: min-max)."""
    names, means, lo, hi, colours = [], [], [], [], []
    for rm in real.methods:
        s = rm.heldout
        if s.mean is None or s.min is None or s.max is None:
            continue
        colour, label = method_style(rm.name)
        names.append(f"{label} (n={len(rm.per_dataset)})")
        colours.append(colour)
        means.append(1e3 * s.mean)
        lo.append(1e3 * (s.mean - s.min))
        hi.append(1e3 * (s.max - s.mean))
        legend.setdefault(label, None)
    x = np.arange(len(names))
    bars = ax.bar(x, means, yerr=[lo, hi], capsize=3, color=colours, alpha=0.8)
    for bar, name in zip(bars, names, strict=True):
        key = name.rsplit(" (n=", 1)[0]
        if legend.get(key) is None:
            legend[key] = bar
    nominal = 1e3 * real.nominal_mean_final_error_m
    h = ax.axhline(nominal, color=method_style("nominal")[0], ls="--")
    legend[f"real: nominal ({nominal:.0f} mm)"] = h
    if real.published is not None:
        pe = 1e3 * real.published.heldout_mean_final_error_m
        legend[f"real: published OptiOdom ({pe:.0f} mm)"] = ax.axhline(pe, color="k", ls=":")
    ax.set_xticks(x, names, rotation=35, ha="right")
    ax.set_ylim(0, 1.15 * max(max(np.add(means, hi)), nominal))
    ax.set_ylabel("held-out mean final position error (mm)")
    ax.set_title(
        f"OptiOdom real runs: {len(real.heldout)} held-out runs\n(bar: mean over "
        "calibration data sets; whiskers: min-max)",
        fontsize=10,
    )
    ax.grid(alpha=0.3, axis="y")


def comparison_figure(sim: SimulatedComparison | None, real: RealComparison | None) -> Any:
    """One figure: simulated validation error per method (box plot, with the noise-free
    residual), E_b / E_d error bias and spread, and the real held-out error per method. Linear
    axes throughout; a method far off the others' scale is named in a note with its numbers.
    Every method has one colour and one name in all panels (:data:`~._figure.METHOD_STYLES`)."""
    panels = (2 if sim is not None else 0) + (1 if real is not None else 0)
    if panels == 0:
        raise ValueError("nothing to draw: neither a simulated nor a real comparison")
    fig = new_figure(5.4 * panels, 5.2, dpi=110)
    axes = list(fig.subplots(1, panels, squeeze=False)[0])
    legend: dict[str, Any] = {}
    if sim is not None:
        _error_panel(axes.pop(0), sim, legend)
        _factor_panel(axes.pop(0), sim, legend)
    if real is not None:
        _real_panel(axes.pop(0), real, legend)
    handles = {k: v for k, v in legend.items() if v is not None}
    fig.legend(
        list(handles.values()), list(handles.keys()), loc="outside lower center", ncol=6, fontsize=8
    )
    return fig
