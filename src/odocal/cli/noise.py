"""``odocal noise``: the non-systematic error parameters k_r, k_l from repeated straight runs."""

from __future__ import annotations

import math

from .common import add_robot_args, noise_track, print_json, print_table, print_warnings


def add_parser(sub) -> None:
    p = sub.add_parser(
        "noise",
        description="Estimate the non-systematic wheel-noise parameters (k in METRES; Chong & "
        "Kleeman's m^0.5 value is the square root) from the final pose errors of repeated "
        "out-and-back or one-way straight runs (RUNS.csv, direction 'fwd'). See "
        "'odocal plan --track' for the protocol.",
    )
    p.add_argument("runs_csv", metavar="RUNS.csv", help="measured runs (fwd,x_m,y_m,theta_deg)")
    add_robot_args(
        p,
        "parameters the robot ran with (default: ROBOT.yaml's 'believed', else nominal); the "
        "wheelbase b of the estimators is ROBOT.yaml's true one, nominal x systematic E_b",
    )
    p.add_argument(
        "--track",
        type=noise_track,
        required=True,
        metavar="out-and-back:D|straight:D",
        help="what was driven: out-and-back:D (forward D m, then backward D m without "
        "turning; systematic errors cancel) or straight:D (forward D m)",
    )
    p.add_argument(
        "--force",
        action="store_true",
        help="estimate k even when the runs look dominated by a systematic part (a warning "
        "instead of an error)",
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def _fmt(v, f=".4g"):
    return "-" if v is None else format(v, f)


def run(args) -> int:
    from ..app.noise import noise

    kind, dist = args.track
    est = noise(
        args.runs_csv, args.robot, params=args.params, track=kind, distance_m=dist, force=args.force
    )
    print_warnings(est.warnings)
    if args.json:
        print_json(est.as_dict())
        return 0
    print(
        f"{kind} {dist:g} m: {est.runs} runs, wheelbase b = {est.wheelbase_m:g} m, "
        f"final heading error {math.degrees(est.theta_mean_rad):+.4f} deg mean, "
        f"{math.degrees(est.theta_std_rad):.4f} deg std"
    )
    lo, hi = est.k_sum_ci95_m
    rows = [
        ("", "k (m)", "95 % interval (m)", "Chong & Kleeman k (m^0.5)"),
        ("k_r + k_l", _fmt(est.k_sum_m), f"{lo:.4g} .. {hi:.4g}", ""),
        (
            "k each, if k_r = k_l",
            _fmt(est.k_sum_m / 2),
            f"{lo / 2:.4g} .. {hi / 2:.4g}",
            _fmt(math.sqrt(est.k_sum_m / 2)),
        ),
        ("k_r", _fmt(est.k_r_m), "", "-" if est.k_r_m is None else _fmt(math.sqrt(est.k_r_m))),
        ("k_l", _fmt(est.k_l_m), "", "-" if est.k_l_m is None else _fmt(math.sqrt(est.k_l_m))),
    ]
    print_table(rows)
    print(f"  {est.split_note}")
    if est.measurement_var_theta_rad2 > 0:
        print(
            "  the instrument's heading noise "
            f"({math.degrees(math.sqrt(est.measurement_var_theta_rad2)):.4g} deg, ROBOT.yaml "
            "measurement) was subtracted from the heading spread"
        )
    print(
        "  units: k here is in metres (variance k |ds| per wheel travel ds); Chong & Kleeman's "
        "k in m^0.5 is its square root"
    )
    return 0
