"""``odocal plan --route R``: the recording ``design --route R`` recommends, as a timed
velocity-command file a robot can execute and a protocol a person can teleoperate, with the
checks that tell during the recording whether it went as planned."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..core.maneuvers import DEFAULT_RATE_HZ, Maneuver, command_series, simulate_recordings
from ..core.model import Kinematics, MeasurementNoise, NonSystematicError
from ..design.route import Route
from ..errors import InputError
from ..io.commands import COMMAND_HEADER, command_csv
from ..io.outputs import OutputPlan
from .common import RobotSpec, input_paths
from .design_route import RouteDesignRun, design_for_route
from .text import Presented, Text, emits_warnings

__all__ = ["RoutePlan", "plan_route", "DEFAULT_COMMANDS", "COMMAND_HEADER"]

DEFAULT_COMMANDS = "route-commands.csv"

#: A maneuver's yaw or distance may differ from the plan by this fraction before the protocol
#: calls it not as planned.
AMOUNT_TOLERANCE = 0.05


def _checks(m: Maneuver, route: Route) -> list[str]:
    """What to watch during one maneuver (in the robot's odometry or a stopwatch)."""
    ccw, cw = m.yaw_rad
    out = [f"takes {m.duration_s:.1f} s"]
    rates = {abs(c[2]) for c in m.commands if c[2] != 0}
    speeds = {abs(c[1]) for c in m.commands if c[1] != 0}
    if speeds:
        out.append(f"speed {', '.join(f'{v:g}' for v in sorted(speeds))} m/s")
    if rates:
        out.append(f"turn rate {', '.join(f'{w:.3g}' for w in sorted(rates))} rad/s reached")
    if m.distance_m:
        out.append(f"{m.distance_m:.2f} m driven")
    if ccw or cw:
        out.append(f"yaw {math.degrees(ccw):.0f} deg CCW / {math.degrees(cw):.0f} deg CW")
    if m.kind == "pause":
        out.append(
            "wheels still" + (" (the gyro's bias is measured here)" if route == "gyro" else "")
        )
    return out


@dataclass(frozen=True)
class RoutePlan(Presented):
    """The recommended recording, its command file and its protocol."""

    design: RouteDesignRun
    commands: Path
    rate_hz: float
    totals: dict[str, float]

    @property
    def warnings(self) -> tuple[str, ...]:
        """The design's warnings."""
        return self.design.warnings

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal plan --route R --json``."""
        rec = self.design.design.recommended
        return {
            "route": self.design.design.route,
            "commands": str(self.commands),
            "runs": self.design.design.recommended.runs,
            "rate_hz": self.rate_hz,
            "maneuvers": [
                m.as_dict() | {"checks": _checks(m, self.design.design.route)}
                for m in rec.maneuvers
            ],  # fmt: skip
            "totals": dict(self.totals),
            "recommended": self.design.as_dict()["recommended"],
            "seed": self.design.seed,
            "robot": self.design.robot,
            "notes": list(self.design.notes),  # the design's caveats (were dropped)
        }

    def text(self) -> str:
        """The printed protocol."""
        d = self.design.design
        rec = d.recommended
        out = Text()
        out(f"Recording protocol for the {d.route} route ({self.design.robot})")
        out(f"  {rec.label}, {rec.duration_s:.0f} s: {d.reason}")
        for note in self.design.notes:  # the design's caveats: what it assumed of the robot
            out(f"  note: {note}")
        out()
        out("Before you start:")
        if d.route == "gyro":
            out("  - record the IMU and the wheel joints (or the controller's odometry)")
        else:
            what = {"trajectory": "the tracker's poses", "slam": "the SLAM's poses on /tf",
                    "scan": "the laser scans"}[d.route]  # fmt: skip
            out(f"  - record the wheel joints (or the controller's odometry) and {what}")
        t = self.totals
        out(
            f"  - a clear floor of at least {t['floor_x_m']:.1f} m x {t['floor_y_m']:.1f} m "
            "(the path's extent, forward x left of the start pose, plus a wheelbase each side); "
            "the robot still at the start"
        )
        out()
        if rec.runs > 1:
            out(
                f"Record {rec.runs} runs, a bag each, every one from a standstill with the same "
                f"commands ({self.commands}): the trajectory fit gains more from several runs "
                "of two minutes than from one long one"
            )
        out("Drive (each step: what to check while recording):")
        for i, m in enumerate(rec.maneuvers, start=1):
            out(f"  {i:3d}. {m.label}")
            out(f"       check: {'; '.join(_checks(m, d.route))}")
        out()
        t = self.totals
        out(
            f"When done{' (each run)' if rec.runs > 1 else ''}: {t['duration_s']:.0f} s, "
            f"{t['distance_m']:.1f} m driven, "
            f"{t['yaw_ccw_deg']:.0f} deg turned CCW and {t['yaw_cw_deg']:.0f} deg CW "
            f"(the odometry's totals should agree within {100 * AMOUNT_TOLERANCE:g} %; a spin "
            "that took much longer than planned did not reach its turn rate)"
        )
        if d.route == "gyro":
            out(
                "  The gyro's total yaw should agree with the odometry's within a few per cent "
                "(the wheelbase error and the gyro's scale); a factor of about 57 is a gyro in "
                "deg/s, an opposite sign a wrong IMU axis: the gyro route refuses both"
            )
        se = ", ".join(
            f"{k} {100 * v:.3g} %" for k, v in rec.relative_std_error.items() if math.isfinite(v)
        )
        out(f"Expected after calibration: standard errors {se}")
        out(
            f"Then: odocal check BAG (is it enough?) and odocal fit BAG --method auto. "
            f"Command file: {self.commands} ({COMMAND_HEADER}: one row per command change, each "
            f"held until the next row's t; times on a {self.rate_hz:g} Hz grid)"
        )
        return str(out)


@emits_warnings
def plan_route(
    route: Route,
    robot: RobotSpec = None,
    *,
    params: str | Path | None = None,
    kinematics: Kinematics | None = None,
    noise_from: str | Path | None = None,
    targets: Sequence[str] = (),
    duration_s: float | None = None,
    validate: tuple[int, float, str] | str | Path | None = None,
    trials: int = 200,
    seed: int = 0,
    out: str | Path = DEFAULT_COMMANDS,
    rate_hz: float = DEFAULT_RATE_HZ,
    force: bool = False,
    progress: Any = None,
    speed_m_s: float | None = None,
    turn_rate_rad_s: float | None = None,
    pose_noise: MeasurementNoise | None = None,
    gyro_arw_rad_sqrt_s: float | None = None,
) -> RoutePlan:
    """Design the recording (:func:`~odocal.app.design_route.design_for_route`, the same
    arguments) and write its command file ``out`` (all or nothing: nothing is written when the
    design fails). An existing ``out`` that is not a command file is replaced only with
    ``force``."""
    out = Path(out)
    read = [noise_from] if noise_from else []
    if isinstance(validate, (str, Path)):
        read.append(validate)  # a command file driven as the validation is an input too
    outputs = OutputPlan(input_paths(robot, params, *read))
    outputs.file(out, "--out")
    if out.is_file() and not force:
        try:
            first = out.read_text(encoding="utf-8", errors="replace").split("\n", 1)[0]
        except OSError:
            first = ""
        if first.strip() != COMMAND_HEADER:
            raise InputError(
                f"--out {out}: exists and is not a command file ({COMMAND_HEADER}); give "
                "another name or --force"
            )
    if not (math.isfinite(rate_hz) and 1 <= rate_hz <= 1000):
        raise InputError(f"--rate must be between 1 and 1000 Hz, got {rate_hz!r}")
    run = design_for_route(
        route, robot, params=params, kinematics=kinematics, noise_from=noise_from,
        targets=targets, duration_s=duration_s, validate=validate, trials=trials, seed=seed,
        progress=progress, speed_m_s=speed_m_s, turn_rate_rad_s=turn_rate_rad_s,
        pose_noise=pose_noise, gyro_arw_rad_sqrt_s=gyro_arw_rad_sqrt_s,
    )  # fmt: skip
    rec = run.design.recommended
    series = command_series(rec.maneuvers, rate_hz)
    ccw = sum(m.yaw_rad[0] for m in rec.maneuvers)
    cw = sum(m.yaw_rad[1] for m in rec.maneuvers)
    believed = run.believed
    assert believed is not None
    _, path, _ = simulate_recordings(
        series, believed, believed, NonSystematicError(), MeasurementNoise(), 1, None
    )
    b = float(believed.wheelbase_m)
    extent = np.ptp(path[0, :, :2], axis=0) + 2 * b
    totals = {
        "floor_x_m": float(extent[0]),
        "floor_y_m": float(extent[1]),
        "duration_s": series.duration_s,
        "distance_m": sum(m.distance_m for m in rec.maneuvers),
        "yaw_ccw_deg": math.degrees(ccw),
        "yaw_cw_deg": math.degrees(cw),
    }
    outputs.commit({out: command_csv(series)})
    return RoutePlan(run, out, float(rate_hz), totals)
