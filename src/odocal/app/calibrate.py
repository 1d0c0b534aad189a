"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..calibration.bcpt import calibrate_bcpt
from ..calibration.heading import calibrate_heading
from ..calibration.result import CalibrationResult, check_physical
from ..calibration.umbmark import calibrate_umbmark
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.robot_file import params_yaml
from ..io.runs_csv import read_circle_runs, read_runs
from .common import RobotSpec, input_paths, refuse_absurd, resolve_robot

__all__ = ["CalibrateResult", "calibrate"]


@dataclass(frozen=True)
class CalibrateResult:
    """A calibration from a run sheet, its warnings (an absurd result is reported, not hidden)
    and the files written."""

    calibration: CalibrationResult
    track: str
    warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal calibrate --json``."""
        return self.calibration.as_dict()


def calibrate(
    runs_csv: str | Path,
    robot: RobotSpec = None,
    *,
    params=None,
    method: str = "heading",
    sides: int = 4,
    side_m: float = 4.0,
    umbmark_form: str = "mean",
    radius_m: float | None = None,
    out: str | Path | None = None,
    force: bool = False,
) -> CalibrateResult:
    """Read RUNS.csv (or the BCPT runs file) and calibrate with ``method`` ('heading', 'umbmark'
    or 'bcpt'), relative to the parameters the robot ran with (``params``, else ROBOT.yaml's
    'believed', else nominal); write PARAMS.yaml to ``out``. A result more than 25 % from what
    the robot ran with is absurd for a calibration: CalibrationError (nothing written) unless
    ``force``."""
    plan = OutputPlan(input_paths(runs_csv, robot, params))
    if out is not None:
        plan.file(out, "--out")
    r = resolve_robot(robot, params)
    ran_with = r.believed_geometry
    notes: list[str] = []
    if radius_m is not None and method != "bcpt":
        raise InputError(f"--radius is only used with --method bcpt (got --method {method})")
    if method == "bcpt":
        if radius_m is None:
            raise InputError("--method bcpt needs --radius R (the commanded circle radius, m)")
        result = calibrate_bcpt(read_circle_runs(runs_csv, notes), radius_m, ran_with)
        track = f"circles of commanded radius {radius_m:g} m"
    else:
        # each method reads only what it uses: heading the final headings, UMBmark the positions
        runs = read_runs(
            runs_csv,
            required=("theta_deg",) if method == "heading" else ("x_m", "y_m"),
            warnings=notes,
        )
        track = f"{sides}-gon side {side_m:g} m"
        if method == "umbmark":
            if sides != 4:
                raise InputError(
                    f"UMBmark is defined for squares only (--sides 4), got --sides {sides}"
                )
            result = calibrate_umbmark(runs, side_m, ran_with, umbmark_form)
        elif method == "heading":
            result = calibrate_heading(runs, sides, side_m, ran_with)
        else:
            raise InputError(f"unknown method {method!r}", field="method")
    c = result.corrected
    check_physical((c.diameter_right_m, c.diameter_left_m, c.wheelbase_m), None, result.method)
    warnings = notes + refuse_absurd(c, result.ran_with, force)
    written: tuple[Path, ...] = ()
    if out is not None:
        text = params_yaml(result.corrected, method=result.method, E_b=result.E_b, E_d=result.E_d)
        written = tuple(plan.commit({Path(out): text}))
    return CalibrateResult(result, track, tuple(warnings), written)
