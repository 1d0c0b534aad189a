"""``odocal plan``: the floor protocol for calibration runs (or k runs) and a blank RUNS.csv."""

from __future__ import annotations

import math

from .common import (
    ProgressBar,
    add_robot_args,
    length_m,
    noise_track,
    positive_int,
    print_json,
    print_table,
    print_warnings,
    seed_int,
    sides_int,
    sigma_theta_deg,
    sigma_xy_m,
    trials_int,
)
from .design import ROUTE_CHOICES, route_design_args, validation_arg

DEFAULT_TEMPLATE = "runs-template.csv"  # as odocal.app.plan (not imported: keeps --help fast)
DEFAULT_NOISE_RUNS = 20
DEFAULT_COMMANDS = "route-commands.csv"  # as odocal.app.plan_route


def add_parser(sub) -> None:
    """Add ``odocal plan``, its arguments and help, to ``sub`` (argparse's subparsers)."""
    p = sub.add_parser(
        "plan",
        description="Print the protocol a person follows on the floor: what to drive, in which "
        "order, how to mark the start pose, what to measure and what the model predicts the "
        "end errors will look like; write a blank RUNS.csv to fill in for 'odocal calibrate' "
        "(or, with --track, for 'odocal noise').",
    )
    add_robot_args(p, "parameters the robot runs with during the runs (default nominal)")
    p.add_argument("--sides", type=sides_int, default=4, metavar="N", help="N-gon (default 4)")
    p.add_argument(
        "--side-length",
        type=length_m,
        default=None,
        metavar="L",
        help="side length in m (default: what 'odocal design --analytic' recommends for the robot)",
    )
    p.add_argument(
        "--runs-per-direction",
        type=positive_int,
        default=None,
        metavar="n",
        help="runs per direction (default 5; with --track: number of runs, default "
        f"{DEFAULT_NOISE_RUNS})",
    )
    p.add_argument(
        "--track",
        type=noise_track,
        default=None,
        metavar="out-and-back:D|straight:D",
        help="plan runs for measuring k instead of a polygon",
    )
    p.add_argument(
        "--out",
        metavar="RUNS.csv",
        default=None,
        help=f"blank run sheet to write (default {DEFAULT_TEMPLATE}); with --route: the "
        f"velocity-command file (default {DEFAULT_COMMANDS})",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="replace --out even if it already holds measured runs (never needed for a blank "
        "sheet)",
    )
    p.add_argument(
        "--route",
        choices=ROUTE_CHOICES,
        default=None,
        help="plan the recording 'odocal design --route R' recommends for a bag route: a "
        "timed velocity-command file (t,v,omega) and the teleoperation protocol with its checks",
    )
    for flag, kw in (
        ("--kinematics", {"choices": ("differential", "skid-steer")}),
        ("--noise-from", {"metavar": "BAG"}),
        ("--target-std-error", {"action": "append", "metavar": "NAME=VALUE"}),
        ("--duration", {"type": float, "metavar": "S"}),
        ("--validate", {"type": validation_arg, "metavar": "SIDES:LENGTH:DIRECTION|FILE.csv"}),
        ("--trials", {"type": trials_int, "metavar": "M"}),
        ("--seed", {"type": seed_int, "metavar": "S"}),
        ("--speed", {"type": float, "metavar": "M/S"}),
        ("--turn-rate", {"type": float, "metavar": "RAD/S"}),
        ("--sigma-xy-m", {"type": sigma_xy_m, "metavar": "S"}),
        ("--sigma-theta-deg", {"type": sigma_theta_deg, "metavar": "S"}),
        ("--gyro-arw-deg-per-sqrt-h", {"type": float, "metavar": "A"}),
    ):
        p.add_argument(
            flag, default=None, help="with --route: as for 'odocal design --route'", **kw
        )
    p.add_argument(
        "--rate",
        type=float,
        default=None,
        metavar="HZ",
        help="with --route: the command file's rate (default 50 Hz)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument(
        "--quiet",
        action="store_true",
        help="no progress bar (also off with --json or when stderr is not a terminal)",
    )
    p.set_defaults(run=run)


_ROUTE_ONLY = ("kinematics", "noise_from", "target_std_error", "duration", "validate", "trials",
               "seed", "rate", "speed", "turn_rate", "sigma_xy_m", "sigma_theta_deg",
               "gyro_arw_deg_per_sqrt_h")  # fmt: skip


def _run_route(args) -> int:
    """``odocal plan --route R``."""
    from ..app.plan_route import plan_route
    from ..errors import InputError

    if args.track is not None:
        raise InputError("--track: only without --route")
    # the polygon's flags (were ignored without a word)
    polygon = [
        flag
        for flag, given in (
            ("--sides", args.sides != 4),
            ("--side-length", args.side_length is not None),
            ("--runs-per-direction", args.runs_per_direction is not None),
        )
        if given
    ]
    if polygon:
        raise InputError(f"{', '.join(polygon)}: only without --route (a polygon plan)")
    bar = ProgressBar("odocal plan --route", enabled=not (args.quiet or args.json))
    try:
        res = plan_route(
            args.route,
            args.robot,
            seed=0 if args.seed is None else args.seed,
            out=DEFAULT_COMMANDS if args.out is None else args.out,
            rate_hz=50.0 if args.rate is None else args.rate,
            force=args.force,
            progress=bar,
            **route_design_args(args),
        )
    finally:
        bar.close()
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    print(res.text())
    print(f"wrote {res.commands}")
    return 0


def run(args) -> int:
    """Run ``odocal plan`` on the parsed ``args`` and print the result (text or ``--json``); returns
    0 (errors are raised: :func:`~odocal.cli.main.main` reports them)."""
    import numpy as np

    if args.route is not None:
        return _run_route(args)
    wrong = [n for n in _ROUTE_ONLY if getattr(args, n, None) is not None]
    if wrong:
        from ..errors import InputError

        flags = ", ".join("--" + n.replace("_", "-") for n in wrong)
        raise InputError(f"{flags}: only with --route")
    args.out = DEFAULT_TEMPLATE if args.out is None else args.out

    from ..app.plan import plan as make_plan

    bar = ProgressBar("odocal plan: choosing the side", enabled=not (args.quiet or args.json))
    try:
        res = make_plan(
            args.robot,
            params=args.params,
            sides=args.sides,
            side_m=args.side_length,
            runs_per_direction=args.runs_per_direction,
            noise_track=args.track,
            out=args.out,
            force=args.force,
            progress=bar,
        )
    finally:
        bar.close()
    plan = res.floor_plan
    print_warnings(res.warnings)
    if args.json:
        print_json(res.as_dict())
        return 0
    for note in res.notes:
        print(f"Note: {note}")
    print(f"Floor protocol: {plan.title}")
    for i, step in enumerate(plan.steps, start=1):
        print(f"{i}. {step}")
    print()
    typical = plan.typical_mean_abs
    if typical:
        print(
            "What to expect: ROBOT.yaml gives no systematic errors (the runs will measure them); "
            "typical robots (E_b 0.97-1.03, E_d 0.995-1.005) end on average up to"
        )
        for d, (x, y, th) in typical.items():
            print(f"  {d}: |x| {x:.3f} m, |y| {y:.3f} m, |theta| {math.degrees(th):.2f} deg")
        print("from the start; each run scatters about its robot's mean by:")
    else:
        print("What to expect (this robot's errors; mean and spread of the measured end errors):")
    rows = [("direction", "x_m", "y_m", "theta_deg")]
    for d, p in plan.predictions.items():
        m, s = np.round(p.error_mean, 12) + 0.0, p.std(measured=True)  # no "-0.0000"
        if typical:  # the mean is the robot's unknown error: the spread alone
            rows.append((d, f"± {s[0]:.4f}", f"± {s[1]:.4f}", f"± {math.degrees(s[2]):.3f}"))
            continue
        rows.append(
            (
                d,
                f"{m[0]:+.4f} ± {s[0]:.4f}",
                f"{m[1]:+.4f} ± {s[1]:.4f}",
                f"{math.degrees(m[2]):+.3f} ± {math.degrees(s[2]):.3f}",
            )
        )
    print_table(rows)
    if typical:
        print(
            "  (± one standard deviation of a single run, including the instrument noise in "
            "ROBOT.yaml; runs of one direction should agree within a few of these, and an end "
            "far beyond the typical ones above usually means a frame or sign mistake)"
        )
    else:
        print(
            "  (± one standard deviation of a single run, including the instrument noise in "
            "ROBOT.yaml; values far outside these usually mean a frame or sign mistake)"
        )
    if "nonsystematic" in plan.unknown:
        print(
            "  (ROBOT.yaml gives no wheel noise k: the spread is the instrument's alone; a real "
            "robot's is larger)"
        )
    c, r, v = plan.calibration, plan.reference, plan.validation
    if c is not None and r is not None and v is not None and np.isfinite(c.post_error_mean_m):
        lo, hi = c.post_error_ci95_m
        print(
            f"  Calibration from these runs (heading-error method, first-order prediction): "
            f"E_b {c.E_b_mean:.4f} ± {c.E_b_std:.4f}, E_d {c.E_d_mean:.5f} ± {c.E_d_std:.5f}; "
            f"then a {v.label} should end {c.post_error_mean_m:.3f} m from its start "
            f"(95 %: {lo:.3f} .. {hi:.3f} m), against {r.uncalibrated_m:.3f} m uncalibrated and "
            f"{r.floor_m:.3f} m with perfect parameters. 'odocal design' compares track sizes."
        )
    print()
    print(f"wrote {args.out} ({len(plan.order)} rows to fill in); then run:")
    print(f"  {plan.next_command}")
    return 0
