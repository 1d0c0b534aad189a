"""``odocal noise``: the non-systematic error parameters k_r, k_l from repeated straight runs."""

from __future__ import annotations

import argparse
import math
import sys

from ..calibration.noise import NOISE_TRACKS, estimate_k
from .common import MAX_LENGTH_M, add_robot_args, print_json, print_table, resolve_robot


def noise_track(text: str) -> tuple[str, float]:
    """Parse 'out-and-back:D' or 'straight:D' (D in m) into (kind, D)."""
    kind, sep, dist = text.partition(":")
    kind = kind.strip().lower()
    if not sep or kind not in NOISE_TRACKS:
        raise argparse.ArgumentTypeError(
            f"expected out-and-back:D or straight:D (D in m), got {text!r}"
        )
    try:
        d = float(dist)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a distance in m: {dist!r} in {text!r}") from None
    if not math.isfinite(d) or d <= 0:
        raise argparse.ArgumentTypeError(f"the distance must be > 0 m, got {dist!r}")
    if d > MAX_LENGTH_M:
        raise argparse.ArgumentTypeError(
            f"the distance must be at most {MAX_LENGTH_M:g} m (check the units), got {dist!r}"
        )
    return kind, d


def add_parser(sub) -> None:
    p = sub.add_parser(
        "noise",
        help="estimate the non-systematic error k_r + k_l from repeated straight runs",
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


def noise_file(path, robot, track: str, distance_m: float, force: bool = False):
    """Read RUNS.csv (direction 'fwd') and estimate k; returns a NoiseEstimate."""
    from ..io.runs_csv import read_runs

    runs = read_runs(path, directions=("fwd",))
    true, believed = robot.true_geometry, robot.believed_geometry
    # systematic curvature of the forward path (rad/m), from ROBOT.yaml's systematic errors
    curvature = float(
        (
            true.diameter_right_m / believed.diameter_right_m
            - true.diameter_left_m / believed.diameter_left_m
        )
        / true.wheelbase_m
    )
    return estimate_k(
        runs,
        track,
        distance_m,
        float(true.wheelbase_m),
        robot.measurement,
        curvature_rad_per_m=curvature,
        strict=not force,
    )


def _fmt(v, f=".4g"):
    return "-" if v is None else format(v, f)


def run(args) -> int:
    robot = resolve_robot(args)
    kind, dist = args.track
    est = noise_file(args.runs_csv, robot, kind, dist, args.force)
    for w in est.warnings:
        print(f"odocal: warning: {w}", file=sys.stderr)
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
