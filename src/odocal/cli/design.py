"""``odocal design``: which test track to drive for calibration (the paper's procedure)."""

from __future__ import annotations

import argparse
import math
from typing import TYPE_CHECKING, Any

from ..core.checks import parse_float, parse_int
from .common import (
    MAX_LENGTH_M,
    ProgressBar,
    add_robot_args,
    fraction,
    positive_int,
    print_json,
    print_warnings,
    seed_int,
    sides_int,
    sigma_theta_deg,
    sigma_xy_m,
    trials_int,
)

if TYPE_CHECKING:
    import numpy as np

    from ..core.model import MeasurementNoise
    from ..design.result import ValidationTrack


def parse_side_lengths(text: str) -> np.ndarray:
    """'START:STOP:STEP' (m, STOP inclusive within float tolerance) or one length 'L'."""
    parts = text.split(":")
    try:
        nums = [parse_float(p.strip()) for p in parts]
    except ValueError:
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP in metres (e.g. 0.5:10:0.5), got {text!r}"
        ) from None
    if len(nums) == 1:
        nums = [nums[0], nums[0], 1.0]
    if len(nums) != 3:
        raise argparse.ArgumentTypeError(
            f"expected START:STOP:STEP in metres (e.g. 0.5:10:0.5), got {text!r}"
        )
    start, stop, step = nums
    if not all(math.isfinite(v) and v > 0 for v in nums):
        raise argparse.ArgumentTypeError(
            f"START, STOP and STEP must be finite numbers > 0, got {text!r}"
        )
    if stop < start:
        raise argparse.ArgumentTypeError(f"STOP must be >= START, got {text!r}")
    if stop > MAX_LENGTH_M:
        raise argparse.ArgumentTypeError(
            f"side lengths must be at most {MAX_LENGTH_M:g} m (check the units), got {text!r}"
        )
    count = math.floor((stop - start) / step + 1e-9) + 1
    if count > 1000:
        raise argparse.ArgumentTypeError(f"{count} side lengths is too many (at most 1000)")
    import numpy as np

    lengths = np.round(start + step * np.arange(count), 12)
    if lengths[0] <= 0:  # below the 1e-12 m rounding
        raise argparse.ArgumentTypeError(f"side lengths must be at least 1e-12 m, got {text!r}")
    return lengths


def parse_validation(text: str) -> ValidationTrack:
    """'SIDES:LENGTH:DIRECTION', e.g. '4:4:ccw' (the paper's 4 m x 4 m square CCW)."""
    from ..core.tracks import MAX_POLYGON_SIDES
    from ..design.result import ValidationTrack

    parts = text.split(":")
    hint = f"expected SIDES:LENGTH:DIRECTION (e.g. 4:4:ccw), got {text!r}"
    if len(parts) != 3:
        raise argparse.ArgumentTypeError(hint)
    try:
        sides = parse_int(parts[0].strip())
        length = parse_float(parts[1].strip())
    except ValueError:
        raise argparse.ArgumentTypeError(hint) from None
    direction = parts[2].strip().lower()
    if sides < 3:
        raise argparse.ArgumentTypeError(f"a polygon needs at least 3 sides, got {text!r}")
    if sides > MAX_POLYGON_SIDES:
        raise argparse.ArgumentTypeError(
            f"a polygon has at most {MAX_POLYGON_SIDES} sides, got {text!r}"
        )
    if not (math.isfinite(length) and 0 < length <= MAX_LENGTH_M):
        raise argparse.ArgumentTypeError(
            f"LENGTH must be a number > 0 and at most {MAX_LENGTH_M:g} m, got {text!r}"
        )
    if direction not in ("cw", "ccw"):
        raise argparse.ArgumentTypeError(f"DIRECTION must be cw or ccw, got {text!r}")
    return ValidationTrack(sides, length, direction)


def validation_arg(text: str) -> ValidationTrack | str:
    """A polygon 'SIDES:LENGTH:DIRECTION', or (a name ending in .csv) a command file's path,
    which only ``--route`` reads."""
    if text.strip().lower().endswith(".csv"):
        return text
    return parse_validation(text)


def add_parser(sub) -> None:
    """Add ``odocal design``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "design",
        description="For each candidate polygon test track, simulate the calibration many times "
        "(n CW + n CCW runs, calibrate, drive a validation track with the result) and recommend "
        "the smallest track that no larger one beats significantly by more than the tolerance. "
        "With no arguments: the paper's Fig. 5 conditions on the built-in robot.",
    )
    add_robot_args(
        p,
        "parameters the robot runs with during the test (default: ROBOT.yaml's 'believed', "
        "else nominal)",
    )
    p.add_argument(
        "--sides",
        type=sides_int,
        action="append",
        metavar="N",
        help="polygon shape (default 4, a square); repeat to compare shapes at equal travel",
    )
    p.add_argument(
        "--side-lengths",
        type=parse_side_lengths,
        default=None,
        metavar="START:STOP:STEP",
        help="candidate side lengths in m, STOP inclusive (default: 20 steps of about 1.3 "
        "wheelbases, 0.5:10:0.5 for the paper's robot)",
    )
    p.add_argument(
        "--runs-per-direction",
        type=positive_int,
        default=5,
        metavar="n",
        help="test runs per direction in each calibration (default 5)",
    )
    p.add_argument(
        "--trials",
        type=trials_int,
        default=None,
        metavar="M",
        help="Monte-Carlo trials per candidate (default 2000; the paper used 800; with --route: "
        "per confirmed candidate, default 200)",
    )
    p.add_argument(
        "--method",
        choices=("heading", "umbmark"),
        default="heading",
        help="calibration method (default heading, the paper's; umbmark: squares only)",
    )
    p.add_argument(
        "--validate",
        type=validation_arg,
        default=None,
        metavar="SIDES:LENGTH:DIRECTION",
        help="validation track driven with each calibration (default: a CCW square of about 10 "
        "wheelbases, 4:4:ccw for the paper's robot); with --route also a command file "
        "FILE.csv (t,v,omega, as 'odocal plan --route' writes)",
    )
    p.add_argument(
        "--alpha",
        type=fraction(lo_open=True),
        default=0.05,
        help="significance level of the rule's one-sided tests (default 0.05)",
    )
    p.add_argument(
        "--tolerance",
        type=fraction(lo_open=False),
        default=0.05,
        help="a larger track must be better by more than this fraction (default 0.05)",
    )
    p.add_argument(
        "--criterion",
        choices=("error", "residual"),
        default="error",
        help="what the rule compares: the error after calibration on the validation track "
        "(default) or the residual, the same drive without wheel noise",
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--reference-sim",
        action="store_true",
        help="simulate with 1 cm midpoint increments everywhere (slow; to check the fast mode)",
    )
    p.add_argument(
        "--analytic",
        action="store_true",
        help="first-order propagation instead of Monte Carlo: expected values, the same "
        "report in milliseconds (docs/nonsystematic-errors.md says when first order holds)",
    )
    p.add_argument(
        "--known-errors",
        action="store_true",
        help="design for the robot's errors as given even when ROBOT.yaml gives no "
        "'systematic' or 'nonsystematic' section (default: design over their typical ranges)",
    )
    p.add_argument(
        "--robot-from",
        nargs="+",
        metavar="RUN_OR_DIR",
        help="measure the robot from tracked runs instead (systematic errors from a trajectory "
        "fit, k from the spread of repeated runs, the instrument from the tracker's jitter "
        "unless given); --robot then only gives the nominal geometry",
    )
    p.add_argument(
        "--sigma-xy-m",
        type=sigma_xy_m,
        metavar="S",
        help="the instrument's position noise per measured final pose, m (replaces the robot's); "
        "with --route: per measured pose (the tracker's, the SLAM's, the scan matcher's)",
    )
    p.add_argument(
        "--sigma-theta-deg",
        type=sigma_theta_deg,
        metavar="S",
        help="the instrument's heading noise per measured final pose, deg (replaces the robot's)",
    )
    _add_route_args(p)
    p.add_argument("--plot", metavar="DIR", help="write PNG figures into DIR")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off with --json or when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


#: What ``--route`` designs over (as odocal.design.route.ROUTES; not imported: keeps --help fast).
ROUTE_CHOICES = ("trajectory", "slam", "scan", "gyro")
#: Flags of the polygon design that a route design does not use, and the route's own flags.
_POLYGON_ONLY = (
    ("sides", "--sides"),
    ("side_lengths", "--side-lengths"),
    ("robot_from", "--robot-from"),
    ("analytic", "--analytic"),
    ("reference_sim", "--reference-sim"),
    ("known_errors", "--known-errors"),
)
_POLYGON_DEFAULTED = (
    ("runs_per_direction", "--runs-per-direction", 5),
    ("method", "--method", "heading"),
    ("alpha", "--alpha", 0.05),
    ("tolerance", "--tolerance", 0.05),
    ("criterion", "--criterion", "error"),
)
_ROUTE_ONLY = (
    ("kinematics", "--kinematics"),
    ("noise_from", "--noise-from"),
    ("target_std_error", "--target-std-error"),
    ("duration", "--duration"),
    ("speed", "--speed"),
    ("turn_rate", "--turn-rate"),
    ("gyro_arw_deg_per_sqrt_h", "--gyro-arw-deg-per-sqrt-h"),
)


def _add_route_args(p: argparse.ArgumentParser) -> None:
    """The flags of ``odocal design --route R``."""
    p.add_argument(
        "--route",
        choices=ROUTE_CHOICES,
        default=None,
        help="design a recording for a bag route instead of a polygon test track: which "
        "maneuvers (straights, spins, arcs, figure-eights, squares), how long; the "
        "predicted standard errors checked by Monte Carlo (docs/design.md)",
    )
    p.add_argument(
        "--kinematics",
        choices=("differential", "skid-steer"),
        default=None,
        help="with --route: the robot's kinematics (default: the robot file's); skid-steer "
        "designs for the effective track",
    )
    p.add_argument(
        "--noise-from",
        metavar="BAG",
        default=None,
        help="with --route: measure the noise from a bag (or run file) with ground truth of this "
        "robot (the check's residual scale of a trajectory fit); a bag of another robot is "
        "refused",
    )
    p.add_argument(
        "--target-std-error",
        action="append",
        metavar="NAME=VALUE",
        default=None,
        help="with --route: a target standard error, e.g. wheelbase=0.2%%, "
        "wheel_diameter=0.05%%, wheelbase=0.5mm, diameter_ratio=0.0005 (repeatable); the "
        "recommendation is the shortest recording reaching every target",
    )
    p.add_argument(
        "--speed",
        type=float,
        default=None,
        metavar="M/S",
        help="with --route: forward speed of the maneuvers (default 0.3 m/s; what is safe "
        "for the robot and the room)",
    )
    p.add_argument(
        "--turn-rate",
        type=float,
        default=None,
        metavar="RAD/S",
        help="with --route: turn rate of the spins (default 0.5 rad/s)",
    )
    p.add_argument(
        "--gyro-arw-deg-per-sqrt-h",
        type=float,
        default=None,
        metavar="A",
        help="with --route gyro: the gyro's angle random walk, deg/sqrt(h) (default 0.3, a "
        "MEMS gyro's datasheet figure)",
    )
    p.add_argument(
        "--duration",
        type=float,
        default=None,
        metavar="S",
        help="with --route: the longest recording allowed (s); without targets the recording "
        "with the least predicted drift on the --validate driving within it",
    )


def run(args: argparse.Namespace) -> int:
    """Run ``odocal design`` on the parsed ``args`` and print the result (text or ``--json``);
    returns 0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    from ..errors import InputError

    given = lambda name: getattr(args, name, None) not in (None, False)  # noqa: E731
    if args.route is not None:
        wrong = [flag for name, flag in _POLYGON_ONLY if given(name)]
        # the polygon rule's flags with a default (a route design ignored them without a word)
        wrong += [flag for name, flag, default in _POLYGON_DEFAULTED
                  if getattr(args, name, default) != default]  # fmt: skip
        if wrong:
            raise InputError(f"{', '.join(wrong)}: only without --route (a polygon design)")
        return _run_route(args)
    wrong = [flag for name, flag in _ROUTE_ONLY if given(name)]
    if isinstance(args.validate, str):
        wrong.append("--validate FILE.csv")
    if wrong:
        raise InputError(f"{', '.join(wrong)}: only with --route")
    from ..app.design import design
    from ..design.spec import DesignSpec

    spec = DesignSpec(
        sides=tuple(args.sides or [4]),
        side_lengths_m=None
        if args.side_lengths is None
        else tuple(float(v) for v in args.side_lengths),
        runs_per_direction=args.runs_per_direction,
        trials=2000 if args.trials is None else args.trials,
        method=args.method,
        validation=args.validate,
        alpha=args.alpha,
        tolerance=args.tolerance,
        criterion=args.criterion,
    )
    bar = ProgressBar("odocal design", enabled=not (args.quiet or args.json))
    try:
        res = design(
            args.robot,
            spec,
            params=args.params,
            engine="analytic" if args.analytic else "monte-carlo",
            seed=args.seed,
            reference_sim=args.reference_sim,
            plot=args.plot,
            progress=bar,
            error_range=False if args.known_errors else None,
            robot_from=args.robot_from,
            measurement=_instrument(args),
        )
    finally:
        bar.close()
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    print(res.text())
    return 0


def _run_route(args: argparse.Namespace) -> int:
    """``odocal design --route R``."""
    from ..app.design_route import design_for_route

    bar = ProgressBar("odocal design --route", enabled=not (args.quiet or args.json))
    try:
        res = design_for_route(
            args.route, args.robot, seed=args.seed, plot=args.plot, progress=bar,
            **route_design_args(args),
        )  # fmt: skip
    finally:
        bar.close()
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    print(res.text())
    return 0


def route_design_args(args: argparse.Namespace) -> dict[str, Any]:
    """The flags a route design shares between ``design --route`` and ``plan --route`` (the
    robot's parameters, kinematics, noise run, targets, duration, validation, trials, speeds and
    the sensors' noise) as the app functions' keyword arguments."""
    v = args.validate
    arw = getattr(args, "gyro_arw_deg_per_sqrt_h", None)
    return {
        "params": args.params,
        "kinematics": args.kinematics,
        "noise_from": args.noise_from,
        "targets": tuple(args.target_std_error or ()),
        "duration_s": args.duration,
        "validate": v if v is None or isinstance(v, str) else (v.sides, v.side_m, v.direction),
        "trials": 200 if args.trials is None else args.trials,
        "speed_m_s": args.speed,
        "turn_rate_rad_s": args.turn_rate,
        "pose_noise": _instrument(args),
        "gyro_arw_rad_sqrt_s": None if arw is None else math.radians(arw) / 60.0,
    }


def _instrument(args: argparse.Namespace) -> MeasurementNoise | None:
    if args.sigma_xy_m is None and args.sigma_theta_deg is None:
        return None
    from ..core.model import MeasurementNoise

    return MeasurementNoise.from_degrees(args.sigma_xy_m or 0.0, args.sigma_theta_deg or 0.0)
