"""The real-data comparison: every method calibrated from recorded data sets, validated on held-out
recorded runs (never on the runs it was calibrated on)."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from ..calibration.result import CalibrationResult
from ..core.model import WheelGeometry
from ..core.odometry import evaluate
from ..errors import CalibrationError
from .methods import METHOD_REGISTRY, MethodEntry

__all__ = [
    "RealMethodResult",
    "RealComparison",
    "compare_real",
    "heldout_error",
    "published_agreement",
    "PUBLISHED_SAME_METHOD",
]


@dataclass(frozen=True)
class RealMethodResult:
    """Held-out validation of one method's calibrations from real data sets.

    per_dataset : list of dict
        ``dataset``, the calibrated geometry, ``heldout_mean_final_error_m`` (m).
    """

    name: str
    per_dataset: list

    def summary(self) -> dict:
        errs = [d["heldout_mean_final_error_m"] for d in self.per_dataset]
        return {
            "name": self.name,
            "calibrations": len(errs),
            "heldout_mean_final_error_m": {
                "mean": float(np.mean(errs)) if errs else None,
                "min": float(np.min(errs)) if errs else None,
                "max": float(np.max(errs)) if errs else None,
            },
            "per_dataset": self.per_dataset,
        }


@dataclass(frozen=True)
class RealComparison:
    heldout: list  # names of the held-out runs
    nominal_mean_final_error_m: float
    published: dict | None  # published OptiOdom ALL_DATASETS_COMBINED geometry and its error
    methods: tuple[RealMethodResult, ...]
    failures: list


def heldout_error(geometry: WheelGeometry, heldout) -> float:
    """Mean final position error (m) of dead reckoning the held-out recordings with ``geometry``."""
    return float(np.mean([evaluate(r, geometry)["final_error_m"] for r in heldout]))


def compare_real(
    datasets: dict,
    heldout,
    methods: list[MethodEntry] | None = None,
    published: WheelGeometry | None = None,
    progress: Callable[[int, int, str], None] | None = None,
) -> RealComparison:
    """Calibrate with every method from real data sets and validate on held-out recordings.

    Parameters
    ----------
    datasets : dict
        kind -> list of data sets (each a list of Recording): 'square', 'ivanjko',
        'circular-calibration' (circle runs for BCPT). Held-out runs must not be among them.
    heldout : list of Recording
        Validation runs (with ground truth), e.g. OptiOdom free/ plus the other circle set.
    published : WheelGeometry, optional
        A reference geometry to validate the same way (e.g. the published OptiOdom result).
    progress : callable, optional
        ``progress(done, total, method)`` after each method.

    A method that fails, or finds no data set it can calibrate from, is listed in ``failures``
    with the reason (never as a row without numbers).
    """
    methods = METHOD_REGISTRY if methods is None else methods
    heldout = list(heldout)
    nominal = float(np.mean([evaluate(r, r.ran_with)["final_error_m"] for r in heldout]))
    out, failures = [], []
    real_methods = [e for e in methods if e.real is not None]
    for k, entry in enumerate(real_methods):
        if progress is not None and k:
            progress(k, len(real_methods), real_methods[k - 1].name)
        try:
            results = entry.real(datasets)
        except CalibrationError as exc:
            failures.append({"method": entry.name, "error": str(exc)})
            continue
        if not results:  # said so, instead of a row without numbers
            failures.append(
                {
                    "method": entry.name,
                    "error": f"no data set it can calibrate from (it needs: {entry.drives})",
                }
            )
            continue
        rows = []
        for name, res in results:
            res: CalibrationResult
            g = res.corrected
            rows.append(
                {
                    "dataset": name,
                    **g.as_dict(),
                    "heldout_mean_final_error_m": heldout_error(g, heldout),
                }
            )
        out.append(RealMethodResult(entry.name, rows))
    if progress is not None:
        progress(len(real_methods), len(real_methods), "real runs")
    pub = None
    if published is not None:
        pub = {
            **published.as_dict(),
            "heldout_mean_final_error_m": heldout_error(published, heldout),
        }
    return RealComparison([r.name for r in heldout], nominal, pub, tuple(out), failures)


# Our method -> the published OptiOdom column computed from the same runs (the published
# UMBmark is the x-form with E_b b in E_d; the published Jung&Chung uses chord and coupling terms
# that our exact heading method does not have, so only rough agreement is expected there).
PUBLISHED_SAME_METHOD = {"umbmark-x": "UMBmark", "heading": "Jung&Chung", "ivanjko": "Ivanjko"}


def published_agreement(real: RealComparison, published: dict[str, dict[str, WheelGeometry]]):
    """Per data set: our calibrated geometry against the published one of the same method.

    ``published`` maps a published method name (e.g. 'UMBmark') to {data set: geometry}.
    Returns a list of dicts (method, published_method, dataset, published, difference,
    max_abs_difference_m)."""
    out = []
    for m in real.methods:
        column = PUBLISHED_SAME_METHOD.get(m.name)
        if column is None:
            continue
        by_set = {k.split("/")[-1]: g for k, g in (published.get(column) or {}).items()}
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
