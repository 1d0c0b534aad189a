"""One bag of a fleet, calibrated where a worker runs it (a process of the pool, a Dask worker,
or the ingest's own process): plain data in, plain data out (the bag's calibration record and
its report), no database.

The task carries the bag's :class:`~odocal.io.fleet_files.Snapshot` taken before its bytes
were hashed; the worker takes another after the calibration, and a bag that changed in between
(still being written) comes back as ``retry``, not as a result.
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

from threadpoolctl import threadpool_limits

from .._version import __version__
from ..calibration.time_offset import TimeOffset
from ..core.model import WheelGeometry
from ..errors import OdocalError
from ..io.fleet_files import Snapshot, bag_span_s, snapshot
from ..io.fleet_record import (
    COVARIANCE_KEYS,
    CalibrationRecord,
    StoredCovariance,
    StoredOffset,
)

if TYPE_CHECKING:  # (the bag route's modules are imported where a bag is calibrated)
    from .fit_auto_result import AutoFitResult
    from .fit_skid import SkidFitResult
    from .fit_skid_gyro import SkidGyroResult

__all__ = [
    "BagTask",
    "BagOutcome",
    "calibrate_bag",
    "calibration_record",
    "skid_record",
    "CHANGED",
]

CHANGED = "the bag changed while it was read (still being written?): tried again at the next ingest"


@dataclass(frozen=True)
class BagTask:
    """What a worker needs: the robot, the bag, its content hash and its snapshot."""

    robot_id: str
    bag: str
    robot_file: str
    content_hash: str
    before: Snapshot


@dataclass(frozen=True)
class BagOutcome:
    """What a worker returns. ``status``: done, failed (``reason``) or retry (``reason``);
    when done, ``record``: the bag's calibration record (:func:`calibration_record`) and
    ``report``: the JSON of ``odocal fit BAG --method auto`` (its page in the dashboard)."""

    task: BagTask
    status: str
    reason: str | None
    span_s: tuple[float, float] | None
    record: CalibrationRecord | None = None
    report: dict[str, Any] | None = None


def _stored_offsets(offsets: Sequence[TimeOffset]) -> tuple[StoredOffset, ...]:
    """The clock offsets as the record keeps them."""
    return tuple(
        StoredOffset(o.label, float(o.offset_s),
                     None if o.stderr_s is None else float(o.stderr_s), bool(o.applied))
        for o in offsets
    )  # fmt: skip


def _plain(g: WheelGeometry) -> WheelGeometry:
    """``g`` with plain floats (not numpy scalars): what the record stores."""
    return WheelGeometry(float(g.diameter_right_m), float(g.diameter_left_m), float(g.wheelbase_m))


def calibration_record(result: AutoFitResult, version: str = __version__) -> CalibrationRecord:
    """What the fleet keeps of one bag's calibration, from the typed result of the bag route:
    the answer route's parameters with their statuses (and its heading ratio when it measured
    only that), the verdict, the clock offsets, what the covariances were computed from, the
    nominal geometry, and ``version``, the odocal that calibrated it."""
    run = result.answer
    answer = None if run is None else run.answer
    cov, n = result.covariance, result.nominal
    return CalibrationRecord(
        odocal_version=version,
        route=None if run is None else run.name,
        model=None if answer is None else answer.model,
        parameters=None if answer is None else answer.parameters,
        heading_ratio=None if answer is None else answer.ratio,
        heading_ratio_std_error=None if answer is None else answer.ratio_std_error,
        enough=bool(result.enough),
        reasons=tuple(result.reasons),
        time_offsets=_stored_offsets(result.time_offsets),
        covariance=None
        if cov is None
        else StoredCovariance(*(float(getattr(cov, k)) for k in COVARIANCE_KEYS)),
        nominal=_plain(n),
    )


def skid_record(
    result: SkidFitResult | SkidGyroResult, version: str = __version__
) -> CalibrationRecord:
    """What the fleet keeps of a skid-steer robot's bag (:mod:`odocal.app.fit_skid`; without a
    truth, :mod:`odocal.app.fit_skid_gyro`): the effective rolling diameters (held at the nominal
    by the gyro) and the effective track, estimated (the drift alarms follow the track
    multiplier), the verdict and the truth's or the IMU's clock offset."""
    answer = result.answer()
    n = result.nominal
    return CalibrationRecord(
        odocal_version=version,
        route=answer.route,
        model=answer.model,
        parameters=answer.parameters,
        heading_ratio=None,
        heading_ratio_std_error=None,
        enough=bool(result.enough),
        reasons=tuple(result.reasons),
        time_offsets=_stored_offsets(result.offsets),
        covariance=None,
        nominal=_plain(n),
    )


def _calibrate(bag: Path, robot_file: str) -> tuple[CalibrationRecord, dict[str, Any]]:
    """One bag's record and report: the skid-steer fit for a robot whose file says
    ``kinematics: skid_steer`` (its halves held out), else the one-command bag route."""
    from ..io.robot_file import load_robot

    robot = load_robot(robot_file)
    if robot.kinematics == "skid-steer":
        from ..io.bag_options import NO_BAG_OPTIONS
        from ..io.bag_skid import has_truth
        from .fit_skid import read_skid_bags, read_skid_logs, skid_fit

        (contents,) = read_skid_bags([bag], NO_BAG_OPTIONS)
        if not has_truth(contents, NO_BAG_OPTIONS):  # the IMU then (the gyro route)
            from ..io.bag_skid import read_skid_gyro_log
            from .fit_skid import refuse_unstated_ran_with
            from .fit_skid_gyro import skid_gyro_fit

            glog = read_skid_gyro_log(contents, NO_BAG_OPTIONS, robot.believed_geometry)
            refuse_unstated_ran_with([(glog.name, glog.wheels)], robot)
            gyro = skid_gyro_fit([glog], robot, NO_BAG_OPTIONS, force=True)
            return skid_record(gyro), gyro.as_dict()
        skid = skid_fit(read_skid_logs([contents], NO_BAG_OPTIONS, robot), robot, force=True)
        return skid_record(skid), skid.as_dict()
    from .fit_auto import fit_auto

    res = fit_auto(bag, robot=robot)
    return calibration_record(res), res.as_dict()


def calibrate_bag(task: BagTask) -> BagOutcome:
    """Run the one-command bag route (the skid-steer fit for a skid-steer robot) on the task's
    bag (module docstring). Never raises for a bag that cannot be calibrated: the reason comes
    back as one line."""
    bag = Path(task.bag)
    record: CalibrationRecord | None = None
    report: dict[str, Any] | None = None
    reason: str | None = None
    try:
        # one core per bag: the workers are the parallelism (BLAS's own threads on a busy
        # machine made a bag 4 times slower)
        with threadpool_limits(limits=1):
            record, result = _calibrate(bag, task.robot_file)
        # through JSON: the same plain values whichever process or machine ran it
        report = json.loads(json.dumps(result))
        status = "done"
    except OdocalError as exc:
        status, reason = "failed", str(exc).splitlines()[0]
    except Exception as exc:  # noqa: BLE001 - one bad bag must not end the night's run
        status, reason = "failed", f"unexpected {type(exc).__name__}: {exc}".splitlines()[0]
    span = bag_span_s(bag) if status == "done" else None
    try:
        changed = snapshot(bag) != task.before
    except OdocalError:
        changed = True
    if changed:
        return BagOutcome(task, "retry", CHANGED, None)
    return BagOutcome(task, status, reason, span, record, report)
