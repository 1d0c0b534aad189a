"""The SLAM bags of a command: each read (:func:`odocal.io.bag_slam.read_slam_series`), then its
relative motions on the wheels' clock (:func:`odocal.calibration.slam_bag.slam_bag`). Used by
``fit --truth-frames``, ``check``, ``validate`` and the one-command route."""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path

from ..calibration.slam import SlamLimits
from ..calibration.slam_bag import SlamBag, slam_bag
from ..core.model import WheelGeometry
from ..io.bag_options import BagOptions
from ..io.bag_slam import read_slam_series
from ..io.bags import BagContents
from ..io.recordings import refuse_repeated

__all__ = ["load_slam_bag", "load_slam_bags"]


def load_slam_bag(
    path: str | Path | BagContents,
    truth_frames: tuple[str, str] = ("map", "base_link"),
    options: BagOptions | None = None,
    *,
    ticks_per_rev: float | None = None,
    stamp_offset_s: float = 0.0,
    ran_with: WheelGeometry | None = None,
    time_offset_s: float | None = None,
    limits: SlamLimits | None = None,
) -> SlamBag:
    """The SLAM relative motions of one bag: read (:func:`~odocal.io.bag_slam.
    read_slam_series`), then on the wheels' clock (:func:`~odocal.calibration.slam_bag.
    slam_bag`: the clock offset ``time_offset_s``, how late the SLAM's clock runs behind the
    wheels', else estimated)."""
    series = read_slam_series(
        path, truth_frames, options, ticks_per_rev=ticks_per_rev,
        stamp_offset_s=stamp_offset_s, ran_with=ran_with,
    )  # fmt: skip
    return slam_bag(series, time_offset_s, limits)


def load_slam_bags(
    paths: Sequence[str | Path],
    truth_frames: tuple[str, str],
    bag: BagOptions,
    *,
    ticks_per_rev: float | None = None,
    stamp_offset_s: float = 0.0,
    ran_with: WheelGeometry | None = None,
    time_offset_s: float | None = None,
) -> list[SlamBag]:
    """:func:`load_slam_bag` of every bag of ``paths`` with the topics of ``bag``; InputError
    when a path is given twice (its runs would count twice)."""
    return [
        load_slam_bag(
            p,
            truth_frames,
            bag,
            ticks_per_rev=ticks_per_rev,
            stamp_offset_s=stamp_offset_s,
            ran_with=ran_with,
            time_offset_s=time_offset_s,
        )  # fmt: skip
        for p in refuse_repeated(paths)
    ]
