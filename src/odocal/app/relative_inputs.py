"""The inputs of a relative-motion fit (:mod:`odocal.app.fit_relative`), one record per file or
bag as ``odocal fit --json`` lists them: a ``.tuple`` file, or a bag of laser scans."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from ..calibration.scan_matching import ScanIntervals

__all__ = ["TupleInput", "ScanSummary"]


@dataclass(frozen=True)
class TupleInput:
    """One ``.tuple`` file of a fit: its path and how many tuples it holds."""

    path: str
    tuples: int

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: the file and its tuple count."""
        return {"path": self.path, "tuples": self.tuples}


@dataclass(frozen=True)
class ScanSummary:
    """One bag of a scan-matching fit: the topics, the scans and intervals matched, and the
    laser's mounting the matcher started from (x_m, y_m, yaw_rad on the base)."""

    bag: str
    scan_topic: str
    joint_topic: str
    scans: int
    intervals: ScanIntervals
    mount_guess: tuple[float, float, float]
    mount_source: str
    warnings: tuple[str, ...]

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready: this bag's entry of ``scan`` in ``fit --method scan --json``."""
        iv = self.intervals
        x, y, yaw = self.mount_guess
        return {
            "bag": self.bag,
            "scan_topic": self.scan_topic,
            "joint_topic": self.joint_topic,
            "scans": self.scans,
            "interval_scans": iv.interval_scans,
            "intervals": iv.intervals,
            "matched": iv.matched,
            "not_converged": iv.not_converged,
            "degenerate": iv.degenerate,
            "mount_guess": {"x_m": x, "y_m": y, "yaw_rad": yaw},
            "mount_source": self.mount_source,
            "warnings": list(self.warnings),
        }
