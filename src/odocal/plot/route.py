"""The figure of ``odocal design --route R --plot DIR``: predicted standard error against the
recording's duration for each maneuver mix (as the paper's Fig. 5 plots the error against the
track size), with the Monte Carlo's realised spread where it was simulated."""

from __future__ import annotations

from typing import Any

from ._figure import new_figure

__all__ = ["route_figures"]

_DURATION_TICKS = (15, 30, 60, 120, 240, 480, 960, 1920, 3600)

_LABELS = {
    "wheelbase": "wheelbase",
    "wheel_diameter": "wheel diameter (worse wheel)",
    "diameter_ratio": "diameter ratio D_R/D_L",
}


def route_figures(design: Any) -> dict[str, Any]:
    """File name -> figure of a :class:`~odocal.design.route.RouteDesign`."""
    from matplotlib.ticker import FuncFormatter, NullFormatter

    plain = FuncFormatter(lambda v, _: f"{v:g}")
    # minor ticks of a log axis: label 2 and 5 x a power of ten only
    some = FuncFormatter(lambda v, _: f"{v:g}" if f"{v:.0e}"[0] in "25" else "")
    cands = design.candidates
    params = [p for p in _LABELS if any(p in c.relative_std_error for c in cands)]
    fig = new_figure(max(7.0, 4.2 * len(params) + 0.6), 5.4)
    axes = fig.subplots(1, len(params), squeeze=False)[0]
    mixes = list(dict.fromkeys(c.mix for c in cands))
    colours = dict(zip(mixes, [f"C{i}" for i in range(len(mixes))], strict=True))
    # one line per mix in one run, one per mix cut into runs of about two minutes (dashed)
    series = list(dict.fromkeys((c.mix, c.runs > 1) for c in cands))
    rec = design.recommended
    for ax, p in zip(axes, params, strict=True):
        for mix, several in series:
            colour = colours[mix]
            cs = sorted(
                (c for c in cands if c.mix == mix and (c.runs > 1) == several),
                key=lambda c: c.duration_s,
            )
            ax.plot(
                [c.duration_s for c in cs],
                [100 * c.relative_std_error[p] for c in cs],
                "o--" if several else "o-",
                color=colour,
                markerfacecolor="white" if several else colour,
                label=f"{mix}{', runs of ~2 min' if several else ''} (predicted)",
            )
            mc = [
                c for c in cs if c.monte_carlo is not None and p in c.monte_carlo.realised_std_error
            ]
            if mc:
                ax.plot(
                    [c.duration_s for c in mc],
                    [
                        100
                        * c.monte_carlo.realised_std_error[p]
                        * c.relative_std_error[p]
                        / c.predicted_std_error[p]
                        for c in mc
                    ],
                    "x",
                    color=colour,
                    markersize=10,
                    markeredgewidth=2,
                    zorder=4,
                    label=f"{mix}{', runs of ~2 min' if several else ''} (Monte Carlo)",
                )
        for t in design_targets(design, p):
            ax.axhline(100 * t, color="0.4", linestyle="--", linewidth=1, label="target")
        ax.plot(
            [rec.duration_s],
            [100 * rec.relative_std_error[p]],
            "*",
            color="k",
            markerfacecolor="none",
            markersize=18,
            zorder=3,
            label="recommended",
        )
        ax.set_xscale("log")
        ax.set_yscale("log")
        ax.xaxis.set_major_formatter(plain)
        ax.xaxis.set_minor_formatter(NullFormatter())
        lo, hi = min(c.duration_s for c in cands), max(c.duration_s for c in cands)
        ax.set_xticks([t for t in _DURATION_TICKS if 0.8 * lo <= t <= 1.25 * hi])
        ax.yaxis.set_major_formatter(plain)
        ax.yaxis.set_minor_formatter(some)
        ax.set_xlabel("recording duration (s)")
        ax.set_ylabel(f"standard error of the {_LABELS[p]} (%)")
        ax.grid(True, which="both", alpha=0.3)
    handles, labels = axes[0].get_legend_handles_labels()
    unique = dict(zip(labels, handles, strict=True))
    ncol = 4 if len(params) > 1 else 2
    fig.legend(unique.values(), unique.keys(), fontsize=8, loc="outside lower center", ncol=ncol)
    fig.suptitle(
        f"{design.route} route: standard error after calibration against recording duration"
        + ("" if len(params) > 1 else "\n(the gyro sees the wheelbase only)")
    )
    return {"route_design.png": fig}


def design_targets(design: Any, parameter: str) -> list[float]:
    """The relative targets on ``parameter`` (the figure draws them)."""
    return [
        t.value for t in getattr(design, "targets", ()) if t.parameter == parameter and t.relative
    ]
