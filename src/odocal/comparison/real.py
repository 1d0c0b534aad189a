"""The real-data comparison: every method calibrated from recorded data sets, validated on held-out
recorded runs (never on the runs it was calibrated on)."""

from __future__ import annotations

import statistics
from collections.abc import Callable, Sequence
from dataclasses import dataclass

import numpy as np

from ..core.model import WheelGeometry
from ..core.odometry import evaluate
from ..core.recording import Recording
from ..errors import CalibrationError
from .methods import METHOD_REGISTRY, MethodEntry

__all__ = [
    "DatasetCalibration",
    "ErrorSpread",
    "RealMethodResult",
    "MethodFailure",
    "PublishedReference",
    "RealComparison",
    "PublishedAgreement",
    "AgreementSummary",
    "compare_real",
    "heldout_error",
    "published_agreement",
    "summarize_agreement",
    "PUBLISHED_SAME_METHOD",
]


@dataclass(frozen=True)
class DatasetCalibration:
    """One method's calibration from one recorded data set and its held-out error (m)."""

    dataset: str
    geometry: WheelGeometry
    heldout_mean_final_error_m: float

    def as_dict(self) -> dict:
        """JSON-ready: the data set, the calibrated geometry (m) and its held-out error (m)."""
        return {
            "dataset": self.dataset,
            **self.geometry.as_dict(),
            "heldout_mean_final_error_m": self.heldout_mean_final_error_m,
        }


@dataclass(frozen=True)
class ErrorSpread:
    """Mean, smallest and largest of a method's held-out errors over its data sets (m); None
    when it has none."""

    mean: float | None
    min: float | None
    max: float | None

    def as_dict(self) -> dict:
        """JSON-ready (m; None without errors)."""
        return {"mean": self.mean, "min": self.min, "max": self.max}


@dataclass(frozen=True)
class RealMethodResult:
    """Held-out validation of one method's calibrations from real data sets."""

    name: str
    per_dataset: tuple[DatasetCalibration, ...]

    @property
    def heldout(self) -> ErrorSpread:
        """The held-out mean final errors (m) of its calibrations: mean, min and max."""
        errs = [d.heldout_mean_final_error_m for d in self.per_dataset]
        if not errs:
            return ErrorSpread(None, None, None)
        return ErrorSpread(float(np.mean(errs)), float(np.min(errs)), float(np.max(errs)))

    def summary(self) -> dict:
        """JSON-ready (one entry of the real data's ``methods`` in ``odocal compare --json``): the
        name, the number of calibrations, their held-out errors (m) and every data set's
        calibration."""
        return {
            "name": self.name,
            "calibrations": len(self.per_dataset),
            "heldout_mean_final_error_m": self.heldout.as_dict(),
            "per_dataset": [d.as_dict() for d in self.per_dataset],
        }


@dataclass(frozen=True)
class MethodFailure:
    """A method that gave no calibration from the real data, and why."""

    method: str
    error: str

    def as_dict(self) -> dict:
        """JSON-ready: the method and its error message."""
        return {"method": self.method, "error": self.error}


@dataclass(frozen=True)
class PublishedReference:
    """A published geometry (e.g. OptiOdom's, from all its data sets) and its held-out error."""

    geometry: WheelGeometry
    heldout_mean_final_error_m: float

    def as_dict(self) -> dict:
        """JSON-ready: the published geometry (m) and its held-out error (m)."""
        return {
            **self.geometry.as_dict(),
            "heldout_mean_final_error_m": self.heldout_mean_final_error_m,
        }


@dataclass(frozen=True)
class RealComparison:
    """The real-data comparison: the held-out runs' names, the uncalibrated (nominal) mean final
    error on them (m), the published reference, every method's results and the failures."""

    heldout: tuple[str, ...]
    nominal_mean_final_error_m: float
    published: PublishedReference | None
    methods: tuple[RealMethodResult, ...]
    failures: tuple[MethodFailure, ...]


def heldout_error(geometry: WheelGeometry, heldout: Sequence[Recording]) -> float:
    """Mean final position error (m) of dead reckoning the held-out recordings with ``geometry``."""
    return float(np.mean([evaluate(r, geometry)["final_error_m"] for r in heldout]))


def _ran_with(recording: Recording) -> WheelGeometry:
    """The parameters a held-out run ran with (its uncalibrated odometry)."""
    if recording.ran_with is None:
        raise CalibrationError(f"{recording.name}: the parameters it ran with are unknown")
    return recording.ran_with


def _calibrate_real(
    entry: MethodEntry, datasets: dict, heldout: Sequence[Recording]
) -> RealMethodResult | MethodFailure:
    """One method's calibrations from every data set it can use, validated on ``heldout``."""
    assert entry.real is not None
    try:
        results = entry.real(datasets)
    except CalibrationError as exc:
        return MethodFailure(entry.name, str(exc))
    if not results:  # said so, instead of a row without numbers
        return MethodFailure(
            entry.name, f"no data set it can calibrate from (it needs: {entry.drives})"
        )
    rows = []
    for name, res in results:
        g = res.corrected
        rows.append(DatasetCalibration(name, g, heldout_error(g, heldout)))
    return RealMethodResult(entry.name, tuple(rows))


def compare_real(
    datasets: dict,
    heldout: Sequence[Recording],
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
    nominal = float(np.mean([evaluate(r, _ran_with(r))["final_error_m"] for r in heldout]))
    out: list[RealMethodResult] = []
    failures: list[MethodFailure] = []
    real_methods = [e for e in methods if e.real is not None]
    for k, entry in enumerate(real_methods):
        if progress is not None and k:
            progress(k, len(real_methods), real_methods[k - 1].name)
        result = _calibrate_real(entry, datasets, heldout)
        if isinstance(result, MethodFailure):
            failures.append(result)
        else:
            out.append(result)
    if progress is not None:
        progress(len(real_methods), len(real_methods), "real runs")
    pub = None
    if published is not None:
        pub = PublishedReference(published, heldout_error(published, heldout))
    return RealComparison(tuple(r.name for r in heldout), nominal, pub, tuple(out), tuple(failures))


# Our method -> the published OptiOdom column computed from the same runs (the published
# UMBmark is the x-form with E_b b in E_d; the published Jung&Chung uses chord and coupling terms
# that our exact heading method does not have, so only rough agreement is expected there).
PUBLISHED_SAME_METHOD = {"umbmark-x": "UMBmark", "heading": "Jung&Chung", "ivanjko": "Ivanjko"}


@dataclass(frozen=True)
class PublishedAgreement:
    """Our calibration from one data set against the published one of the same method: the
    differences (ours - published, m) of the wheelbase and the wheel diameters."""

    method: str
    published_method: str
    dataset: str
    published: WheelGeometry
    wheelbase_m: float
    wheel_diameter_right_m: float
    wheel_diameter_left_m: float

    @property
    def max_abs_difference_m(self) -> float:
        """The largest absolute difference (m) of the three."""
        return max(
            abs(v)
            for v in (self.wheelbase_m, self.wheel_diameter_right_m, self.wheel_diameter_left_m)
        )

    def as_dict(self) -> dict:
        """JSON-ready: the methods, the data set, the published geometry (m) and the differences
        (m)."""
        return {
            "method": self.method,
            "published_method": self.published_method,
            "dataset": self.dataset,
            "published": self.published.as_dict(),
            "difference": {
                "wheelbase_m": self.wheelbase_m,
                "wheel_diameter_right_m": self.wheel_diameter_right_m,
                "wheel_diameter_left_m": self.wheel_diameter_left_m,
            },
            "max_abs_difference_m": self.max_abs_difference_m,
        }


def published_agreement(
    real: RealComparison, published: dict[str, dict[str, WheelGeometry]]
) -> tuple[PublishedAgreement, ...]:
    """Per data set: our calibrated geometry against the published one of the same method.

    ``published`` maps a published method name (e.g. 'UMBmark') to {data set: geometry}."""
    out = []
    for m in real.methods:
        column = PUBLISHED_SAME_METHOD.get(m.name)
        if column is None:
            continue
        by_set = {k.split("/")[-1]: g for k, g in (published.get(column) or {}).items()}
        for row in m.per_dataset:
            g = by_set.get(row.dataset)
            if g is None:
                continue
            ours = row.geometry.as_dict()
            out.append(
                PublishedAgreement(
                    m.name,
                    column,
                    row.dataset,
                    g,
                    ours["wheelbase_m"] - g.wheelbase_m,
                    ours["wheel_diameter_right_m"] - g.diameter_right_m,
                    ours["wheel_diameter_left_m"] - g.diameter_left_m,
                )
            )
    return tuple(out)


@dataclass(frozen=True)
class AgreementSummary:
    """One of our methods against the published one, over the data sets both calibrated: how
    many, and the largest and the median of the largest parameter difference (m)."""

    method: str
    published_method: str
    datasets: int
    largest_m: float
    median_m: float


def summarize_agreement(rows: Sequence[PublishedAgreement]) -> tuple[AgreementSummary, ...]:
    """:class:`AgreementSummary` per (our method, published method), in the order of ``rows``."""
    by_pair: dict[tuple[str, str], list[float]] = {}
    for a in rows:
        by_pair.setdefault((a.method, a.published_method), []).append(a.max_abs_difference_m)
    return tuple(
        AgreementSummary(ours, theirs, len(d), max(d), statistics.median(d))
        for (ours, theirs), d in by_pair.items()
    )
