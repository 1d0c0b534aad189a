"""odocal: odometry calibration and test-track design for differential-drive robots.

The everyday API, with the arguments, units and files of the command line (metres, degrees in
files and in names that say so, ROBOT.yaml / RUNS.csv / PARAMS.yaml)::

    import odocal

    robot = odocal.make_robot(0.066, 0.160, E_b=1.02, E_d=1.004, k_r_m=1e-6,
                              sigma_xy_m=0.01, sigma_theta_deg=1.0)
    odocal.simulate(robot, sides=4, side_m=1.0, runs=5, seed=1, out="runs.csv")
    cal = odocal.calibrate("runs.csv", robot)          # the track is read from the run sheet
    odocal.export(cal, ros2="diff_drive.yaml")
    best = odocal.design_track(robot).result.recommended

Each function is the command of the same name (``odocal.app.<command>``; ``design_track`` is
``odocal design``, since ``odocal.design`` is the design subpackage) and returns a frozen result
with ``as_dict()`` (the ``--json``); ``print(result)`` shows the command's text, and the command's
warnings are emitted through :mod:`warnings` as :class:`OdocalWarning`. Names are imported on
first use, so ``import odocal`` (and ``odocal --help``) stays fast.
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

from ._version import __version__

# name -> (module, attribute): resolved on first access (PEP 562). The design command is
# ``design_track``: a function named ``design`` would be replaced by the subpackage odocal.design
# the moment anything imports it.
_API: dict[str, tuple[str, str | None]] = {
    # commands
    "simulate": ("odocal.app.simulate", "simulate"),
    "calibrate": ("odocal.app.calibrate", "calibrate"),
    "fit": ("odocal.app.fit", "fit"),
    "design_track": ("odocal.app.design", "design"),
    "design": ("odocal.design", None),  # the subpackage (the command is design_track)
    "validate": ("odocal.app.validate", "validate"),
    "export": ("odocal.app.export", "export"),
    "plan": ("odocal.app.plan", "plan"),
    "noise": ("odocal.app.noise", "noise"),
    "compare": ("odocal.app.compare", "compare"),
    "reproduce": ("odocal.app.reproduce", "reproduce"),
    "ttest": ("odocal.app.ttest", "ttest"),
    "make_robot": ("odocal.app.common", "make_robot"),
    # types
    "Robot": ("odocal.core.model", "Robot"),
    "WheelGeometry": ("odocal.core.model", "WheelGeometry"),
    "SystematicError": ("odocal.core.model", "SystematicError"),
    "NonSystematicError": ("odocal.core.model", "NonSystematicError"),
    "MeasurementNoise": ("odocal.core.model", "MeasurementNoise"),
    "DesignSpec": ("odocal.design.spec", "DesignSpec"),
    "ValidationTrack": ("odocal.design.result", "ValidationTrack"),
    "CalibrateResult": ("odocal.app.calibrate", "CalibrateResult"),
    "FitResult": ("odocal.app.fit", "FitResult"),
    "DesignRun": ("odocal.app.design", "DesignRun"),
    "SimulateResult": ("odocal.app.simulate", "SimulateResult"),
    "Validation": ("odocal.app.validate", "Validation"),
    "load_robot": ("odocal.io.robot_file", "load_robot"),
    "load_params": ("odocal.io.robot_file", "load_params"),
    "PRESETS": ("odocal.presets", "PRESETS"),
    # errors
    "OdocalError": ("odocal.errors", "OdocalError"),
    "InputError": ("odocal.errors", "InputError"),
    "ModelError": ("odocal.errors", "ModelError"),
    "CalibrationError": ("odocal.errors", "CalibrationError"),
    "OdocalWarning": ("odocal.errors", "OdocalWarning"),
}

__all__ = [
    "__version__",
    "simulate",
    "calibrate",
    "fit",
    "design_track",
    "validate",
    "export",
    "plan",
    "noise",
    "compare",
    "reproduce",
    "ttest",
    "make_robot",
    "Robot",
    "WheelGeometry",
    "SystematicError",
    "NonSystematicError",
    "MeasurementNoise",
    "DesignSpec",
    "ValidationTrack",
    "CalibrateResult",
    "FitResult",
    "DesignRun",
    "SimulateResult",
    "Validation",
    "load_robot",
    "load_params",
    "PRESETS",
    "OdocalError",
    "InputError",
    "ModelError",
    "CalibrationError",
    "OdocalWarning",
]


def __getattr__(name: str) -> Any:
    try:
        module, attr = _API[name]
    except KeyError:
        raise AttributeError(f"module 'odocal' has no attribute {name!r}") from None
    value = importlib.import_module(module)
    if attr is not None:
        value = getattr(value, attr)
    globals()[name] = value  # the next access is a plain lookup
    return value


def __dir__() -> list[str]:
    return sorted(__all__)


if TYPE_CHECKING:  # for type checkers and IDEs; never executed
    from .app.calibrate import CalibrateResult, calibrate
    from .app.common import make_robot
    from .app.compare import compare
    from .app.design import DesignRun
    from .app.design import design as design_track
    from .app.export import export
    from .app.fit import FitResult, fit
    from .app.noise import noise
    from .app.plan import plan
    from .app.reproduce import reproduce
    from .app.simulate import SimulateResult, simulate
    from .app.ttest import ttest
    from .app.validate import Validation, validate
    from .core.model import (
        MeasurementNoise,
        NonSystematicError,
        Robot,
        SystematicError,
        WheelGeometry,
    )
    from .design.result import ValidationTrack
    from .design.spec import DesignSpec
    from .errors import CalibrationError, InputError, ModelError, OdocalError, OdocalWarning
    from .io.robot_file import load_params, load_robot
    from .presets import PRESETS
