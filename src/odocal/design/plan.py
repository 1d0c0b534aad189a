"""The floor protocol: what a person drives, measures and should expect (``odocal plan``).

Pure: builds a :class:`FloorPlan` from a robot and a track; the CLI prints it and writes the run
sheet.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ..core.covariance import PosePrediction, mean_final_pose, predict
from ..core.jsonable import finite_or_none
from ..core.model import Robot
from ..core.simulate import odometric_pose
from ..core.tracks import Track, out_and_back, polygon, straight_line
from ..errors import ModelError
from .analytic import AnalyticReference, analytic_design, analytic_reference
from .result import Candidate, ValidationTrack
from .robust import plausible_robots, unknown_errors
from .spec import scaled_sizes

__all__ = ["FloorPlan", "build_plan"]


@dataclass(frozen=True)
class FloorPlan:
    """What to drive, in which order, and what the model predicts for the end errors.

    Attributes
    ----------
    kind : str
        'polygon', 'out-and-back' or 'straight'.
    title : str
    order : tuple of str
        Direction label of every run, in driving order ('cw'/'ccw' or 'fwd').
    predictions : dict of str to PosePrediction
        Predicted end pose (mean error and covariance incl. the instrument) per direction label.
    steps : tuple of str
        The protocol, one step per item.
    next_command : str
        The odocal command that reads the filled-in RUNS.csv.
    calibration, reference : Candidate, AnalyticReference or None
        For polygons: the analytic design's prediction of the heading-error calibration from
        these runs and of the error on the paper's 4 m CCW validation square (with the true
        parameters: the floor; uncalibrated).
    track : (int, float) or None
        For polygons: (sides, side_m), written into the run sheet as data.
    validation : ValidationTrack or None
        The validation track of the prediction (a square scaled to the robot, as in
        ``odocal design``).
    typical_mean_abs : dict of str to (float, float, float)
        When ROBOT.yaml gives no systematic errors (the runs are to measure them): per
        direction, the largest |mean end error| (x_m, y_m, theta_rad) of the plausible robots
        (typical E_b, E_d; :mod:`odocal.design.robust`); then ``calibration`` is None.
    unknown : tuple of str
        The error classes ROBOT.yaml does not give ('systematic', 'nonsystematic').
    """

    kind: str
    title: str
    order: tuple[str, ...]
    predictions: dict[str, PosePrediction]
    steps: tuple[str, ...]
    next_command: str
    calibration: Candidate | None = None
    reference: AnalyticReference | None = None
    track: tuple[int, float] | None = None
    validation: ValidationTrack | None = None
    typical_mean_abs: dict = field(default_factory=dict)
    unknown: tuple[str, ...] = ()

    @staticmethod
    def template_comments() -> tuple[str, ...]:
        """The fixed comment lines of every blank run sheet (after its title line)."""
        return (
            "# Fill in every run: x_m, y_m (m) and theta_deg (deg), the final pose ERROR (actual -",
            "# odometric) in the start frame: +x start heading, +y left, theta CCW positive, the",
            "# small deviation from the commanded turn. The heading-error method needs only",
            "# theta_deg (leave x_m, y_m empty if you cannot measure them); UMBmark needs",
            "# x_m, y_m.",
            "# Keep the rows in driving order and the 'sides'/'side_m' lines above: they tell",
            "# odocal calibrate which track the runs drove.",
        )

    def template_csv(self) -> str:
        """Blank RUNS.csv: the track as ``# sides:``/``# side_m:`` settings (read by ``odocal
        calibrate``), comment lines, header, one row per run with the direction filled in."""
        lines = []
        if self.track is not None:
            lines += [f"# sides: {self.track[0]}", f"# side_m: {self.track[1]:.12g}"]
        lines += [
            f"# odocal run sheet: {self.title}",
            *self.template_comments(),
            "direction,x_m,y_m,theta_deg,run",
        ]
        lines += [f"{d},,,,{i}" for i, d in enumerate(self.order, start=1)]
        return "\n".join(lines) + "\n"

    def as_dict(self) -> dict:
        """JSON-ready (``odocal plan --json`` without the run sheet's path and notes): the protocol,
        the runs in order and the predicted errors (m, deg), plus the calibration's prediction
        and the typical errors when known."""

        def pose(v):
            return {"x_m": float(v[0]), "y_m": float(v[1]), "theta_deg": math.degrees(v[2])}

        extra = {}
        if self.calibration is not None:
            c, r = self.calibration, self.reference
            assert r is not None
            extra["calibration_prediction"] = {
                "method": "heading",
                "E_b_mean": finite_or_none(c.E_b_mean),
                "E_b_std": finite_or_none(c.E_b_std),
                "E_d_mean": finite_or_none(c.E_d_mean),
                "E_d_std": finite_or_none(c.E_d_std),
                "validation": self.validation.as_dict() if self.validation else None,
                "post_error_mean_m": finite_or_none(c.post_error_mean_m),
                "post_error_ci95_m": [finite_or_none(v) for v in c.post_error_ci95_m],
                "floor_m": r.floor_m,
                "uncalibrated_m": r.uncalibrated_m,
            }
        if self.typical_mean_abs:
            extra["typical_mean_abs"] = {d: pose(v) for d, v in self.typical_mean_abs.items()}
        return extra | {
            "unknown_errors": list(self.unknown),
            "kind": self.kind,
            "title": self.title,
            "order": list(self.order),
            "runs": len(self.order),
            "steps": list(self.steps),
            "next_command": self.next_command,
            "predicted": {
                d: {"mean": pose(p.error_mean), "std": pose(p.std(measured=True))}
                for d, p in self.predictions.items()
            },
        }


_START = (
    "Mark the start pose on the floor: a cross under the midpoint between the wheel contact "
    "points (the axle centre), and a line (tape or a straight edge) of 1 m or more along the "
    "start heading. This defines the start frame: origin at the cross, +x along the line, +y to "
    "the robot's left."
)
_PLACE = (
    "Before every run, place the robot on the start pose (axle centre on the cross, heading "
    "along the line) and reset its odometry. Use the same parameters in the robot for all runs "
    "(those in ROBOT.yaml 'believed', else nominal): do not recalibrate between runs."
)
_OPEN_LOOP = (
    "Drive open loop on the wheel encoders (odometry only, no external correction), slowly and "
    "with gentle accelerations so the wheels do not slip; the same speed profile for every run."
)


def _measure_step(closed: bool, extra: str = "", example: str = "") -> str:
    what = (
        "Since the track ends where it starts, the error (actual - odometric) is simply the "
        "measured final pose."
        if closed
        else extra
    )
    return (
        "At the end of each run, measure the final pose in the START frame: x_m along the start "
        "line, y_m to its left (m), and theta_deg, the final heading minus the start heading, CCW "
        "positive, unwrapped: the small deviation from the commanded total turn"
        + (example or " (ending 2 deg to the left of the start line is +2)")
        + ". "
        + what
    )


# Most runs per direction a floor plan lists.
MAX_PLAN_RUNS = 1000


def build_plan(
    robot: Robot,
    *,
    sides: int | None = None,
    side_m: float | None = None,
    runs_per_direction: int = 5,
    noise_track: tuple[str, float] | None = None,
    runs_path: str = "RUNS.csv",
    robot_arg: str = "ROBOT.yaml",
) -> FloorPlan:
    """The floor protocol for an N-gon of side ``side_m`` (m) driven ``runs_per_direction`` times
    CW and CCW, or (``noise_track`` = ('out-and-back' | 'straight', D m)) ``runs_per_direction``
    runs for measuring k. Predictions come from :func:`odocal.core.covariance.predict`."""
    n = int(runs_per_direction)
    if not 1 <= n <= MAX_PLAN_RUNS:
        raise ModelError(
            f"runs per direction must be 1 .. {MAX_PLAN_RUNS} (runs a person drives), got {n}"
        )
    if noise_track is None:
        if sides is None or side_m is None:
            raise ModelError("a polygon plan needs the number of sides and the side length")
        tracks: dict[str, Track] = {d: polygon(sides, side_m, d) for d in ("cw", "ccw")}
        order = tuple(("cw", "ccw")[i % 2] for i in range(2 * n))
        shape = {3: "triangle", 4: "square"}.get(sides, f"regular {sides}-gon")
        turn = 360.0 / sides
        title = (
            f"{shape}, {sides} sides of {side_m:g} m ({sides * side_m:g} m travel), "
            f"{n} CW + {n} CCW runs"
        )
        steps: tuple[str, ...] = (
            _START,
            f"Free floor: the {shape} lies to the right of the start line for CW runs (y < 0) "
            f"and to its left for CCW runs (y > 0); keep about {side_m:g} m x {side_m:g} m clear "
            "on both sides plus a margin for the errors below.",
            f"One run: {sides} times (straight {side_m:g} m, then turn on the spot by "
            f"{turn:g} deg): right turns (-{turn:g} deg) for CW, left turns (+{turn:g} deg) "
            f"for CCW. Total commanded heading change: -360 deg (CW), +360 deg (CCW).",
            _OPEN_LOOP,
            f"Order: alternate CW and CCW (CW, CCW, CW, ...; {2 * n} runs, as in the template). "
            "Why not blocks: a slow drift during the session (battery voltage, tyre temperature, "
            "floor) then affects both directions alike and cancels, instead of becoming a "
            "CW - CCW difference that the calibration would read as a wheelbase error.",
            _PLACE,
            _measure_step(
                True,
                example=" (a CW run turns -360 deg; ending 2 deg to the left of the start line is "
                "+2, not -358)",
            ),
            "Write each run into the template row of the same number. Measure all three values "
            "if you can: the heading-error method (default) uses theta_deg (with only a gyro or "
            "a protractor, leave x_m and y_m empty), UMBmark (--method umbmark) uses x_m and "
            "y_m.",
        )
        next_cmd = f"odocal calibrate {runs_path} --robot {robot_arg}"
        kind = "polygon"
    else:
        kind, d = noise_track
        tr = out_and_back(d) if kind == "out-and-back" else straight_line(d)
        tracks = {"fwd": tr}
        order = ("fwd",) * n
        title = f"{kind} {d:g} m, {n} runs (non-systematic error k)"
        drive = (
            f"One run: forward {d:g} m, stop, then backward {d:g} m WITHOUT turning (reverse "
            "the wheels). The robot retraces its own arc, so systematic errors cancel and the "
            "end spread is purely random."
            if kind == "out-and-back"
            else f"One run: forward {d:g} m in a straight line. Systematic curvature only shifts "
            "the mean; the spread about the mean is random."
        )
        meas_extra = (
            "The robot ends near the start, so the error is simply the measured final pose."
            if kind == "out-and-back"
            else f"The robot believes it ends at x = {d:g} m, y = 0, heading 0: record "
            f"x_m = measured x - {d:g}, y_m = measured y, theta_deg = measured heading."
        )
        steps = (
            _START,
            drive,
            _OPEN_LOOP,
            f"Drive {n} runs (10 to 20 give a usable 95 % interval; fewer than 3 cannot be "
            "used) in one session; 'odocal noise' flags a drift with run order.",
            _PLACE,
            _measure_step(kind == "out-and-back", meas_extra)
            + " The heading is what k is computed from: measure it as precisely as you can "
            "(its instrument noise, ROBOT.yaml measurement.sigma_theta_deg, is subtracted).",
            "Write each run into the template (direction 'fwd').",
        )
        next_cmd = f"odocal noise {runs_path} --robot {robot_arg} --track {kind}:{d:g}"
    predictions = {lab: predict(t, robot, max_step_m=0.02) for lab, t in tracks.items()}
    calibration = reference = validation = None
    typical: dict[str, tuple[float, float, float]] = {}
    unknown = unknown_errors(robot)
    if kind == "polygon" and "systematic" in unknown:
        # the robot's errors are what the runs will measure: show what typical robots do
        for lab, t in tracks.items():
            means = np.array(
                [mean_final_pose(t, r.true_geometry, r.believed_geometry) - odometric_pose(t)
                 for _, r in plausible_robots(robot, ("systematic",))]
            )  # fmt: skip
            m = np.max(np.abs(means), axis=0)
            typical[lab] = (float(m[0]), float(m[1]), float(m[2]))
    elif kind == "polygon":
        assert sides is not None and side_m is not None
        validation = scaled_sizes(float(robot.nominal.wheelbase_m))[1]
        validate = validation.track()
        calibration = analytic_design(robot, sides, [side_m], n, "heading", validate)[0]
        reference = analytic_reference(robot, validate)
    track = (int(sides), float(side_m)) if kind == "polygon" and sides and side_m else None
    return FloorPlan(
        kind,
        title,
        order,
        predictions,
        steps,
        next_cmd,
        calibration,
        reference,
        track,
        validation,
        typical,
        unknown,
    )
