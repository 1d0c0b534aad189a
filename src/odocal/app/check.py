"""``odocal check``: is this log enough? What the recorded motion lets a fit see."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from ..calibration.fit_settings import DEFAULT_TRAJECTORY, TrajectorySettings
from ..calibration.identifiability import (
    MAX_BLOCKS_PER_RUN,
    Degeneracy,
    LogCheck,
    NoiseModel,
    judge,
    log_information,
    with_prediction,
)
from ..calibration.relative_motions import stack_motions
from ..calibration.slam_bag import SlamBag
from ..calibration.slam_noise import SLAM_POSE_NOISE, slam_noise_model
from ..calibration.topup import TopUp, find_top_up
from ..core.model import Kinematics, Robot, WheelGeometry
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.bag_recording import load_bag_run, without_gyro
from ..io.bags import BagContents
from ..io.recordings import load_recordings
from .common import (
    RobotSpec,
    kinematics_of,
    load_warnings,
    nominal_geometry,
    optional_robot,
    refuse_still_runs,
    unused_offsets,
)
from .slam_bags import load_slam_bags
from .text import Presented, Text, check_text, emits_warnings

if TYPE_CHECKING:  # the skid-steer check's types (its modules are imported where it runs)
    from ..calibration.skid_steer import SkidLog
    from ..calibration.time_offset import TimeOffset

__all__ = [
    "CheckResult",
    "check",
    "check_loaded",
    "check_bag",
    "JUDGES",
    "noise_model",
    "refuse_blind",
    "slam_noise",
    "SLAM_POSE_NOISE",
    "check_skid",
    "check_skid_logs",
    "SKID_NOISE",
]


@dataclass(frozen=True)
class CheckResult(Presented):
    """The check of a log, the noise it assumed and where that came from."""

    check: LogCheck
    noise_source: str
    recordings: int
    load_warnings: tuple[str, ...] = ()
    kinematics: Kinematics = "differential"
    notes: tuple[str, ...] = ()
    top_up: TopUp | None = None

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal check --json``: the check, the noise it assumed and its source,
        and what to add (``top_up``, None where not computed)."""
        return self.check.as_dict() | {
            "noise_source": self.noise_source,
            "load_warnings": list(self.load_warnings),
            "kinematics": self.kinematics,
            "notes": list(self.notes),
            "top_up": None if self.top_up is None else self.top_up.as_dict(),
        }

    def text(self) -> str:
        """The text of ``odocal check``: enough or not, the predicted standard errors, the
        motion, its degeneracies and what to drive."""
        out = Text()
        out(f"Is this log enough? {self.recordings} run(s)")
        out(f"  ({JUDGES})")
        if self.kinematics == "skid-steer":
            out("  skid-steer: b is the effective track")
        check_text(out, self)
        for note in self.notes:
            out(f"  {note}")
        if self.top_up is not None:
            t = self.top_up
            out(f"  what to add: {t.sentence()}")
            out(f"    (speeds from the log: {t.rates.source})")
        return str(out)


#: What the check judges, in words: the information in the motion, not a result.
JUDGES = (
    "this judges what the recorded motion lets a calibration see, its information, not "
    "whether a calibration of it is right: that is fit's held-out check and cross-checks"
)


def noise_model(r: Robot | None) -> tuple[NoiseModel, str]:
    """The stated noise: the robot's ``nonsystematic`` and ``measurement`` where given (a part
    left at zero keeps the default), else the defaults of :class:`NoiseModel`."""
    default = NoiseModel()
    if r is None:
        return default, "default (k 1e-6 m per wheel, tracker 1 mm and 0.2 deg): give --robot"
    wheel = r.nonsystematic if not r.nonsystematic.is_zero else default.wheel
    meas = r.measurement if not r.measurement.is_zero else default.measurement
    parts = [
        "ROBOT.yaml nonsystematic" if wheel is r.nonsystematic else "default k",
        "ROBOT.yaml measurement" if meas is r.measurement else "default tracker noise",
    ]
    return NoiseModel(wheel, meas), ", ".join(parts)


def check_loaded(
    recordings: Sequence[Recording],
    geometry: WheelGeometry,
    robot: Robot | None = None,
    *,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    mounting: bool = False,
    max_blocks_per_run: int = MAX_BLOCKS_PER_RUN,
    noise: tuple[NoiseModel, str] | None = None,
    top_up: bool = False,
) -> CheckResult:
    """The check of loaded recordings, linearised at ``geometry``, with ``robot``'s noise (or
    ``noise``: a model and where it came from), for the trajectory fit of ``settings`` (its
    residual, segment length, heading weight, samples and run weight); with ``top_up``, also
    the shortest addition that makes the log enough (:func:`~odocal.calibration.topup.
    find_top_up`). A run in which the robot never moves is an InputError."""
    refuse_still_runs(recordings)
    model, source = noise if noise is not None else noise_model(robot)
    recordings = list(recordings)
    info = log_information(
        recordings,
        geometry,
        noise=model,
        residual=settings.residual,
        segment_m=settings.segment_m,
        heading_weight_m=settings.heading_weight_m,
        samples_per_run=settings.samples_per_run,
        run_weight=settings.run_weight,
        mounting=mounting,
        max_blocks_per_run=max_blocks_per_run,
    )
    chk = judge(info, recordings)
    more = find_top_up(info, chk, recordings) if top_up else None
    return CheckResult(chk, source, len(recordings), top_up=more)


@emits_warnings
def check(
    paths: str | Path | Sequence[str | Path],
    *,
    robot: RobotSpec = None,
    ticks_per_rev: float | None = None,
    bag: BagOptions = NO_BAG_OPTIONS,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
    mounting: bool = False,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    kinematics: Kinematics | None = None,
) -> CheckResult:
    """Load the runs in ``paths`` (ground truth optional) and check what they let a trajectory
    fit with ``settings`` see, at the nominal geometry (``robot``, else the recordings'
    metadata). ``truth_frames``: bags whose truth is a SLAM pose on /tf (its stamps
    ``slam_stamp_offset_s`` late). ``kinematics`` (default: the robot file's, else
    differential): 'skid-steer' checks bags for the effective track
    (:func:`check_skid`)."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    notes: list[str] = []
    r = optional_robot(robot)
    if kinematics_of(kinematics, r) == "skid-steer":
        if truth_frames is not None or mounting:
            flag = "--truth-frames" if truth_frames is not None else "--mounting"
            raise InputError(f"{flag} is not used by the skid-steer check", field=flag[2:])
        return check_skid(paths, r, bag, ticks_per_rev)
    noise = None
    if truth_frames is not None:
        slam = load_slam_bags(
            paths,
            truth_frames,
            bag,
            ticks_per_rev=ticks_per_rev,
            stamp_offset_s=slam_stamp_offset_s,
            ran_with=None if r is None else r.believed_geometry,
            time_offset_s=bag.time_offset("slam"),
        )
        recordings = [b.recording for b in slam]
    else:
        with without_gyro():  # the check does not use the gyro heading
            recordings = load_recordings(
                paths, ticks_per_rev=ticks_per_rev, warnings=notes, bag=bag,
                ran_with=None if r is None else r.believed_geometry,
            )  # fmt: skip
    geometry = nominal_geometry(r, recordings)
    if geometry is None:
        raise InputError(
            "the check needs the robot's nominal geometry: give --robot ROBOT.yaml (the "
            "recordings carry no firmware parameters)"
        )
    prediction = None
    if truth_frames is not None:
        model, source, prediction = slam_noise(slam, r, geometry)
        noise = (model, source)
    res = check_loaded(
        recordings, geometry, r, settings=settings, mounting=mounting, noise=noise,
        top_up=truth_frames is None,
    )  # fmt: skip
    if prediction is not None and np.all(np.isfinite(prediction)):
        what = "the SLAM route's relative-motion fit (intervals between updates)"
        res = replace(res, check=with_prediction(res.check, prediction, what))
    no_truth = tuple(str(x.meta["no_truth"]) for x in recordings if x.meta.get("no_truth"))
    return replace(res, load_warnings=tuple(notes) + no_truth + load_warnings(recordings))


def check_bag(
    bag: BagContents,
    robot: Robot,
    options: BagOptions = NO_BAG_OPTIONS,
    slam: Sequence[SlamBag] = (),
) -> CheckResult:
    """The check of a bag already read (:func:`~odocal.io.bags.read_bag_once`): its wheel
    motion (joint states, else the controller's odometry inverted through the geometry it ran
    with) at the nominal geometry; with ``slam`` (the SLAM route's loaded bags) the SLAM
    truth's recording, the log's own noise and the SLAM route's predicted errors, as
    ``check --truth-frames`` gives them. ``fit --method auto`` prints it."""
    prediction = None
    noise = None
    if slam:
        recordings = [b.recording for b in slam]
        model, source, prediction = slam_noise(slam, robot, robot.nominal)
        noise = (model, source)
    else:
        with without_gyro():
            recordings = [load_bag_run(bag, options, ran_with=robot.believed_geometry)]
    res = check_loaded(recordings, robot.nominal, robot, noise=noise)
    if prediction is not None and np.all(np.isfinite(prediction)):
        what = "the SLAM route's relative-motion fit (intervals between updates)"
        res = replace(res, check=with_prediction(res.check, prediction, what))
    return replace(res, load_warnings=load_warnings(recordings))


def slam_noise(
    bags: Sequence[SlamBag], robot: Robot | None, geometry: WheelGeometry | None = None
) -> tuple[NoiseModel, str, np.ndarray | None]:
    """The noise of a SLAM-truth check and where it came from
    (:func:`~odocal.calibration.slam_noise.slam_noise_model` over the intervals between the
    SLAM's updates of every bag); with ``geometry``, also the covariance of (D_R, D_L, b) that
    the SLAM route's relative-motion fit would have with that noise, else None."""
    noise = slam_noise_model(stack_motions([b.relative_motions for b in bags]), robot, geometry)
    return noise.model, noise.description, noise.covariance


def refuse_blind(log_check: CheckResult | None, force: bool) -> list[str]:
    """A log that cannot see a parameter at all (the check's 'blind' findings: only straight
    lines leave b undetermined, and the fit moves it anywhere) gives no calibration to export:
    CalibrationError (nothing written) unless ``force``; then the findings are warnings."""
    if log_check is None:
        return []
    found = [g.message for g in log_check.check.degeneracies if g.severity == "blind"]
    if not found:
        return []
    advice = "".join(f"; suggestion: {s}" for s in log_check.check.suggestions[:1])
    problem = f"these runs cannot determine the calibration: {found[0]}{advice}"
    if not force:
        raise CalibrationError(f"{problem}; nothing written (--force exports it anyway)")
    return [f"{problem} (exported anyway: --force)"]


# ------------------------------------------------------------- skid-steer robots

#: Where the check's standard errors come from, in words.
SKID_NOISE = (
    "the skid-steer fit's own errors (the delete-one-block jackknife over 15 s blocks of the "
    "log's residuals: its slip; the truth's clock offset's share added), as D_R, D_L and the "
    "effective track b"
)


def _skid_covariance(
    logs: Sequence[SkidLog], nominal: WheelGeometry, offsets: Sequence[TimeOffset]
) -> tuple[WheelGeometry | None, np.ndarray | None, str]:
    """The exported model fitted to ``logs`` (effective track, a wheel scale per side) and the
    covariance of (D_R, D_L, b) it implies; (None, None, why) when it cannot be fitted."""
    from ..calibration.skid_steer import fit_skid_logs
    from .fit_skid import EXPORTED

    try:
        fit, _ = fit_skid_logs(logs, nominal, EXPORTED[0], offsets=offsets,
                               wheel_scales=EXPORTED[1])  # fmt: skip
    except CalibrationError as exc:
        return None, None, str(exc)
    names = ("scale_right", "scale_left", "track_multiplier")
    idx = [fit.names.index(n) for n in names]
    jac = np.diag([nominal.diameter_right_m, nominal.diameter_left_m, nominal.wheelbase_m])
    cov = jac @ fit.covariance[np.ix_(idx, idx)] @ jac.T
    geometry = WheelGeometry(
        nominal.diameter_right_m * fit.value("scale_right"),
        nominal.diameter_left_m * fit.value("scale_left"),
        nominal.wheelbase_m * fit.value("track_multiplier"),
    )
    return geometry, cov, ""


def _curve_note(
    logs: Sequence[SkidLog],
    nominal: WheelGeometry,
    offsets: Sequence[TimeOffset],
    multiplier: float | None,
) -> str:
    """At which turn rates the multiplier's curve can be read (the turn-rate model's knots: the
    nominal wheels' yaw rates; over ``multiplier``, about the robot's)."""
    from ..calibration.skid_steer import (
        SkidIntervals,
        offset_at,
        skid_intervals,
        turn_rate_knots,
    )

    parts = [
        skid_intervals(log, offset_s=offset_at(o, log))
        for log, o in zip(logs, offsets, strict=True)
    ]
    try:
        knots = turn_rate_knots(SkidIntervals.concatenate(parts), nominal)
    except CalibrationError as exc:
        return f"the multiplier against the turn rate cannot be read: {exc}"
    rates = ", ".join(f"{k / (multiplier or 1.0):.2g}" for k in knots)
    what = "yaw rates of about" if multiplier else "nominal wheel yaw rates"
    return (
        f"the multiplier against the turn rate can be read at {what} {rates} rad/s (each with "
        "a full turn near it); a controller turning faster or slower is extrapolated"
    )


def check_skid_logs(
    logs: Sequence[SkidLog], robot: Robot, truth_offset_s: float | None = None
) -> CheckResult:
    """The check of skid-steer logs already read (``check BAG... --kinematics skid-steer``).

    A skid-steer robot's random error is its slip, not its wheels' noise, and a stated ``k``
    and tracker noise say nothing of it. So the standard errors are the skid-steer fit's own
    (the delete-one-block jackknife over 15 s blocks of the log's residuals, the truth's clock
    offset's share added: :func:`~odocal.calibration.skid_steer.fit_skid_logs`), mapped onto
    D_R, D_L and b (the effective track), and judged by the differential-drive check's
    thresholds; the motion, its degenerate motions and the blind directions are the
    differential-drive check's of the same motion, linearised at the fitted effective
    geometry. It also says at which turn rates the multiplier's curve can be read."""
    from .fit_skid import skid_recordings

    if not logs:
        raise InputError("no recording to check")
    nominal = robot.nominal
    recordings, offsets = skid_recordings(logs, truth_offset_s)
    geometry, cov, why = _skid_covariance(logs, nominal, offsets)
    stated = "the motion's findings at the stated noise (a skid-steer log's own is its slip)"
    res = check_loaded(
        recordings, geometry or nominal, robot, noise=(NoiseModel(), stated)
    )  # fmt: skip
    if cov is not None:
        chk = with_prediction(res.check, cov, "the skid-steer fit (its own residuals)")
        res = replace(res, check=chk, noise_source=SKID_NOISE)
    notes = []
    for o in offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        notes.append(f"clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.found}; applied)")
    if cov is None:
        notes.append(f"no skid-steer fit of this log ({why}): the errors are the stated noise's")
        # 'fit' refuses this log for the same reason: it is not enough, whatever its motion
        refused = Degeneracy(
            "skid-fit-refused", "blind", "the effective track and the wheel scales",
            f"the skid-steer fit cannot use this log: {why}",
        )  # fmt: skip
        res = replace(
            res, check=replace(res.check, degeneracies=(*res.check.degeneracies, refused))
        )
    mult = None if geometry is None else float(geometry.wheelbase_m / nominal.wheelbase_m)
    notes.append(_curve_note(logs, nominal, offsets, mult))
    return replace(
        res, kinematics="skid-steer", notes=tuple(notes),
        load_warnings=tuple(w for o in offsets for w in o.warnings),
    )  # fmt: skip


def check_skid(
    paths: Sequence[str | Path],
    robot: Robot | None,
    bag: BagOptions,
    ticks_per_rev: float | None = None,
) -> CheckResult:
    """``check BAG... --kinematics skid-steer``: the bags read as the skid-steer fit reads them,
    checked (:func:`check_skid_logs`)."""
    from .fit_skid import read_skid_logs

    if robot is None:
        raise InputError(
            "--kinematics skid-steer needs the robot file (--robot ROBOT.yaml): the nominal "
            "wheel diameter and wheelbase the effective track is relative to"
        )
    logs = read_skid_logs(paths, bag, robot, ticks_per_rev)
    res = check_skid_logs(logs, robot, bag.time_offset("truth"))
    return replace(
        res, load_warnings=res.load_warnings + unused_offsets(bag.time_offsets, ["truth"])
    )
