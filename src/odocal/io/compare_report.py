"""I/O for ``odocal compare``: the OptiOdom real-data split, the JSON document, the figure.

matplotlib is imported lazily inside :func:`plot_comparison` (Agg backend).
"""

from __future__ import annotations

import csv
import io
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.compare import (
    Budget,
    RealComparison,
    SimulatedComparison,
    compare_real,
    compare_simulated,
)
from ..core.model import WheelGeometry
from ..errors import InputError
from .optiodom import is_optiodom_dataset, load_optiodom_dataset
from .textfile import atomic_path, read_text

__all__ = [
    "Comparison",
    "run_comparison",
    "published_agreement",
    "PUBLISHED_SAME_METHOD",
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


# Our method -> the published OptiOdom column computed from the same runs (the published
# UMBmark is the x-form with E_b b in E_d; the published Jung&Chung uses chord and coupling terms
# that our exact heading method does not have, so only rough agreement is expected there).
PUBLISHED_SAME_METHOD = {"umbmark-x": "UMBmark", "heading": "Jung&Chung", "ivanjko": "Ivanjko"}


@dataclass(frozen=True)
class Comparison:
    """What ``odocal compare`` computes.

    Attributes
    ----------
    simulated : SimulatedComparison
    real : RealComparison or None
        Only with a real-data folder.
    published_same_method : list of dict
        Per data set, our geometry against the published one of the same method.
    """

    simulated: SimulatedComparison
    real: RealComparison | None
    published_same_method: list


def run_comparison(
    robot,
    trials: int = 200,
    seed: int = 0,
    runs: int = 10,
    travel_m: float | None = None,
    ivanjko_straight_m: float | None = None,
    realdata=None,
    circle_set: str | None = None,
) -> Comparison:
    """The simulated comparison on ``robot`` and, with ``realdata`` (an ``optiodom_diff``
    folder), the held-out comparison on real runs. See ``odocal.calibration.compare``."""
    sim = compare_simulated(
        robot, trials=trials, seed=seed, budget=Budget(runs, travel_m, ivanjko_straight_m)
    )
    if realdata is None:
        return Comparison(sim, None, [])
    datasets, heldout = load_optiodom_split(realdata, circle_set)
    real = compare_real(datasets, heldout, published=read_published(realdata))
    return Comparison(sim, real, published_agreement(real, realdata))


def published_agreement(real: RealComparison, folder) -> list:
    """Per data set: our calibrated geometry against the published one of the same method."""
    out = []
    for m in real.methods:
        column = PUBLISHED_SAME_METHOD.get(m.name)
        if column is None:
            continue
        pub = read_published(folder, column, None) or {}
        by_set = {k.split("/")[-1]: g for k, g in pub.items()}
        for row in m.per_dataset:
            g = by_set.get(row["dataset"])
            if g is None:
                continue
            diffs = {
                "wheelbase_m": row["wheelbase_m"] - g.wheelbase_m,
                "wheel_diameter_right_m": row["wheel_diameter_right_m"] - g.diameter_right_m,
                "wheel_diameter_left_m": row["wheel_diameter_left_m"] - g.diameter_left_m,
            }
            out.append(
                {
                    "method": m.name,
                    "published_method": column,
                    "dataset": row["dataset"],
                    "published": g.as_dict(),
                    "difference": diffs,
                    "max_abs_difference_m": max(abs(v) for v in diffs.values()),
                }
            )
    return out


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
    fig.tight_layout()
    with atomic_path(path) as tmp:
        fig.savefig(tmp, dpi=110, format="png")
    plt.close(fig)
