"""The figure of ``odocal compare``: every method's validation error and calibration spread."""

from __future__ import annotations

from typing import Any

import numpy as np

from ..comparison.real import RealComparison
from ..comparison.simulated import SimulatedComparison
from ._figure import new_figure

__all__ = ["comparison_figure"]


def comparison_figure(sim: SimulatedComparison | None, real: RealComparison | None) -> Any:
    """One figure: simulated validation error per method (box plot, with the noise-free
    residual), E_b / E_d error bias and spread, and the real held-out error per method."""
    panels = (2 if sim is not None else 0) + (1 if real is not None else 0)
    if panels == 0:
        raise ValueError("nothing to draw: neither a simulated nor a real comparison")
    fig = new_figure(5.2 * panels, 4.6, dpi=110)
    axes = list(fig.subplots(1, panels, squeeze=False)[0])
    if sim is not None:
        ax = axes.pop(0)
        names = [m.name for m in sim.methods]
        data = [1e3 * m.final_error_m[np.isfinite(m.final_error_m)] for m in sim.methods]
        ax.boxplot(data, whis=(5, 95), showfliers=False)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
        sys_err = [1e3 * np.nanmean(m.systematic_error_m) for m in sim.methods]
        ax.plot(range(1, len(names) + 1), sys_err, "rD", label="noise-free residual (mean)")
        # log scale: a poorly conditioned method (linear) can miss by metres while the others
        # differ by millimetres
        ax.set_yscale("log")
        ax.set_ylabel("validation final position error (mm, log scale)")
        nom = 1e3 * float(np.mean(sim.nominal_final_error_m))
        ax.set_title(
            f"Simulated: {sim.validation}, {sim.trials} trials\n(box: quartiles, whiskers: "
            f"5-95 %; uncalibrated: {nom:.0f} mm)",
            fontsize=10,
        )
        ax.legend(fontsize=8, loc="upper left")

        ax = axes.pop(0)
        stats = []
        for i, m in enumerate(sim.methods):
            eb = 1e2 * m.E_b_error[np.isfinite(m.E_b_error)]
            ed = 1e2 * m.E_d_error[np.isfinite(m.E_d_error)]
            if len(eb) > 1:
                stats.append((i, m.name, eb, ed))
        # a method whose spread is 20 times the typical one would squash the others: list it in
        # a note instead of drawing it
        typical = np.median([max(eb.std(ddof=1), 1e-12) for _, _, eb, _ in stats] or [1.0])
        typical_d = np.median([max(ed.std(ddof=1), 1e-12) for _, _, _, ed in stats] or [1.0])
        off = []
        for i, name, eb, ed in stats:
            if eb.std(ddof=1) > 20 * typical or ed.std(ddof=1) > 20 * typical_d:
                off.append(
                    f"{name}: E_b {eb.mean():+.2f} +- {eb.std(ddof=1):.2f} %, "
                    f"E_d {ed.mean():+.3f} +- {ed.std(ddof=1):.3f} % (off scale)"
                )
                continue
            ax.errorbar(
                eb.mean(),
                ed.mean(),
                xerr=eb.std(ddof=1),
                yerr=ed.std(ddof=1),
                fmt="o",
                capsize=3,
                label=name,
                color=f"C{i}",
            )
        for k, text in enumerate(off):
            ax.text(0.02, 0.03 + 0.06 * k, text, transform=ax.transAxes, fontsize=7, color="0.3")
        ax.axhline(0, color="gray", lw=0.8)
        ax.axvline(0, color="gray", lw=0.8)
        ax.set_xlabel("E_b error (%): bias +- std")
        ax.set_ylabel("E_d error (%): bias +- std")
        ax.set_title("Calibrated vs true geometry", fontsize=10)
        ax.legend(fontsize=8, loc="upper right")
    if real is not None:
        ax = axes.pop(0)
        names, means, lo, hi = [], [], [], []
        for m in real.methods:
            s = m.summary()["heldout_mean_final_error_m"]
            if s["mean"] is None:
                continue
            names.append(f"{m.name} (n={len(m.per_dataset)})")
            means.append(1e3 * s["mean"])
            lo.append(1e3 * (s["mean"] - s["min"]))
            hi.append(1e3 * (s["max"] - s["mean"]))
        x = np.arange(len(names))
        ax.bar(x, means, yerr=[lo, hi], capsize=3, color="C0")
        ax.axhline(
            1e3 * real.nominal_mean_final_error_m,
            color="gray",
            ls="--",
            label=f"nominal ({1e3 * real.nominal_mean_final_error_m:.0f} mm)",
        )
        if real.published is not None:
            pe = 1e3 * real.published["heldout_mean_final_error_m"]
            ax.axhline(pe, color="C3", ls=":", label=f"published OptiOdom ({pe:.0f} mm)")
        ax.set_xticks(x, names, rotation=30, ha="right")
        ax.set_ylim(0, 1.3 * max(max(np.add(means, hi)), 1e3 * real.nominal_mean_final_error_m))
        ax.set_ylabel("held-out mean final position error (mm)")
        ax.set_title(
            f"OptiOdom real runs: {len(real.heldout)} held-out runs\n(bar: mean over "
            "calibration data sets; whiskers: min-max)",
            fontsize=10,
        )
        ax.legend(fontsize=8, loc="upper left")
    return fig
