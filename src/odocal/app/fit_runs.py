"""``odocal fit`` on runs with ground truth (or, for the heading method, a gyro heading): the
trajectory fit and its relatives, the linear estimator and UMBmark and the heading method on
recorded squares.

:func:`fit_runs` is the route itself, I/O-free over loaded recordings (as evo's
``main_ape.ape()``); :func:`fit_run_files` loads the runs, calls it and writes what was asked
for. The router :func:`odocal.app.fit.fit` chooses this route.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..calibration.banded import fit_trajectory_bands
from ..calibration.fit_methods import FitMethod
from ..calibration.fit_settings import (
    DEFAULT_SQUARES,
    DEFAULT_TRAJECTORY,
    SquareSettings,
    TrajectorySettings,
    check_method_settings,
)
from ..calibration.heldout import HeldOut, heldout_runs
from ..calibration.linear import fit_linear
from ..calibration.noise import refuse_without_repeats
from ..calibration.result import GeometryFit
from ..calibration.squares import fit_recorded_squares
from ..calibration.time_offset import TimeOffset, pooled_offset_s, truth_on_wheel_clock
from ..calibration.trajectory import fit_trajectory_model
from ..calibration.turning import EffectiveWheelbase
from ..core.model import Robot, WheelGeometry
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from .check import CheckResult, check_loaded, refuse_blind
from .common import (
    NO_EXPORTS,
    Exports,
    RobotSpec,
    load_warnings,
    nominal_geometry,
    optional_robot,
    refuse_absurd,
    refuse_still_runs,
    refuse_untrusted,
)
from .measured import MeasuredRobot, measure_robot
from .text import Presented, Text, check_text, written_lines

__all__ = [
    "FitResult",
    "fit_recordings",
    "fit_runs",
    "fit_run_files",
    "CHECK_MAX_BLOCKS",
]

# The finest segment layout the log check follows within fit (its dense covariance grows as
# blocks^2): beyond, the check is skipped with a warning.
CHECK_MAX_BLOCKS = 300


@dataclass(frozen=True)
class FitResult(Presented):
    """A fit from recorded runs, the nominal geometry it is compared with, the loaders'
    warnings and the files written.

    Attributes
    ----------
    fit : GeometryFit
    nominal : WheelGeometry or None
    recordings : int
        Runs loaded.
    load_warnings : tuple of str
        What the readers said.
    written : tuple of Path
    log_check : CheckResult or None
        Is this log enough? (trajectory fits; docs/check.md)
    forced : tuple of str
        The absurd-result messages accepted with ``force``.
    measured : MeasuredRobot or None
        The robot measured from the runs (``robot_out``).
    time_offsets : tuple of TimeOffset
        The truth's clock offset against the wheels, per data set (trajectory fits; applied).
    heldout : HeldOut or None
        The blocked cross-validation over the runs (trajectory fits with a nominal geometry).
    notes : tuple of str
        What was not checked, and why.
    """

    fit: GeometryFit
    nominal: WheelGeometry | None
    recordings: int
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    log_check: CheckResult | None = None
    forced: tuple[str, ...] = ()
    measured: MeasuredRobot | None = None
    time_offsets: tuple[TimeOffset, ...] = ()
    heldout: HeldOut | None = None
    notes: tuple[str, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The fit's warnings, and the absurd-result messages accepted with ``force``."""
        own = tuple(self.fit.warnings)
        offsets = tuple(w for o in self.time_offsets for w in o.warnings)
        return own + offsets + tuple(w for w in self.forced if w not in own)

    @property
    def time_offsets_s(self) -> dict[str, float]:
        """Source -> clock offset (s): the truth's estimate, weighted over the data sets by
        their standard errors (each data set's own, and whether it was applied, in
        ``time_offsets``)."""
        return {"truth": pooled_offset_s(self.time_offsets)} if self.time_offsets else {}

    def text(self) -> str:
        """The text ``odocal fit`` prints for a fit of runs with ground truth."""
        return runs_text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit --json``."""
        out = self.fit.as_dict()
        out["warnings"] = list(self.load_warnings) + list(self.warnings)
        out["nominal"] = None if self.nominal is None else self.nominal.as_dict()
        if self.log_check is not None:
            out["log_check"] = self.log_check.as_dict()
        if self.time_offsets or self.heldout is not None or self.notes:
            out["time_offsets_s"] = self.time_offsets_s
            out["time_offsets"] = [o.as_dict() for o in self.time_offsets]
            out["heldout"] = None if self.heldout is None else self.heldout.as_dict()
            out["notes"] = list(self.notes)
        return out


def fit_recordings(
    recordings: Sequence[Recording],
    method: FitMethod = "trajectory",
    *,
    nominal: WheelGeometry | None = None,
    ran_with: WheelGeometry | None = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    squares: SquareSettings = DEFAULT_SQUARES,
) -> GeometryFit:
    """Calibrate from loaded recordings (with ground truth, or for the heading method a gyro
    heading: ``squares.heading_source='gyro'``); returns a ``GeometryFit``.

    Trajectory fits also report the effective wheelbase per band of motion
    (``effective_wheelbase``, :mod:`odocal.calibration.turning`). ``settings.wheelbase_model``
    'banded' fits one wheelbase per excited band (:func:`~odocal.calibration.banded.fit_banded`;
    refused with the reason when the runs excite fewer than two bands). ``settings.motion_mix``
    (band -> share of the rotation) fits the banded model too and makes the result's wheelbase
    the single value that is best for that mix of its band wheelbases, with its standard error
    and what it costs (``motion_mix``); a share in a band the runs do not excite is refused."""
    check_method_settings(method, settings, squares)
    if squares.heading_source != "gyro":
        require_ground_truth(recordings, f"--method {method}")
    if method == "linear":
        return fit_linear(recordings, nominal)
    if method == "trajectory":
        return fit_trajectory_bands(recordings, nominal, settings)
    if method in ("umbmark", "heading"):
        return fit_recorded_squares(
            recordings,
            method,
            side_m=squares.side_m,
            ran_with=ran_with,
            nominal=nominal,
            umbmark_form=squares.umbmark_form,
            heading_source=squares.heading_source,
            sides=squares.sides,
        )
    raise InputError(f"unknown method {method!r}", field="method")


def _used(recordings: Sequence[Recording], fit: GeometryFit) -> list[Recording]:
    """The recordings the fit used."""
    names = set(fit.runs)
    return [r for r in recordings if r.name in names]


def _with_log_check(
    recordings: Sequence[Recording],
    fit: GeometryFit,
    robot: Robot | None,
    settings: TrajectorySettings,
) -> tuple[GeometryFit, CheckResult | None]:
    """Is this log enough? What the recorded motion let this fit see (docs/check.md); skipped
    (a warning on the fit) for a segment layout too fine to check quickly."""
    try:
        check = check_loaded(
            _used(recordings, fit),
            fit.geometry,
            robot,
            settings=settings,
            max_blocks_per_run=CHECK_MAX_BLOCKS,
        )
    except CalibrationError as exc:
        return replace(fit, warnings=[*fit.warnings, f"log check skipped: {exc}"]), None
    return fit, check


def fit_runs(
    recordings: Sequence[Recording],
    method: FitMethod = "trajectory",
    *,
    robot: Robot | None = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    squares: SquareSettings = DEFAULT_SQUARES,
    force: bool = False,
    measure: bool = False,
    truth_offset_s: float | None = None,
    heldout_check: bool = True,
) -> FitResult:
    """The route of runs with ground truth, I/O-free: calibrate ``recordings`` with ``method``
    against the nominal geometry (``robot``'s, else the runs' most common ran-with parameters),
    check the log (trajectory fits) and with ``measure`` measure the robot (this calibration's
    systematic errors, k from the repeated runs, the tracker's jitter).

    Trajectory fits first move each data set's truth onto the wheels' clock (its offset
    estimated, or ``truth_offset_s``), and afterwards check the answer on runs it did not fit
    (``heldout_check``; needs the nominal geometry): when no model beats the nominal one there,
    CalibrationError unless ``force``.

    A result more than 25 % from nominal is absurd for a calibration: CalibrationError unless
    ``force`` (then its messages are warnings). A run in which the robot never moves is an
    InputError."""
    refuse_still_runs(recordings)
    nominal = nominal_geometry(robot, recordings)
    if measure:  # refused before the fit, not after it
        if nominal is None:
            raise InputError("--robot-out needs the nominal geometry: give --robot ROBOT.yaml")
        refuse_without_repeats(recordings)
    ran_with = None if robot is None else robot.believed_geometry
    offsets: tuple[TimeOffset, ...] = ()
    if method == "trajectory":
        recordings, offsets = truth_on_wheel_clock(recordings, truth_offset_s)
    fit = fit_recordings(
        recordings, method, nominal=nominal, ran_with=ran_with, settings=settings, squares=squares
    )
    log_check = None
    heldout: HeldOut | None = None
    notes: tuple[str, ...] = ()
    blind: list[str] = []
    if method == "trajectory":
        fit, log_check = _with_log_check(recordings, fit, robot, settings)
        blind = refuse_blind(log_check, force)
        if heldout_check:
            heldout, notes = _heldout(_used(recordings, fit), nominal, fit, settings, force)
    forced = [*blind, *refuse_absurd(fit.geometry, nominal, force)]
    measured = None
    if measure:
        assert nominal is not None  # checked above
        measured = measure_robot(_used(recordings, fit), nominal, fit=fit, force=force)
    return FitResult(
        fit,
        nominal,
        len(recordings),
        load_warnings(recordings),
        (),
        log_check,
        tuple(forced),
        measured,
        offsets,
        heldout,
        notes,
    )


def _heldout(
    runs: Sequence[Recording],
    nominal: WheelGeometry | None,
    fit: GeometryFit,
    settings: TrajectorySettings,
    force: bool,
) -> tuple[HeldOut | None, tuple[str, ...]]:
    """The held-out check of a trajectory fit over its runs (:func:`heldout_runs`): a note
    when it cannot be made; CalibrationError (nothing written) unless ``force`` when no model
    beats the nominal geometry on runs it did not fit."""
    if nominal is None:
        return None, ("no held-out check: it needs the nominal geometry (--robot)",)
    fixed = replace(settings, drop_outliers=False, wheelbase_model="constant", motion_mix=None)
    try:
        h = heldout_runs(
            runs, nominal, fit.geometry,
            lambda rs, model: fit_trajectory_model(rs, model, nominal, fixed),
        )  # fmt: skip
    except CalibrationError as exc:
        return None, (f"no held-out check: {exc}",)
    refuse_untrusted(h, force)
    return h, ()


def fit_run_files(
    paths: Sequence[str | Path],
    method: FitMethod,
    plan: OutputPlan,
    *,
    robot: RobotSpec = None,
    settings: TrajectorySettings = DEFAULT_TRAJECTORY,
    squares: SquareSettings = DEFAULT_SQUARES,
    bag: BagOptions = NO_BAG_OPTIONS,
    ticks_per_rev: float | None = None,
    exports: Exports = NO_EXPORTS,
    plot: str | Path | None = None,
    robot_out: str | Path | None = None,
    force: bool = False,
) -> FitResult:
    """Load the runs in ``paths``, :func:`fit_runs` them, and write (all or none, checked
    against ``plan``'s inputs) the ``exports``, the effective-wheelbase figure into the folder
    ``plot`` and the measured robot to ``robot_out``."""
    notes: list[str] = []
    recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, warnings=notes, bag=bag)
    result = fit_runs(
        recordings,
        method,
        robot=optional_robot(robot),  # read once: it may be a pipe
        settings=settings,
        squares=squares,
        force=force,
        measure=robot_out is not None,
        truth_offset_s=bag.time_offset("truth"),
    )
    files: dict[Path, Any] = {}
    if plot is not None:
        from ..plot.fit import fit_figures

        files.update(fit_figures(result.fit, plot))
    if robot_out is not None and result.measured is not None:
        from ..io.robot_file import robot_yaml

        measured = result.measured
        files[Path(robot_out)] = robot_yaml(measured.robot, measured.describe())
    written = exports.write(
        plan, result.fit.geometry, result.nominal, files=files,
        record={"method": result.fit.method}, doubts=result.forced,
    )  # fmt: skip
    return replace(result, load_warnings=tuple(notes) + result.load_warnings, written=written)


def runs_text(res: FitResult) -> str:
    """The text of a fit of runs with ground truth: the geometry against nominal, then what the
    method adds and the log check."""
    out = Text()
    result, nominal = res.fit, res.nominal
    out(f"{result.method} fit from {len(result.runs)} run(s)")
    g, se = result.geometry.as_dict(), result.stderr
    nom = None if nominal is None else nominal.as_dict()
    rows = [("", "nominal", "calibrated", "std. error")]
    for key in ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m"):
        err = se.get(key)
        rows.append(
            (
                key,
                "-" if nom is None else f"{nom[key]:.6f}",
                f"{g[key]:.6f}",
                "-" if err is None else f"{err:.2e}",
            )
        )
    out.table(rows)
    if result.covariance_formal is not None:
        out(f"std. errors: {result.uncertainty} (formal ones in the JSON)")
    if result.squares is not None:
        out(
            f"pooled from {len(result.squares.data_sets)} data set(s): per data set, "
            "composed with its ran-with parameters; scale = nominal mean diameter"
        )
    if result.excluded:
        out("excluded: " + ", ".join(Path(n).name for n in result.excluded))
    rms = _residual_rms(result)
    if rms is not None:
        out(f"residual RMS {rms:.3g} ({_residual_kind(result)})")
    _print_bands(out, result)
    if res.log_check is not None:
        out("Is this log enough? (odocal check)")
        check_text(out, res.log_check, indent="  ")
    _print_offsets(out, res.time_offsets)
    if res.heldout is not None:
        out(res.heldout.verdict())
        line = res.heldout.drift_line()
        if line is not None:
            out(line)
    for note in res.notes:
        out(note)
    written_lines(out, res.written)
    return str(out)


def _print_offsets(out: Text, offsets: tuple[TimeOffset, ...]) -> None:
    """The clock offsets: every applied one, and how many were found within their noise."""
    quiet = [o for o in offsets if not o.applied]
    for o in offsets:
        if o.applied:
            se = "" if o.stderr_s is None else f" +- {o.stderr_s:.4f}"
            out(f"clock offset of the {o.label}: {o.offset_s:+.4f}{se} s ({o.how}; applied)")
    if quiet:
        worst = max(abs(o.offset_s) for o in quiet)
        out(
            f"clock offsets within their noise (not applied): {len(quiet)} of {len(offsets)} "
            f"source(s), at most {1e3 * worst:.1f} ms"
        )


def _residual_rms(fit: GeometryFit) -> float | None:
    if fit.trajectory is not None:
        return fit.trajectory.residual_rms
    return None if fit.banded is None else fit.banded.residual_rms


def _residual_kind(fit: GeometryFit) -> str:
    return "pose" if fit.trajectory is None else fit.trajectory.settings.residual


def _radius(lo: float, hi: float | None) -> str:
    if lo == 0:
        return f"< {hi:.3g}"
    return f"> {lo:.3g}" if hi is None else f"{lo:.3g}-{hi:.3g}"


def _print_band_table(out: Text, table: EffectiveWheelbase) -> None:
    rows = [
        (
            "band",
            "turn radius (m)",
            "eff. wheelbase (m)",
            "95 % interval",
            "segments",
            "share of rotation",
        )
    ]
    for b in table.bands:
        est, ci = "not excited", ""
        if b.excited and b.wheelbase_m is not None and b.ci95_m is not None:
            est = f"{b.wheelbase_m:.6f}"
            ci = f"{b.ci95_m[0]:.6f}-{b.ci95_m[1]:.6f}"
        rows.append(
            (
                b.band,
                _radius(*b.radius_range_m),
                est,
                ci,
                f"{b.segments} ({b.runs} runs)",
                f"{100 * b.rotation_share:.0f} %",
            )
        )
    out.table(rows, "effective wheelbase per band of motion (at the fitted diameters):")


def _print_bands(out: Text, fit: GeometryFit) -> None:
    """The effective wheelbase per band of motion, the banded fit and the motion mix."""
    if fit.effective_wheelbase is not None:
        _print_band_table(out, fit.effective_wheelbase)
    if fit.banded is not None:
        fitted = ", ".join(f"{k} {v:.6f} m" for k, v in fit.banded.band_wheelbase_m.items())
        out(f"banded model: {fitted}")
    mix = fit.motion_mix
    if mix is not None:
        shares = ", ".join(f"{k} {100 * v:.0f} %" for k, v in mix.mix.items())
        errs = ", ".join(f"{k} {v:+.2f}" for k, v in mix.heading_error_deg_per_turn.items())
        se = "" if mix.wheelbase_stderr_m is None else f" +- {mix.wheelbase_stderr_m:.2e}"
        out(
            f"single wheelbase for the motion mix ({shares}): {mix.wheelbase_m:.6f}{se} m; "
            f"heading error per full turn (deg): {errs}; RMS "
            f"{mix.rms_heading_error_deg_per_turn:.2f} deg per turn"
        )
