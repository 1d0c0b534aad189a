"""``odocal fit`` on relative motions: the relative-motion calibration (Censi et al. 2013) of the
wheel geometry and the sensor's mounting, from ``.tuple`` files, from bags whose truth is a SLAM
pose on /tf (``--truth-frames``, :mod:`odocal.app.fit_slam`) or from bags with a 2D laser
(``--method scan``, :mod:`odocal.app.fit_scan`).

:func:`fit_relative` is the route itself, I/O-free over loaded relative motions (as evo's
``main_ape.ape()``); :func:`fit_tuple_files`, :func:`odocal.app.fit_slam.fit_slam_bags` and
:func:`odocal.app.fit_scan.fit_scan_bags` load each kind of input, call it and write what was
asked for (with the result, the checks and the exports shared here). The router
:func:`odocal.app.fit.fit` chooses among them.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any, Literal

import numpy as np

from ..calibration.censi import PARAMETERS, SensorOdometryFit, fit_censi
from ..calibration.heldout import HeldOut
from ..calibration.interval_noise import IntervalNoise
from ..calibration.relative_checks import (
    PreferredAnswer,
    RelativeChecks,
    check_relative_fit,
    interval_blocks,
    preferred_answer,
)
from ..calibration.relative_motions import RelativeMotions, overlapping_sources, stack_motions
from ..calibration.slam_bag import SlamBag
from ..calibration.time_offset import TimeOffset, TimingCheck
from ..core.model import WheelGeometry
from ..errors import InputError
from ..io.outputs import OutputPlan
from ..io.tuples import read_tuples, refuse_repeated_tuples, refuse_still_tuples
from .common import NO_EXPORTS, Exports, RobotSpec, refuse_absurd, refuse_untrusted, robot_nominal
from .relative_inputs import ScanSummary, TupleInput
from .text import Presented, Text, written_lines

__all__ = [
    "RelativeSource",
    "TupleInput",
    "ScanSummary",
    "RelativeFitResult",
    "fit_relative",
    "is_tuple_file",
    "fit_tuple_files",
    "export_relative",
    "route_figures",
    "relative_checks",
    "write_bag_route",
]

#: Where the relative motions came from.
RelativeSource = Literal["tuples", "slam", "scan"]

#: What each source's inputs can get wrong when the result is absurd.
ABSURD_HINTS: dict[str, str] = {
    "tuples": "check the tuples' units (phi_l, phi_r average wheel speeds in rad/s, not deg/s or "
    "rpm; sm in metres and radians)",
    "slam": "check the wheel joints (swapped or inverted), --ticks-per-rev and --truth-frames",
    "scan": "check the scan header (angle_min, angle_increment; an upside-down laser), the "
    "laser's mounting in /tf_static, the wheel joints and --ticks-per-rev",
}


@dataclass(frozen=True)
class RelativeFitResult(Presented):
    """A relative-motion fit, the nominal geometry it is compared with, its inputs and the files
    written.

    Attributes
    ----------
    fit : SensorOdometryFit
        The geometry and the sensor's mounting.
    nominal : WheelGeometry or None
    recordings : int
        Files or bags given.
    source : {'tuples', 'slam', 'scan'}
    tuple_files, slam_bags, scans : tuple
        The inputs of each source (the others empty).
    written : tuple of Path
    forced : tuple of str
        The absurd-result messages accepted with ``force``.
    time_offsets : tuple of TimeOffset
        Each bag's clock offset of its truth source against the wheels (SLAM, laser).
    heldout : HeldOut or None
        The blocked cross-validation against the nominal geometry (bags with a nominal).
    noise : IntervalNoise or None
        The wheels' random error and the truth's, from the residuals (bags).
    timing : TimingCheck or None
        Whether the wheels' turning against the source's depends on the interval length.
    notes : tuple of str
        What was not checked, and why.
    """

    fit: SensorOdometryFit
    nominal: WheelGeometry | None
    recordings: int
    source: RelativeSource
    tuple_files: tuple[TupleInput, ...] = ()
    slam_bags: tuple[SlamBag, ...] = ()
    scans: tuple[ScanSummary, ...] = ()
    written: tuple[Path, ...] = ()
    forced: tuple[str, ...] = ()
    load_warnings: tuple[str, ...] = ()
    time_offsets: tuple[TimeOffset, ...] = ()
    heldout: HeldOut | None = None
    noise: IntervalNoise | None = None
    timing: TimingCheck | None = None
    notes: tuple[str, ...] = ()

    @property
    def answer(self) -> PreferredAnswer:
        """The answer: the full fit, or the restricted model the held-out check preferred when
        the full one did not beat the nominal geometry."""
        return preferred_answer(self.fit, self.heldout)

    @property
    def model(self) -> str:
        """The model of the answer: 'full', or the preferred restricted model."""
        return self.answer.model

    @property
    def geometry(self) -> WheelGeometry:
        """The answer's geometry."""
        return self.answer.geometry

    @property
    def geometry_stderr(self) -> tuple[float | None, float | None, float | None]:
        """Standard errors of the answer's (D_R, D_L, b) (m)."""
        return self.answer.stderr

    @property
    def method(self) -> Literal["relative", "scan"]:
        """The method, as ``odocal fit --method`` names it."""
        return "scan" if self.source == "scan" else "relative"

    @property
    def warnings(self) -> tuple[str, ...]:
        """The fit's warnings, and the absurd-result messages accepted with ``force``."""
        own = tuple(self.fit.warnings)
        offsets = tuple(w for o in self.time_offsets for w in o.warnings)
        timing = () if self.timing is None or self.timing.warning is None else (
            self.timing.warning,
        )  # fmt: skip
        return own + offsets + timing + tuple(w for w in self.forced if w not in own)

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> clock offset (s) applied; with several bags, the first bag's (each bag's
        own is in ``time_offsets``)."""
        out: dict[str, float] = {}
        for o in self.time_offsets:
            out.setdefault(o.source, o.applied_s)
        return out

    def text(self) -> str:
        """The text ``odocal fit`` prints for a relative-motion fit."""
        return relative_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit --json`` for relative motions."""
        out = self.fit.as_dict()
        out["warnings"] = list(self.load_warnings) + list(self.warnings)
        out["nominal"] = None if self.nominal is None else self.nominal.as_dict()
        if self.source == "tuples":
            out["inputs"] = [t.as_dict() for t in self.tuple_files]
        elif self.source == "slam":
            out["slam"] = [b.as_dict() for b in self.slam_bags]
        else:
            out["method"] = "scan"
            out["scan"] = [s.as_dict() for s in self.scans]
        if self.source != "tuples":
            out["time_offsets_s"] = self.time_offsets_s
            out["time_offsets"] = [o.as_dict() for o in self.time_offsets]
            out["heldout"] = None if self.heldout is None else self.heldout.as_dict()
            out["model"] = self.model
            if self.model != "full":
                g = self.geometry
                out["answer"] = g.as_dict() | {
                    "stderr": dict(zip(("wheel_diameter_right_m", "wheel_diameter_left_m",
                                        "wheelbase_m"), self.geometry_stderr, strict=True)),
                }  # fmt: skip
            out["noise"] = None if self.noise is None else self.noise.as_dict()
            out["timing"] = None if self.timing is None else self.timing.as_dict()
            out["notes"] = list(self.notes)
        return out


def fit_relative(
    motions: Sequence[RelativeMotions],
    nominal: WheelGeometry | None,
    *,
    sensor_pose: tuple[float, float, float] | None = None,
    force: bool = False,
    source: RelativeSource = "tuples",
    names: Sequence[str | Path] | None = None,
    origins_s: Sequence[float] | None = None,
) -> tuple[SensorOdometryFit, tuple[str, ...]]:
    """The relative-motion route, I/O-free: the calibration of the intervals of every source in
    ``motions`` together (``sensor_pose`` fixed, else estimated), and the absurd-result
    messages accepted with ``force`` (without it a result more than 25 % from ``nominal``, or
    one that is no plausible robot, is a CalibrationError whose hint names what ``source``'s
    inputs can get wrong). Two sources (``names``, default numbered) whose intervals overlap in
    time (each on its clock from ``origins_s``, s since the epoch: a bag's start) with the same
    measurements are one recording given twice
    (:func:`~odocal.calibration.relative_motions.overlapping_sources`): InputError."""
    overlap = overlapping_sources(motions, origins_s)
    if overlap is not None:
        i, j, lo, hi = overlap
        name = [str(n) for n in names] if names else [f"input {k + 1}" for k in range(len(motions))]
        raise InputError(
            f"{name[i]} and {name[j]} cover the same time ({hi - lo:.3g} s of it) with the "
            "same measurements: one recording given twice (a copy under another name, or a "
            "log and a part of it) would count twice; give each once"
        )
    m = stack_motions(motions)
    result = fit_censi(
        m.phi_right_rad,
        m.phi_left_rad,
        m.sensor_motion,
        sensor_pose=sensor_pose,
        nominal=nominal,
        wheel_increments=m.increments,
        clusters=interval_blocks(m),
    )
    return result, tuple(refuse_absurd(result.geometry, nominal, force, ABSURD_HINTS[source]))


def is_tuple_file(path: str | Path) -> bool:
    """A ``.tuple`` file of relative motions, by its name."""
    return Path(path).suffix.lower() == ".tuple"


def export_relative(
    plan: OutputPlan,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
    method: str,
    exports: Exports,
    geometry: WheelGeometry | None = None,
    model: str = "full",
    files: dict[Path, Any] | None = None,
    doubts: Sequence[str] = (),
) -> tuple[Path, ...]:
    """PARAMS.yaml and the ros2_control file of a relative-motion fit (the sensor's mounting
    beside the values): ``geometry`` (default the fit's) of ``model``."""
    record: dict[str, str | float] = {
        "method": method,
        "sensor_x_m": result.sensor_x_m,
        "sensor_y_m": result.sensor_y_m,
        "sensor_yaw_rad": result.sensor_yaw_rad,
    }
    if model != "full":
        record["model"] = f"{model} (preferred by the held-out check)"
    chosen = result.geometry if geometry is None else geometry
    return exports.write(plan, chosen, nominal, files=files, record=record, doubts=doubts)


def route_figures(res: RelativeFitResult, plot: str | Path | None) -> dict[Path, Any] | None:
    """The bag route's figures for ``--plot`` (:mod:`odocal.plot.bag`); InputError when there
    is nothing to draw."""
    if plot is None:
        return None
    from ..plot.bag import bag_figures

    figures = bag_figures(res.time_offsets, res.heldout, plot)
    if not figures:
        raise InputError(
            "--plot: no clock offset was estimated and no held-out check was made (give "
            "--robot for the check); nothing to draw",
            field="plot",
        )
    return figures


def relative_checks(
    motions: RelativeMotions,
    usable: np.ndarray,
    mount: np.ndarray,
    result: SensorOdometryFit,
    nominal: WheelGeometry | None,
    *,
    source: str,
    force: bool = False,
    where: str | Path | None = None,
    noise: bool = True,
) -> RelativeChecks:
    """The held-out check and the one-log noise estimate of a bag route
    (:func:`~odocal.calibration.relative_checks.check_relative_fit`). A log too short for the
    check is an InputError unless ``force``; a calibration that no model can make beat the
    nominal one on the held-out blocks is a CalibrationError unless ``force`` (nothing
    written)."""
    checks = check_relative_fit(motions, usable, mount, result, nominal, source=source, noise=noise)
    if checks.heldout_problem is not None and not force:
        raise InputError(f"{checks.heldout_problem} (--force fits without it)", where)
    refuse_untrusted(checks.heldout, force)
    return checks


def write_bag_route(
    res: RelativeFitResult, plan: OutputPlan, exports: Exports, plot: str | Path | None
) -> RelativeFitResult:
    """Write a bag route's ``exports`` (the answer's geometry, of the model the held-out check
    preferred) and its figures into ``plot``; ``res`` with the files written."""
    files = route_figures(res, plot)
    written = export_relative(
        plan, res.fit, res.nominal, res.method, exports, res.geometry, res.model, files,
        res.forced,
    )  # fmt: skip
    return replace(res, written=written)


def fit_tuple_files(
    paths: Sequence[str | Path],
    plan: OutputPlan,
    *,
    robot: RobotSpec = None,
    exports: Exports = NO_EXPORTS,
    force: bool = False,
) -> RelativeFitResult:
    """``fit FILE.tuple ...``: the relative motions of ``.tuple`` files (the sensor's mounting
    estimated too)."""
    nominal = robot_nominal(robot)
    data = [read_tuples(p) for p in paths]
    refuse_still_tuples(data)
    refuse_repeated_tuples(data)
    motions = [RelativeMotions(d.phi_right_rad, d.phi_left_rad, d.sensor_motion) for d in data]
    result, forced = fit_relative(motions, nominal, force=force)
    written = export_relative(plan, result, nominal, "relative", exports, doubts=forced)
    inputs = tuple(TupleInput(str(d.path), len(d.phi_right_rad)) for d in data)
    return RelativeFitResult(
        result, nominal, len(paths), "tuples", tuple_files=inputs, written=written, forced=forced
    )


def relative_text(res: RelativeFitResult) -> str:
    """The text of a relative-motion fit (``.tuple`` files, SLAM bags, laser scans)."""
    out = Text()
    r, nominal = res.fit, res.nominal
    out(
        f"relative-motion fit (Censi et al. 2013) from {r.tuples_used} of {r.tuples_total} "
        f"intervals ({r.tuples_dropped} dropped as outliers)"
    )
    d = r.as_dict()
    rows = [("", "nominal", "calibrated", "std. error")]
    nom = {} if nominal is None else nominal.as_dict()
    for key in PARAMETERS:
        if key.startswith("sensor") and r.sensor_pose_fixed:
            continue
        v, se = d[key], d["stderr"].get(key)
        rows.append(
            (
                key,
                f"{nom[key]:.6f}" if key in nom else "-",
                "-" if v is None else f"{v:.6f}",
                "-" if se is None else f"{se:.2e}",
            )
        )
    out.table(rows)
    if r.covariance_formal is not None:
        out(f"  std. errors: {r.uncertainty} (formal ones in the JSON)")
    for b in res.slam_bags:
        out(f"  {b.path}: {b.chain}: {b.motions.summary()}")
        out(f"    wheels: {b.wheels}")
    for s in res.scans:
        x, y, yaw = s.mount_guess
        out(
            f"  {s.bag}: {s.intervals.matched} of {s.intervals.intervals} scan intervals matched "
            f"({s.scans} scans on {s.scan_topic}, {s.intervals.interval_scans} apart); laser "
            f"mounting from {s.mount_source}: x {x:.4f} m, y {y:.4f} m, yaw {yaw:.4f} rad"
        )
    _print_checks(out, res)
    written_lines(out, res.written)
    return str(out)


def _print_checks(out: Text, res: RelativeFitResult) -> None:
    """Clock offsets, the held-out check, the answer's model and the one-log noise."""
    for o in res.time_offsets:
        se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
        out(f"  clock offset of the {o.label}: {o.offset_s:+.4f}{se} s ({o.how}; > 0: its "
              "stamps run late)")  # fmt: skip
    if res.heldout is not None:
        out(f"  {res.heldout.verdict()}")
    if res.model != "full":
        g, errs = res.geometry, res.geometry_stderr
        cells = [
            f"{name} {v:.6f}" + (" (nominal)" if not e else f" +- {e:.2e}")
            for name, v, e in zip(("D_R", "D_L", "b"), (g.diameter_right_m, g.diameter_left_m,
                                                        g.wheelbase_m), errs, strict=True)
        ]  # fmt: skip
        out(f"  the answer is the '{res.model}' model: {', '.join(cells)} m")
    if res.noise is not None:
        n = res.noise
        lo, hi = n.k_ci95_m
        out(
            f"  random error: wheels k_r + k_l {n.k_sum_m:.3g} m (95 %: {lo:.3g} to {hi:.3g}); "
            f"truth {1e3 * n.truth_sigma_xy_m:.3g} mm, {math.degrees(n.truth_sigma_theta_rad):.3g}"
            f" deg per interval ({n.intervals} intervals)"
        )
    for note in res.notes:
        out(f"  {note}")
