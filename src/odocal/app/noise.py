"""``odocal noise``: the non-systematic error parameters k_r, k_l, from repeated out-and-back or
straight runs typed into RUNS.csv, or from recorded runs of repeated tracks."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.noise import NoiseEstimate, estimate_k
from ..core.checks import check_number, check_positive_float
from ..core.covariance import OdometryCovariance, odometry_covariance
from ..core.model import MeasurementNoise, Robot, WheelGeometry
from ..core.recording import Recording
from ..design.metrics import leg_heading_systematic_rad
from ..errors import InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.limits import (
    LENGTH_MIN_M,
    TRACK_LENGTH_MAX_M,
    speed_problem,
    twist_window_problem,
)
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from ..io.robot_file import load_robot, robot_yaml
from ..io.ros2_export import DEFAULT_CONTROLLER, ros2_params_yaml
from ..io.runs_csv import read_runs
from .common import (
    RobotSpec,
    input_paths,
    load_warnings,
    refuse_still_runs,
    require_robot,
    resolve_robot,
)
from .measured import MeasuredRobot, measure_robot

__all__ = ["noise", "noise_recordings", "RecordedNoiseResult", "cruise_speed_m_s"]


def noise(
    runs_csv: str | Path,
    robot: RobotSpec = None,
    *,
    params: str | Path | WheelGeometry | None = None,
    track: str = "out-and-back",
    distance_m: float,
    force: bool = False,
) -> NoiseEstimate:
    """Read RUNS.csv (direction 'fwd') of repeated ``track`` runs ('out-and-back' or 'straight'
    of ``distance_m``) and estimate k (m). The wheelbase is the robot's TRUE one (nominal x E_b);
    the systematic curvature of the forward path comes from ROBOT.yaml's systematic errors.
    ``force``: estimate even when the runs look dominated by a systematic part (a warning)."""
    distance_m = _distance("distance_m", distance_m)
    require_robot(robot, "its wheelbase and systematic errors set the estimate of k")
    r = resolve_robot(robot, params)
    notes: list[str] = []
    runs = read_runs(runs_csv, directions=("fwd",), warnings=notes)
    curvature = float(leg_heading_systematic_rad(r, 1.0))  # rad per metre of believed travel
    est = estimate_k(
        runs,
        track,
        distance_m,
        float(r.true_geometry.wheelbase_m),
        r.measurement,
        curvature_rad_per_m=curvature,
        strict=not force,
    )
    return replace(est, warnings=(*notes, *est.warnings)) if notes else est


def _distance(name: str, value: float) -> float:
    """A driven distance (m) within the flags' limits (odocal.io.limits)."""
    return check_number(
        name, value, at_least=LENGTH_MIN_M, at_most=TRACK_LENGTH_MAX_M, hint=" m (check the units)"
    )


def cruise_speed_m_s(recordings: Sequence[Recording], geometry: WheelGeometry) -> float:
    """The speed the runs drive at: the 90th percentile of the axle-centre speed (m/s) over the
    samples where the robot moves (speed above 10 % of the runs' top speed)."""
    speeds = []
    for r in recordings:
        dt = np.diff(np.asarray(r.time_s, dtype=float))
        ds = 0.25 * (
            np.diff(r.wheel_angle_right_rad) * geometry.diameter_right_m
            + np.diff(r.wheel_angle_left_rad) * geometry.diameter_left_m
        )
        ok = dt > 0
        speeds.append(np.abs(ds[ok] / dt[ok]))
    v = np.concatenate(speeds) if speeds else np.zeros(0)
    if v.size == 0 or not np.any(v > 0):
        raise InputError("the runs do not move: no speed for the covariances (give --speed)")
    return float(np.percentile(v[v > 0.1 * v.max()], 90))


@dataclass(frozen=True)
class RecordedNoiseResult:
    """k from recorded runs, the robot measured with it, and the files written.

    ``covariance`` is set when ``--ros2`` asked for the controller file."""

    measured: MeasuredRobot
    nominal: WheelGeometry
    covariance: OdometryCovariance | None
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The warnings of the k estimate and of the trajectory fit behind the systematic errors."""
        return tuple(self.measured.noise.warnings) + tuple(self.measured.fit.warnings)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal noise RUN_OR_DIR... --json``: the k estimate (as for RUNS.csv:
        ``k_sum_m``, ``k_sum_ci95``, ``k_r_m``, ``k_l_m``, ...) plus ``robot`` (the measured
        robot) and ``ros2_covariance`` when written."""
        out = self.measured.noise.as_dict()
        out["robot"] = self.measured.as_dict()
        out["ros2_covariance"] = None if self.covariance is None else self.covariance.as_dict()
        out["written"] = [str(p) for p in self.written]
        return out


def _nominal(robot: Robot | None, recordings: Sequence[Recording]) -> WheelGeometry:
    """The robot's nominal geometry, else the runs' most common ran-with parameters."""
    if robot is not None:
        return robot.nominal
    known = [r.ran_with for r in recordings if r.ran_with is not None]
    if not known:
        raise InputError(
            "the nominal geometry is unknown (no metadata in the recordings): give --robot"
        )
    return max(set(known), key=known.count)


def _instrument(
    robot: Robot | None, sigma_xy_m: float | None, sigma_theta_deg: float | None
) -> MeasurementNoise | None:
    """The instrument: the sigmas given, else the robot's measurement, else None (the tracker's
    jitter)."""
    if sigma_xy_m is not None or sigma_theta_deg is not None:
        return MeasurementNoise.from_degrees(sigma_xy_m or 0.0, sigma_theta_deg or 0.0)
    if robot is not None and not robot.measurement.is_zero:
        return robot.measurement
    return None


def _covariance(
    measured: MeasuredRobot,
    recordings: Sequence[Recording],
    speed_m_s: float | None,
    distance_m: float,
    window_s: float,
) -> OdometryCovariance:
    """The controller's covariances from the measured wheel noise, at ``speed_m_s`` (default:
    the runs' cruise speed)."""
    geometry = measured.robot.true_geometry
    k = measured.robot.nonsystematic
    speed = speed_m_s if speed_m_s is not None else cruise_speed_m_s(recordings, geometry)
    return odometry_covariance(
        k.k_r_m,
        k.k_l_m,
        float(geometry.wheelbase_m),
        speed_m_s=speed,
        distance_m=distance_m,
        window_s=window_s,
    )


def noise_recordings(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotSpec = None,
    sigma_xy_m: float | None = None,
    sigma_theta_deg: float | None = None,
    force: bool = False,
    robot_out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = DEFAULT_CONTROLLER,
    speed_m_s: float | None = None,
    distance_m: float = 1.0,
    window_s: float = 0.2,
    ticks_per_rev: float | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
) -> RecordedNoiseResult:
    """k_r, k_l from recorded runs of repeated tracks (OptiOdom folders, run CSVs, bags; the
    topics and joints of bags from ``bag``).

    ``robot``: ROBOT.yaml for the nominal geometry (default: the recordings' metadata) and the
    instrument (its ``measurement``); ``sigma_xy_m``/``sigma_theta_deg`` give the instrument
    (per measured final pose) and override it; without either, the tracker's jitter is used.
    The geometry (and the systematic errors) come from the trajectory fit of the runs. Writes the
    measured robot to ``robot_out`` (ROBOT.yaml) and a ros2_control file with covariances to
    ``ros2`` (speed ``speed_m_s``, default the runs' cruise speed; pose after ``distance_m``;
    velocity over ``window_s``)."""
    paths = [paths] if isinstance(paths, (str, Path)) else list(paths)
    distance_m = _distance("distance_m", distance_m)
    for name, value, problem in (
        ("speed_m_s", speed_m_s, speed_problem),
        ("window_s", window_s, twist_window_problem),
    ):
        if value is not None:
            said = problem(check_positive_float(name, value))
            if said:
                raise InputError(said, field=name)
    plan = OutputPlan([*map(Path, paths), *input_paths(robot)])
    if robot_out is not None:
        plan.file(robot_out, "--robot-out")
    if ros2 is not None:
        plan.file(ros2, "--ros2")
    recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, bag=bag)
    require_ground_truth(recordings, "odocal noise on recorded runs")
    refuse_still_runs(recordings)
    rob = load_robot(robot) if robot else None
    nominal = _nominal(rob, recordings)
    measurement = _instrument(rob, sigma_xy_m, sigma_theta_deg)
    measured = measure_robot(recordings, nominal, measurement=measurement, force=force)
    covariance = None
    contents: dict[Path, str] = {}
    if ros2 is not None:
        covariance = _covariance(measured, recordings, speed_m_s, distance_m, window_s)
        contents[Path(ros2)] = ros2_params_yaml(
            measured.robot.true_geometry,
            nominal,
            controller_name,
            covariance=covariance,
            method="odocal noise",
        )
    if robot_out is not None:
        contents[Path(robot_out)] = robot_yaml(measured.robot, measured.describe())
    written = tuple(plan.commit(contents)) if contents else ()
    return RecordedNoiseResult(measured, nominal, covariance, load_warnings(recordings), written)
