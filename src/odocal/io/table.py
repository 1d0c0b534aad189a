"""The one reader of comma-separated tables (RUNS.csv, generic run CSVs, t-test samples, ...).

A table is UTF-8 text whose lines end in LF, CR LF or CR (and nowhere else: a form feed is
whitespace inside its line): blank lines are skipped; lines starting with ``#`` are comments (those
before the header may carry ``key: value`` settings); the first other line is the header row of
unique, non-empty column names; every further line is a row with as many fields as the header.
Fields are trimmed; CSV quoting is honoured.

A sheet saved by a spreadsheet in the European dialect (a header separated by ``;``, decimal
commas: the default of Excel and LibreOffice where the comma is the decimal separator) is read as
the comma-separated table it stands for, line for line; separators padding a comment line, and
empty fields padding a line beyond the header's columns (``cw;0,5;1;;``), are dropped. A sheet
of one column has no separator at all: its commas are decimal commas. What cannot be read
unambiguously is refused with what to change: a header that mixes ``;`` and ``,``, a sheet with
both decimal commas and decimal points, a thousands separator, one column whose every value has
a comma before three digits (``1,500``: 1.5 or 1500).

Every problem is an :class:`~odocal.errors.InputError` naming the file, the line and the field:
over-long lines or fields, duplicated column names or settings, a row of the wrong width, a value
that is not a finite number, or a number beyond the plausible magnitude the caller gives.

The rows after the header are split when they are read: :attr:`Table.rows` line by line (small
tables); :meth:`Table.numbers` parses numeric columns in vectorised passes over chunks of a few
megabytes (numpy's loadtxt; row widths checked by counting separators), so a table of millions
of rows needs memory of the order of its size. Only a chunk where that fails is parsed line by
line, which names the first bad line or field.
"""

from __future__ import annotations

import csv
import functools
import io
import math
import re
from collections.abc import Iterator, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from ..core.checks import parse_float
from ..errors import InputError
from .textfile import read_text

__all__ = [
    "Table",
    "Cells",
    "LineNumbers",
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
    """``raw`` (trimmed) as a finite float written as a plain decimal number
    (:func:`~odocal.core.checks.parse_float`: ``1_0`` is no number here, though Python's float()
    reads it as 10), or an InputError naming file, line and field.

    ``at_most`` bounds the magnitude (a larger value is implausible: a unit slip or a broken
    file); numbers that overflow a float (1e400, a 400-digit integer) are refused the same way.
    """
    text = raw.strip()
    if not text:
        raise InputError("not filled in (empty)", path, line, name)
    if len(text) > MAX_FIELD_CHARS:
        raise InputError(f"over-long value ({len(text)} characters)", path, line, name)
    try:
        v = parse_float(text)
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


def _universal_newlines(text: str) -> str:
    """``text`` with every line ending (CR LF, a lone CR) as LF: lines end there and nowhere
    else (a form feed or a vertical tab is whitespace inside its line, as in a spreadsheet's
    CSV; str.splitlines() would break a comment line at it)."""
    if "\r" not in text:
        return text
    return text.replace("\r\n", "\n").replace("\r", "\n")


# Characters of one vectorised pass (the pass ends at a line break).
_CHUNK_CHARS = 1 << 23


def _body_fields(path, no: int, line: str, width: int) -> list[str] | None:
    """The fields of one line after the header (None for a blank or comment line); an InputError
    for an over-long line, bad CSV or the wrong width."""
    if len(line) > MAX_LINE_CHARS:
        raise InputError(f"over-long line ({len(line)} characters)", path, no)
    stripped = line.strip()
    if not stripped or stripped.startswith("#"):
        return None
    try:
        fields = _split(line)
    except csv.Error as exc:
        raise InputError(f"not valid CSV: {exc}", path, no) from None
    if len(fields) != width:
        raise InputError(f"expected {width} fields as in the header, got {len(fields)}", path, no)
    return fields


@dataclass(frozen=True)
class Cells:
    """Some columns of a chunk of rows, split in one vectorised pass (:meth:`Table.row_chunks`).

    Attributes
    ----------
    lines : ndarray of int
        The line number of each row.
    columns : list of ndarray of bytes
        Each column's fields as they are in the file (dtype ``S``; not trimmed).
    start, stop : int
        The chunk's characters in the table's body (:meth:`Table.split` splits them line by
        line).
    """

    lines: np.ndarray
    columns: list[np.ndarray]
    start: int
    stop: int


class LineNumbers:
    """``table.lines[i]``: the line of data row i, without splitting the rows until asked."""

    def __init__(self, table: Table):
        self._table = table

    def __getitem__(self, index: int) -> int:
        return self._table.line_of(index)


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
    settings : dict of str -> (str, int)
        ``# key: value`` comment lines above the header: value and line number.
    text : str
        The whole text; the rows start at offset ``body`` (the character after the header line).
    """

    path: str
    header: tuple[str, ...]
    header_line: int
    settings: dict[str, tuple[str, int]] = field(default_factory=dict)
    text: str = field(default="", repr=False)
    body: int = 0

    def _lines(self, start: int = 0, stop: int | None = None) -> Iterator[tuple[int, str]]:
        """(line number, line) of the body's characters [start, stop) (offsets into the body,
        at line starts; only for bodies without odd line breaks)."""
        first = self.header_line + 1 + self.text.count("\n", self.body, self.body + start)
        chunk = self.text[self.body + start : None if stop is None else self.body + stop]
        return enumerate(chunk.split("\n"), start=first)

    @functools.cached_property
    def rows(self) -> list[tuple[int, list[str]]]:
        """Each data row's line number and its trimmed fields (every line checked)."""
        numbered = self._lines()
        width = len(self.header)
        out = []
        for no, line in numbered:
            fields = _body_fields(self.path, no, line, width)
            if fields is not None:
                out.append((no, fields))
        return out

    def _split_slowly(self) -> bool:
        """Rows already split, or comment lines after the header."""
        return "rows" in self.__dict__ or self.text.find("#", self.body) >= 0

    def line_of(self, index: int) -> int:
        """Line number of data row ``index`` (0-based), for messages."""
        return self.rows[index][0]

    @property
    def lines(self) -> LineNumbers:
        """The line number of each data row, ``lines[i]``, found only when asked (messages)."""
        return LineNumbers(self)

    def has(self, name: str) -> bool:
        """Whether the header has a column ``name``."""
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

    def _chunks(self) -> Iterator[tuple[int, int]]:
        """(start, stop) offsets into the body of chunks of a few megabytes, at line starts."""
        end = len(self.text) - self.body
        start = 0
        while start < end:
            stop = self.text.find("\n", self.body + min(start + _CHUNK_CHARS, end - 1))
            stop = end if stop < 0 else stop - self.body + 1
            yield start, stop
            start = stop

    def _chunk_rows(self, start: int, stop: int) -> list[tuple[int, list[str]]]:
        """The rows of the body's characters [start, stop), split line by line (each checked)."""
        rows = []
        width = len(self.header)
        for no, line in self._lines(start, stop):
            fields = _body_fields(self.path, no, line, width)
            if fields is not None:
                rows.append((no, fields))
        return rows

    def row_chunks(self, names: Sequence[str]) -> Iterator[Cells | list[tuple[int, list[str]]]]:
        """The rows in chunks of a few megabytes, each either :class:`Cells` (the columns
        ``names`` split in one vectorised pass) or, where that pass cannot be trusted (quotes,
        comment lines, a row of the wrong width, an over-long field), the rows split line by
        line as in :attr:`rows` (an InputError names a bad line)."""
        idx = [self.index(n) for n in names]
        if self._split_slowly():
            yield self.rows
            return
        for start, stop in self._chunks():
            cells = self._cells(start, stop, idx)
            yield self._chunk_rows(start, stop) if cells is None else cells

    def _line_bounds(
        self, chunk: str
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray] | None:
        """The bytes of ``chunk``, where its lines start and end, and its commas; None where a
        vectorised split cannot be trusted (quotes, a filled line without a comma per column
        boundary)."""
        if '"' in chunk:
            return None
        raw = np.frombuffer(chunk.encode("utf-8"), dtype=np.uint8)
        ends = np.flatnonzero(raw == 10)
        if len(raw) and raw[-1] != 10:
            ends = np.append(ends, len(raw))
        starts = np.r_[0, ends[:-1] + 1] if len(ends) else ends
        commas = np.flatnonzero(raw == 44)
        count = np.searchsorted(commas, ends) - np.searchsorted(commas, starts)
        if np.any(count[ends > starts] != len(self.header) - 1):
            return None
        return raw, starts, ends, commas

    def _cells(self, start: int, stop: int, idx: list[int]) -> Cells | None:
        """The fields ``idx`` of the body's characters [start, stop) as byte strings, or None
        where a vectorised split cannot be trusted."""
        chunk = self.text[self.body + start : self.body + stop]
        lines = self._line_bounds(chunk)
        if lines is None:
            return None
        raw, starts, ends, commas = lines
        filled = ends > starts
        if np.any(ends - starts > MAX_LINE_CHARS):
            return None
        width = len(self.header)
        # every comma belongs to a filled row, width - 1 of them each
        sep = commas.reshape(int(filled.sum()), width - 1)
        first = self.header_line + 1 + self.text.count("\n", self.body, self.body + start)
        columns = []
        for j in idx:
            lo = starts[filled] if j == 0 else sep[:, j - 1] + 1
            hi = ends[filled] if j == width - 1 else sep[:, j]
            size = hi - lo
            chars = int(size.max(initial=0))
            if chars > MAX_FIELD_CHARS:
                return None
            chars = max(chars, 1)
            offsets = np.arange(chars)
            at = np.minimum(lo[:, None] + offsets, max(len(raw) - 1, 0))
            block = np.where(offsets < size[:, None], raw[at] if len(raw) else 0, 0)
            columns.append(np.ascontiguousarray(block, dtype=np.uint8).view(f"S{chars}")[:, 0])
        return Cells(first + np.flatnonzero(filled), columns, start, stop)

    def split(self, cells: Cells) -> list[tuple[int, list[str]]]:
        """The rows of the chunk of ``cells`` split line by line, as :attr:`rows` (where the
        caller cannot trust its vectorised values: the slow way names what is wrong)."""
        return self._chunk_rows(cells.start, cells.stop)

    def numbers(
        self,
        names: Sequence[str],
        *,
        at_most: dict[str, float] | float | None = None,
        unit_hint: str = "check the units",
    ) -> np.ndarray:
        """The columns ``names`` as floats, shape (rows, len(names)).

        Every value must be a finite number (at most ``at_most`` in magnitude: one bound for
        all, or per column), and every row must have the header's width. Vectorised passes over
        chunks of a few megabytes; a chunk where one fails is parsed line by line, which names
        the first bad line or field.
        """
        idx = [self.index(n) for n in names]
        limits = [(at_most.get(n) if isinstance(at_most, dict) else at_most) for n in names]
        checks = (names, idx, limits, unit_hint)
        if self._split_slowly():
            return self._parse_rows(self.rows, checks)
        parts = []
        for start, stop in self._chunks():
            part = self._fast(start, stop, idx, limits)
            if part is None:  # the slow way names what is wrong (or accepts what numpy did not)
                part = self._parse_rows(self._chunk_rows(start, stop), checks)
            parts.append(part)
        if not parts:
            return np.empty((0, len(names)))
        return parts[0] if len(parts) == 1 else np.concatenate(parts)

    def _fast(self, start: int, stop: int, idx: list[int], limits) -> np.ndarray | None:
        """The body's characters [start, stop) parsed in one vectorised pass, or None where that
        cannot be trusted: quotes, lines of spaces, a line long enough to hold an over-long
        field, a row of the wrong width, a value numpy does not read, a non-finite or too large
        value."""
        chunk = self.text[self.body + start : self.body + stop]
        lines = self._line_bounds(chunk)
        if lines is None:
            return None
        _, starts, ends, _ = lines
        lengths = ends - starts
        if lengths.max(initial=0) > MAX_FIELD_CHARS:
            return None
        filled = lengths > 0  # numpy's loadtxt skips empty lines, as the table does
        try:
            data = np.loadtxt(
                io.StringIO(chunk), delimiter=",", usecols=idx, ndmin=2, comments=None
            )
        except ValueError:
            return None
        if len(data) != int(filled.sum()) or not np.all(np.isfinite(data)):
            return None
        for k, lim in enumerate(limits):
            if lim is not None and len(data) and np.max(np.abs(data[:, k])) > lim:
                return None
        return data

    def _parse_rows(self, rows, checks) -> np.ndarray:
        """Rows already split, parsed field by field (each error named)."""
        names, idx, limits, unit_hint = checks
        out = np.empty((len(rows), len(names)))
        for i, (no, f) in enumerate(rows):
            for k, (n, j, lim) in enumerate(zip(names, idx, limits, strict=True)):
                out[i, k] = parse_number(f[j], self.path, no, n, at_most=lim, unit_hint=unit_hint)
        return out


def _head_lines(text: str) -> Iterator[str]:
    """The lines of ``text`` (line ends already LF) with their line breaks, one at a time
    (the header is near the top of a file whose rows may be millions)."""
    start = 0
    while start < len(text):
        end = text.find("\n", start)
        end = len(text) if end < 0 else end + 1
        yield text[start:end]
        start = end


_DECIMAL_COMMA = re.compile(r"^[+-]?(\d+,\d*|,\d+)([eE][+-]?\d+)?$")
_DECIMAL_POINT = re.compile(r"^[+-]?(\d+\.\d*|\.\d+)([eE][+-]?\d+)?$")
# a comma before three digits after one to three digits: 1,500 is 1.5 or 1500
_THOUSANDS_LIKE = re.compile(r"^[+-]?[1-9][0-9]{0,2},[0-9]{3}$")
_GROUPED = re.compile(r"^[+-]?\d{1,3}([.\s\u00a0\u202f']\d{3})+(,\d*)?$")
_SETTING_COMMA = re.compile(r"^(#[^:]*:\s*[+-]?\d*),(\d+)$")
_SEMICOLON_ADVICE = (
    "save the sheet again as CSV with one decimal separator (in LibreOffice: 'Save As', "
    "'Text CSV', field delimiter ';' or ',')"
)


def _csv_field(text: str) -> str:
    return f'"{text.replace(chr(34), chr(34) * 2)}"' if ("," in text or '"' in text) else text


def _semicolon_fields(path: Any, no: int, line: str) -> list[str]:
    """The fields of one line separated by ';' (CSV quoting honoured)."""
    if '"' not in line:
        return line.split(";")
    try:
        return next(csv.reader([line], delimiter=";"))
    except csv.Error as exc:
        raise InputError(f"not valid CSV: {exc}", path, no) from None


def _unpadded(fields: list[str], width: int) -> list[str]:
    """``fields`` without the empty fields beyond the first ``width``: a spreadsheet pads every
    line with separators to its widest one (``cw;0,5;1;;``)."""
    end = len(fields)
    while end > width and not fields[end - 1].strip():
        end -= 1
    return fields[:end]


def _semicolon_text(path: Any, text: str, header_no: int, declared: bool = True) -> str:
    """A sheet saved by a spreadsheet in the European dialect (fields separated by ';', decimal
    commas: Excel's and LibreOffice's default where the comma is the decimal separator) as the
    comma-separated text it stands for, line for line; empty fields padding a line beyond the
    header's columns (and the header's own) are dropped. Decimal points are read too, but not
    both in one sheet (then a point may group thousands); a number with a thousands separator,
    or a row separated by ',' under a ';' header, is refused with what to change.

    ``declared``: the header is separated by ';' (the dialect is declared); else the sheet is
    one column without a separator, whose commas are decimal commas only when they cannot be
    thousands separators (not every value a comma before three digits)."""
    out = []
    comma_line = point_line = 0
    width = 0
    thousands_like: tuple[int, str] | None = None  # the first '1,500': 1.5 or 1500?
    decimal_only = False  # a decimal comma that groups no thousands ('0,5', '12,25')
    for no, line in enumerate(text.split("\n"), start=1):
        stripped = line.strip()
        if not stripped:
            out.append(line)
            continue
        if stripped.startswith("#"):  # a spreadsheet pads comment lines with separators
            stripped = stripped.rstrip("; \t")
            out.append(_SETTING_COMMA.sub(r"\1.\2", stripped) if no < header_no else stripped)
            continue
        if len(line) > MAX_LINE_CHARS:
            raise InputError(f"over-long line ({len(line)} characters)", path, no)
        fields = _semicolon_fields(path, no, line)
        if no == header_no:
            width = len(_unpadded(fields, 0))
        fields = _unpadded(fields, width)
        if width > 1 and len(fields) == 1 and "," in line and no > header_no:
            raise InputError(
                "fields separated by ',' under a header separated by ';': use one separator in "
                f"the whole sheet; {_SEMICOLON_ADVICE}",
                path,
                no,
            )
        converted = []
        for f in fields:
            f = f.strip()
            if _GROUPED.match(f) and ("," in f or not _DECIMAL_POINT.match(f)):
                raise InputError(
                    f"{f!r} groups thousands: write numbers without a thousands separator "
                    "(format the cells as plain numbers)",
                    path,
                    no,
                )
            if _DECIMAL_COMMA.match(f):
                if _THOUSANDS_LIKE.match(f):
                    thousands_like = thousands_like or (no, f)
                else:
                    decimal_only = True
                f = f.replace(",", ".")
                comma_line = comma_line or no
            elif _DECIMAL_POINT.match(f):
                point_line = point_line or no
            converted.append(_csv_field(f))
        out.append(",".join(converted))
    if comma_line and point_line:
        raise InputError(
            f"separated by ';' with decimal commas (line {comma_line}) and decimal points "
            f"(line {point_line}): a point may group thousands, so the numbers are ambiguous; "
            f"{_SEMICOLON_ADVICE}",
            path,
            point_line,
        )
    if not declared and thousands_like is not None and not decimal_only:
        no, value = thousands_like
        raise InputError(
            f"{value!r} may be a decimal comma or a thousands separator (every value of this "
            "column has a comma before three digits): write the numbers with a decimal point, "
            "or without a thousands separator",
            path,
            no,
        )
    return "\n".join(out)


def _commas_below(text: str, start: int) -> bool:
    """Whether a line of ``text`` after the offset ``start`` that is not a comment holds a
    comma."""
    at = text.find(",", start)
    while at >= 0:
        line_start = text.rfind("\n", 0, at) + 1
        if not text[line_start:at].lstrip().startswith("#"):
            return True
        line_end = text.find("\n", at)
        if line_end < 0:
            return False
        at = text.find(",", line_end)
    return False


def _comma_text(path: Any, text: str) -> str:
    """``text`` as a comma-separated table: as it is, or converted from the semicolon dialect
    (:func:`_semicolon_text`) when its header row is separated by ';' and holds no ','."""
    offset = 0  # characters up to the end of the current line
    for no, line in enumerate(_head_lines(text), start=1):
        offset += len(line)
        stripped = line.strip()
        if not stripped or stripped.startswith("#"):
            continue
        if ";" not in stripped:
            if "," not in stripped and _commas_below(text, offset):
                # one column: a spreadsheet writes no separator, so a comma below is decimal
                return _semicolon_text(path, text, no, declared=False)
            return text
        if "," in stripped:
            raise InputError(
                "the header row mixes ';' and ',' as field separators: use one of them (commas "
                "with decimal points, or semicolons with decimal commas)",
                path,
                no,
            )
        return _semicolon_text(path, text, no)
    return text


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
    header row (every line is a row; e.g. OptiOdom run files). The rows are checked when they
    are read (:attr:`Table.rows`, :meth:`Table.numbers`).
    """
    if text is None:
        text = read_text(path)
    text = _universal_newlines(text)
    if columns is None:
        text = _comma_text(path, text)
    if columns is not None:
        if not any(ln.strip() and not ln.lstrip().startswith("#") for ln in _head_lines(text)):
            raise InputError(f"empty file, expected {what}", path)
        return Table(str(path), tuple(columns), 0, {}, text, 0)
    found: dict[str, tuple[str, int]] = {}
    offset = 0  # characters before the current line
    for no, line in enumerate(_head_lines(text), start=1):
        offset += len(line)
        line = line.rstrip("\n")
        if len(line) > MAX_LINE_CHARS:
            raise InputError(f"over-long line ({len(line)} characters)", path, no)
        stripped = line.strip()
        if not stripped:
            continue
        if stripped.startswith("#"):
            if settings and ":" in stripped:
                key, value = (s.strip() for s in stripped[1:].split(":", 1))
                value = value.rstrip(",; \t")  # a spreadsheet pads a comment with separators
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
        return Table(str(path), tuple(fields), no, found, text, offset)
    raise InputError(f"empty file, expected {what}", path)


@dataclass(frozen=True)
class ColumnSample:
    """The finite values of one column of a table (blank cells skipped)."""

    path: str
    column: str
    values: np.ndarray


def _is_number(text: str) -> bool:
    try:
        return math.isfinite(parse_float(text))
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
