"""``odocal calibrate``: E_b, E_d and corrected parameters from measured polygon or circle runs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..calibration.bcpt import calibrate_bcpt
from ..calibration.heading import calibrate_heading
from ..calibration.heading_check import refuse_flipped_headings
from ..calibration.result import CalibrationResult, check_physical
from ..calibration.umbmark import calibrate_umbmark
from ..core.jsonable import jsonable
from ..core.model import Robot, WheelGeometry
from ..core.plausibility import (
    end_distance_problem,
    end_error_bounds,
    heading_error_problem,
    track_size_problem,
    wrap_heading_error,
)
from ..core.runs import EndPoseRuns
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.ros2_export import DEFAULT_CONTROLLER
from ..io.runs_csv import RunSheet, read_circle_runs, read_run_sheet
from .common import (
    RobotSpec,
    input_paths,
    refuse_absurd,
    register_exports,
    require_robot,
    resolve_robot,
    robot_label,
    write_exports,
)
from .text import Presented, Text, emits_warnings, written_lines

__all__ = ["CalibrateResult", "calibrate", "resolve_track"]


@dataclass(frozen=True)
class CalibrateResult(Presented):
    """A calibration from a run sheet, its warnings (an absurd result is reported, not hidden)
    and the files written.

    Attributes
    ----------
    calibration : CalibrationResult
        E_b, E_d, the corrected geometry and its uncertainty from the run-to-run spread.
    track : str
        The track the runs drove, in words.
    warnings : tuple of str
    written : tuple of Path
    track_source : str
        Where the track came from: 'run sheet', 'arguments' or 'both' (they agree).
    nominal : WheelGeometry or None
        The nominal geometry (the base values of a ros2_control export).
    robot : str
        The robot the runs were calibrated for (a ROBOT.yaml path or a built-in's name; there is
        no default robot: its geometry sets E_d and every exported value).
    """

    calibration: CalibrationResult
    track: str
    warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    track_source: str = "arguments"
    nominal: WheelGeometry | None = None
    robot: str = ""

    @property
    def correction_needed(self) -> bool | None:
        """False when E_b and E_d are both within their 95 % intervals of 1 (a robot that already
        runs with calibrated parameters: the runs show no correction beyond their noise), True
        when one is not, None without an uncertainty (fewer than 2 runs in a direction)."""
        unc = self.calibration.uncertainty
        if unc is None:
            return None
        ci = unc.ci95()
        return not all(ci[k][0] <= 1.0 <= ci[k][1] for k in ("E_b", "E_d"))

    def as_dict(self) -> dict:
        """The JSON of ``odocal calibrate --json``: the result, its uncertainty, the inputs it
        was computed from, whether a correction is needed, the warnings and the files written."""
        inputs = {k: jsonable(v) for k, v in self.calibration.inputs.items()}
        return self.calibration.as_dict() | {
            "correction_needed": self.correction_needed,
            "track": self.track,
            "track_source": self.track_source,
            "robot": self.robot,
            "inputs": inputs,
            "nominal": None if self.nominal is None else self.nominal.as_dict(),
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }

    def text(self) -> str:
        """The text of ``odocal calibrate``: the method and runs, the table of the calibrated
        values with their uncertainty, the mean errors and the files written."""
        out = Text()
        result = self.calibration
        ins = result.inputs
        label = result.method + (f" ({ins['form']}-form)" if "form" in ins else "")
        where = "" if self.track_source == "arguments" else f" (track from the {self.track_source})"
        if self.track_source == "both":
            where = " (track from the run sheet and the arguments)"
        out(f"{label} from {ins['runs_cw']} CW and {ins['runs_ccw']} CCW runs, {self.track}{where}")
        r, c, unc = result.ran_with, result.corrected, result.uncertainty
        out(
            f"robot {self.robot}: ran with wheel diameters {r.diameter_right_m:.6g} / "
            f"{r.diameter_left_m:.6g} m (right / left), wheelbase {r.wheelbase_m:.6g} m"
        )
        ci = unc.ci95() if unc is not None else {}

        def cell(name: str, value: float, digits: int) -> tuple[str, str, str]:
            if unc is None:
                return f"{value:.{digits}f}", "-", "-"
            k = ("E_b", "E_d", *_GEOMETRY).index(name)
            lo, hi = ci[name]
            return (
                f"{value:.{digits}f}",
                f"{unc.stderr[k]:.{digits}f}",
                f"{lo:.{digits}f} .. {hi:.{digits}f}",
            )

        rows: list[tuple] = [("", "ran with", "calibrated", "std error", "95 % interval")]
        rows.append(("E_b", "", *cell("E_b", result.E_b, 6)))
        rows.append(("E_d", "", *cell("E_d", result.E_d, 6)))
        for name, ran, cal in zip(
            _GEOMETRY,
            (r.diameter_right_m, r.diameter_left_m, r.wheelbase_m),
            (c.diameter_right_m, c.diameter_left_m, c.wheelbase_m),
            strict=True,
        ):
            rows.append((name, f"{ran:.6f}", *cell(name, float(cal), 6)))
        out.table(rows)
        if unc is not None:
            out(
                "  std error and 95 % interval from the run-to-run spread (delta method; Student "
                f"t with {min(unc.dof):.1f} or more degrees of freedom)"
            )
        if "mean_theta_cw_rad" in ins:
            out(
                f"  mean heading error: CW {math.degrees(ins['mean_theta_cw_rad']):+.4f} deg, "
                f"CCW {math.degrees(ins['mean_theta_ccw_rad']):+.4f} deg"
            )
        if "mean_radius_cw_m" in ins:
            out(
                f"  mean radius: CW {ins['mean_radius_cw_m']:.6f} m, "
                f"CCW {ins['mean_radius_ccw_m']:.6f} m (first order: E_b "
                f"{ins['first_order_E_b']:.6f}, E_d {ins['first_order_E_d']:.6f})"
            )
        if self.correction_needed is False:
            out(
                "  no further correction needed: E_b and E_d are within their 95 % intervals of 1 "
                "(the robot already runs with calibrated parameters; the corrected values differ "
                "from them by less than the runs can resolve)"
            )
        written_lines(out, self.written)
        return str(out)


_GEOMETRY = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")


def resolve_track(
    sheet: RunSheet, sides: int | None, side_m: float | None
) -> tuple[int, float, str]:
    """The polygon the runs drove: from the sheet's ``# sides:``/``# side_m:`` lines and/or the
    arguments, which must agree. No default side length: a wrong one gives a wrong E_d."""
    path = sheet.path
    for name, given, on_sheet in (("sides", sides, sheet.sides), ("side_m", side_m, sheet.side_m)):
        if given is not None and on_sheet is not None and not math.isclose(given, on_sheet):
            flag = "--sides" if name == "sides" else "--side-length"
            raise InputError(
                f"{flag} {given:g} disagrees with the run sheet's '{name}: {on_sheet:g}': which "
                "track did the runs drive? Correct the sheet or leave the flag out",
                path,
                sheet.setting_lines.get(name),
                name,
            )
    side = side_m if side_m is not None else sheet.side_m
    if side is None:
        raise InputError(
            "which track did the runs drive? Give --side-length L (m; and --sides N if not a "
            "square), or keep the '# sides:' and '# side_m:' lines that 'odocal plan' writes "
            "into the run sheet",
            path,
        )
    n = sides if sides is not None else (sheet.sides if sheet.sides is not None else 4)
    on_sheet = sheet.side_m is not None
    source = (
        "both" if (side_m is not None and on_sheet) else ("run sheet" if on_sheet else "arguments")
    )
    return int(n), float(side), source


def _checked_runs(
    sheet: RunSheet, sides: int, side_m: float, robot: Robot
) -> tuple[EndPoseRuns, list[str]]:
    """The runs with their heading errors wrapped into [-180, 180) deg, each row alike (a warning
    names the rows), where this robot cannot deviate by half a turn on this track; and refused
    when an end error cannot belong to this robot on this track (a unit slip)."""
    runs, warnings = sheet.runs, []
    m = robot.measurement
    bounds = end_error_bounds(
        sides, side_m, robot.believed_geometry, m.sigma_theta_rad, m.sigma_xy_m
    )
    err = runs.errors.copy()
    theta = err[:, 2]
    finite = np.isfinite(theta)
    wrapped = theta
    if bounds.unambiguous:
        wrapped = np.where(finite, wrap_heading_error(np.where(finite, theta, 0.0)), theta)
    moved = finite & ~np.isclose(wrapped, theta, rtol=0.0, atol=1e-12)
    if np.any(moved):
        rows = ", ".join(
            f"line {sheet.lines[i]}: {math.degrees(theta[i]):g} -> {math.degrees(wrapped[i]):+.4g}"
            for i in np.flatnonzero(moved)
        )
        warnings.append(
            f"{sheet.path}: theta_deg read as the deviation from the commanded turn, a full turn "
            f"removed ({rows}); theta_deg is the small final heading ERROR, not the total turn"
        )
    elif not bounds.unambiguous and np.any(np.abs(theta[finite]) > math.pi):
        warnings.append(
            f"{sheet.path}: on this track the robot's heading error may exceed 180 deg, so "
            "theta_deg is taken as written (unwrapped, e.g. from a gyro); a protractor cannot "
            "tell such errors apart: drive a shorter track"
        )
    err[:, 2] = wrapped
    # the first row (in file order) with an implausible heading or end, named as the row checks
    # name it; found in one vectorised pass (a sheet may hold millions of runs)
    far = np.abs(np.where(finite, wrapped, 0.0)) > bounds.heading_rad
    with np.errstate(invalid="ignore"):
        far |= np.hypot(err[:, 0], err[:, 1]) > bounds.distance_m * (1.0 - 1e-12)
    for i in np.flatnonzero(far):
        line = int(sheet.lines[i])
        if finite[i]:
            problem = heading_error_problem(float(wrapped[i]), bounds)
            if problem:
                raise InputError(problem, sheet.path, line, "theta_deg")
        if np.isfinite(err[i, 0]) and np.isfinite(err[i, 1]):
            problem = end_distance_problem(float(err[i, 0]), float(err[i, 1]), bounds)
            if problem:
                raise InputError(problem, sheet.path, line, "x_m")
    return EndPoseRuns(runs.directions, err), warnings


@emits_warnings
def calibrate(
    runs_csv: str | Path,
    robot: RobotSpec = None,
    *,
    params=None,
    method: str = "heading",
    sides: int | None = None,
    side_m: float | None = None,
    umbmark_form: str = "mean",
    radius_m: float | None = None,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
    force: bool = False,
) -> CalibrateResult:
    """Read RUNS.csv (or the BCPT runs file) and calibrate ``robot`` (required: a ROBOT.yaml
    path, a built-in's name or a Robot) with ``method`` ('heading', 'umbmark' or 'bcpt'),
    relative to the parameters the robot ran with (``params``, else ROBOT.yaml's 'believed',
    else nominal).

    The polygon (``sides``, ``side_m`` in m) comes from the arguments or the run sheet's
    ``# sides:``/``# side_m:`` lines (they must agree; there is no default side length). Headings
    are in degrees in the sheet, as on the command line. Writes PARAMS.yaml to ``out`` and the
    ros2_control ``diff_drive_controller`` file to ``ros2`` (the export of ``odocal fit``). A
    result more than 25 % from what the robot ran with is absurd for a calibration:
    CalibrationError (nothing written) unless ``force``; so are headings that the positions of
    the same runs say have the wrong sign (:mod:`odocal.calibration.heading_check`; an
    InputError)."""
    require_robot(robot, "its geometry sets E_d and every exported value")
    plan = OutputPlan(input_paths(runs_csv, robot, params))
    register_exports(plan, out, ros2)
    r = resolve_robot(robot, params)
    label = robot_label(robot, params)
    ran_with = r.believed_geometry
    notes: list[str] = []
    source = "arguments"
    if radius_m is not None and method != "bcpt":
        raise InputError(f"--radius is only used with --method bcpt (got --method {method})")
    if method == "bcpt":
        if radius_m is None:
            raise InputError("--method bcpt needs --radius R (the commanded circle radius, m)")
        result = calibrate_bcpt(read_circle_runs(runs_csv, notes, radius_m), radius_m, ran_with)
        track = f"circles of commanded radius {radius_m:g} m"
    elif method in ("heading", "umbmark"):
        # each method reads only what it uses: heading the final headings, UMBmark the positions
        sheet = read_run_sheet(
            runs_csv,
            required=("theta_deg",) if method == "heading" else ("x_m", "y_m"),
            warnings=notes,
        )
        sides, side_m, source = resolve_track(sheet, sides, side_m)
        problem = track_size_problem(float(ran_with.wheelbase_m), side_m)
        if problem:
            raise InputError(problem, sheet.path, sheet.setting_lines.get("side_m"), "side_m")
        runs, wrapped = _checked_runs(sheet, sides, side_m, r)
        notes += wrapped
        notes += refuse_flipped_headings(runs, sides, side_m, ran_with, force, sheet.path)
        track = f"{sides}-gon side {side_m:g} m"
        if method == "umbmark":
            if sides != 4:
                raise InputError(
                    f"UMBmark is defined for squares only (--sides 4), got --sides {sides}"
                )
            result = calibrate_umbmark(runs, side_m, ran_with, umbmark_form)
        else:
            result = calibrate_heading(runs, sides, side_m, ran_with)
    else:
        raise InputError(f"unknown method {method!r}", field="method")
    if result.uncertainty is None:
        notes.append(
            "fewer than 2 runs in a direction: no run-to-run spread, so no standard errors; "
            "drive at least 2 (better 5) runs per direction"
        )
    c = result.corrected
    check_physical((c.diameter_right_m, c.diameter_left_m, c.wheelbase_m), None, result.method)
    forced = refuse_absurd(c, result.ran_with, force)
    notes += forced
    written = write_exports(
        plan,
        result.corrected,
        r.nominal,
        out,
        ros2,
        controller_name,
        record={"method": result.method, "E_b": result.E_b, "E_d": result.E_d},
        doubts=forced,
    )
    return CalibrateResult(result, track, tuple(notes), written, source, r.nominal, label)
