"""Exceptions that the CLI turns into one line ``odocal: error: ...`` and exit status 2."""

# Every character at which str.splitlines() (or a terminal) would break a line.
_LINE_BREAKS = "\n\r\x0b\x0c\x1c\x1d\x1e\x85\u2028\u2029"
_ESCAPES = {ord(c): repr(c)[1:-1] for c in _LINE_BREAKS}


def one_line(text: str) -> str:
    """``text`` with every line-breaking character written as its escape (``\\n``, ...): a
    message naming a file called ``a<newline>b.csv`` stays one line."""
    return text.translate(_ESCAPES)


def quote_path(path) -> str:
    """How a message names ``path``: as it is, or quoted with escapes (Python's repr) when it
    holds a character that is not printable (a line break, a tab, ...) or spaces at an end."""
    name = str(path)
    if name.isprintable() and name == name.strip():
        return name
    return repr(name)


class OdocalError(Exception):
    """Base of every error odocal reports to a user as a one-line message."""


class ModelError(OdocalError, ValueError):
    """A model value is invalid (not finite, not positive where it must be, ...)."""


class CalibrationError(ModelError):
    """The measurements do not allow a calibration (e.g. an equation is undefined)."""


class InputError(OdocalError):
    """A file or argument is unusable. The message names the file, line and field."""

    def __init__(self, message: str, path=None, line: int | None = None, field: str | None = None):
        where = []
        if path is not None:
            where.append(quote_path(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field '{field}'")
        super().__init__(
            f"{': '.join([', '.join(where)] if where else [])}{': ' if where else ''}{message}"
        )
        self.path, self.line, self.field = path, line, field


class BagDataError(InputError):
    """A bag whose data are broken (time running backwards or repeating, every message twice, a
    clock reset, two joints named the same, a value that is not finite, a truncated file): an
    error naming the bag and the topic, never one route's reason among others."""


class OdocalWarning(UserWarning):
    """What a command called from Python warns about (the same words as the command line's
    ``odocal: warning: ...`` lines, also kept in the result's ``warnings``): filter it with
    ``warnings.simplefilter("ignore", odocal.OdocalWarning)`` or turn it into an error."""


class WorkerLost(OdocalError):
    """A worker process ended without returning its result (killed by a signal or for lack of
    memory): reported as one line, never waited for."""
