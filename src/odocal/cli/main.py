"""The ``odocal`` command: parses arguments, runs one command, turns known errors into one line.

Each command lives in its own module with ``add_parser(subparsers)`` and ``run(args) -> int``.
Only the module of the command being run is imported (and builds its parser); the others are
listed by name and one-line help from :data:`COMMANDS`, so ``odocal --help`` and every short
command start fast.
"""

from __future__ import annotations

import argparse
import gc
import importlib
import os
import signal
import sys
import warnings
from typing import Any

from .._version import __version__
from ..errors import OdocalError, OdocalWarning, one_line

#: command name -> (module in odocal.cli, the one line of ``odocal --help``)
COMMANDS: dict[str, tuple[str, str]] = {
    "design": ("design", "choose the test-track size (Monte-Carlo, the paper's procedure)"),
    "simulate": ("simulate", "simulate test runs on a polygon track and write RUNS.csv"),
    "calibrate": ("calibrate", "calibrate E_b, E_d from RUNS.csv"),
    "plan": ("plan", "floor protocol for calibration runs (or k runs) and a blank RUNS.csv"),
    "noise": (
        "noise",
        "estimate the wheel noise k_r + k_l from repeated runs (RUNS.csv or recordings)",
    ),
    "fit": ("fit", "calibrate wheel diameters and wheelbase from recorded runs"),
    "validate": ("validate", "compare calibrated and nominal parameters on recorded runs"),
    "check": ("check", "is this log enough? predicted standard errors and degenerate motions"),
    "compare": (
        "compare",
        "compare calibration methods on one simulated robot (and real OptiOdom runs)",
    ),
    "reproduce": (
        "reproduce",
        "regenerate the paper's figures and compare with its numbers (and, with --realdata, "
        "run its experiment on a real robot)",
    ),
    "ttest": ("ttest", "Student and Welch t-tests of two samples (CSV columns)"),
    "bag-info": ("bag_info", "list the topics, duration and frames of a ROS bag"),
    "fleet": ("fleet", "a fleet: calibrate every new bag, drift alarms, dashboard (ingest, ...)"),
}


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2), as every other odocal error."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"odocal: error: {one_line(message)} (see '{self.prog} --help')\n")


class _Listed:
    """The subparsers action as a command module sees it: its parser gets the listing's line."""

    def __init__(self, sub, line: str):
        self._sub, self._line = sub, line

    def add_parser(self, name: str, **kwargs) -> argparse.ArgumentParser:
        return self._sub.add_parser(name, help=self._line, **kwargs)


def build_parser(command: str | None = None) -> argparse.ArgumentParser:
    """The parser. The module of ``command`` (of every command when None) adds its own. Without
    a known command ('': help, version, a mistake), the others are listed by name and one-line
    help; with one, only its parser is built (every other listing would go unread)."""
    parser = _Parser(
        prog="odocal",
        description="Odometry calibration and test-track design for differential-drive robots.",
    )
    parser.add_argument("--version", action="version", version=f"odocal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for name, (module, line) in COMMANDS.items():
        if command is None or name == command:
            importlib.import_module(f".{module}", __package__).add_parser(_Listed(sub, line))
        elif command not in COMMANDS:
            sub.add_parser(name, help=line)
    return parser


def _command(argv: list[str]) -> str:
    """The command named in ``argv`` (its first word that is a command), else ''."""
    for word in argv:
        if not word.startswith("-"):
            return word if word in COMMANDS else ""
        if word in ("-h", "--help", "--version"):
            return ""
    return ""


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every ``finally`` runs (temporary files removed, no
    half-written output)."""


#: The signals that end a command with one line and exit status 128 + the signal number.
_STOPS = {
    signal.SIGINT: "odocal: interrupted; nothing half-written",
    signal.SIGTERM: "odocal: terminated (SIGTERM); nothing half-written",
}


def _install_stops(received: list[int]) -> dict[int, Any]:
    """Handlers for SIGINT and SIGTERM that note the signal in ``received`` and unwind (raise
    KeyboardInterrupt, :class:`Terminated`); the previous handlers, to restore. SIGINT is left
    alone when it is not Python's default (ignored in a background job, a caller's own)."""

    def stop(signum: int, frame: object) -> None:  # noqa: ARG001 - the signal module's API
        received.append(signum)
        raise Terminated if signum == signal.SIGTERM else KeyboardInterrupt

    previous: dict[int, Any] = {}
    try:
        if signal.getsignal(signal.SIGINT) is signal.default_int_handler:
            previous[signal.SIGINT] = signal.signal(signal.SIGINT, stop)
        previous[signal.SIGTERM] = signal.signal(signal.SIGTERM, stop)
    except ValueError:  # not the main thread: leave the signals alone
        pass
    return previous


def main(argv: list[str] | None = None) -> int:
    """Run ``odocal`` with ``argv`` (default ``sys.argv[1:]``); returns the exit code: 0, 2 for an
    :class:`~odocal.errors.OdocalError` (one line on stderr), 128 + the signal number when
    interrupted (Ctrl-C, SIGINT: 130) or terminated (SIGTERM: 143), with one line on stderr,
    whatever the signal interrupted (an import, a worker process starting, a figure being
    drawn, a file being written: nothing is half-written). Without any argument it prints the
    help on stdout and returns 2 (a usage error: no command ran; ``odocal --help`` returns 0)."""
    argv = sys.argv[1:] if argv is None else list(argv)
    if not argv:  # no command: the help (on stdout), exit status 2 (nothing was run)
        build_parser("").print_help()
        return 2
    received: list[int] = []
    previous = _install_stops(received)
    try:
        args = build_parser(_command(argv)).parse_args(argv)
        with warnings.catch_warnings():
            # the command prints its result's warnings itself (odocal: warning: ...)
            warnings.simplefilter("ignore", OdocalWarning)
            return int(args.run(args) or 0)
    except BaseException as exc:
        # after a signal, whatever surfaces while unwinding (also an error of the machinery it
        # interrupted) is that signal
        signum = received[0] if received else None
        if signum is None and isinstance(exc, KeyboardInterrupt):
            signum = signal.SIGTERM if isinstance(exc, Terminated) else signal.SIGINT
        if signum is not None:
            print(_STOPS[signal.Signals(signum)], file=sys.stderr)
            return 128 + signum
        if isinstance(exc, OdocalError):
            print(f"odocal: error: {one_line(str(exc))}", file=sys.stderr)
            return 2
        if isinstance(exc, BrokenPipeError):
            return 0
        raise
    finally:
        for signum, handler in previous.items():
            signal.signal(signum, handler if handler is not None else signal.SIG_DFL)


def entry() -> None:
    """The ``odocal`` command (console script, ``python -m odocal``): :func:`main`, then exit
    without the interpreter's last garbage collection over every object the command leaves
    behind (matplotlib's are many: 0.1-0.2 s of a command that drew figures). Every output file
    is closed by then, and the exit handlers still run. (Not in :func:`main`, which library
    callers and the tests call many times in one process.)

    BLAS runs on one thread unless the user's environment says otherwise (set before numpy is
    imported, inherited by worker processes): odocal's matrices are small, and OpenBLAS threads
    competing for busy cores made scipy's L-BFGS-B several times slower
    (benchmarks/results/blas-threads.txt)."""
    for var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
        os.environ.setdefault(var, "1")
    status = main()
    gc.freeze()
    sys.exit(status)


if __name__ == "__main__":
    entry()
