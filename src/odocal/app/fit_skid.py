"""``odocal fit BAG... --kinematics skid-steer``: the effective track of a skid-steer or tracked
robot (and its wheel scales), the multipliers ros2_control's ``diff_drive_controller`` needs, the
track against the turn rate, and how far the odometry then drifts on recordings the fit did not
see (docs/skid-steer.md).

:func:`skid_fit` is the route, I/O-free over loaded logs (:class:`~odocal.calibration.skid_steer.
SkidLog`: the wheels and a truth pose track, each on its own clock); :func:`fit_skid_bags` reads
the bags (:func:`odocal.io.bag_skid.read_skid_log`), calls it and writes what was asked for.

1. **The answer** is the model the controller can hold: the effective track with a wheel scale
   per side (``wheel_separation_multiplier`` and the two radius multipliers), fitted on every
   recording pooled, each with its truth's clock offset (estimated), with cluster-robust errors
   over time blocks and the offsets' own uncertainty (:func:`~odocal.calibration.skid_steer.
   fit_skid_logs`).
2. **Held out** (:func:`~odocal.calibration.skid_steer.cross_validate`): every model of the
   literature is fitted without one recording (one half of a single recording) and scored on it
   by the KITTI-style drift (% of 10 m of truth path, :mod:`odocal.core.path_drift`); the
   nominal geometry too. The one that wins is named, beside the one exported.
3. **Per recording**: each recording's own multiplier and its distance from the others' (in
   combined standard errors): beyond 3 the robot (its load, its tyres, the ground) changed.
4. **The curve**: the multiplier at knots of the turn rate the recordings cover, for a
   controller that turns at other rates.
5. **Verdict**: trustworthy when the exported model beats the nominal on the held-out
   recordings, the recordings agree, and the answer is a plausible skid-steer robot (a track
   multiplier 0.8-3, wheel scales within 25 % of the nominal).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

import numpy as np

from ..calibration.result import ABSURD_FRACTION
from ..calibration.route_answer import RouteAnswer, route_answer
from ..calibration.skid_steer import (
    CANDIDATES,
    Candidate,
    SkidHeldOut,
    SkidLog,
    SkidSteerFit,
    TurnRateRow,
    candidate_label,
    cross_validate,
    fit_skid_logs,
    skid_recording,
    truth_clock_offset,
    z_score,
)
from ..calibration.time_offset import TimeOffset
from ..core.model import Robot, WheelGeometry
from ..core.path_drift import PathDrift
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from ..io.bag_options import BagOptions
from ..io.bag_skid import SkidGyroLog
from ..io.bags import BagContents
from ..io.outputs import OutputPlan
from .common import NO_EXPORTS, Exports
from .text import Presented, Text, verdict_lines, written_lines

__all__ = ["SkidFitResult", "RecordingMultiplier", "skid_fit", "fit_skid_bags", "EXPORTED"]

#: The model a diff_drive_controller can hold: the effective track and a wheel scale per side.
EXPORTED: Candidate = ("effective-track", "left-right")
#: A skid-steer robot's effective track is wider than its wheelbase, but not beyond this range
#: of multipliers (the Warthog's is 1.6-1.7, a Husky's 1.8-1.9, a tracked robot's 1.1-1.5).
TRACK_MULTIPLIER_RANGE = (0.8, 3.0)
#: Recordings whose multipliers differ by more than this many combined standard errors are of
#: a robot that changed.
MAX_Z = 3.0


@dataclass(frozen=True)
class RecordingMultiplier:
    """One recording's own multiplier, and its distance from the others' in combined standard
    errors (None with one recording)."""

    name: str
    multiplier: float
    stderr: float
    z: float | None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready."""
        return {"recording": self.name, "multiplier": self.multiplier, "std_error": self.stderr,
                "z": self.z}  # fmt: skip


def _drift_dict(d: PathDrift | None) -> dict[str, Any] | None:
    """The JSON contract's drift (:meth:`~odocal.core.path_drift.PathDrift.contract`)."""
    return None if d is None or not d.pieces else d.contract()


@dataclass(frozen=True)
class SkidFitResult(Presented):
    """A skid-steer calibration (module docstring).

    Attributes
    ----------
    names : tuple of str
        The recordings.
    nominal : WheelGeometry
    fit : SkidSteerFit
        The exported model on every recording pooled.
    offsets : tuple of TimeOffset
        Each recording's truth clock offset against its wheels.
    per_recording : tuple of RecordingMultiplier
    curve : tuple of TurnRateRow
        The multiplier at knots of the wheel yaw rate (empty when the recordings cover too few).
    heldout : SkidHeldOut or None
        Every model scored on recordings (or halves) it did not see.
    reasons : tuple of str
        Why the answer is not to be trusted (empty: it is).
    notes : tuple of str
    written : tuple of Path
    """

    names: tuple[str, ...]
    nominal: WheelGeometry
    fit: SkidSteerFit
    offsets: tuple[TimeOffset, ...]
    per_recording: tuple[RecordingMultiplier, ...] = ()
    curve: tuple[TurnRateRow, ...] = ()
    heldout: SkidHeldOut | None = None
    reasons: tuple[str, ...] = ()
    notes: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    load_warnings: tuple[str, ...] = ()

    method = "skid-steer"

    @property
    def enough(self) -> bool:
        """A trustworthy answer: nothing speaks against it."""
        return not self.reasons

    @property
    def geometry(self) -> WheelGeometry:
        """The exported model as a differential drive's geometry: each side's effective rolling
        diameter and the effective track."""
        m = self.fit.model
        return WheelGeometry.unchecked(2 * m.radius_right_m, 2 * m.radius_left_m, m.track_m)

    @property
    def multipliers(self) -> dict[str, float]:
        """The diff_drive_controller multipliers against the nominal geometry."""
        return self.fit.model.ros2_multipliers(self.nominal)

    def answer(self) -> RouteAnswer:
        """The exported model as a route's answer (the 'trajectory' route of a truth pose,
        model 'skid-steer'): each side's effective rolling diameter and the effective track,
        with their covariance from the fit's (the scales times the nominal diameters, the
        multiplier times the nominal wheelbase)."""
        names = self.fit.names
        jac = np.zeros((3, len(names)))
        n = self.nominal
        for row, (name, ref) in enumerate((("scale_right", n.diameter_right_m),
                                           ("scale_left", n.diameter_left_m),
                                           ("track_multiplier", n.wheelbase_m))):  # fmt: skip
            jac[row, names.index(name)] = float(ref)
        cov = jac @ self.fit.covariance @ jac.T
        se = np.sqrt(np.clip(np.diag(cov), 0.0, None))
        return route_answer(
            "trajectory", "skid-steer", self.geometry, (float(se[0]), float(se[1]), float(se[2])),
            cov,
        )  # fmt: skip

    @property
    def track_multiplier(self) -> tuple[float, float]:
        """The effective track over the nominal wheelbase, and its standard error."""
        return self.fit.track_multiplier()

    def drift(self, label: str) -> PathDrift | None:
        """The pooled held-out drift of a model (:func:`candidate_label`, or 'nominal')."""
        h = self.heldout
        if h is None or label not in h.labels:
            return None
        return h.pooled(label)

    @property
    def warnings(self) -> tuple[str, ...]:
        """The clock offsets' warnings."""
        return tuple(w for o in self.offsets for w in o.warnings)

    def text(self) -> str:
        """The text ``odocal fit --kinematics skid-steer`` prints."""
        return skid_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit --kinematics skid-steer --json``."""
        m, se = self.track_multiplier
        h = self.heldout
        exported = candidate_label(EXPORTED)
        return {
            "method": "skid-steer",
            "kinematics": "skid-steer",
            "recordings": list(self.names),
            "nominal": self.nominal.as_dict(),
            "model": self.fit.as_dict(),
            "track_multiplier": {"value": m, "std_error": se},
            "effective_track_m": float(self.fit.model.track_m),
            "ros2": {"wheel_separation": float(self.nominal.wheelbase_m), **self.multipliers},
            "turn_rate": [
                {
                    "wheel_yaw_rate_rad_s": r.wheel_rate_rad_s,
                    "yaw_rate_rad_s": r.true_rate_rad_s,
                    "multiplier": r.multiplier,
                    "std_error": r.stderr,
                }
                for r in self.curve
            ],  # fmt: skip
            "per_recording": [r.as_dict() for r in self.per_recording],
            "time_offsets": [o.as_dict() for o in self.offsets],
            "heldout": None
            if h is None
            else {
                "units": list(h.held_out),
                "exported": exported,
                "best": h.best(),
                "models": {lab: _drift_dict(self.drift(lab)) for lab in h.labels},
            },
            "drift_percent_per_10m": _drift_dict(self.drift(exported)),
            "nominal_drift_percent_per_10m": _drift_dict(self.drift("nominal")),
            "notes": list(self.notes),
            "verdict": {"enough": self.enough, "reasons": list(self.reasons)},
            "warnings": list(self.warnings),
            "written": [str(p) for p in self.written],
        }


def truth_offsets(logs: Sequence[SkidLog], given_s: float | None = None) -> tuple[TimeOffset, ...]:
    """Each log's truth clock offset (0, with the reason, where it cannot be estimated);
    ``given_s`` (``--time-offset truth=S``): that one for every log, not estimated."""
    out = []
    for log in logs:
        if given_s is not None:
            out.append(replace(TimeOffset.given("truth", given_s), part=log.name))
            continue
        try:
            out.append(truth_clock_offset(log))
        except CalibrationError as exc:
            out.append(TimeOffset.not_estimated("truth", str(exc)))
    return tuple(out)


def skid_recordings(
    logs: Sequence[SkidLog], truth_offset_s: float | None = None
) -> tuple[list[Recording], tuple[TimeOffset, ...]]:
    """Each log as a wheel-rate recording with its truth on the wheels' clock
    (:func:`~odocal.calibration.skid_steer.skid_recording`, its offset estimated as the fit
    estimates it), and those offsets (named after their bags); a truth that no longer overlaps
    the wheels once shifted is an InputError."""
    recordings, offsets = [], []
    for log, offset in zip(logs, truth_offsets(logs, truth_offset_s), strict=True):
        offset = replace(offset, part=Path(log.name).name)
        try:
            recordings.append(skid_recording(log, offset))
        except CalibrationError as exc:
            raise InputError(str(exc), log.name) from None
        offsets.append(offset)
    return recordings, tuple(offsets)


def _per_recording(
    logs: Sequence[SkidLog], nominal: WheelGeometry, offsets: Sequence[TimeOffset]
) -> tuple[RecordingMultiplier, ...]:
    """Each recording's own multiplier, and its distance from the inverse-variance mean of the
    others'."""
    own = []
    for log, o in zip(logs, offsets, strict=True):
        f, _ = fit_skid_logs([log], nominal, EXPORTED[0], offsets=[o], wheel_scales=EXPORTED[1])
        own.append(f.track_multiplier())
    out = []
    for k, (log, (m, se)) in enumerate(zip(logs, own, strict=True)):
        rest = [x for j, x in enumerate(own) if j != k]
        z = None
        if rest:
            w = np.array([1 / s**2 for _, s in rest])
            mean = float(np.sum(w * np.array([v for v, _ in rest])) / np.sum(w))
            z = z_score(m, se, mean, float(1 / math.sqrt(np.sum(w))))
        out.append(RecordingMultiplier(log.name, m, se, z))
    return tuple(out)


def _halves(log: SkidLog) -> list[SkidLog]:
    """A single recording's two halves in time, each its own group (the held-out units)."""
    t = np.asarray(log.time_s)
    mid = 0.5 * (float(t[0]) + float(t[-1]))
    return [
        log.window(float(t[0]), mid, group="first half"),
        log.window(mid, float(t[-1]), group="second half"),
    ]


def _curve(
    logs: Sequence[SkidLog], nominal: WheelGeometry, offsets: Sequence[TimeOffset]
) -> tuple[tuple[TurnRateRow, ...], tuple[str, ...]]:
    """The turn-rate table (left and right wheel scales), or a note why not."""
    try:
        f, _ = fit_skid_logs(logs, nominal, "turn-rate", offsets=offsets,
                             wheel_scales="left-right", offset_variance=False)  # fmt: skip
    except CalibrationError as exc:
        return (), (f"no turn-rate table: {exc}",)
    return f.turn_rate_rows(), ()


def _plausibility(res_fit: SkidSteerFit, nominal: WheelGeometry) -> list[str]:
    """What makes the answer no plausible skid-steer robot (the units, the wheels' scale)."""
    out = []
    m, _ = res_fit.track_multiplier()
    lo, hi = TRACK_MULTIPLIER_RANGE
    if not lo <= m <= hi:
        out.append(
            f"the effective track is {m:.3g} times the wheelbase: no skid-steer robot's "
            f"({lo:g}-{hi:g}); check the wheelbase and the units of the robot file"
        )
    model = res_fit.model
    for side, r, d in (("right", model.radius_right_m, nominal.diameter_right_m),
                       ("left", model.radius_left_m, nominal.diameter_left_m)):  # fmt: skip
        scale = 2 * r / float(d)
        if abs(scale - 1) > ABSURD_FRACTION:
            what = (
                "a sprocket radius given as a wheel diameter, or a diameter in other units?"
                if abs(scale - 0.5) < 0.1 or abs(scale - 2.0) < 0.4
                else "the wheel diameter of the robot file, its units, or the joint rates"
            )
            out.append(
                f"the {side} side rolls {scale:.3g} times the nominal wheel's circumference: "
                f"more than 25 % off; {what}"
            )
    return out


#: Least turning (rad, all recordings, as the nominal wheels say) that can show the track.
MIN_TURNING_RAD = 2 * math.pi


def _refuse_no_turning(
    logs: Sequence[SkidLog] | Sequence[SkidGyroLog], nominal: WheelGeometry
) -> None:
    """Recordings that do not turn cannot show the effective track (only straight driving sees
    the wheels' scale): InputError saying so, before any fit (each route's: the truth's, the
    gyro's)."""
    turned = 0.0
    for log in logs:
        dr = np.diff(np.asarray(log.angle_right_rad)) * 0.5 * float(nominal.diameter_right_m)
        dl = np.diff(np.asarray(log.angle_left_rad)) * 0.5 * float(nominal.diameter_left_m)
        turned += float(np.sum(np.abs(dr - dl))) / float(nominal.wheelbase_m)
    if turned < MIN_TURNING_RAD:
        raise InputError(
            f"the recordings turn {math.degrees(turned):.0f} deg in all (by the wheels): the "
            "effective track cannot be seen without turning; drive spins and arcs in both "
            f"directions, at least {math.degrees(MIN_TURNING_RAD):.0f} deg (odocal check says "
            "the same of a differential drive's log)"
        )


def skid_fit(
    logs: Sequence[SkidLog],
    robot: Robot,
    *,
    force: bool = False,
    candidates: Sequence[Candidate] = CANDIDATES,
    truth_offset_s: float | None = None,
) -> SkidFitResult:
    """The skid-steer route, I/O-free (module docstring). An answer that is no plausible
    skid-steer robot is a CalibrationError unless ``force`` (then a reason).
    ``truth_offset_s``: the truth's clock offset as given (else estimated per log)."""
    if not logs:
        raise InputError("no recording to fit")
    nominal = robot.nominal
    _refuse_no_turning(logs, nominal)
    offsets = truth_offsets(logs, truth_offset_s)
    fit, _ = fit_skid_logs(logs, nominal, EXPORTED[0], offsets=offsets, wheel_scales=EXPORTED[1])
    reasons = _plausibility(fit, nominal)
    if reasons and not force:
        raise CalibrationError(f"{reasons[0]}; nothing written (--force accepts it anyway)")
    notes: list[str] = []
    per = _per_recording(logs, nominal, offsets) if len(logs) > 1 else ()
    for r in per:
        if r.z is not None and abs(r.z) > MAX_Z:
            reasons.append(
                f"{r.name}: its multiplier {r.multiplier:.4f} +- {r.stderr:.4f} differs from "
                f"the other recordings' by {r.z:+.1f} combined standard errors: the robot, its "
                "load or the ground changed between them (fit them apart)"
            )
    units = list(logs) if len(logs) > 1 else _halves(logs[0])
    unit_offsets = offsets if len(logs) > 1 else (offsets[0], offsets[0])
    heldout = None
    try:
        heldout = cross_validate(units, nominal, candidates, offsets=unit_offsets)
    except CalibrationError as exc:
        notes.append(f"no held-out check: {exc}")
        reasons.append("no held-out check: the recordings cannot show that the calibration helps")
    if heldout is not None:
        exported = candidate_label(EXPORTED)
        cal, nom = heldout.pooled_median_pct(exported), heldout.pooled_median_pct("nominal")
        if not cal < nom:
            reasons.append(
                f"held out, the calibrated odometry drifts {cal:.3g} % per 10 m against "
                f"{nom:.3g} % with the nominal geometry: the calibration does not help"
            )
    curve, more = _curve(logs, nominal, offsets)
    notes += more
    return SkidFitResult(
        tuple(log.name for log in logs), nominal, fit, offsets, per, curve, heldout,
        tuple(reasons), tuple(notes),
    )  # fmt: skip


def read_skid_bags(paths: Sequence[str | Path], bag: BagOptions) -> list[BagContents]:
    """Each bag read once (every topic a skid-steer route may use), the same bag twice refused;
    a path that is no bag is an InputError."""
    from ..io.bags import is_bag, read_bag_once
    from ..io.recordings import refuse_repeated

    named = (bag.joint_topic, bag.truth_topic, bag.odom_topic, bag.imu_topic)
    out = []
    for p in refuse_repeated(paths):
        if not is_bag(p):
            raise InputError("--kinematics skid-steer reads ROS bags (wheels and a truth pose)", p)
        out.append(read_bag_once(p, named))
    return out


def read_skid_logs(
    paths: Sequence[str | Path] | Sequence[BagContents],
    bag: BagOptions,
    robot: Robot | None,
    ticks_per_rev: float | None = None,
) -> list[SkidLog]:
    """Each bag's wheels and truth (:func:`~odocal.io.bag_skid.read_skid_log`; the wheels from
    the controller's odometry are inverted through ``robot``'s believed geometry); paths are
    read by :func:`read_skid_bags`."""
    from ..io.bag_skid import read_skid_log

    contents = [c for c in paths if isinstance(c, BagContents)]
    if len(contents) != len(paths):
        contents = read_skid_bags([p for p in paths if not isinstance(p, BagContents)], bag)
    ran_with = None if robot is None else robot.believed_geometry
    logs = [read_skid_log(c, bag, ran_with, ticks_per_rev=ticks_per_rev) for c in contents]
    refuse_unstated_ran_with([(log.name, log.wheels) for log in logs], robot)
    return logs


def refuse_unstated_ran_with(sources: Sequence[tuple[str, str]], robot: Robot | None) -> None:
    """Wheels that are the controller's odometry, inverted through a geometry the robot file
    does not state, would make a skid-steer answer of a guess (its controller runs with a
    multiplier of 1.5-1.9, not the nominal 1): InputError saying how to state it."""
    if robot is None or robot.ran_with_stated:
        return
    for name, source in sources:
        if source != "joint_states":
            raise InputError(
                f"the wheels are the controller's odometry ({source}), and the robot file does "
                "not say what the controller ran with: state its wheel_separation_multiplier "
                "(and radius multipliers) or a 'believed' geometry in the robot file (a stock "
                "Husky: wheel_separation_multiplier: 1.875), or record the joint states; the "
                "nominal geometry is not guessed",
                name,
            )


def fit_skid_bags(
    paths: Sequence[str | Path] | Sequence[BagContents],
    plan: OutputPlan,
    bag: BagOptions,
    *,
    robot: Robot,
    ticks_per_rev: float | None = None,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
    plot: str | Path | None = None,
) -> SkidFitResult:
    """``fit BAG... --kinematics skid-steer``: every bag read (:func:`~odocal.io.bag_skid.
    read_skid_log`), fitted (:func:`skid_fit`) and the ``exports`` written (:func:`write_skid`)."""
    logs = read_skid_logs(paths, bag, robot, ticks_per_rev)
    res = skid_fit(logs, robot, force=force, truth_offset_s=bag.time_offset("truth"))
    return write_skid(res, plan, exports, force, plot, "skid-steer", "")


def write_skid(
    res: Any, plan: OutputPlan, exports: Exports, force: bool, plot: str | Path | None,
    method: str, sensor: str,
) -> Any:  # fmt: skip
    """A skid-steer route's exports (the effective geometry's multipliers, recorded as
    ``method``) and the curve's figure (its title naming ``sensor`` if any), all or none; none
    when the verdict has reasons, unless ``force`` (then the files carry them). ``res``: a
    :class:`SkidFitResult` or a :class:`~odocal.app.fit_skid_gyro.SkidGyroResult`."""
    if res.reasons and not force and (exports.out or exports.ros2):
        return res
    files: dict[Path, Any] = {}
    if plot is not None:
        if not res.curve:
            raise InputError(
                "--plot: the recordings cover too few turn rates for the multiplier's curve "
                f"({'; '.join(res.notes) or 'no table'}); nothing written",
                field="plot",
            )
        from ..plot.skid import skid_figures

        by = f", {sensor}" if sensor else ""
        title = f"Effective track against the turn rate{by} ({len(res.names)} recording(s))"
        files.update(skid_figures(plot, res.curve, res.track_multiplier, title))
    written = exports.write(
        plan, res.geometry, res.nominal, files=files, record={"method": method},
        doubts=res.reasons,
    )  # fmt: skip
    return replace(res, written=written)


def skid_text(res: SkidFitResult) -> str:
    """The text of a skid-steer fit."""
    out = Text()
    out(f"skid-steer fit of {len(res.names)} recording(s)")
    m, se = res.track_multiplier
    b = float(res.nominal.wheelbase_m)
    out(
        f"  effective track {res.fit.model.track_m:.4f} m = wheel_separation {b:.4g} m x "
        f"wheel_separation_multiplier {m:.4f} +- {se:.4f}"
    )
    mult = res.multipliers
    for side in ("right", "left"):
        name = f"{side}_wheel_radius_multiplier"
        out(f"  {name} {mult[name]:.4f} +- {res.fit.se(f'scale_{side}'):.4f}")
    for o in res.offsets:
        pm = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"clock offset of the {o.label}: {o.offset_s:+.4f}{pm} s ({o.how})")
    if res.per_recording:
        out("per recording (its own multiplier; z against the others'):")
        rows: list[tuple[str, ...]] = [("", "multiplier", "std. error", "z")]
        for r in res.per_recording:
            z = "-" if r.z is None else f"{r.z:+.2f}"
            rows.append((Path(r.name).name, f"{r.multiplier:.4f}", f"{r.stderr:.4f}", z))
        out.table(rows)
    if res.curve:
        out("the multiplier against the turn rate (for a controller turning at other rates):")
        curve: list[tuple[str, ...]] = [("|yaw rate| rad/s", "multiplier", "std. error")]
        curve += [(f"{r.true_rate_rad_s:.3g}", f"{r.multiplier:.4f}", f"{r.stderr:.4f}")
                  for r in res.curve]  # fmt: skip
        out.table(curve)
    h = res.heldout
    if h is not None:
        exported = candidate_label(EXPORTED)
        out(f"held out ({', '.join(Path(u).name for u in h.held_out)} each left out), median "
            "drift in % of 10 m of truth path:")  # fmt: skip
        best = h.best()
        for lab in h.labels:
            tag = " (exported: what the controller holds)" if lab == exported else ""
            tag += " (best)" if lab == best else ""
            out(f"  {lab:32s} {h.pooled_median_pct(lab):6.2f}{tag}")
    for note in res.notes:
        out(note)
    verdict_lines(out, res.enough, res.reasons)
    written_lines(out, res.written)
    return str(out)
