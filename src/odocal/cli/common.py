"""Arguments and output helpers shared by the commands."""

from __future__ import annotations

import argparse
import json
import math
import sys

__all__ = [
    "add_robot_args",
    "add_track_args",
    "length_m",
    "positive_float",
    "positive_int",
    "print_json",
    "print_recording_warnings",
    "print_warnings",
    "print_table",
    "resolve_robot",
]


def positive_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v <= 0:
        raise argparse.ArgumentTypeError(f"must be a finite number > 0, got {text!r}")
    return v


# Largest length a flag may give (m): beyond 100 km a length is a unit mistake, and the
# statistics of a track that long overflow.
MAX_LENGTH_M = 1e5


def length_m(text: str) -> float:
    """A length in metres: finite, > 0 and at most MAX_LENGTH_M."""
    v = positive_float(text)
    if v > MAX_LENGTH_M:
        raise argparse.ArgumentTypeError(
            f"must be at most {MAX_LENGTH_M:g} m (check the units), got {text!r}"
        )
    return v


def nonnegative_float(text: str) -> float:
    try:
        v = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not a number: {text!r}") from None
    if not math.isfinite(v) or v < 0:
        raise argparse.ArgumentTypeError(f"must be a finite number >= 0, got {text!r}")
    return v


def positive_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be >= 1, got {text!r}")
    return v


def sides_int(text: str) -> int:
    v = positive_int(text)
    if v < 3:
        raise argparse.ArgumentTypeError(f"a polygon needs at least 3 sides, got {text!r}")
    return v


def seed_int(text: str) -> int:
    try:
        v = int(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"not an integer: {text!r}") from None
    if v < 0:
        raise argparse.ArgumentTypeError(f"must be >= 0, got {text!r}")
    return v


def add_robot_args(p: argparse.ArgumentParser, params_help: str) -> None:
    p.add_argument(
        "--robot",
        metavar="ROBOT.yaml",
        default=None,
        help="robot file, or a built-in: paper-fig3, paper-fig5 (default), paper-experiment",
    )
    p.add_argument("--params", metavar="PARAMS.yaml", default=None, help=params_help)


def add_track_args(p: argparse.ArgumentParser, default_sides=4, default_side=4.0) -> None:
    p.add_argument(
        "--sides",
        type=sides_int,
        default=default_sides,
        metavar="N",
        help=f"regular N-gon test track (default {default_sides}, a square)",
    )
    p.add_argument(
        "--side-length",
        type=length_m,
        default=default_side,
        metavar="L",
        help=f"side length in m (default {default_side:g})",
    )


def resolve_robot(args):
    """The Robot of --robot, with --params (if given) installed as its believed geometry."""
    from ..io.robot_file import load_params, load_robot

    robot = load_robot(args.robot)
    if getattr(args, "params", None):
        robot = robot.with_believed(load_params(args.params))
    return robot


def print_warnings(warnings, prefix: str = "") -> None:
    """Each warning as one line ``odocal: warning: ...`` on stderr (never on stdout)."""
    for w in warnings:
        print(f"odocal: warning: {prefix}{w}", file=sys.stderr)


def print_recording_warnings(recordings) -> None:
    """The loaders' warnings about recorded runs (e.g. a bag's wheel signs), one line each."""
    for r in recordings:
        print_warnings(r.meta.get("warnings", ()) if r.meta else (), f"{r.name}: ")


def print_json(obj) -> None:
    text = json.dumps(obj, indent=2, allow_nan=False)  # all or nothing: no half-printed object
    sys.stdout.write(text + "\n")


def print_table(rows: list[tuple], title: str | None = None) -> None:
    """Two or more columns, left column left-aligned, the rest right-aligned."""
    if title:
        print(title)
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells if i < len(r)) for i in range(max(map(len, cells)))]
    for r in cells:
        parts = [r[0].ljust(widths[0])] + [c.rjust(widths[i + 1]) for i, c in enumerate(r[1:])]
        print("  " + "  ".join(parts).rstrip())
