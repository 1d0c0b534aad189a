"""``odocal design --route R``: what to record for a bag route (docs/design.md, "Designing a
recording for a bag route")."""

from __future__ import annotations

import dataclasses
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.relative_motions import RelativeMotions, stack_motions, wheel_increments
from ..calibration.slam_noise import slam_noise_model
from ..calibration.trajectory import fit_trajectory
from ..core.checks import check_seed
from ..core.maneuvers import GyroNoise, Maneuver, spin, straight
from ..core.model import (
    KINEMATICS,
    Kinematics,
    MeasurementNoise,
    Robot,
    SystematicError,
    WheelGeometry,
)
from ..core.plausibility import track_size_problem
from ..core.recording import Recording
from ..core.skid_steer import SkidSteerModel
from ..design.route import (
    ROUTES,
    TARGET_PARAMETERS,
    Route,
    RouteDesign,
    RouteNoise,
    RouteSpec,
    Target,
    default_noise,
    design_route,
    target_problem,
)
from ..errors import CalibrationError, InputError, ModelError
from ..io.outputs import OutputPlan
from .common import RobotSpec, input_paths, refuse_still_runs, resolve_robot, robot_label
from .text import Presented, Text, emits_warnings, written_lines

__all__ = ["RouteDesignRun", "design_for_route", "parse_target", "polygon_validation"]

#: A noise bag whose fitted wheel diameters or wheelbase differ from the robot file's by more
#: than this fraction is of another robot (or the robot file is wrong).
OTHER_ROBOT_FRACTION = 0.15
#: A skid-steer robot's wheels slip: its fitted diameters may be this fraction off.
SKID_DIAMETER_FRACTION = 0.35
#: A --validate command file must drive at least this far (m): the predicted drift is per
#: distance, over pieces of 1 m of path at the least (a spin in place has no piece).
MIN_VALIDATION_M = 2.0
#: The largest angle random walk (deg/sqrt(h)) taken for a gyro: beyond it a unit slip.
MAX_GYRO_ARW_DEG_SQRT_H = 100.0
#: The most Monte Carlo trials per confirmed candidate (more ran out of memory: a traceback).
MAX_ROUTE_TRIALS = 2000

_TARGET = re.compile(r"^\s*([a-z_]+)\s*=\s*([0-9.eE+-]+)\s*(%|mm|m)?\s*$")


def parse_target(text: str) -> Target:
    """'wheelbase=0.2%' (relative), 'wheel_diameter=0.05mm' or 'wheelbase=0.001m' (absolute,
    m), 'diameter_ratio=0.0005' (unitless). InputError on anything else."""
    m = _TARGET.match(text)
    hint = (
        f"--target-std-error expects NAME=VALUE with NAME one of {', '.join(TARGET_PARAMETERS)} "
        f"and VALUE a percentage (0.2%) or a length (0.5mm, 0.001m), got {text!r}"
    )
    if not m:
        raise InputError(hint)
    name, number, unit = m.groups()
    try:
        value = float(number)
    except ValueError:
        raise InputError(hint) from None
    if name not in TARGET_PARAMETERS or not (math.isfinite(value) and value > 0):
        raise InputError(hint)
    if unit == "%":
        return Target(name, value / 100.0, True)
    if name == "diameter_ratio":
        if unit is not None:
            raise InputError(f"diameter_ratio has no unit: give a fraction or a %, got {text!r}")
        return Target(name, value, False)
    if unit is None:
        raise InputError(f"{hint} (a length needs its unit)")
    return Target(name, value / 1000.0 if unit == "mm" else value, False)


def polygon_validation(
    sides: int, side_m: float, direction: str, speed: float, rate: float
) -> tuple[Maneuver, ...]:
    """A polygon validation driving (``--validate SIDES:LENGTH:DIRECTION``) as maneuvers: each
    side a straight, each corner a spin on the spot of the exterior angle."""
    turn = (1 if direction.lower() == "ccw" else -1) * 2 * math.pi / sides
    return tuple(m for _ in range(sides) for m in (straight(side_m, speed), spin(turn, rate)))


@dataclass(frozen=True)
class RouteDesignRun(Presented):
    """A route design, how it was made (seed, robot, kinematics), the figures written and the
    geometry it assumed (``true``: what the robot drives with; ``believed``: what its
    controller runs with)."""

    design: RouteDesign
    seed: int
    robot: str
    kinematics: Kinematics
    seconds: float = math.nan
    written: tuple[Path, ...] = ()
    notes: tuple[str, ...] = ()
    true: WheelGeometry | None = None
    believed: WheelGeometry | None = None

    @property
    def warnings(self) -> tuple[str, ...]:
        """The design's warnings."""
        return tuple(self.design.warnings)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal design --route R --json``."""
        return self.design.as_dict() | {
            "seed": self.seed,
            "robot": self.robot,
            "kinematics": self.kinematics,
            "notes": list(self.notes),
            "geometry_assumed": {
                "true": None if self.true is None else self.true.as_dict(),
                "ran_with": None if self.believed is None else self.believed.as_dict(),
            },
            "written": [str(p) for p in self.written],
        }

    def text(self) -> str:
        """The text of ``odocal design --route R``."""
        d = self.design
        rec = d.recommended
        out = Text()
        out(f"What to record for the {d.route} route ({self.robot}, seed {self.seed})")
        out(f"  noise: {_noise_words(d.noise, d.route)}")
        for note in self.notes:
            out(f"  note: {note}")
        out()
        out(f"Recommended: {rec.label}, {rec.duration_s:.0f} s ({d.reason})")
        if rec.runs > 1:
            out(f"  {rec.runs} runs (a bag each, from a standstill), each of:")
        for i, m in enumerate(rec.maneuvers, start=1):
            out(f"  {i:3d}. {m.label}")
        out()
        rows: list[tuple] = [("parameter", "predicted SE", "relative", "Monte Carlo SE")]
        mc = rec.monte_carlo
        for k, v in rec.predicted_std_error.items():
            real = None if mc is None else mc.realised_std_error.get(k)
            unit = "" if k == "diameter_ratio" else " m"
            rows.append(
                (
                    _NAMES.get(k, k) if self.kinematics == "differential" else _SKID.get(k, k),
                    f"{v:.3g}{unit}",
                    f"{100 * rec.relative_std_error[k]:.3g} %",
                    "-" if real is None else f"{real:.3g}{unit}",
                )
            )
        out.table(rows)
        out(
            f"  predicted post-calibration drift on the validation driving: "
            f"{rec.drift_percent_per_10m:.3g} % of distance (uncalibrated: "
            f"{d.uncalibrated_drift_percent:.3g} %)"
        )
        if mc is not None:
            out(
                f"  (Monte Carlo: {mc.trials} simulated recordings, {mc.simulated}; their "
                f"calibrations drift {mc.realised_drift_percent_per_10m:.3g} % on the validation "
                "driving)"
            )
        out()
        out("Candidates (predicted):")
        rows = [("mix", "duration_s", *(f"SE {k} %" for k in rec.relative_std_error), "drift %")]
        for c in d.candidates:
            rows.append(
                (
                    c.label,
                    f"{c.duration_s:.0f}",
                    *(f"{100 * v:.3g}" for v in c.relative_std_error.values()),
                    f"{c.drift_percent_per_10m:.3g}",
                )
            )
        out.table(rows)
        out()
        out("Not simulated: " + "; ".join(d.not_estimated))
        if math.isfinite(self.seconds):
            out(f"({self.seconds:.1f} s)")
        written_lines(out, self.written)
        out(f"Next: odocal plan --route {d.route} ... writes the command file and the protocol")
        return str(out)


_NAMES = {"wheelbase": "wheelbase", "wheel_diameter": "wheel diameter", "diameter_ratio": "D_R/D_L"}
_SKID = _NAMES | {"wheelbase": "effective track"}


def _effective_track_robot(r: Robot) -> tuple[Robot, list[str]]:
    """A skid-steer robot as the differential drive of its effective track
    (:class:`~odocal.core.skid_steer.SkidSteerModel`: the robot file's track x the
    wheel_separation_multiplier it runs with), and what that assumes."""
    nominal, ran = r.nominal, r.believed_geometry
    multiplier = float(ran.wheelbase_m / nominal.wheelbase_m)
    model = SkidSteerModel.from_geometry(nominal, multiplier)
    effective = dataclasses.replace(nominal, wheelbase_m=model.track_m)
    notes = [
        f"skid-steer: designed for the effective track {model.track_m:.4g} m (track "
        f"{float(nominal.wheelbase_m):.4g} m x multiplier {multiplier:.4g}) as a differential "
        "drive's wheelbase ('wheelbase' below is the effective track); its dependence on the "
        "turn rate and the lateral slip are not simulated: spin at the rates the robot will use"
    ]
    if not r.ran_with_stated or multiplier == 1.0:
        notes.append(
            "skid-steer without a wheel_separation_multiplier: the effective track is taken as "
            "the physical one; skid-steer robots typically turn as if 1.5 to 2 times wider "
            "(docs/skid-steer.md), which lengthens the spins' wheel travel"
        )
    return dataclasses.replace(r, nominal=effective, believed=None, kinematics="skid-steer"), notes


def _noise_words(n: RouteNoise, route: Route) -> str:
    parts = [f"k {n.wheel.k_r_m:.3g}/{n.wheel.k_l_m:.3g} m"]
    if route == "gyro":
        parts.append(f"gyro {n.gyro.arw_rad_sqrt_s:.3g} rad/sqrt(s)")
    else:
        parts.append(
            f"{route} pose {1000 * n.pose.sigma_xy_m:.3g} mm, "
            f"{math.degrees(n.pose.sigma_theta_rad):.3g} deg"
        )
    return ", ".join(parts) + f" ({n.source})"


def _other_robot(
    g: WheelGeometry, robot: WheelGeometry, physical_track_m: float | None = None
) -> str | None:
    """The parameters of ``g`` more than :data:`OTHER_ROBOT_FRACTION` from the robot file's
    ``robot``, in words, or None. A skid-steer robot (``physical_track_m`` given) turns as if
    wider and its wheels slip: its track may be :data:`~odocal.app.fit_skid.
    TRACK_MULTIPLIER_RANGE` times the physical one, its diameters
    :data:`SKID_DIAMETER_FRACTION` off."""
    from .fit_skid import TRACK_MULTIPLIER_RANGE

    frac = OTHER_ROBOT_FRACTION if physical_track_m is None else SKID_DIAMETER_FRACTION
    pairs = [
        ("wheel diameter right", g.diameter_right_m, robot.diameter_right_m),
        ("wheel diameter left", g.diameter_left_m, robot.diameter_left_m),
    ]
    off = [(k, a, b) for k, a, b in pairs if abs(a / b - 1) > frac]
    words = [f"{k} {a:.4g} m (robot file {b:.4g} m)" for k, a, b in off]
    if physical_track_m is None:
        if abs(g.wheelbase_m / robot.wheelbase_m - 1) > frac:
            words.append(f"wheelbase {g.wheelbase_m:.4g} m (robot file {robot.wheelbase_m:.4g} m)")
    else:
        lo, hi = TRACK_MULTIPLIER_RANGE
        if not lo <= g.wheelbase_m / physical_track_m <= hi:
            words.append(
                f"effective track {g.wheelbase_m:.4g} m ({g.wheelbase_m / physical_track_m:.3g} x "
                f"the robot file's {physical_track_m:.4g} m, outside {lo:g}-{hi:g})"
            )
    if not words:
        return None
    return ", ".join(words) + f" (more than {100 * frac:.0f} % from the robot file)"


#: The intervals (s) a noise run is cut into for the noise's estimate.
INTERVAL_S = 1.0


def _interval_motions(rec: Recording, every_s: float) -> RelativeMotions:
    """A run with ground truth as relative motions over intervals of about ``every_s``: the
    wheel rotations (totals and increments) and the truth's motion in its frame at each
    interval's start."""
    t = np.asarray(rec.time_s, float)
    gt = np.asarray(rec.ground_truth, float)
    # the edges at samples with a truth (a truth stamped at its own instants, e.g. a skid-steer
    # log's ICP, is NaN between them)
    ok = np.flatnonzero(np.all(np.isfinite(gt), axis=1))
    tv = t[ok]
    edges = ok[np.unique(np.minimum(np.searchsorted(tv, np.arange(tv[0], tv[-1], every_s)),
                                    len(ok) - 1))]  # fmt: skip
    edges = np.append(edges, ok[-1]) if edges[-1] != ok[-1] else edges
    i, j = edges[:-1], edges[1:]
    c, s = np.cos(gt[i, 2]), np.sin(gt[i, 2])
    dx, dy = gt[j, 0] - gt[i, 0], gt[j, 1] - gt[i, 1]
    motion = np.column_stack([c * dx + s * dy, -s * dx + c * dy, gt[j, 2] - gt[i, 2]])
    right, left = rec.wheel_angle_right_rad, rec.wheel_angle_left_rad
    inc = wheel_increments(t, right, left, t[i], t[j])
    return RelativeMotions(right[j] - right[i], left[j] - left[i], motion, inc, t[i], t[j])


def _gyro_noise(recs: Sequence[Recording], believed: WheelGeometry) -> tuple[GyroNoise, str] | None:
    """The gyro's angle random walk and bias from the still periods of runs with a gyro heading
    (wheels still for 2 s or more): the bias is the still rate's mean, the random walk its
    batch-means standard error times the square root of the still time
    (:func:`~odocal.calibration.gyro.still_bias`, what the gyro route uses); None without one."""
    from ..calibration.gyro import still_bias, still_intervals
    from ..core.odometry import dead_reckon

    rates, times, spans = [], [], []
    for rec in recs:
        if rec.gyro_yaw_rad is None or len(rec.time_s) < 3:
            continue
        t = np.asarray(rec.time_s, float)
        odo = dead_reckon(rec.wheel_angle_right_rad, rec.wheel_angle_left_rad, believed)
        speed = np.hypot(*np.gradient(odo[:, :2], t, axis=0).T)
        still = still_intervals(t, np.gradient(odo[:, 2], t), speed, min_duration_s=2.0)
        if still:
            rates.append(np.gradient(np.asarray(rec.gyro_yaw_rad, float), t))
            times.append(t)
            spans.append(still)
    if not spans:
        return None
    est, se, n = [], [], 0
    seconds = 0.0
    for r, t, still in zip(rates, times, spans, strict=True):
        e, s_e, k, sec = still_bias(t, r, still)
        if e is not None and s_e is not None and math.isfinite(s_e):
            est.append(e)
            se.append(s_e**2 * sec)  # arw^2 from each run's still time
            n += k
            seconds += sec
    if not se:
        return None
    arw = math.sqrt(float(np.mean(se)))
    bias = float(np.mean(est))
    words = f"{arw:.3g} rad/sqrt(s), bias {bias:+.3g} rad/s (from {seconds:.0f} s standing still)"
    return GyroNoise(arw, bias), words


def _stated(
    noise: RouteNoise,
    route: Route,
    pose: MeasurementNoise | None,
    arw: float | None,
) -> RouteNoise:
    """``noise`` with the parts the user stated (the route's pose noise, the gyro's random
    walk) replacing the defaults or the measured ones."""
    said = []
    if pose is not None:
        if route == "gyro":
            raise InputError("--sigma-xy-m / --sigma-theta-deg: the gyro route measures no pose")
        # a part left at zero (not given) keeps the default or the measured one
        kept = MeasurementNoise(
            pose.sigma_xy_m or noise.pose.sigma_xy_m,
            pose.sigma_theta_rad or noise.pose.sigma_theta_rad,
        )
        noise = dataclasses.replace(noise, pose=kept)
        said.append(f"{route} pose noise stated")
    if arw is not None:
        if route != "gyro":
            raise InputError("--gyro-arw-deg-per-sqrt-h: only with --route gyro")
        deg_h = math.degrees(arw) * 60.0  # the flag's unit, deg/sqrt(h)
        if not (math.isfinite(arw) and arw > 0 and deg_h <= MAX_GYRO_ARW_DEG_SQRT_H):
            raise InputError(
                f"--gyro-arw-deg-per-sqrt-h must be > 0 and at most "
                f"{MAX_GYRO_ARW_DEG_SQRT_H:g} deg/sqrt(h) (a MEMS gyro's is about 0.1-10), "
                f"got {deg_h:.6g}"
            )
        noise = dataclasses.replace(noise, gyro=dataclasses.replace(noise.gyro, arw_rad_sqrt_s=arw))
        said.append("gyro random walk stated")
    if not said:
        return noise
    return dataclasses.replace(noise, source=f"{noise.source}; {', '.join(said)}")


def _noise_from_bag(
    path: str | Path, robot: Robot, route: Route, physical_track_m: float | None
) -> tuple[RouteNoise, list[str], WheelGeometry]:
    """The route's noise measured from a bag (or run file) the user has, and the geometry
    fitted to it: the trajectory fit of its truth gives the geometry; the wheels' k and the
    truth's pose noise are estimated apart from the residuals of 1 s intervals after a
    relative-motion fit (:func:`~odocal.calibration.slam_noise.slam_noise_model`, what
    ``check`` does for a SLAM truth). A bag
    whose fitted geometry is not the robot file's is refused by name (``physical_track_m``: a
    skid-steer robot's, :func:`_other_robot`)."""
    from ..io.recordings import load_recordings  # files only here

    notes: list[str] = []
    if physical_track_m is not None:
        return _noise_from_skid_bag(path, robot, route, physical_track_m)
    try:
        recs = load_recordings([path], ran_with=robot.believed_geometry, warnings=notes)
    except (CalibrationError, ModelError) as e:
        raise InputError(f"--noise-from {path}: {e}") from None
    for rec in recs:  # the parameters its controller ran with, where the run says them
        ran = rec.ran_with
        if ran is None or ran == robot.believed_geometry:
            continue
        said = _other_robot(ran, robot.believed_geometry, None)
        if said:
            raise InputError(
                f"--noise-from {path}: a run of another robot? its controller ran with {said}; "
                "nothing written"
            )
    recs = [r for r in recs if r.ground_truth is not None]
    try:
        refuse_still_runs(recs)  # a fit of it returns the start: no geometry, no noise
    except InputError as e:
        raise InputError(f"--noise-from {path}: {e}") from None
    if not recs:
        raise InputError(
            f"--noise-from {path}: no ground truth (a tracker, SLAM or scan pose) to measure the "
            "noise against; nothing written"
        )
    try:
        fit = fit_trajectory(recs, nominal=robot.nominal)
    except CalibrationError as e:
        raise InputError(f"--noise-from {path}: the trajectory fit failed: {e}") from None
    from .check import check_loaded

    # what 'fit' refuses (only straight lines: b anywhere) is no geometry for the design's truth
    blind = check_loaded(recs, fit.geometry, robot).check.degeneracies
    found = [g.message for g in blind if g.severity == "blind"]
    if found:
        raise InputError(
            f"--noise-from {path}: the run cannot show the robot's geometry: {found[0]}; "
            "nothing written"
        )
    return _measured_noise(path, recs, fit.geometry, robot, route, physical_track_m, notes)


def _noise_from_skid_bag(
    path: str | Path, robot: Robot, route: Route, physical_track_m: float
) -> tuple[RouteNoise, list[str], WheelGeometry]:
    """:func:`_noise_from_bag` of a skid-steer robot: the bag read and fitted as ``fit
    --kinematics skid-steer`` reads and fits it (its truth's clock offset estimated and applied;
    the effective track and a wheel scale per side), not by the differential trajectory fit (an
    ICP truth stamped late and the skid made that 'non-physical', or wheels 50 % apart)."""
    from ..io.bag_options import NO_BAG_OPTIONS
    from ..io.bags import is_bag
    from .check import _skid_covariance
    from .fit_skid import _refuse_no_turning, read_skid_logs, skid_recordings

    if not is_bag(path):
        raise InputError("--noise-from: a skid-steer robot's noise is measured from a bag", path)
    try:
        logs = read_skid_logs([path], NO_BAG_OPTIONS, robot)
        _refuse_no_turning(logs, robot.nominal)
        recs, offsets = skid_recordings(logs)
    except (CalibrationError, ModelError, InputError) as e:
        raise InputError(f"--noise-from {path}: {e}") from None
    geometry, _, why = _skid_covariance(logs, robot.nominal, offsets)
    if geometry is None:
        raise InputError(f"--noise-from {path}: the skid-steer fit failed: {why}")
    notes = [
        f"--noise-from {Path(path).name}: clock offset of the {o.label}: {o.offset_s:+.4f} s "
        f"({o.found}; applied)"
        for o in offsets
    ]
    gyro_recs: Sequence[Recording] = ()
    if route == "gyro":  # the gyro heading of the bag's runs as the differential route reads them
        from ..io.recordings import load_recordings

        try:
            gyro_recs = load_recordings([path], ran_with=robot.believed_geometry)
        except (CalibrationError, ModelError, InputError):
            gyro_recs = ()
    return _measured_noise(
        path, recs, geometry, robot, route, physical_track_m, notes, gyro_recs=gyro_recs
    )


def _measured_noise(
    path: str | Path,
    recs: Sequence[Recording],
    geometry: WheelGeometry,
    robot: Robot,
    route: Route,
    physical_track_m: float | None,
    notes: list[str],
    *,
    gyro_recs: Sequence[Recording] | None = None,
) -> tuple[RouteNoise, list[str], WheelGeometry]:
    """The rest of :func:`_noise_from_bag`: a fitted ``geometry`` of another robot refused, the
    noise measured from the runs ``recs`` (the gyro's from ``gyro_recs``, default ``recs``)."""
    said = _other_robot(geometry, robot.nominal, physical_track_m)
    if said:
        raise InputError(
            f"--noise-from {path}: a bag of another robot? its wheels and truth give {said}; "
            "nothing written"
        )
    base = default_noise(route, robot)
    # the noise of the wheels and of the truth, separately, from the intervals' residuals after
    # a relative-motion fit: what check estimates for a SLAM truth (calibration.slam_noise)
    motions = stack_motions([_interval_motions(rec, INTERVAL_S) for rec in recs])
    measured = slam_noise_model(motions, None)
    words = measured.description.replace("SLAM pose", "truth pose")
    words = words.replace("SLAM intervals", f"{INTERVAL_S:g} s intervals")
    if "could not give it" in words:
        notes.append(f"--noise-from {Path(path).name}: {words}")
    wheel = measured.model.wheel
    pose = measured.model.measurement
    source = f"measured from {Path(path).name}: {words}"
    gyro = base.gyro
    if route == "gyro":
        pose = base.pose
        measured_gyro = _gyro_noise(
            recs if gyro_recs is None else gyro_recs, robot.believed_geometry
        )
        if measured_gyro is None:
            notes.append(
                f"--noise-from {Path(path).name}: no gyro heading with still periods of 2 s or "
                "more; the gyro's noise stays the default"
            )
        else:
            gyro, words_g = measured_gyro
            source += f"; gyro {words_g}"
    noise = dataclasses.replace(base, wheel=wheel, pose=pose, gyro=gyro, source=source)
    return noise, notes, geometry


@emits_warnings
def design_for_route(
    route: Route,
    robot: RobotSpec = None,
    *,
    params: str | Path | None = None,
    kinematics: Kinematics | None = None,
    noise_from: str | Path | None = None,
    targets: Sequence[str | Target] = (),
    duration_s: float | None = None,
    validate: tuple[int, float, str] | str | Path | None = None,
    trials: int = 200,
    seed: int = 0,
    plot: str | Path | None = None,
    progress: Any = None,
    speed_m_s: float | None = None,
    turn_rate_rad_s: float | None = None,
    pose_noise: MeasurementNoise | None = None,
    gyro_arw_rad_sqrt_s: float | None = None,
) -> RouteDesignRun:
    """Design the recording for ``route`` (:func:`odocal.design.route.design_route`) for
    ``robot``: noise from ROBOT.yaml and the route's defaults or measured from ``noise_from``;
    ``targets`` ('wheelbase=0.2%' ...); at most ``duration_s`` of driving at ``speed_m_s`` and
    spins at ``turn_rate_rad_s`` (what is safe for the robot); ``validate`` a polygon
    (sides, side_m, direction) or a command file (t,v,omega) the calibrated robot should drive
    well; ``trials`` Monte Carlo
    trials per confirmed candidate; figures into the folder ``plot``. InputError (nothing
    written) for a target the route cannot see or no allowed recording reaches, a validation
    driving the model cannot simulate, a noise bag of another robot."""
    import time

    start = time.perf_counter()
    if route not in ROUTES:
        raise InputError(f"--route must be one of {', '.join(ROUTES)}, got {route!r}")
    seed = check_seed("seed", seed)
    parsed = tuple(t if isinstance(t, Target) else parse_target(t) for t in targets)
    named = [t.parameter for t in parsed]
    twice = sorted({n for n in named if named.count(n) > 1})
    if twice:
        raise InputError(
            f"--target-std-error {', '.join(twice)} given more than once: give one target per "
            "parameter"
        )
    problem = target_problem(route, parsed)
    if problem:
        raise InputError(problem)
    if duration_s is not None and not (math.isfinite(duration_s) and 0 < duration_s <= 3600):
        raise InputError(f"--duration must be > 0 and at most 3600 s, got {duration_s!r}")
    if not 2 <= trials <= MAX_ROUTE_TRIALS:
        raise InputError(
            f"--trials with --route must be 2 to {MAX_ROUTE_TRIALS} (each trial simulates and "
            f"calibrates a whole recording: 5000 took 3.5 GB and 97 s), got {trials}"
        )
    read = [noise_from] if noise_from else []
    if isinstance(validate, (str, Path)):
        read.append(validate)
    plan = OutputPlan(input_paths(robot, params, *read))
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    r = resolve_robot(robot, params)
    kin = kinematics or r.kinematics
    if kin not in KINEMATICS:
        raise InputError(f"--kinematics must be one of {', '.join(KINEMATICS)}, got {kin!r}")
    notes: list[str] = []
    physical = float(r.nominal.wheelbase_m)
    if kin == "skid-steer":
        r, more = _effective_track_robot(r)
        if noise_from is None:
            notes += more
        else:  # the noise run measures the track (below)
            notes.append(
                "skid-steer: designed for the effective track the noise run shows, as a "
                "differential drive's wheelbase ('wheelbase' below is the effective track); its "
                "dependence on the turn rate and the lateral slip are not simulated"
            )
    if r.systematic == type(r.systematic)() and noise_from is None:
        notes.append(
            "ROBOT.yaml gives no systematic errors: the design linearises at the nominal "
            "geometry (the standard errors hardly depend on the errors)"
        )
    spec_speed = RouteSpec().speed_m_s if speed_m_s is None else float(speed_m_s)
    spec_rate = RouteSpec().turn_rate_rad_s if turn_rate_rad_s is None else float(turn_rate_rad_s)
    if not (math.isfinite(spec_speed) and 0.01 <= spec_speed <= 5.0):
        raise InputError(f"--speed must be between 0.01 and 5 m/s, got {spec_speed!r}")
    if not (math.isfinite(spec_rate) and 0.05 <= spec_rate <= 5.0):
        raise InputError(f"--turn-rate must be between 0.05 and 5 rad/s, got {spec_rate!r}")
    validation: tuple[Maneuver, ...] | None = None
    b = float(r.believed_geometry.wheelbase_m)
    if isinstance(validate, (str, Path)):
        from ..io.commands import read_commands

        drive = read_commands(validate, "--validate")
        if drive.distance_m < MIN_VALIDATION_M:
            raise InputError(
                f"--validate: the commands drive {drive.distance_m:.3g} m in all; the predicted "
                f"drift is per distance and needs at least {MIN_VALIDATION_M:g} m of driving",
                validate,
            )
        validation = (drive,)
    elif validate is not None:
        sides, side, direction = validate
        problem = track_size_problem(b, float(side), "validation")
        if problem:
            raise InputError(f"--validate: the model cannot simulate this driving: {problem}")
        validation = polygon_validation(sides, float(side), direction, spec_speed, spec_rate)
    if noise_from is not None:
        noise, more, fitted = _noise_from_bag(
            noise_from, r, route, physical if kin == "skid-steer" else None
        )
        notes += more
        # the robot as the bag shows it: the fit is the truth, the controller's the belief
        belief = r.believed_geometry
        if _other_robot(fitted, belief, None):
            notes.append(
                "the robot file's parameters are far from what the noise run shows (more than "
                f"{100 * OTHER_ROBOT_FRACTION:.0f} %): the design assumes the robot drives with "
                "the fitted ones (odocal fit that run, or state the controller's multipliers)"
            )
            belief = fitted
        # (E_d is the absolute diameter ratio: the fitted one, about the fit's mean diameter)
        truth = SystematicError.between(fitted, fitted)
        r = dataclasses.replace(r, nominal=fitted, systematic=truth, believed=belief)
        g = fitted
        notes.append(
            f"the geometry fitted to {Path(noise_from).name} is the design's true geometry: "
            f"wheel diameters {g.diameter_right_m:.4g} / {g.diameter_left_m:.4g} m, "
            f"{'effective track' if kin == 'skid-steer' else 'wheelbase'} {g.wheelbase_m:.4g} m"
        )
    else:
        noise = default_noise(route, r, kin)
    noise = _stated(noise, route, pose_noise, gyro_arw_rad_sqrt_s)
    try:
        spec = RouteSpec(
            route=route, max_duration_s=duration_s, targets=parsed, validation=validation,
            trials=trials, speed_m_s=spec_speed, turn_rate_rad_s=spec_rate,
        )  # fmt: skip
        result = design_route(r, spec, noise, np.random.default_rng(seed), progress=progress)
    except (CalibrationError, ModelError) as e:
        raise InputError(f"design --route {route}: {e}; nothing written") from None
    written: tuple[Path, ...] = ()
    if plot is not None:
        from ..plot.route import route_figures

        figs = route_figures(result)
        written = tuple(plan.commit({Path(plot) / k: v for k, v in figs.items()}))
    label = robot_label(robot, params)
    return RouteDesignRun(
        result, seed, label, kin, time.perf_counter() - start, written, tuple(notes),
        r.true_geometry, r.believed_geometry,
    )  # fmt: skip
