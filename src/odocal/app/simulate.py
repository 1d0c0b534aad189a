"""``odocal simulate``: drive a test track n times with a simulated robot."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..core.checks import check_int, check_positive_float, check_seed
from ..core.covariance import PosePrediction, correlation, predict
from ..core.runs import EndPoseRuns
from ..core.simulate import measure
from ..core.simulate import simulate as simulate_track
from ..core.tracks import Track, polygon
from ..errors import ModelError
from ..io.limits import TRACK_LENGTH_MAX_M
from ..io.outputs import OutputPlan
from ..io.runs_csv import refuse_replacing_measurements, runs_csv_text
from ..io.track_file import load_track
from .common import RobotSpec, input_paths, resolve_robot, robot_label
from .text import Presented, Text, written_lines

__all__ = ["SimulateResult", "simulate", "simulate_runs", "SIGNATURE"]

#: The comment line that marks a run sheet ``simulate`` wrote (not measurements).
SIGNATURE = "# odocal simulate:"


@dataclass(frozen=True)
class SimulateResult(Presented):
    """Simulated runs: measured final pose errors per run, optionally the first-order prediction.

    Attributes
    ----------
    runs : EndPoseRuns
        Final pose errors (actual - odometric; x_m, y_m, theta_rad) with the instrument's noise.
    track : str
        The track's name.
    directions : tuple of str
    runs_per_direction, seed : int
    predicted : dict of direction -> PosePrediction, or None
    written : tuple of Path
    robot : str
        The robot driven (a file, or a built-in's name; by default ``paper-fig5``).
    """

    runs: EndPoseRuns
    track: str
    directions: tuple[str, ...]
    runs_per_direction: int
    seed: int
    predicted: dict[str, PosePrediction] | None = None
    written: tuple[Path, ...] = ()
    robot: str = ""

    def as_dict(self) -> dict:
        """The JSON of ``odocal simulate --json``."""
        out = _stats(self.runs.errors) | {
            "seed": self.seed,
            "robot": self.robot,
            "track": self.track,
            "by_direction": {d: _stats(self.runs.select(d)) for d in self.directions},
        }
        if self.predicted is not None:
            out["predicted"] = {d: _prediction_dict(p) for d, p in self.predicted.items()}
            out["monte_carlo_covariance"] = {
                d: _cov_list(np.cov(self.runs.select(d).T, ddof=1))
                if self.runs.count(d) > 1
                else None
                for d in self.directions
            }
        return out

    def text(self) -> str:
        """The text of ``odocal simulate``: the mean and spread of the final pose errors per
        direction (and the prediction beside the Monte Carlo), the files written."""
        out = Text()
        summary = self.as_dict()
        out(
            f"{self.track}: {self.runs_per_direction} run(s) per direction, seed {self.seed}, "
            f"robot {self.robot}"
        )
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
        out.table(rows)
        if self.predicted is not None:
            _prediction_text(out, self.runs, self.predicted)
        written_lines(out, self.written)
        return str(out)


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


PAIRS = (("x", "y", 0, 1), ("x", "theta", 0, 2), ("y", "theta", 1, 2))


def _prediction_dict(p: PosePrediction) -> dict:
    """JSON of a PosePrediction: mean error, std and correlations of a MEASURED final pose."""
    mean, std, c = p.error_mean, p.std(measured=True), p.measured_covariance
    r = correlation(c)
    return {
        "mean": {"x_m": float(mean[0]), "y_m": float(mean[1]), "theta_deg": math.degrees(mean[2])},
        "std": {"x_m": float(std[0]), "y_m": float(std[1]), "theta_deg": math.degrees(std[2])},
        "correlation": {f"{a}_{b}": float(r[i, j]) for a, b, i, j in PAIRS},
        "covariance": _cov_list(c),
        "covariance_units": "x_m, y_m, theta_rad (m^2, m rad, rad^2)",
        "includes_measurement_noise": True,
    }


def simulate_runs(robot, track_for, directions, runs: int, seed: int, max_step: float):
    """Simulate ``runs`` runs per direction; returns EndPoseRuns of measured errors."""
    rng = np.random.default_rng(seed)
    labels, errs = [], []
    for d in directions:
        res = simulate_track(track_for(d), robot, runs, rng, max_step_m=max_step)
        errs.append(measure(res.errors, robot, rng))
        labels += [d] * runs
    return EndPoseRuns(tuple(labels), np.vstack(errs))


def simulate(
    robot: RobotSpec = None,
    *,
    params=None,
    sides: int = 4,
    side_m: float = 4.0,
    track: str | Path | Track | None = None,
    directions: Sequence[str] = ("cw", "ccw"),
    runs: int = 5,
    seed: int = 0,
    max_step_m: float = 0.01,
    predict_covariance: bool = False,
    out: str | Path | None = None,
    force: bool = False,
) -> SimulateResult:
    """Drive a regular N-gon (``sides``, ``side_m`` in m) or a ``track`` (a Track, or a track
    file whose direction label is used) ``runs`` times per direction with the robot; optionally
        predict the final-pose covariance to first order; write RUNS.csv to ``out``, marked as
    simulated (``# odocal simulate:``): an existing ``out`` that may hold measurements (any file
    but an earlier simulated sheet) is replaced only with ``force``."""
    if track is None:
        sides = check_int("sides", sides, at_least=3)  # polygon() bounds it, with its reason
        side_m = check_positive_float("side_m", side_m, at_most=TRACK_LENGTH_MAX_M, hint=" m")
    runs = check_int("runs", runs, at_least=1)
    seed = check_seed("seed", seed)
    max_step_m = check_positive_float(
        "max_step_m", max_step_m, at_most=TRACK_LENGTH_MAX_M, hint=" m"
    )
    if isinstance(directions, str) or not set(directions) <= {"cw", "ccw"} or not directions:
        raise ModelError(f"directions must be some of ('cw', 'ccw'), got {directions!r}")
    plan = OutputPlan(input_paths(robot, params, None if isinstance(track, Track) else track))
    if out is not None:
        plan.file(out, "--out")
        refuse_replacing_measurements(out, "--out", "simulate", SIGNATURE, force=force)
    r = resolve_robot(robot, params)
    if track is not None:
        if isinstance(track, Track):
            trk, label = track, track.direction_label
        else:
            trk, label = load_track(track)
        directions = (label,)
        name = trk.name

        def track_for(d):
            return trk
    else:
        name = f"{sides}-gon, side {side_m:g} m"

        def track_for(d):
            return polygon(sides, side_m, d)

    directions = tuple(directions)
    end = simulate_runs(r, track_for, directions, runs, seed, max_step_m)
    predicted = None
    if predict_covariance:
        predicted = {d: predict(track_for(d), r, max_step_m=max_step_m) for d in directions}
    written: tuple[Path, ...] = ()
    label = robot_label(robot, params)
    if out is not None:
        text = runs_csv_text(
            end,
            {"run": list(range(1, len(end.directions) + 1))},
            track=None if track is not None else (sides, side_m),
            signature=f"{SIGNATURE} simulated runs, not measurements (robot {label}, seed {seed})",
        )
        written = tuple(plan.commit({Path(out): text}))
    return SimulateResult(end, name, directions, runs, seed, predicted, written, label)


def _prediction_text(out: Text, runs: EndPoseRuns, predicted: dict) -> None:
    out("predicted (first-order propagation + instrument noise) vs Monte Carlo:")
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
                    *(f"{r[i, j]:+.3f}" for _, _, i, j in PAIRS),
                )
            )
    out.table(rows)
