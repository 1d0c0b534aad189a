"""``odocal fit``: calibrate D_R, D_L and b from recorded runs (files, folders, bags)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field, replace
from pathlib import Path

import numpy as np

from ..calibration.banded import fit_banded
from ..calibration.censi import SensorOdometryFit, fit_censi, predict_sensor_motion
from ..calibration.gyro import GyroResult, gyro_calibration, integrate_rate
from ..calibration.linear import fit_linear
from ..calibration.result import ABSURD_FRACTION, GeometryFit
from ..calibration.scan_matching import match_intervals
from ..calibration.squares import fit_recorded_squares
from ..calibration.trajectory import fit_trajectory
from ..calibration.turning import (
    BANDS,
    effective_wheelbase,
    nearest_estimated_band,
    wheelbase_for_mix,
)
from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from ..io.bag_slam import load_slam_bag, wheel_increments
from ..io.bags import (
    BASE_FRAMES,
    IMU,
    JOINT_STATE,
    LASER_SCAN,
    ODOMETRY,
    check_bag_path,
    imu_series,
    is_bag,
    joint_series,
    pick_topic,
    pose_series,
    present,
    read_bag,
    scan_series,
    static_rotation,
    transform_buffer,
)
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, refuse_repeated, require_ground_truth
from ..io.robot_file import load_robot
from ..io.tuples import read_tuples
from .check import CheckResult, check_loaded
from .common import (
    input_paths,
    nominal_geometry,
    optional_robot,
    refuse_absurd,
    register_exports,
    write_exports,
)

__all__ = [
    "METHODS",
    "FitResult",
    "GyroFitResult",
    "fit",
    "fit_recordings",
    "fit_gyro",
    "fit_gyro_bag",
]

METHODS = ("trajectory", "linear", "umbmark", "heading", "gyro", "relative", "scan")
WHEELBASE_MODELS = ("constant", "banded")


def _check_heading_source(method: str, heading_source: str) -> None:
    if heading_source == "gyro" and method != "heading":
        raise InputError(f"--heading-source gyro is for --method heading, not {method}")


def fit_recordings(
    recordings: Sequence[Recording],
    method: str = "trajectory",
    *,
    nominal: WheelGeometry | None = None,
    ran_with: WheelGeometry | None = None,
    residual: str = "pose",
    segment_m: float = 1.0,
    heading_weight_m: float = 0.1,
    exclude=(),
    drop_outliers: bool = False,
    run_weight: str = "travel",
    side_m: float | None = None,
    umbmark_form: str = "mean",
    heading_source: str = "truth",
    sides: int = 4,
    wheelbase_model: str = "constant",
    motion_mix: dict[str, float] | None = None,
) -> GeometryFit:
    """Calibrate from loaded recordings (with ground truth, or for the heading method a gyro
    heading: ``heading_source='gyro'``); returns a ``GeometryFit``.

    Trajectory fits also report the effective wheelbase per band of motion
    (``extras['effective_wheelbase']``, :mod:`odocal.calibration.turning`). ``wheelbase_model``
    'banded' fits one wheelbase per excited band (:func:`fit_banded`; refused with the reason
    when the runs excite fewer than two bands). ``motion_mix`` (band -> share of the rotation)
    makes the result's wheelbase the single value that is best for that mix, with what it costs
    (``extras['motion_mix']``)."""
    if wheelbase_model not in WHEELBASE_MODELS:
        raise InputError(
            f"wheelbase model must be one of {', '.join(WHEELBASE_MODELS)}, got "
            f"{wheelbase_model!r}",
            field="wheelbase-model",
        )
    if method != "trajectory" and (wheelbase_model != "constant" or motion_mix):
        raise InputError(
            "--wheelbase-model banded and --motion-mix need the trajectory method "
            "(--method trajectory)",
            field="method",
        )
    _check_heading_source(method, heading_source)
    if heading_source != "gyro":
        require_ground_truth(list(recordings), f"--method {method}")
    if method == "linear":
        return fit_linear(recordings, nominal)
    if method == "trajectory":
        fit = fit_trajectory(
            recordings,
            nominal=nominal,
            residual=residual,
            segment_m=segment_m,
            heading_weight_m=heading_weight_m,
            exclude=exclude,
            drop_outliers=drop_outliers,
            run_weight=run_weight,
        )
        used = [r for r in recordings if r.name in set(fit.runs)]
        if wheelbase_model == "banded":
            banded = fit_banded(
                used,
                fit.geometry,
                nominal=nominal,
                mix=motion_mix,
                heading_weight_m=heading_weight_m,
            )
            return replace(
                banded,
                excluded=fit.excluded,
                outliers=fit.outliers,
                per_run=fit.per_run,
                warnings=list(fit.warnings) + list(banded.warnings),
                extras={**banded.extras, "constant_fit": fit.geometry.as_dict()},
            )
        return _with_bands(fit, used, motion_mix)
    if method in ("umbmark", "heading"):
        return fit_recorded_squares(
            recordings,
            method,
            side_m=side_m,
            ran_with=ran_with,
            nominal=nominal,
            umbmark_form=umbmark_form,
            heading_source=heading_source,
            sides=sides,
        )
    raise InputError(f"unknown method {method!r}", field="method")


def _with_bands(fit: GeometryFit, runs, motion_mix) -> GeometryFit:
    """The constant-wheelbase fit with its effective wheelbase per band of motion, a warning
    when excited bands disagree, and (with ``motion_mix``) the single wheelbase for the mix
    from the band estimates."""
    table = effective_wheelbase(runs, fit.geometry)
    extras = {**fit.extras, "wheelbase_model": "constant", "effective_wheelbase": table.as_dict()}
    warnings = list(fit.warnings)
    excited = [b for b in table.bands if b.excited and b.ci95_m is not None]
    for i, x in enumerate(excited):
        for y in excited[i + 1 :]:
            if x.ci95_m[1] < y.ci95_m[0] or y.ci95_m[1] < x.ci95_m[0]:
                warnings.append(
                    f"the robot turns differently in band '{x.band}' (effective wheelbase "
                    f"{x.wheelbase_m:.5g} m) and band '{y.band}' ({y.wheelbase_m:.5g} m; 95 % "
                    "intervals apart): one wheelbase is a compromise; see --wheelbase-model "
                    "banded and --motion-mix"
                )
    geometry = fit.geometry
    if motion_mix:
        known = {b.band: b.wheelbase_m for b in table.bands if b.excited}
        if not known:
            raise InputError(
                "--motion-mix: no band of motion is excited by these runs, so no band has an "
                "effective wheelbase to mix",
                field="motion-mix",
            )
        idx = [BANDS.index(k) for k in known]
        nearest = nearest_estimated_band(idx)
        per_band = {n: known[BANDS[nearest[i]]] for i, n in enumerate(BANDS)}
        for name, share in motion_mix.items():
            if share > 0 and name not in known:
                warnings.append(
                    f"the motion mix turns {100 * share:.0f} % in band '{name}', which these "
                    f"runs do not excite: its wheelbase is taken from band "
                    f"'{BANDS[nearest[BANDS.index(name)]]}'"
                )
        choice = wheelbase_for_mix(per_band, motion_mix)
        geometry = WheelGeometry(
            geometry.diameter_right_m, geometry.diameter_left_m, choice.wheelbase_m
        )
        extras["motion_mix"] = choice.as_dict()
        extras["constant_fit"] = fit.geometry.as_dict()
    return replace(fit, geometry=geometry, warnings=warnings, extras=extras)


@dataclass(frozen=True)
class FitResult:
    """A fit from recorded runs, the nominal geometry it is compared with, the loaders'
    warnings and the files written."""

    fit: GeometryFit | SensorOdometryFit
    nominal: WheelGeometry | None
    recordings: int
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()
    extra: dict = field(default_factory=dict)
    log_check: CheckResult | None = None
    forced: tuple[str, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The fit's warnings, and the absurd-result messages accepted with ``force``."""
        own = tuple(self.fit.warnings)
        return own + tuple(w for w in self.forced if w not in own)

    def as_dict(self) -> dict:
        """The JSON of ``odocal fit --json``."""
        out = self.fit.as_dict()
        out["warnings"] = list(self.load_warnings) + list(self.warnings)
        out["nominal"] = None if self.nominal is None else self.nominal.as_dict()
        out.update(self.extra)
        if self.log_check is not None:
            out["log_check"] = self.log_check.as_dict()
        return out


def _at_diameters(result: GeometryFit, reference: WheelGeometry) -> dict | None:
    """A banded fit's wheelbases rescaled to ``reference``'s mean diameter (the same turning
    gains), so that they compare with the band table, which is at the reference's diameters."""
    bands = result.extras.get("band_wheelbase_m")
    if not bands:
        return None
    scale = float(reference.mean_diameter_m / result.geometry.mean_diameter_m)
    return {k: v * scale for k, v in bands.items()}


def _load_warnings(recordings) -> tuple[str, ...]:
    return tuple(
        f"{r.name}: {w}" for r in recordings for w in (r.meta.get("warnings", ()) if r.meta else ())
    )


def _is_tuple_file(path) -> bool:
    return Path(path).suffix.lower() == ".tuple"


def fit(
    paths: Sequence[str | Path],
    method: str | None = None,
    *,
    robot=None,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = "diff_drive_controller",
    ticks_per_rev: float | None = None,
    bag_options: dict | None = None,
    force: bool = False,
    truth_frames: tuple[str, str] | None = None,
    slam_stamp_offset_s: float = 0.0,
    scan_interval_s: float = 0.5,
    plot: str | Path | None = None,
    robot_out: str | Path | None = None,
    **options,
) -> FitResult:
    """Load the runs in ``paths`` and calibrate with ``method`` (not 'gyro': see
    :func:`fit_gyro`); write PARAMS.yaml to ``out``, a ros2_control file to ``ros2`` and the
    effective-wheelbase figure (trajectory fits) into the folder ``plot`` and the measured robot
    (this calibration's systematic errors, k from the repeated runs among ``paths``, the tracker's
    jitter) to ``robot_out`` (a ROBOT.yaml for ``odocal design --robot``).

    ``robot``: ROBOT.yaml (nominal geometry; for runs without metadata, the parameters they ran
    with: its 'believed', else nominal). A result more than 25 % from nominal is absurd for a
    calibration: CalibrationError (nothing written) unless ``force``. ``options`` go to
    :func:`fit_recordings`.

    Relative motions (``method='relative'``, the default for them): ``.tuple`` files (wheel
    rotations and sensor displacements per interval; the sensor's mounting is estimated too), or
    bags whose ground truth is a SLAM pose on /tf between ``truth_frames`` (e.g. ('map',
    'base_link'); only the relative motions between the SLAM's update instants are used, see
    docs/slam-truth.md).

    Laser scans (``method='scan'``): bags with wheel joints and ``sensor_msgs/LaserScan``; the
    laser's own motion between scans ``scan_interval_s`` apart comes from scan matching
    (:mod:`odocal.calibration.scan_matching`), then the same relative-motion calibration, the
    laser's mounting included. Needs the nominal geometry (``robot``) for the matcher's start."""
    if isinstance(paths, (str, Path)):
        paths = [paths]
    plan = OutputPlan(input_paths(list(paths), robot))
    if plot is not None and method not in (None, "trajectory"):
        raise InputError("--plot draws the effective wheelbase of a trajectory fit", field="plot")
    if robot_out is not None and method in ("relative", "scan"):
        raise InputError("--robot-out needs runs with ground truth (not --method relative/scan)")
    register_exports(plan, out, ros2)
    if robot_out is not None:
        plan.file(robot_out, "--robot-out")
    if plot is not None:
        from ..plot._figure import require_matplotlib

        require_matplotlib()
        plan.folder(plot, "--plot")
    refuse_repeated(paths)  # the same file twice would count twice, whatever it holds
    common = dict(
        robot=robot,
        out=out,
        ros2=ros2,
        controller_name=controller_name,
        ticks_per_rev=ticks_per_rev,
        bag_options=bag_options or {},
        force=force,
    )
    if method == "scan":
        return _fit_scan(paths, plan, scan_interval_s=scan_interval_s, **common)
    # a pipe or <(...) has no name to tell a tuple file by: --method relative says it is one
    tuples = [
        p
        for p in paths
        if _is_tuple_file(p) or (method == "relative" and truth_frames is None and not is_bag(p))
    ]
    if tuples or truth_frames is not None or method == "relative":
        if method not in (None, "relative"):
            what = "--truth-frames (a SLAM pose)" if truth_frames else ".tuple files"
            raise InputError(
                f"{what} give relative motions only: use --method relative, not --method {method}"
            )
        return _fit_relative(
            paths,
            tuples,
            plan,
            truth_frames=truth_frames,
            slam_stamp_offset_s=slam_stamp_offset_s,
            **common,
        )
    method = method or "trajectory"
    # before the runs are loaded (many bags take a while), as fit_recordings checks it
    _check_heading_source(method, options.get("heading_source", "truth"))
    opts = {k: v for k, v in (bag_options or {}).items() if k != "scan_topic"}
    notes: list[str] = []
    recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, warnings=notes, **opts)
    r = optional_robot(robot)  # read once: it may be a pipe
    nominal = nominal_geometry(r, recordings)
    ran_with = None if r is None else r.believed_geometry
    result = fit_recordings(recordings, method, nominal=nominal, ran_with=ran_with, **options)
    log_check = None
    if method == "trajectory":
        # is this log enough? what the recorded motion let this fit see (docs/check.md)
        used = set(result.runs)
        try:
            log_check = check_loaded(
                [r for r in recordings if r.name in used],
                result.geometry,
                r,
                max_blocks_per_run=_CHECK_MAX_BLOCKS,
                **{k: options[k] for k in _CHECK_SETTINGS if k in options},
            )
        except CalibrationError as exc:  # a very fine segment layout: the check would be slow
            result = replace(result, warnings=[*result.warnings, f"log check skipped: {exc}"])
    files = {}
    if plot is not None:
        from ..plot.real_experiment import wheelbase_bands_figure

        used = [r for r in recordings if r.name in set(result.runs)]
        lines = {"one wheelbase (this fit)": float(result.geometry.wheelbase_m)}
        reference = result.geometry
        if "constant_fit" in result.extras:
            c = result.extras["constant_fit"]
            reference = WheelGeometry(
                c["wheel_diameter_right_m"], c["wheel_diameter_left_m"], c["wheelbase_m"]
            )
            lines = {
                "constant fit": c["wheelbase_m"],
                "single value for the motion mix": float(
                    result.geometry.wheelbase_m
                    * reference.mean_diameter_m
                    / result.geometry.mean_diameter_m
                ),
            }
        table = effective_wheelbase(used, reference)
        files[Path(plot) / "effective_wheelbase.png"] = wheelbase_bands_figure(
            {"segment estimate": table},
            "Effective wheelbase per band of motion",
            lines,
            _at_diameters(result, reference),
        )
    forced = refuse_absurd(result.geometry, nominal, force)
    if robot_out is not None:
        from ..io.robot_file import robot_yaml
        from .measured import measure_robot

        if nominal is None:
            raise InputError("--robot-out needs the nominal geometry: give --robot ROBOT.yaml")
        used = [r for r in recordings if r.name in set(result.runs)]
        measured = measure_robot(used, nominal, fit=result, force=force)
        files[Path(robot_out)] = robot_yaml(measured.robot, measured.describe())
    written = write_exports(
        plan,
        result.geometry,
        nominal,
        out,
        ros2,
        controller_name,
        files=files,
        method=result.method,
    )
    return FitResult(
        result,
        nominal,
        len(recordings),
        tuple(notes) + _load_warnings(recordings),
        written,
        {},
        log_check,
        tuple(forced),
    )


# fit_recordings' options that the log check shares (the trajectory fit's residual settings), and
# the finest segment layout it follows within fit (its dense covariance grows as blocks^2)
_CHECK_SETTINGS = ("residual", "segment_m", "heading_weight_m", "run_weight")
_CHECK_MAX_BLOCKS = 300


def _stack_increments(parts) -> tuple[np.ndarray, np.ndarray]:
    """Per-interval wheel increments of several bags, (right, left), rows zero padded to one
    width."""
    k = max(r.shape[1] for r, _ in parts)

    def pad(a: np.ndarray) -> np.ndarray:
        return np.pad(a, ((0, 0), (0, k - a.shape[1])))

    return (
        np.concatenate([pad(r) for r, _ in parts]),
        np.concatenate([pad(lft) for _, lft in parts]),
    )


def _fit_relative(
    paths,
    tuples,
    plan: OutputPlan,
    *,
    robot,
    out,
    ros2,
    controller_name,
    ticks_per_rev,
    bag_options: dict,
    truth_frames,
    slam_stamp_offset_s: float,
    force: bool = False,
) -> FitResult:
    """Relative-motion calibration (Censi et al. 2013) from tuple files or SLAM bags."""
    nominal = load_robot(robot).nominal if robot else None
    extra: dict = {}
    if tuples:
        if len(tuples) != len(paths):
            raise InputError(".tuple files cannot be mixed with other run files in one fit")
        if truth_frames is not None:
            raise InputError("--truth-frames is for bags; .tuple files hold relative motions")
        data = [read_tuples(p) for p in tuples]
        phi_r = np.concatenate([d.phi_right_rad for d in data])
        phi_l = np.concatenate([d.phi_left_rad for d in data])
        motion = np.concatenate([d.sensor_motion for d in data])
        result = fit_censi(phi_r, phi_l, motion, nominal=nominal)
        extra["inputs"] = [{"path": str(d.path), "tuples": len(d.phi_right_rad)} for d in data]
    else:
        if truth_frames is None:
            raise InputError("--method relative needs .tuple files or bags with --truth-frames")
        bags = []
        for p in paths:
            if not is_bag(p):
                raise InputError("--truth-frames needs ROS bags", p)
            bags.append(
                load_slam_bag(
                    p,
                    truth_frames,
                    joint_topic=bag_options.get("joint_topic"),
                    right_joint=bag_options.get("right_joint"),
                    left_joint=bag_options.get("left_joint"),
                    ticks_per_rev=ticks_per_rev,
                    stamp_offset_s=slam_stamp_offset_s,
                )
            )
        m = [b.motions for b in bags]
        result = fit_censi(
            np.concatenate([x.phi_right_rad for x in m]),
            np.concatenate([x.phi_left_rad for x in m]),
            np.concatenate([x.sensor_motion for x in m]),
            sensor_pose=(0.0, 0.0, 0.0),  # the truth frame is the base itself
            nominal=nominal,
            wheel_increments=_stack_increments([b.increments for b in bags]),
        )
        extra["slam"] = [
            {
                "bag": b.path,
                "chain": b.chain,
                "correction_edge": b.correction,
                **asdict(b.motions.counts),
                "dropped": b.motions.counts.dropped,
                "segments": b.motions.segments,
                "summary": b.motions.summary(),
                "warnings": list(b.motions.warnings),
            }
            for b in bags
        ]
    record = {
        "sensor_x_m": result.sensor_x_m,
        "sensor_y_m": result.sensor_y_m,
        "sensor_yaw_rad": result.sensor_yaw_rad,
    }
    forced = refuse_absurd(result.geometry, nominal, force)
    written = write_exports(
        plan, result.geometry, nominal, out, ros2, controller_name, method="relative", **record
    )
    return FitResult(result, nominal, len(paths), (), written, extra, forced=tuple(forced))


def _fit_scan(
    paths,
    plan: OutputPlan,
    *,
    robot,
    out,
    ros2,
    controller_name,
    ticks_per_rev,
    bag_options: dict,
    scan_interval_s: float,
    force: bool = False,
) -> FitResult:
    """``fit BAG --method scan``: scan matching, then the relative-motion calibration."""
    if not robot:
        raise InputError(
            "--method scan needs the nominal geometry (--robot ROBOT.yaml): the scan matcher "
            "starts from the odometry's motion"
        )
    nominal = load_robot(robot).nominal
    parts = []
    for p in paths:
        if not is_bag(p):
            raise InputError("--method scan needs ROS bags with laser scans", p)
        parts.append(_scan_intervals(p, nominal, ticks_per_rev, bag_options, scan_interval_s))

    def stack(key: str) -> np.ndarray:
        return np.concatenate([x[key] for x in parts])

    result = fit_censi(
        stack("phi_right_rad"),
        stack("phi_left_rad"),
        stack("motion"),
        nominal=nominal,
        wheel_increments=_stack_increments([x["increments"] for x in parts]),
    )
    record = {
        "sensor_x_m": result.sensor_x_m,
        "sensor_y_m": result.sensor_y_m,
        "sensor_yaw_rad": result.sensor_yaw_rad,
    }
    forced = refuse_absurd(result.geometry, nominal, force)
    written = write_exports(
        plan, result.geometry, nominal, out, ros2, controller_name, method="scan", **record
    )
    extra = {"method": "scan", "scan": [x["summary"] for x in parts]}
    return FitResult(result, nominal, len(paths), (), written, extra, forced=tuple(forced))


def _scan_intervals(path, nominal, ticks_per_rev, bag_options: dict, interval_s: float) -> dict:
    """Wheel rotations and scan-matched laser motions over intervals of one bag."""
    p = check_bag_path(path)

    def choose(info):
        opt = bag_options.get
        return {
            "joints": pick_topic(
                info, opt("joint_topic"), (JOINT_STATE,), "wheel joints", p, "--joint-topic"
            ),
            "scan": pick_topic(
                info, opt("scan_topic"), (LASER_SCAN,), "laser scans", p, "--scan-topic"
            ),
            "tf": present(info, "/tf"),
            "tf_static": present(info, "/tf_static"),
        }

    bag = read_bag(p, choose)
    jt, st = bag.picked["joints"], bag.picked["scan"]
    joints = joint_series(
        bag, jt, bag_options.get("right_joint"), bag_options.get("left_joint"), ticks_per_rev
    )
    scans = scan_series(bag, st)
    warnings = []
    mount = np.zeros(3)
    mount_source = "none (assumed at the base origin)"
    buf = transform_buffer(bag)
    base = next((f for f in BASE_FRAMES if f in buf.frames), None)
    if base is not None and scans.frame_id in buf.frames:
        mount = buf.lookup(base, scans.frame_id, scans.time_s[:1], max_extrapolation_s=1e9)
        mount = mount.planar()[0]
        mount_source = f"tf ({base} -> {scans.frame_id})"
    else:
        warnings.append(
            f"no transform from the base to the laser frame '{scans.frame_id}': the matcher "
            "starts as if the laser sat at the base origin"
        )
    t_j, right, left = joints.time_s, joints.values["right"], joints.values["left"]
    inside = np.flatnonzero((scans.time_s >= t_j[0]) & (scans.time_s <= t_j[-1]))
    if len(inside) < 2:
        raise InputError("the laser scans and the wheel joints hardly overlap in time", p, None, st)
    t_s = scans.time_s[inside]
    stride = max(1, int(round(interval_s / float(np.median(np.diff(t_s))))))
    starts = np.arange(0, len(inside) - stride, stride)
    iv = np.column_stack([inside[starts], inside[starts + stride]])
    wr, wl = np.interp(scans.time_s, t_j, right), np.interp(scans.time_s, t_j, left)
    phi_r, phi_l = wr[iv[:, 1]] - wr[iv[:, 0]], wl[iv[:, 1]] - wl[iv[:, 0]]
    moving = np.maximum(np.abs(phi_r), np.abs(phi_l)) > 1e-3
    iv, phi_r, phi_l = iv[moving], phi_r[moving], phi_l[moving]
    guesses = predict_sensor_motion(nominal, mount, phi_r, phi_l)
    try:
        matches = match_intervals(scans.time_s, scans.points_m, iv, guesses)
    except CalibrationError as exc:
        raise InputError(str(exc), p, None, st) from None
    ok = matches.usable
    if ok.sum() < 10:
        raise InputError(
            f"only {int(ok.sum())} of {len(ok)} scan intervals matched; record a longer drive "
            "in a room with walls the laser sees",
            p,
            None,
            st,
        )
    inc = wheel_increments(t_j, right, left, matches.start_time_s[ok], matches.end_time_s[ok])
    summary = {
        "bag": str(p),
        "scan_topic": st,
        "joint_topic": jt,
        "scans": int(len(scans.time_s)),
        "interval_scans": int(stride),
        "intervals": int(len(ok)),
        "matched": int(ok.sum()),
        "not_converged": int((~matches.converged).sum()),
        "degenerate": int(matches.degenerate.sum()),
        "mount_guess": {"x_m": float(mount[0]), "y_m": float(mount[1]), "yaw_rad": float(mount[2])},
        "mount_source": mount_source,
        "warnings": warnings,
    }
    return {
        "phi_right_rad": phi_r[ok],
        "phi_left_rad": phi_l[ok],
        "motion": matches.motion[ok],
        "increments": inc,
        "summary": summary,
    }


@dataclass(frozen=True)
class GyroFitResult:
    """A gyro-only calibration from a bag, with the calibrated geometry when the nominal one is
    known (effective wheelbase = nominal b x wheelbase_multiplier; diameters unchanged)."""

    gyro: GyroResult
    nominal: WheelGeometry | None
    geometry: WheelGeometry | None
    written: tuple[Path, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        return tuple(self.gyro.warnings)

    def as_dict(self) -> dict:
        out = self.gyro.as_dict()
        if self.geometry is not None:
            out.update({f"calibrated_{k}": v for k, v in self.geometry.as_dict().items()})
        return out


def fit_gyro(
    bag: str | Path,
    *,
    robot=None,
    out: str | Path | None = None,
    ros2: str | Path | None = None,
    controller_name: str = "diff_drive_controller",
    odom_topic: str | None = None,
    imu_topic: str | None = None,
    joint_topic: str | None = None,
    imu_axis: str | None = None,
    force: bool = False,
) -> GyroFitResult:
    """``odocal fit BAG --method gyro``: the gyro's rotation against the wheel odometry's.

    A wheelbase multiplier more than 25 % from 1 is absurd for a calibration: CalibrationError
    (nothing written) unless ``force``."""
    plan = OutputPlan([Path(bag), *([Path(robot)] if robot and Path(robot).exists() else [])])
    register_exports(plan, out, ros2)
    nominal = load_robot(robot).nominal if robot else None
    opts = {
        "odom_topic": odom_topic,
        "imu_topic": imu_topic,
        "joint_topic": joint_topic,
        "imu_axis": imu_axis,
        "wheel_geometry": nominal,
    }
    result = fit_gyro_bag(bag, **{k: v for k, v in opts.items() if v})
    if (out or ros2) and nominal is None:
        raise InputError("--out/--ros2 with --method gyro need the nominal geometry: --robot")
    m = float(result.wheelbase_multiplier)
    if abs(m - 1) > ABSURD_FRACTION and not force:
        raise CalibrationError(
            f"wheelbase_multiplier = {m:.6g} is {100 * (m - 1):+.0f} % from 1: absurd for a "
            "calibration; check the IMU axis and the wheel joints; nothing written (--force "
            "accepts the result anyway)"
        )
    geometry = None
    written: tuple[Path, ...] = ()
    if nominal is not None:
        geometry = WheelGeometry(
            nominal.diameter_right_m,
            nominal.diameter_left_m,
            nominal.wheelbase_m * result.wheelbase_multiplier,
        )
        written = write_exports(plan, geometry, nominal, out, ros2, controller_name, method="gyro")
    return GyroFitResult(result, nominal, geometry, written)


def fit_gyro_bag(
    path,
    *,
    odom_topic: str | None = None,
    imu_topic: str | None = None,
    joint_topic: str | None = None,
    imu_axis: str | None = None,
    wheel_geometry: WheelGeometry | None = None,
    imu_rotation=None,
    right_joint: str | None = None,
    left_joint: str | None = None,
    invert_right: bool = False,
    invert_left: bool = False,
    bias="auto",
    min_still_s: float = 1.0,
):
    """Gyro-only heading calibration from a bag (see :mod:`odocal.calibration.gyro`).

    The odometric rotation comes from a ``nav_msgs/Odometry`` topic (its POSE yaw, unwrapped:
    the controller's own integrated heading, which also covers dropped messages and is not
    smoothed like the twist; the twist's angular.z is integrated only if the pose never turns),
    or from JointState wheel angles with ``wheel_geometry`` (nominal diameters and wheelbase).
    Topic defaults: explicit topics win; else the only Odometry topic; else the JointState topic
    (needs ``wheel_geometry``). IMU mounting: ``imu_axis`` if given, else ``/tf_static`` (base
    frame = the odometry's child frame, or base_link / base_footprint), else detected.
    With ``wheel_geometry`` the result's meta also holds ``wheelbase_used_m`` and
    ``wheelbase_corrected_m`` (with an Odometry topic, pass the geometry the controller ran with).
    ``imu_rotation`` (shape (3, 3), R_base_imu, e.g. from
    :func:`~odocal.calibration.gyro.rotation_from_rpy`) overrides ``/tf_static``.
    Returns a :class:`~odocal.calibration.gyro.GyroResult`. Bags only: reads it with
    :mod:`odocal.io.bags`.
    """
    p = check_bag_path(path)

    def choose(info):
        it = pick_topic(info, imu_topic, (IMU,), "gyro", p, "--imu-topic")
        use_joints = joint_topic is not None
        if odom_topic is None and joint_topic is None:
            has_odom = any(t.msgtype == ODOMETRY for t in info)
            has_joints = any(t.msgtype == JOINT_STATE for t in info)
            use_joints = not has_odom and has_joints
        if use_joints:
            if wheel_geometry is None:
                raise InputError(
                    "odometry from wheel joints needs the nominal wheel geometry (--robot)", p
                )
            src = pick_topic(info, joint_topic, (JOINT_STATE,), "wheel joints", p, "--joint-topic")
        else:
            src = pick_topic(info, odom_topic, (ODOMETRY,), "wheel odometry", p, "--odom-topic")
        return {"imu": it, "odometry": src, "tf_static": present(info, "/tf_static")}

    bag = read_bag(p, choose)
    it, src = bag.picked["imu"], bag.picked["odometry"]
    use_joints = bag.msgtype(src) == JOINT_STATE
    imu = imu_series(bag, it)
    meta = {"bag": str(p), "imu_topic": it, "odom_topic": src}
    if use_joints:
        js = joint_series(bag, src, right_joint, left_joint)
        g = wheel_geometry
        s_r = js.values["right"] * (0.5 * g.diameter_right_m * (-1.0 if invert_right else 1.0))
        s_l = js.values["left"] * (0.5 * g.diameter_left_m * (-1.0 if invert_left else 1.0))
        t_o, yaw = js.time_s, (s_r - s_l) / g.wheelbase_m
        speed = np.gradient(0.5 * (s_r + s_l), t_o) if len(t_o) > 2 else None
        base_frames = BASE_FRAMES
        meta.update(odometry_source="joint_states", **js.meta)
    else:
        od = pose_series(bag, src)
        t_o, speed = od.time_s, od.values["speed"]
        yaw = od.values["yaw"]
        meta["odometry_source"] = "pose_yaw"
        if np.ptp(yaw) < 1e-9 and np.any(np.abs(od.values["yaw_rate"]) > 1e-6):
            yaw = integrate_rate(t_o, od.values["yaw_rate"])
            meta["odometry_source"] = "twist_integrated"
        base_frames = ((od.child_frame_id,) if od.child_frame_id else ()) + BASE_FRAMES
    rotation, source = imu_rotation, ("rotation" if imu_rotation is not None else None)
    if imu_axis is None and imu_rotation is None and imu.frame_id:
        rot, parent = static_rotation(bag, imu.frame_id, base_frames)
        if rot is not None:
            same = parent == imu.frame_id.lstrip("/")
            rotation, source = rot, ("imu frame_id is the base frame" if same else "tf_static")
            meta["tf_chain"] = f"{parent} -> {imu.frame_id}"
    try:
        result = gyro_calibration(
            imu.time_s,
            imu.values["angular_velocity"],
            t_o,
            odom_yaw_rad=yaw,
            odom_speed_m_s=speed,
            rotation=rotation,
            imu_axis=imu_axis,
            mounting_source=source,
            bias=bias,
            min_still_s=min_still_s,
            meta=meta,
        )
    except CalibrationError as exc:
        hint = ""
        if use_joints and "opposite directions" in str(exc):
            hint = "; or the wheel joints are swapped"
        raise InputError(f"{exc}{hint} (IMU '{it}', odometry '{src}')", p) from None
    if wheel_geometry is not None:
        b = float(wheel_geometry.wheelbase_m)
        extra = {"wheelbase_used_m": b, "wheelbase_corrected_m": b * result.wheelbase_multiplier}
        result = replace(result, meta={**result.meta, **extra})
    return result
