"""``odocal simulate``: drive a test track n times with a simulated robot."""

from __future__ import annotations

import math

import numpy as np

from ..core.covariance import correlation, predict
from ..core.runs import EndPoseRuns
from ..core.simulate import measure, simulate
from ..core.tracks import polygon
from .common import (
    add_robot_args,
    add_track_args,
    positive_float,
    positive_int,
    print_json,
    print_table,
    resolve_robot,
    seed_int,
)


def add_parser(sub) -> None:
    p = sub.add_parser(
        "simulate",
        help="simulate test runs on a polygon track and write RUNS.csv",
        description="Drive a regular N-gon (or a track file) open loop with a simulated robot "
        "and report the final pose errors (actual - odometric). With --out, write them as "
        "RUNS.csv for 'odocal calibrate'.",
    )
    add_robot_args(p, "believed parameters the robot runs with (e.g. a calibration result)")
    add_track_args(p)
    p.add_argument("--track", metavar="TRACK.yaml", help="a custom track file instead of --sides")
    p.add_argument(
        "--direction",
        choices=("cw", "ccw", "both"),
        default="both",
        help="driving direction (default both: n CW runs, then n CCW runs)",
    )
    p.add_argument(
        "--runs", type=positive_int, default=5, metavar="n", help="runs per direction (default 5)"
    )
    p.add_argument("--seed", type=seed_int, default=0, metavar="S", help="random seed (default 0)")
    p.add_argument(
        "--max-step",
        type=positive_float,
        default=0.01,
        metavar="M",
        help="largest wheel travel of one integration increment, m (default 0.01)",
    )
    p.add_argument(
        "--predict",
        action="store_true",
        help="also print the final-pose covariance predicted by first-order propagation "
        "(eqs. (8)-(10), plus the instrument noise) beside the Monte-Carlo one",
    )
    p.add_argument("--out", metavar="RUNS.csv", help="write the runs in RUNS.csv format")
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.set_defaults(run=run)


def _stats(e: np.ndarray) -> dict:
    n = len(e)
    std = e.std(axis=0, ddof=1) if n > 1 else np.full(3, math.nan)

    def pose(v):
        return {
            "x_m": float(v[0]),
            "y_m": float(v[1]),
            "theta_deg": None if math.isnan(v[2]) else math.degrees(float(v[2])),
        } | ({} if not math.isnan(v[0]) else {"x_m": None, "y_m": None})

    return {"runs": n, "mean": pose(e.mean(axis=0)), "std": pose(std)}


def _cov_list(c: np.ndarray) -> list:
    return [[float(v) for v in row] for row in c]


_PAIRS = (("x", "y", 0, 1), ("x", "theta", 0, 2), ("y", "theta", 1, 2))


def _prediction_dict(p) -> dict:
    """JSON of a PosePrediction: mean error, std and correlations of a MEASURED final pose."""
    mean, std, c = p.error_mean, p.std(measured=True), p.measured_covariance
    r = correlation(c)
    return {
        "mean": {"x_m": float(mean[0]), "y_m": float(mean[1]), "theta_deg": math.degrees(mean[2])},
        "std": {"x_m": float(std[0]), "y_m": float(std[1]), "theta_deg": math.degrees(std[2])},
        "correlation": {f"{a}_{b}": float(r[i, j]) for a, b, i, j in _PAIRS},
        "covariance": _cov_list(c),
        "covariance_units": "x_m, y_m, theta_rad (m^2, m rad, rad^2)",
        "includes_measurement_noise": True,
    }


def _print_prediction(runs: EndPoseRuns, predicted: dict) -> None:
    print("predicted (first-order propagation + instrument noise) vs Monte Carlo:")
    rows = [
        (
            "direction",
            "",
            "mean x_m",
            "mean y_m",
            "mean theta_deg",
            "std x_m",
            "std y_m",
            "std theta_deg",
            "r_xy",
            "r_xth",
            "r_yth",
        )
    ]
    for d, p in predicted.items():
        e = runs.select(d)
        cases = [("predicted", p.error_mean, p.measured_covariance)]
        if len(e) > 1:
            cases.append((f"MC ({len(e)} runs)", e.mean(axis=0), np.cov(e.T, ddof=1)))
        for label, m, c in cases:
            s = np.sqrt(np.maximum(np.diag(c), 0.0))
            r = correlation(c)
            rows.append(
                (
                    d,
                    label,
                    f"{m[0]:.4f}",
                    f"{m[1]:.4f}",
                    f"{math.degrees(m[2]):.3f}",
                    f"{s[0]:.4f}",
                    f"{s[1]:.4f}",
                    f"{math.degrees(s[2]):.3f}",
                    *(f"{r[i, j]:+.3f}" for _, _, i, j in _PAIRS),
                )
            )
    print_table(rows)


def simulate_runs(robot, track_for, directions, runs: int, seed: int, max_step: float):
    """Simulate ``runs`` runs per direction; returns EndPoseRuns of measured errors."""
    rng = np.random.default_rng(seed)
    labels, errs = [], []
    for d in directions:
        res = simulate(track_for(d), robot, runs, rng, max_step_m=max_step)
        errs.append(measure(res.errors, robot, rng))
        labels += [d] * runs
    return EndPoseRuns(tuple(labels), np.vstack(errs))


def run(args) -> int:
    from ..io.runs_csv import write_runs
    from ..io.track_file import load_track

    robot = resolve_robot(args)
    if args.track:
        track, label = load_track(args.track)
        directions = [label]
        track_for = lambda d: track  # noqa: E731
        name = track.name
    else:
        directions = ["cw", "ccw"] if args.direction == "both" else [args.direction]
        track_for = lambda d: polygon(args.sides, args.side_length, d)  # noqa: E731
        name = f"{args.sides}-gon, side {args.side_length:g} m"
    runs = simulate_runs(robot, track_for, directions, args.runs, args.seed, args.max_step)
    if args.out:
        write_runs(args.out, runs, {"run": list(range(1, len(runs.directions) + 1))})
    summary = _stats(runs.errors) | {
        "seed": args.seed,
        "track": name,
        "by_direction": {d: _stats(runs.select(d)) for d in directions},
    }
    if args.predict:
        predicted = {d: predict(track_for(d), robot, max_step_m=args.max_step) for d in directions}
        summary["predicted"] = {d: _prediction_dict(p) for d, p in predicted.items()}
        summary["monte_carlo_covariance"] = {
            d: _cov_list(np.cov(runs.select(d).T, ddof=1)) if runs.count(d) > 1 else None
            for d in directions
        }
    if args.json:
        print_json(summary)
        return 0
    print(f"{name}: {args.runs} run(s) per direction, seed {args.seed}")
    rows = [
        (
            "direction",
            "runs",
            "mean x_m",
            "mean y_m",
            "mean theta_deg",
            "std x_m",
            "std y_m",
            "std theta_deg",
        )
    ]
    for d, s in summary["by_direction"].items():
        m, sd = s["mean"], s["std"]
        fmt = lambda v, f: "-" if v is None else format(v, f)  # noqa: E731
        rows.append(
            (
                d,
                s["runs"],
                fmt(m["x_m"], ".4f"),
                fmt(m["y_m"], ".4f"),
                fmt(m["theta_deg"], ".3f"),
                fmt(sd["x_m"], ".4f"),
                fmt(sd["y_m"], ".4f"),
                fmt(sd["theta_deg"], ".3f"),
            )
        )
    print_table(rows)
    if args.predict:
        _print_prediction(runs, predicted)
    if args.out:
        print(f"wrote {args.out}")
    return 0
