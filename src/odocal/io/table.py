"""The one reader of comma-separated tables (RUNS.csv, generic run CSVs, t-test samples, ...).

A table is UTF-8 text: blank lines are skipped; lines starting with ``#`` are comments (those
before the header may carry ``key: value`` settings); the first other line is the header row of
unique, non-empty column names; every further line is a row with as many fields as the header.
Fields are trimmed; CSV quoting is honoured.

Every problem is an :class:`~odocal.errors.InputError` naming the file, the line and the field:
over-long lines or fields, duplicated column names or settings, a row of the wrong width, a value
that is not a finite number, or a number beyond the plausible magnitude the caller gives.

Numeric columns are parsed in one vectorised pass (:meth:`Table.numbers`); only when that fails is
the table scanned line by line to name the first bad field.
"""

from __future__ import annotations

import csv
import io
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..errors import InputError
from .textfile import read_text

__all__ = [
    "Table",
    "ColumnSample",
    "read_table",
    "read_column",
    "parse_number",
    "MAX_FIELD_CHARS",
    "MAX_LINE_CHARS",
]

#: Longest field (characters): a number or a name needs far fewer; a longer one is a broken file.
MAX_FIELD_CHARS = 200
#: Longest line (characters).
MAX_LINE_CHARS = 20_000

_SIMPLE_NUMBER = re.compile(r"^[+-]?(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$")


def parse_number(
    raw: str,
    path: Any,
    line: int | None,
    name: str,
    *,
    positive: bool = False,
    nonnegative: bool = False,
    at_most: float | None = None,
    unit_hint: str = "check the units",
) -> float:
    """``raw`` as a finite float, or an InputError naming file, line and field.

    ``at_most`` bounds the magnitude (a larger value is implausible: a unit slip or a broken
    file); numbers that overflow a float (1e400, a 400-digit integer) are refused the same way.
    """
    text = raw.strip()
    if not text:
        raise InputError("not filled in (empty)", path, line, name)
    if len(text) > MAX_FIELD_CHARS:
        raise InputError(f"over-long value ({len(text)} characters)", path, line, name)
    try:
        v = float(text)
    except ValueError:
        raise InputError(f"not a number: {text!r}", path, line, name) from None
    if math.isnan(v):
        raise InputError(f"must be finite, got {text!r}", path, line, name)
    if math.isinf(v):
        if text.lower().lstrip("+-") in ("inf", "infinity"):
            raise InputError(f"must be finite, got {text!r}", path, line, name)
        raise InputError(f"number too large for a float: {text[:24]}...", path, line, name)
    if positive and v <= 0:
        raise InputError(f"must be a finite number > 0, got {text!r}", path, line, name)
    if nonnegative and v < 0:
        raise InputError(f"must be a finite number >= 0, got {text!r}", path, line, name)
    if at_most is not None and abs(v) > at_most:
        raise InputError(
            f"implausibly large, got {text!r} (at most {at_most:g} in magnitude; {unit_hint})",
            path,
            line,
            name,
        )
    return v


def _split(line: str) -> list[str]:
    if '"' not in line:
        return [f.strip() for f in line.split(",")]
    return [f.strip() for f in next(csv.reader(io.StringIO(line)))]


@dataclass(frozen=True)
class Table:
    """A parsed table.

    Attributes
    ----------
    path : str
        Where it came from (for messages).
    header : tuple of str
        Column names, in file order.
    header_line : int
        Line number of the header row (1-based).
    rows : list of (int, list of str)
        Each data row's line number and its trimmed fields.
    settings : dict of str -> (str, int)
        ``# key: value`` comment lines above the header: value and line number.
    """

    path: str
    header: tuple[str, ...]
    header_line: int
    rows: list[tuple[int, list[str]]]
    settings: dict[str, tuple[str, int]] = field(default_factory=dict)

    def has(self, name: str) -> bool:
        return name in self.header

    def index(self, name: str) -> int:
        """Position of column ``name`` (InputError naming the header if absent)."""
        try:
            return self.header.index(name)
        except ValueError:
            raise InputError(
                f"no column '{name}'; the header has {', '.join(self.header)}",
                self.path,
                self.header_line,
                name,
            ) from None

    def require(self, names: Sequence[str]) -> None:
        """InputError listing the columns of ``names`` the header lacks."""
        missing = [c for c in names if c not in self.header]
        if missing:
            raise InputError(
                f"missing column(s) {', '.join(missing)}; the header must contain "
                f"{','.join(names)}",
                self.path,
                self.header_line,
            )

    def cells(self, name: str) -> list[tuple[int, str]]:
        """(line, text) of column ``name`` in every row."""
        j = self.index(name)
        return [(no, f[j]) for no, f in self.rows]

    def numbers(
        self,
        names: Sequence[str],
        *,
        at_most: dict[str, float] | float | None = None,
        unit_hint: str = "check the units",
    ) -> np.ndarray:
        """The columns ``names`` as floats, shape (rows, len(names)).

        Every value must be a finite number (at most ``at_most`` in magnitude: one bound for
        all, or per column). A vectorised pass first; on failure, the first bad field is named.
        """
        idx = [self.index(n) for n in names]
        limits = [(at_most.get(n) if isinstance(at_most, dict) else at_most) for n in names]
        try:
            with np.errstate(over="ignore", invalid="ignore"):
                data = np.array([[f[j] for j in idx] for _, f in self.rows], dtype=float)
            ok = data.size == 0 or bool(np.all(np.isfinite(data)))
            if ok:
                for k, lim in enumerate(limits):
                    if lim is not None and data.size and np.max(np.abs(data[:, k])) > lim:
                        ok = False
            if ok and all(len(f[j]) <= MAX_FIELD_CHARS for _, f in self.rows for j in idx):
                return data.reshape(len(self.rows), len(names))
        except ValueError:
            pass
        # slow path: name the first bad field
        for no, f in self.rows:
            for n, j, lim in zip(names, idx, limits, strict=True):
                parse_number(f[j], self.path, no, n, at_most=lim, unit_hint=unit_hint)
        raise AssertionError("unreachable: the vectorised and per-field parses disagree")


def read_table(
    path: Any,
    *,
    what: str = "a header row",
    text: str | None = None,
    settings: Sequence[str] = (),
    columns: Sequence[str] | None = None,
) -> Table:
    """Read a table from ``path`` (or from ``text`` already read from it; see module docstring).

    ``what`` says what the header should look like, for the empty-file message. ``# key: value``
    lines above the header whose key is in ``settings`` are collected (a key given twice is an
    error); other comments are free text. ``columns``: the column names of a table WITHOUT a
    header row (every line is a row; e.g. OptiOdom run files).
    """
    if text is None:
        text = read_text(path)
    header: list[str] | None = list(columns) if columns is not None else None
    header_line = 0
    rows: list[tuple[int, list[str]]] = []
    found: dict[str, tuple[str, int]] = {}
    for no, line in enumerate(text.splitlines(), start=1):
        if len(line) > MAX_LINE_CHARS:
            raise InputError(f"over-long line ({len(line)} characters)", path, no)
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if settings and header is None and ":" in stripped:
                key, value = (s.strip() for s in stripped[1:].split(":", 1))
                if key not in settings:
                    continue
                if key in found:
                    raise InputError(
                        f"setting given twice (first on line {found[key][1]})", path, no, key
                    )
                found[key] = (value, no)
            continue
        try:
            fields = _split(line)
        except csv.Error as exc:
            raise InputError(f"not valid CSV: {exc}", path, no) from None
        if header is None:
            header, header_line = fields, no
            for k, h in enumerate(fields):
                if h == "":
                    raise InputError(
                        f"the header row has an empty column name (column {k + 1})", path, no
                    )
                if len(h) > MAX_FIELD_CHARS:
                    raise InputError(f"over-long column name ({len(h)} characters)", path, no)
                if fields.index(h) != k:
                    raise InputError(
                        f"column '{h}' appears twice in the header (columns "
                        f"{fields.index(h) + 1} and {k + 1})",
                        path,
                        no,
                        h,
                    )
            continue
        if len(fields) != len(header):
            raise InputError(
                f"expected {len(header)} fields as in the header, got {len(fields)}", path, no
            )
        rows.append((no, fields))
    if header is None or (columns is not None and not rows):
        raise InputError(f"empty file, expected {what}", path)
    return Table(str(path), tuple(header), header_line, rows, found)


@dataclass(frozen=True)
class ColumnSample:
    """The finite values of one column of a table (blank cells skipped)."""

    path: str
    column: str
    values: np.ndarray


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(float(text))
    except ValueError:
        return False


def read_column(
    path: Any, column: str | None = None, *, table: Table | None = None
) -> ColumnSample:
    """The values of ``column`` (default: the first column whose every non-blank cell is a
    finite number). Blank cells are skipped; anything else that is not a finite number is an
    InputError naming the file, line and field."""
    table = table or read_table(path, what="a header row and values")
    if not table.rows:
        raise InputError("no data rows after the header", path)
    if column is None:
        for name in table.header:
            cells = [c for _, c in table.cells(name) if c != ""]
            if cells and all(_is_number(c) for c in cells):
                column = name
                break
        else:
            raise InputError("no numeric column (every column holds text)", path)
    values = [parse_number(c, path, no, column) for no, c in table.cells(column) if c != ""]
    if len(values) < 2:
        raise InputError(f"a t-test needs at least 2 values, got {len(values)}", path, None, column)
    arr = np.asarray(values)
    with np.errstate(over="ignore", invalid="ignore"):
        spread_ok = math.isfinite(float(np.mean(arr))) and math.isfinite(float(np.std(arr, ddof=1)))
    if not spread_ok:
        raise InputError(
            "values too large for a t-test (their mean or spread overflows)", path, None, column
        )
    return ColumnSample(str(path), column, arr)
