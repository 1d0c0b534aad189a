"""The ``odocal`` command: parses arguments, runs one command, turns known errors into one line.

Each command lives in its own module with ``add_parser(subparsers)`` and ``run(args) -> int``.
"""

from __future__ import annotations

import argparse
import signal
import sys

from .. import __version__
from ..errors import OdocalError
from . import (
    bag_info,
    calibrate,
    check,
    compare,
    design,
    fit,
    noise,
    plan,
    reproduce,
    simulate,
    ttest,
    validate,
)

COMMANDS = [
    design,
    simulate,
    calibrate,
    plan,
    noise,
    fit,
    validate,
    check,
    compare,
    reproduce,
    ttest,
    bag_info,
]


class _Parser(argparse.ArgumentParser):
    """argparse with one-line errors (exit status 2), as every other odocal error."""

    def error(self, message: str):  # noqa: D401 - argparse API
        self.exit(2, f"odocal: error: {message} (see '{self.prog} --help')\n")


def build_parser() -> argparse.ArgumentParser:
    parser = _Parser(
        prog="odocal",
        description="Odometry calibration and test-track design for differential-drive robots.",
    )
    parser.add_argument("--version", action="version", version=f"odocal {__version__}")
    sub = parser.add_subparsers(dest="command", metavar="COMMAND", parser_class=_Parser)
    sub.required = True
    for module in COMMANDS:
        module.add_parser(sub)
    return parser


class Terminated(KeyboardInterrupt):
    """SIGTERM, raised like Ctrl-C so that every ``finally`` runs (temporary files removed, no
    half-written output)."""


def _terminate(signum, frame):  # noqa: ARG001 - the signal module's API
    raise Terminated


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    installed = False
    try:
        previous = signal.signal(signal.SIGTERM, _terminate)
        installed = True
    except ValueError:  # not the main thread: leave the signal alone
        pass
    try:
        return int(args.run(args) or 0)
    except OdocalError as exc:
        print(f"odocal: error: {exc}", file=sys.stderr)
        return 2
    except Terminated:
        print("odocal: terminated (SIGTERM); nothing half-written", file=sys.stderr)
        return 128 + signal.SIGTERM
    except KeyboardInterrupt:
        print("odocal: interrupted; nothing half-written", file=sys.stderr)
        return 128 + signal.SIGINT
    except BrokenPipeError:
        return 0
    finally:
        if installed:
            signal.signal(signal.SIGTERM, previous if previous is not None else signal.SIG_DFL)


if __name__ == "__main__":
    sys.exit(main())
