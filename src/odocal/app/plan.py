"""``odocal plan``: the floor protocol for calibration runs (or k runs) and a blank RUNS.csv."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

from ..core.model import Robot
from ..core.plausibility import track_size_problem
from ..design.analytic import analytic_design_result
from ..design.plan import FloorPlan, build_plan
from ..design.robust import range_design, unknown_errors
from ..design.spec import DesignSpec
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.runs_csv import refuse_replacing_measurements
from ..presets import DEFAULT_ROBOT
from .common import RobotSpec, input_paths, resolve_robot

__all__ = ["PlanResult", "plan", "DEFAULT_TEMPLATE", "DEFAULT_NOISE_RUNS"]

DEFAULT_TEMPLATE = "runs-template.csv"
DEFAULT_NOISE_RUNS = 20


@dataclass(frozen=True)
class PlanResult:
    """The floor plan, the run sheet written and the warnings."""

    floor_plan: FloorPlan
    sheet: Path
    warnings: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal plan --json``: the floor plan, the run sheet written (``template``)
        and the notes."""
        return self.floor_plan.as_dict() | {"template": str(self.sheet), "notes": list(self.notes)}


_SHEET_HEADER = ("direction", "x_m", "y_m", "theta_deg", "run")
#: The comment line that marks a run sheet ``plan`` wrote.
SIGNATURE = "# odocal run sheet:"


def plan(
    robot: RobotSpec = None,
    *,
    params=None,
    sides: int = 4,
    side_m: float | None = None,
    runs_per_direction: int | None = None,
    noise_track: tuple[str, float] | None = None,
    out: str | Path = DEFAULT_TEMPLATE,
    force: bool = False,
    progress=None,
) -> PlanResult:
    """Build the floor protocol and write the blank run sheet ``out``.

    Without ``side_m`` the polygon's side is what ``odocal design --analytic`` recommends for this
    robot (over the typical ranges of its errors when ROBOT.yaml does not give them); the run
    sheet records the track either way.

    A blank run sheet (e.g. from an earlier ``plan``) is replaced; one that already holds a
    measured value, or a file that is not a run sheet, is not, unless ``force``."""
    out = Path(out)
    # the default name is checked like any other, and the message says it was the default
    flag = "--out" if str(out) != DEFAULT_TEMPLATE else f"--out (default {DEFAULT_TEMPLATE})"
    outputs = OutputPlan(input_paths(robot, params))
    outputs.file(out, flag)
    refuse_replacing_measurements(
        out,
        flag,
        "plan",
        SIGNATURE,
        force=force,
        blank=(_SHEET_HEADER, FloorPlan.template_comments()),
    )
    r = resolve_robot(robot, params)
    notes = []
    if side_m is None and noise_track is None:
        side_m, note = suggested_side(r, sides, progress)
        notes.append(note)
    b = float(r.believed_geometry.wheelbase_m)
    side = noise_track[1] if noise_track else side_m
    assert side is not None  # given, suggested above, or the noise track's
    problem = track_size_problem(b, side)
    if problem:
        raise InputError(problem)
    n = runs_per_direction or (DEFAULT_NOISE_RUNS if noise_track else 5)
    fp = build_plan(
        r,
        sides=sides,
        side_m=side_m,
        runs_per_direction=n,
        noise_track=noise_track,
        runs_path=str(out),
        robot_arg=str(robot) if isinstance(robot, (str, Path)) else DEFAULT_ROBOT,
    )
    warnings = []
    c = fp.calibration
    if c is not None and not math.isfinite(c.post_error_mean_m):
        warnings.append(
            f"no calibration prediction: the heading-error method is undefined for a "
            f"{side_m:g} m side (too short to resolve E_d)"
        )
    outputs.commit({out: fp.template_csv()})
    return PlanResult(fp, out, tuple(warnings), tuple(notes))


def suggested_side(robot: Robot, sides: int = 4, progress=None) -> tuple[float, str]:
    """The side (m) the analytic design recommends for ``robot`` (over plausible errors when it
    gives none), and a note saying so."""
    spec = DesignSpec(sides=(sides,)).for_wheelbase(float(robot.nominal.wheelbase_m))
    unknown = unknown_errors(robot)
    if unknown:
        d = range_design(robot, spec, progress=progress)
        return d.recommended.side_m, (
            f"side {d.recommended.side_m:g} m: the design's recommendation over the typical "
            f"ranges of the robot's {' and '.join(unknown)} errors (no size beats it by more "
            f"than {100 * d.within:.1f} %; 'odocal design --robot ...' shows it)"
        )
    res = analytic_design_result(robot, spec)
    return res.recommended.side_m, (
        f"side {res.recommended.side_m:g} m: what 'odocal design --analytic' recommends for "
        "this robot (give --side-length to choose another)"
    )
