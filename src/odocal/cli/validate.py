"""``odocal validate``: how well given parameters dead-reckon recorded runs, against nominal."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from ..errors import InputError
from .common import positive_float, print_json, print_recording_warnings, print_table
from .fit import add_bag_args, bag_options


@dataclass(frozen=True)
class Validation:
    """Per-run errors of ``params`` and of the nominal geometry on recorded runs.

    runs : list of dict, one per run: ``path``, ``final_error_m``, ``max_error_m``,
    ``final_heading_error_rad``, ``max_heading_error_rad`` (for ``params``) and the same keys
    prefixed ``nominal_`` (None where the nominal geometry is unknown).
    """

    runs: list
    params: object
    nominal_known: bool

    def as_dict(self) -> dict:
        def mean(key):
            vals = [r[key] for r in self.runs if r[key] is not None]
            return float(np.mean(vals)) if vals else None

        out = {
            "runs": self.runs,
            "mean_final_error_m": mean("final_error_m"),
            "mean_max_error_m": mean("max_error_m"),
            "mean_final_heading_error_rad": mean("final_heading_error_rad"),
            "mean_nominal_final_error_m": mean("nominal_final_error_m"),
            "mean_nominal_max_error_m": mean("nominal_max_error_m"),
            "mean_nominal_final_heading_error_rad": mean("nominal_final_heading_error_rad"),
            "params": self.params.as_dict(),
        }
        return out


def validate_recordings(recordings, params, nominal=None) -> Validation:
    """Evaluate ``params`` (WheelGeometry) and the nominal geometry on each run.

    The nominal geometry of a run is ``nominal`` if given, else the run's ``ran_with``.
    """
    from ..core.odometry import evaluate
    from ..io.recordings import require_ground_truth

    require_ground_truth(recordings, "validate")
    runs, known = [], True
    for r in recordings:
        row = {"path": r.name, **evaluate(r, params)}
        nom = nominal or r.ran_with
        if nom is None:
            known = False
            row.update({f"nominal_{k}": None for k in list(row) if k != "path"})
        else:
            row.update({f"nominal_{k}": v for k, v in evaluate(r, nom).items()})
        runs.append(row)
    return Validation(runs, params, known)


def plot_validation(recordings, params, nominal, folder) -> list[Path]:
    """One PNG per run in ``folder``: ground truth, nominal and calibrated dead reckoning."""
    from ..core.odometry import dead_reckon
    from ..io.trajectory_plot import plot_run

    folder = Path(folder)
    if not folder.is_dir():
        try:
            folder.mkdir(parents=True)
        except OSError as exc:
            raise InputError(f"cannot create the plot folder: {exc.strerror}", folder) from None
    written, used = [], set()
    for r in recordings:
        stem = re.sub(r"[^A-Za-z0-9_.-]+", "_", Path(r.name).stem) or "run"
        name, i = stem, 1
        while name in used:
            i += 1
            name = f"{stem}-{i}"
        used.add(name)
        trajs = {}
        nom = nominal or r.ran_with
        if nom is not None:
            trajs["nominal"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, nom)
        trajs["calibrated"] = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, params)
        title = Path(r.name).name + (f" ({r.label})" if r.label else "")
        written.append(plot_run(folder / f"{name}.png", title, r.ground_truth, trajs))
    return written


def add_parser(sub) -> None:
    p = sub.add_parser(
        "validate",
        help="compare calibrated and nominal parameters on recorded runs",
        description="Dead-reckon recorded runs with the given parameters and with the nominal "
        "ones, and report the final and maximum position and heading errors per run.",
    )
    p.add_argument("paths", nargs="+", metavar="RUN_OR_DIR", help="run file, folder or bag")
    p.add_argument(
        "--params", metavar="PARAMS.yaml", required=True, help="the parameters to validate"
    )
    p.add_argument(
        "--robot", metavar="ROBOT.yaml", help="nominal geometry (default: the runs' metadata)"
    )
    p.add_argument("--json", action="store_true", help="print one JSON object")
    p.add_argument("--plot", metavar="DIR", help="write one PNG trajectory plot per run into DIR")
    p.add_argument(
        "--ticks-per-rev",
        type=positive_float,
        metavar="N",
        help="encoder ticks per wheel revolution for tick inputs that do not give it",
    )
    add_bag_args(p)
    p.set_defaults(run=run)


def run(args) -> int:
    from ..io.recordings import load_recordings
    from ..io.robot_file import load_params

    params = load_params(args.params)
    recordings = load_recordings(args.paths, ticks_per_rev=args.ticks_per_rev, **bag_options(args))
    print_recording_warnings(recordings)
    nominal = None
    if args.robot:
        from ..io.robot_file import load_robot

        nominal = load_robot(args.robot).nominal
    result = validate_recordings(recordings, params, nominal)
    plots = plot_validation(recordings, params, nominal, args.plot) if args.plot else []
    d = result.as_dict()
    if plots:
        d["plots"] = [str(p) for p in plots]
    if args.json:
        print_json(d)
        return 0

    def mm(v):
        return "-" if v is None else f"{1000 * v:.1f}"

    def deg(v):
        return "-" if v is None else f"{math.degrees(v):.2f}"

    rows = [
        (
            "run",
            "final mm",
            "max mm",
            "final deg",
            "nominal final mm",
            "nominal max mm",
            "nominal final deg",
        )
    ]
    for r in result.runs:
        rows.append(
            (
                Path(r["path"]).name,
                mm(r["final_error_m"]),
                mm(r["max_error_m"]),
                deg(r["final_heading_error_rad"]),
                mm(r["nominal_final_error_m"]),
                mm(r["nominal_max_error_m"]),
                deg(r["nominal_final_heading_error_rad"]),
            )
        )
    rows.append(
        (
            "mean",
            mm(d["mean_final_error_m"]),
            mm(d["mean_max_error_m"]),
            deg(d["mean_final_heading_error_rad"]),
            mm(d["mean_nominal_final_error_m"]),
            mm(d["mean_nominal_max_error_m"]),
            deg(d["mean_nominal_final_heading_error_rad"]),
        )
    )
    print_table(rows, title=f"{len(result.runs)} run(s), parameters from {args.params}")
    if plots:
        print(f"wrote {len(plots)} plot(s) to {args.plot}")
    return 0
