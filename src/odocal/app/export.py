"""Export a calibration: PARAMS.yaml and the ros2_control ``diff_drive_controller`` file.

The one export path of every calibration (``odocal calibrate --ros2``, ``odocal fit --ros2`` and
this function use :func:`odocal.app.common.write_exports`): the base values are the NOMINAL
geometry, the calibration goes into the multipliers (docs/real-robots.md, "Outputs").
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

from ..core.model import WheelGeometry
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.ros2_export import DEFAULT_CONTROLLER
from .common import register_exports, write_exports

__all__ = ["export"]


def _geometry_and_nominal(result: Any, nominal: WheelGeometry | None):
    """(calibrated geometry, nominal or None, method) of a calibration result of any command."""
    if isinstance(result, WheelGeometry):
        return result, nominal, "given"
    calibration = getattr(result, "calibration", None)  # CalibrateResult
    if calibration is not None:
        return calibration.corrected, nominal or result.nominal, calibration.method
    fit = getattr(result, "fit", None)  # FitResult
    if fit is not None:
        return fit.geometry, nominal or result.nominal, fit.method
    geometry = getattr(result, "geometry", None)  # GeometryFit, GyroFitResult
    if isinstance(geometry, WheelGeometry):
        nom = nominal or getattr(result, "nominal", None)
        return geometry, nom, getattr(result, "method", "gyro")
    corrected = getattr(result, "corrected", None)  # CalibrationResult
    if isinstance(corrected, WheelGeometry):
        return corrected, nominal, result.method
    raise InputError(f"cannot export a {type(result).__name__}: give a calibration result")


def export(
    result: Any,
    *,
    ros2: str | Path | None = None,
    out: str | Path | None = None,
    nominal: WheelGeometry | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
) -> tuple[Path, ...]:
    """Write ``result`` (what ``calibrate`` or ``fit`` returned, or a calibrated
    :class:`~odocal.core.model.WheelGeometry`) as a ros2_control file ``ros2`` and/or a
    PARAMS.yaml ``out``; all or none. ``nominal`` (m): the base values of the ros2_control file
    (default: the nominal geometry the result carries, i.e. ROBOT.yaml's). Returns the paths
    written."""
    geometry, nom, method = _geometry_and_nominal(result, nominal)
    if ros2 is None and out is None:
        raise InputError("nothing to export: give ros2=FILE.yaml and/or out=PARAMS.yaml")
    plan = OutputPlan([])
    register_exports(plan, out, ros2)
    return write_exports(plan, geometry, nom, out, ros2, controller_name, record={"method": method})
