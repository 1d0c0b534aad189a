"""I/O for ``odocal compare``: the OptiOdom real-data split, the JSON document, the figure.

matplotlib is imported lazily inside :func:`plot_comparison` (Agg backend).
"""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np

from ..calibration.compare import RealComparison, SimulatedComparison
from ..core.model import WheelGeometry
from ..errors import InputError
from .optiodom import is_optiodom_dataset, load_optiodom_dataset
from .textfile import atomic_path, read_text

__all__ = [
    "CALIBRATION_CIRCLE_SET",
    "load_optiodom_split",
    "read_published",
    "comparison_document",
    "plot_comparison",
]

# OptiOdom circle data set used to calibrate BCPT (first arc radius 0.85 m); the other circle
# data set (250620202104, first arc 0.375 m) is held out with free/.
CALIBRATION_CIRCLE_SET = "231220200121"


def load_optiodom_split(folder, calibration_circle_set: str | None = None):
    """Calibration data sets and held-out runs from an ``optiodom_diff`` folder.

    Returns ``(datasets, heldout)``: ``datasets`` maps 'square', 'ivanjko' and
    'circular-calibration' to lists of data sets (lists of Recording); ``heldout`` is the runs of
    free/ and of every circular data set except the calibration one: ``calibration_circle_set``
    (a data set id; default :data:`CALIBRATION_CIRCLE_SET`, or the first circular data set found
    if that one is absent).
    """
    folder = Path(folder)
    if not folder.is_dir():
        raise InputError("not a folder (expected an optiodom_diff folder)", folder)

    def sets(kind):
        base = folder / kind
        if not base.is_dir():
            return []
        return [d for d in sorted(base.iterdir()) if is_optiodom_dataset(d)]

    found = {k: sets(k) for k in ("square", "ivanjko", "circular", "free")}
    if not any(found.values()):
        raise InputError(
            "no OptiOdom data sets (expected square/, ivanjko/, circular/, free/ sub-folders)",
            folder,
        )
    circles = found["circular"]
    if calibration_circle_set is not None:
        cal = [d for d in circles if d.name == calibration_circle_set]
        if not cal:
            raise InputError(
                f"no circular data set '{calibration_circle_set}' (found: "
                f"{', '.join(d.name for d in circles) or 'none'})",
                folder / "circular",
            )
    else:
        cal = [d for d in circles if d.name == CALIBRATION_CIRCLE_SET] or circles[:1]
    datasets = {
        "square": [load_optiodom_dataset(d) for d in found["square"]],
        "ivanjko": [load_optiodom_dataset(d) for d in found["ivanjko"]],
        "circular-calibration": [load_optiodom_dataset(d) for d in cal],
    }
    heldout = []
    for d in found["free"] + [c for c in circles if c not in cal]:
        heldout += load_optiodom_dataset(d)
    if not heldout:
        raise InputError("no held-out runs (free/ or a second circular/ data set)", folder)
    return datasets, heldout


def read_published(folder, method: str = "Sousa", dataset: str = "ALL_DATASETS_COMBINED"):
    """Published calibrated geometry from ``reference_results_diff.csv`` (first row of
    ``method`` and ``dataset`` with no note), or None if the file is absent."""
    path = Path(folder) / "reference_results_diff.csv"
    if not path.is_file():
        return None
    out = {}
    for row in csv.DictReader(io.StringIO(read_text(path))):
        if row.get("method") != method or row.get("note"):
            continue
        try:
            g = WheelGeometry(float(row["cal_Dr_m"]), float(row["cal_Dl_m"]), float(row["cal_b_m"]))
        except (KeyError, ValueError):
            raise InputError("bad calibrated values", path, None, "cal_b_m") from None
        out[row["dataset"]] = g
    if dataset is None:
        return out
    return out.get(dataset)


def comparison_document(sim: SimulatedComparison | None, real: RealComparison | None, **extra):
    """The JSON document of ``odocal compare --json``."""
    doc: dict = dict(extra)
    if sim is not None:
        nom = sim.nominal_final_error_m
        doc["simulated"] = {
            "trials": sim.trials,
            "seed": sim.seed,
            "budget": {"runs": sim.budget_runs, "travel_m": sim.budget_travel_m},
            "validation_track": sim.validation,
            "nominal": {
                "final_error_m": {
                    "mean": float(nom.mean()),
                    "std": float(nom.std(ddof=1)),
                    "p95": float(np.quantile(nom, 0.95)),
                },
                "systematic_final_error_m": sim.nominal_systematic_error_m,
            },
            "methods": [m.summary() for m in sim.methods],
        }
    if real is not None:
        doc["realdata"] = {
            "heldout_runs": real.heldout,
            "nominal_mean_final_error_m": real.nominal_mean_final_error_m,
            "published": real.published,
            "methods": [m.summary() for m in real.methods],
            "failures": real.failures,
        }
    return doc


def plot_comparison(sim: SimulatedComparison | None, real: RealComparison | None, path) -> None:
    """One PNG: simulated validation error per method (box plot, with the noise-free residual),
    E_b / E_d error bias and spread, and the real held-out error per method."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:  # pragma: no cover - depends on the installation
        raise InputError("plots need matplotlib: pip install 'odocal[plot]'") from None

    panels = (2 if sim is not None else 0) + (1 if real is not None else 0)
    if panels == 0:
        return
    fig, axes = plt.subplots(1, panels, figsize=(5.2 * panels, 4.6), squeeze=False)
    axes = list(axes[0])
    if sim is not None:
        ax = axes.pop(0)
        names = [m.name for m in sim.methods]
        data = [1e3 * m.final_error_m[np.isfinite(m.final_error_m)] for m in sim.methods]
        ax.boxplot(data, whis=(5, 95), showfliers=False)
        ax.set_xticks(range(1, len(names) + 1), names, rotation=30, ha="right")
        sys_err = [1e3 * np.nanmean(m.systematic_error_m) for m in sim.methods]
        ax.plot(range(1, len(names) + 1), sys_err, "rD", label="noise-free residual (mean)")
        top = max(np.quantile(d, 0.95) for d in data if len(d))
        ax.set_ylim(0, 1.25 * max(top, max(sys_err)))
        ax.set_ylabel("validation final position error (mm)")
        nom = 1e3 * float(np.mean(sim.nominal_final_error_m))
        ax.set_title(
            f"Simulated: {sim.validation}, {sim.trials} trials\n(box: quartiles, whiskers: "
            f"5-95 %; uncalibrated: {nom:.0f} mm)",
            fontsize=10,
        )
        ax.legend(fontsize=8, loc="upper left")

        ax = axes.pop(0)
        for i, m in enumerate(sim.methods):
            eb = 1e2 * m.E_b_error[np.isfinite(m.E_b_error)]
            ed = 1e2 * m.E_d_error[np.isfinite(m.E_d_error)]
            if len(eb) == 0:
                continue
            ax.errorbar(
                eb.mean(),
                ed.mean(),
                xerr=eb.std(ddof=1),
                yerr=ed.std(ddof=1),
                fmt="o",
                capsize=3,
                label=m.name,
                color=f"C{i}",
            )
        ax.axhline(0, color="gray", lw=0.8)
        ax.axvline(0, color="gray", lw=0.8)
        ax.set_xlabel("E_b error (%): bias +- std")
        ax.set_ylabel("E_d error (%): bias +- std")
        ax.set_title("Calibrated vs true geometry", fontsize=10)
        ax.legend(fontsize=8)
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
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
