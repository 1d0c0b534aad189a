"""HTML from the Markdown odocal's reports are written in (:mod:`odocal.io.auto_report`), for
pages that show a report (the fleet dashboard's bag pages): no dependency, and only the subset
the reports use.

- ``#`` to ``######`` headings; paragraphs (lines until a blank line); ``- `` list items;
- pipe tables: a header row, a ``|---|---|`` row, body rows (a cell's ``\\|`` is a pipe; a row
  with more cells than the header keeps the rest, pipes and all, in its last cell);
- inline: ``**bold**`` and ```code```.

Everything else is text: every ``<``, ``>``, ``&`` and quote is escaped, so a report naming a
file called ``<script>`` shows that name and runs nothing.
"""

from __future__ import annotations

import html
import re

__all__ = ["markdown_html"]

_HEADING = re.compile(r"^(#{1,6})\s+(.*?)\s*#*\s*$")
_SEPARATOR = re.compile(r"^\s*\|?\s*:?-+:?\s*(\|\s*:?-+:?\s*)*\|?\s*$")
_CODE = re.compile(r"(`+)(.+?)\1")
_BOLD = re.compile(r"\*\*(.+?)\*\*")
_PIPE = re.compile(r"(?<!\\)\|")


def _text(s: str) -> str:
    """Escaped text with ``**bold**``."""
    return _BOLD.sub(r"<strong>\1</strong>", html.escape(s, quote=True))


def _inline(s: str) -> str:
    """One line's inline Markdown (code spans, bold) as HTML, the rest escaped."""
    out, at = [], 0
    for m in _CODE.finditer(s):
        out.append(_text(s[at : m.start()]))
        out.append(f"<code>{html.escape(m.group(2).strip(), quote=True)}</code>")
        at = m.end()
    out.append(_text(s[at:]))
    return "".join(out)


def _cells(row: str, n: int | None = None) -> list[str]:
    """The cells of a table row (``n``: the header's count; more are kept in the last)."""
    s = row.strip()
    if s.startswith("|"):
        s = s[1:]
    if s.endswith("|") and not s.endswith("\\|"):
        s = s[:-1]
    cells = _PIPE.split(s)
    if n is not None and len(cells) > n > 0:
        cells = [*cells[: n - 1], "|".join(cells[n - 1 :])]
    return [c.strip().replace("\\|", "|") for c in cells]


def _table(rows: list[str]) -> str:
    head = _cells(rows[0])
    n = len(head)
    out = ["<table><thead><tr>", *(f"<th>{_inline(c)}</th>" for c in head), "</tr></thead>"]
    out.append("<tbody>")
    for row in rows[2:]:
        cells = _cells(row, n)
        cells += [""] * (n - len(cells))
        out.append("<tr>" + "".join(f"<td>{_inline(c)}</td>" for c in cells) + "</tr>")
    out.append("</tbody></table>")
    return "".join(out)


def _is_table_start(lines: list[str], i: int) -> bool:
    return (
        lines[i].lstrip().startswith("|")
        and i + 1 < len(lines)
        and _SEPARATOR.match(lines[i + 1]) is not None
    )


def markdown_html(text: str) -> str:
    """The HTML of ``text`` (module docstring): one block element per line of output."""
    lines = text.splitlines()
    blocks: list[str] = []
    i = 0
    while i < len(lines):
        line = lines[i]
        if not line.strip():
            i += 1
            continue
        m = _HEADING.match(line)
        if m:
            level = len(m.group(1))
            blocks.append(f"<h{level}>{_inline(m.group(2))}</h{level}>")
            i += 1
            continue
        if _is_table_start(lines, i):
            rows = lines[i : i + 2]
            i += 2
            while i < len(lines) and lines[i].lstrip().startswith("|"):
                rows.append(lines[i])
                i += 1
            blocks.append(_table(rows))
            continue
        if line.startswith("- "):
            items = []
            while i < len(lines) and lines[i].startswith("- "):
                items.append(f"<li>{_inline(lines[i][2:])}</li>")
                i += 1
            blocks.append("<ul>" + "".join(items) + "</ul>")
            continue
        para = []
        while (
            i < len(lines)
            and lines[i].strip()
            and not _HEADING.match(lines[i])
            and not lines[i].startswith("- ")
            and not _is_table_start(lines, i)
        ):
            para.append(_inline(lines[i].strip()))
            i += 1
        blocks.append("<p>" + "\n".join(para) + "</p>")
    return "\n".join(blocks) + ("\n" if blocks else "")
