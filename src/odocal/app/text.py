"""The words of a result: the one home of the text ``odocal`` prints, which is also a result's
``str`` (and, in a notebook, its Markdown), and the warnings a command emits through Python's
:mod:`warnings` when called from Python.

A result class inherits :class:`Presented` and defines ``text()``; the command line prints
``res.text()`` (its warnings, on stderr, separately), so the table is written once.
"""

from __future__ import annotations

import functools
import warnings
from collections.abc import Callable, Iterable
from typing import Any, TypeVar

from ..errors import OdocalWarning

__all__ = [
    "Text",
    "Presented",
    "table_lines",
    "check_text",
    "result_warnings",
    "emits_warnings",
    "format_topics",
]


def table_lines(rows: list[tuple], title: str | None = None) -> list[str]:
    """Two or more columns, left column left-aligned, the rest right-aligned (each line indented
    by two spaces), after the ``title`` line if any."""
    cells = [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells if i < len(r)) for i in range(max(map(len, cells)))]
    lines = [title] if title else []
    for r in cells:
        parts = [r[0].ljust(widths[0])] + [c.rjust(widths[i + 1]) for i, c in enumerate(r[1:])]
        lines.append("  " + "  ".join(parts).rstrip())
    return lines


class Text:
    """Lines of text being written: ``out(line)`` adds a line (as ``print`` would), ``out.table``
    a table; ``str(out)`` is the whole text."""

    def __init__(self) -> None:
        self.lines: list[str] = []

    def __call__(self, line: str = "") -> None:
        """Add ``line`` (it may hold line breaks)."""
        self.lines.append(line)

    def table(self, rows: list[tuple], title: str | None = None) -> None:
        """Add a table (:func:`table_lines`)."""
        self.lines += table_lines(rows, title)

    def __str__(self) -> str:
        return "\n".join(self.lines)


class Presented:
    """A result that reads as the command line prints it: ``str(result)`` is the text of the
    command (without its warnings, which are in ``result.warnings``), and a notebook shows it as
    Markdown (the warnings first, then the text)."""

    def text(self) -> str:
        """The text the command prints for this result."""
        raise NotImplementedError

    def __str__(self) -> str:
        return self.text()

    def _repr_markdown_(self) -> str:
        said = "".join(f"**warning:** {w}\n\n" for w in result_warnings(self))
        return f"{said}```text\n{self.text()}\n```\n"


def result_warnings(result: Any) -> tuple[str, ...]:
    """The warnings a result carries (its ``load_warnings`` then its ``warnings``), each once."""
    said: list[str] = []
    for name in ("load_warnings", "warnings"):
        for w in getattr(result, name, None) or ():
            if w not in said:
                said.append(w)
    return tuple(said)


F = TypeVar("F", bound=Callable[..., Any])


def emits_warnings(command: F) -> F:
    """A public command: each warning of its result is also emitted once through Python's
    :mod:`warnings` as :class:`~odocal.errors.OdocalWarning`, pointing at the caller (the command
    line, which prints them itself, ignores that category)."""

    @functools.wraps(command)
    def run(*args: Any, **kwargs: Any) -> Any:
        result = command(*args, **kwargs)
        for w in result_warnings(result):
            warnings.warn(w, OdocalWarning, stacklevel=2)
        return result

    return run  # type: ignore[return-value]


def check_text(out: Text, res: Any, indent: str = "") -> None:
    """The human-readable check (``odocal check``; also the 'Is this log enough?' section of
    ``odocal fit``)."""
    from ..calibration.identifiability import degenerate_motions  # only where a check is shown

    c = res.check
    d = c.motion.as_dict()
    out(
        f"{indent}{'enough' if c.ok else 'NOT enough'} for "
        f"{', '.join(c.parameters)}: condition number {c.condition_number:.3g}; weakest: "
        f"{c.weakest_direction}"
    )
    rows = [("", "value", "predicted std. error")]
    for name, value in zip(c.parameters, c.values, strict=True):
        se = c.stderr[name]
        rows.append(
            (
                indent + name,
                f"{value:.6g}",
                "not identifiable" if se == float("inf") else f"{se:.2e}",
            )
        )
    out.table(rows)
    out(f"{indent}  motion: {_motion_line(d)}")
    for g in c.degeneracies:
        out(f"{indent}  {g.severity}: {g.message}")
    for m in degenerate_motions(c):
        out(f"{indent}  degenerate motion: {m['name']} [{m['code']}]: hides {m['hides']}")
    for s in c.suggestions:
        out(f"{indent}  suggestion: {s}")
    out(f"{indent}  noise: {res.noise_source}")


def _motion_line(d: dict[str, Any]) -> str:
    head = (
        f"{d['travel_m']:.1f} m driven, {d['rotation_deg']:.0f} deg turned "
        f"({d['rotation_left_deg']:.0f} left, {d['rotation_right_deg']:.0f} right); "
    )
    if d["share_straight"] is None:  # no wheel travel: no shares (None in the JSON)
        return head + "no wheel travel"
    return head + (
        f"wheel travel {100 * d['share_straight']:.0f} % straight, "
        f"{100 * d['share_spot']:.0f} % spot turns, {100 * d['share_arc']:.0f} % arcs"
    )


def written_lines(out: Text, written: Iterable[Any]) -> None:
    """One ``wrote PATH`` line per file written."""
    for f in written:
        out(f"wrote {f}")


def format_topics(topics: Iterable[Any]) -> str:
    """A readable table of a bag's topics (name, type, count)."""
    rows = [("topic", "type", "messages")] + [(t.name, t.msgtype, str(t.count)) for t in topics]
    w0, w1, w2 = (max(len(r[i]) for r in rows) for i in range(3))
    return "\n".join(f"{a.ljust(w0)}  {b.ljust(w1)}  {c.rjust(w2)}" for a, b, c in rows)


def verdict_lines(out: Text, enough: bool, reasons: tuple[str, ...] | list[str]) -> None:
    """The verdict of a route that weighs its answer: trustworthy, or not and why."""
    if enough:
        out("verdict: trustworthy")
        return
    out("verdict: NOT to be trusted:")
    for reason in reasons:
        out(f"  - {reason}")
