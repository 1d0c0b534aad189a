"""Exceptions that the CLI turns into one line ``odocal: error: ...`` and exit status 2."""


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
            where.append(str(path))
        if line is not None:
            where.append(f"line {line}")
        if field is not None:
            where.append(f"field '{field}'")
        super().__init__(
            f"{': '.join([', '.join(where)] if where else [])}{': ' if where else ''}{message}"
        )
        self.path, self.line, self.field = path, line, field


class WorkerLost(OdocalError):
    """A worker process ended without returning its result (killed by a signal or for lack of
    memory): reported as one line, never waited for."""
