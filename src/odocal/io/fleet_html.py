"""The fleet dashboard (``odocal fleet report --html DIR``): static, self-contained HTML pages
(inline CSS, inline SVG figures; no script, no server, no network), opened from disk.

- ``index.html``: the fleet table, the largest drift first, each robot linked to its page;
- ``robots/<robot_id>.html``: the parameter history figure, the active alarms (and those an
  operator acknowledged), every bag with its status (its verdict from its calibration record)
  and a link to its calibration report;
- ``bags/<hash>.html``: one bag's calibration report (the bag route's report, as
  ``odocal fit BAG --method auto --out`` writes it, from the ``fit --json`` the database keeps
  for it), as HTML (:mod:`odocal.io.markdown_html`), with the held-out check's figure drawn from
  it (:func:`heldout_svg`).
"""

from __future__ import annotations

import hashlib
import html
import math
from collections.abc import Mapping, Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import Any
from urllib.parse import quote

from ..errors import quote_path
from .auto_report import auto_report_markdown
from .fleet_db import BagRow
from .markdown_html import markdown_html

__all__ = ["fleet_pages", "bag_page_name", "robot_page_name", "shown_id", "heldout_svg"]

_CSS = """
body{font-family:system-ui,sans-serif;margin:1.5em;color:#222;max-width:72em}
table{border-collapse:collapse;font-size:0.9em}
th,td{border:1px solid #ccc;padding:0.3em 0.6em;text-align:right;white-space:nowrap}
th{background:#f0f0f0} td:first-child,th:first-child{text-align:left}
tr.alarm td{background:#fde8e8} tr.problem td{background:#fdf1dc}
.ok{color:#2a7d2a} .bad{color:#b22}
pre{background:#f7f7f7;padding:1em;overflow-x:auto} a{color:#1a5fb4}
.report table{margin-bottom:1em} .report td,.report th{white-space:normal;text-align:left}
code{background:#f3f3f3;padding:0 0.2em}
"""

_KEYS = (
    ("wheel_diameter_right_m", "D_R (mm)"),
    ("wheel_diameter_left_m", "D_L (mm)"),
    ("wheelbase_m", "b (mm)"),
)


def bag_page_name(content_hash: str) -> str:
    """The file of a bag's report, relative to the dashboard's folder."""
    return f"bags/{content_hash[:16]}.html"


#: The longest file name most file systems take (bytes).
MAX_NAME_BYTES = 255


def robot_page_name(robot_id: str) -> str:
    """The file of a robot's page, relative to the dashboard's folder: ``robots/<id>.html``
    when the id makes a printable file name that fits (:data:`MAX_NAME_BYTES` with ``.html``);
    otherwise its printable part, cut to 200 bytes, and 12 hex digits of its sha256 (distinct
    ids, distinct pages: a 251-character id stopped the whole dashboard)."""
    name = f"{robot_id}.html"
    if robot_id.isprintable() and len(name.encode()) <= MAX_NAME_BYTES:
        return f"robots/{name}"
    printable = "".join(c if c.isprintable() else "_" for c in robot_id)
    cut = printable.encode()[:200].decode(errors="ignore")
    digest = hashlib.sha256(robot_id.encode("utf-8", "surrogateescape")).hexdigest()[:12]
    return f"robots/{cut}-{digest}.html"


def shown_id(robot_id: str) -> str:
    """A robot id as a page shows it: as it is, or quoted with escapes when it holds a line break
    or another character that is not printable (:func:`~odocal.errors.quote_path`)."""
    return quote_path(robot_id)


def _e(v: Any) -> str:
    return html.escape(str(v), quote=True)


def _page(title: str, body: str) -> str:
    return (
        f'<!DOCTYPE html>\n<html lang="en"><head><meta charset="utf-8">'
        f"<title>{_e(title)}</title><style>{_CSS}</style></head>\n<body>\n{body}\n"
        "</body></html>\n"
    )


def _mm(p: Mapping[str, Any] | None, key: str) -> str:
    v = (p or {}).get(key)
    if not v:
        return "—"
    return f"{1e3 * v['value']:.3f} ± {1e3 * v['std_error']:.3f}"


def _drift_cell(r: Mapping[str, Any]) -> str:
    d = r.get("drift")
    if not r.get("trusted_calibration", True):  # (no drift to see without one: not 'no')
        return '<span class="bad">no trusted calibration</span>'
    if not d:
        return '<span class="ok">no</span>'
    return (
        f'<span class="bad">{_e(d["parameter"])} {d["size_percent"]:+.2f} % '
        f"({d['z']:+.1f} se)</span>"
    )


def _index(status: Mapping[str, Any], generated: str) -> str:
    head = "".join(
        f"<th>{_e(h)}</th>"
        for h in (
            "robot",
            "bags",
            "failed",
            "untrusted",
            "last calibrated",
            *(t for _, t in _KEYS),
            "drift alarm",
        )
    )
    rows = []
    for r in status["robots"]:
        cls = ' class="alarm"' if r["drift_alarm"] else ""
        if not r["trusted_calibration"]:
            cls = ' class="problem"'
        cells = [
            f'<a href="{_e(quote(robot_page_name(r["robot_id"])))}">{_e(shown_id(r["robot_id"]))}'
            "</a>",
            _e(r["bags"]),
            _e(r["bags_failed"]),
            _e(r["bags_untrusted"]),
            _e((r["last_calibrated"] or "never")[:16].replace("T", " ")),
            *(_mm(r["parameters"], k) for k, _ in _KEYS),
            _drift_cell(r),
        ]
        rows.append(f"<tr{cls}>" + "".join(f"<td>{c}</td>" for c in cells) + "</tr>")
    n_alarm = sum(1 for r in status["robots"] if r["drift_alarm"])
    n_untrusted = sum(1 for r in status["robots"] if not r["trusted_calibration"])
    body = (
        f"<h1>Fleet odometry</h1><p>{len(status['robots'])} robots, {n_alarm} with a drift "
        f"alarm, {n_untrusted} without a trusted calibration; generated {_e(generated)} from "
        f"{_e(status['db'])}. Parameters: the "
        "filtered level ± its standard error (docs/fleet.md).</p>\n"
        f'<table id="fleet"><thead><tr>{head}</tr></thead><tbody>\n'
        + "\n".join(rows)
        + "\n</tbody></table>"
    )
    return _page("Fleet odometry", body)


def _alarm_table(alarms: Sequence[Mapping[str, Any]]) -> str:
    rows = "".join(
        f"<tr><td>{_e(a['parameter'])}</td><td>{1e3 * a['size_m']:+.3f}</td>"
        f"<td>{a['size_percent']:+.2f}</td><td>{a['z']:+.1f}</td><td>{_e(a['change_bag'])}</td>"
        f"<td>{_e(a['bag'])}</td></tr>"
        for a in alarms
    )
    return (
        "<table><tr><th>parameter</th><th>step (mm)</th><th>step (%)</th><th>se</th>"
        f"<th>first bag of the new level</th><th>found at bag</th></tr>{rows}</table>"
    )


def _robot(robot: Mapping[str, Any], bags: Sequence[BagRow], svg: str) -> str:
    alarms = robot["alarms"]
    alarm_html = _alarm_table(alarms) if alarms else "<p>No active drift alarm.</p>"
    acknowledged = robot.get("alarms_acknowledged") or []
    if acknowledged:
        alarm_html += (
            "<p>Acknowledged (<code>odocal fleet ack</code>; no longer active):</p>"
            + _alarm_table(acknowledged)
        )
    bag_rows = []
    for i, b in enumerate(bags):
        link = (
            f'<a href="../{_e(bag_page_name(b.content_hash))}">report</a>'
            if b.record is not None
            else ""
        )
        verdict = ""
        if b.record is not None:
            verdict = "trustworthy" if b.record.enough else "not trustworthy"
        bag_rows.append(
            f"<tr><td>{i}</td><td>{_e(b.path)}</td><td>{_e(_utc(b.start_s))}</td>"
            f"<td>{_e(b.status)}</td><td>{_e(verdict or b.reason or '')}</td>"
            f"<td>{link}</td></tr>"
        )
    body = (
        f'<p><a href="../index.html">fleet</a></p><h1>{_e(shown_id(robot["robot_id"]))}</h1>'
        f"<h2>Drift alarms</h2>{alarm_html}<h2>Parameter history</h2>{svg}"
        "<h2>Bags</h2><table><tr><th>#</th><th>bag</th><th>start (UTC)</th><th>status</th>"
        "<th>verdict or reason</th><th></th></tr>" + "".join(bag_rows) + "</table>"
    )
    return _page(f"robot {shown_id(robot['robot_id'])}", body)


def _num(v: Any) -> float | None:
    """A finite number, or None."""
    return float(v) if isinstance(v, int | float) and math.isfinite(v) else None


def _step(top: float) -> float:
    """A round tick step for an axis from 0 to ``top`` (4 to 10 ticks)."""
    step = 10.0 ** math.floor(math.log10(top / 4.0))
    for f in (1.0, 2.0, 5.0, 10.0):
        if top / (f * step) <= 10.0:
            return f * step
    return 10.0 * step


def heldout_svg(heldout: Mapping[str, Any]) -> str:
    """The held-out check of a stored result (its ``heldout`` object) as an inline SVG bar chart,
    what ``fit --plot``'s heldout.png shows: the mean end error of the held-out stretches with
    the nominal parameters and with each model, the answer's model in dark blue. Drawn as text
    (a millisecond, 3 KB: a matplotlib figure per bag made a dashboard of 1,000 bags 150 s
    and 35 MB longer)."""
    models = heldout.get("models") or []
    names = ["nominal", *(str(m.get("model")) for m in models)]
    values = [_num(heldout.get("nominal_final_error_m"))]
    values += [_num(m.get("mean_final_error_m")) for m in models]
    colours = ["#999999"] + [
        "#1f77b4" if m.get("model") == heldout.get("preferred_model") else "#9edae5" for m in models
    ]
    w, h, left, right, top, bottom = 560, 300, 70, 20, 56, 36
    pw, ph = w - left - right, h - top - bottom
    vmax = max((v for v in values if v is not None), default=0.0)
    ymax = 1.15 * vmax if vmax > 0 else 1.0
    step = _step(ymax)

    def y(v: float) -> float:
        return top + ph * (1.0 - v / ymax)

    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{w}" height="{h}" '
        f'viewBox="0 0 {w} {h}" role="img" aria-label="held-out check" '
        'font-family="system-ui,sans-serif" font-size="11">',
        f'<text x="{w / 2:g}" y="18" text-anchor="middle" font-size="12">Held out: '
        f"{_e(heldout.get('folds'))} time blocks, {_e(heldout.get('chains'))} stretches of "
        f"median {_num(heldout.get('chain_seconds')) or 0:.0f} s</text>",
        f'<text x="{w / 2:g}" y="34" text-anchor="middle">(dark blue: the model of the '
        "answer)</text>",
    ]
    k = 0
    while k * step <= ymax * (1 + 1e-9):
        yy = y(k * step)
        out.append(
            f'<line x1="{left}" x2="{w - right}" y1="{yy:.1f}" y2="{yy:.1f}" stroke="#ddd"/>'
            f'<text x="{left - 6}" y="{yy + 4:.1f}" text-anchor="end">{k * step:.3g}</text>'
        )
        k += 1
    slot = pw / max(1, len(names))
    for i, (name, v, c) in enumerate(zip(names, values, colours, strict=True)):
        x = left + slot * (i + 0.2)
        bw = slot * 0.6
        cx = x + bw / 2
        if v is not None:
            out.append(
                f'<rect x="{x:.1f}" y="{y(v):.1f}" width="{bw:.1f}" height="{ph * v / ymax:.1f}" '
                f'fill="{c}"/><text x="{cx:.1f}" y="{y(v) - 4:.1f}" text-anchor="middle">'
                f"{v:.3g} m</text>"
            )
        out.append(f'<text x="{cx:.1f}" y="{top + ph + 16}" text-anchor="middle">{_e(name)}</text>')
    out.append(
        f'<line x1="{left}" x2="{left}" y1="{top}" y2="{top + ph}" stroke="#333"/>'
        f'<line x1="{left}" x2="{w - right}" y1="{top + ph}" y2="{top + ph}" stroke="#333"/>'
        f'<text transform="translate(14 {top + ph / 2:.1f}) rotate(-90)" text-anchor="middle">'
        "mean end error of the held-out stretches (m)</text></svg>"
    )
    return "".join(out)


def _figures(result: Mapping[str, Any]) -> str:
    """The report's figures, from what the database keeps of the bag's result."""
    parts = []
    if result.get("heldout"):
        parts.append(f"<h3>Held-out check</h3>\n{heldout_svg(result['heldout'])}")
    if result.get("time_offsets"):
        parts.append(
            "<p>The clock offsets' loss profiles (the report's time_offset.png) are not kept in "
            "the fleet database: <code>odocal fit BAG --method auto --robot ROBOT.yaml --plot "
            "DIR</code> draws them.</p>"
        )
    return "<h2>Figures</h2>\n" + "\n".join(parts) + "\n" if parts else ""


def _bag(robot_id: str, b: BagRow, report: Mapping[str, Any]) -> str:
    """A bag's page: its report (the bag route's Markdown, as HTML) with its figures."""
    md = auto_report_markdown(dict(report))
    # the report's closing line names figure files a dashboard does not have: the figures
    # themselves follow instead
    md = "\n".join(line for line in md.splitlines() if not line.startswith("Figures: "))
    body = (
        f'<p><a href="../{_e(quote(robot_page_name(robot_id)))}">{_e(shown_id(robot_id))}</a>'
        f"</p>\n<p>sha256 {_e(b.content_hash)}</p>\n"
        f'<div class="report">\n{markdown_html(md)}{_figures(report)}</div>'
    )
    return _page(f"bag {b.path}", body)


def _utc(t: float | None) -> str:
    return "" if t is None else datetime.fromtimestamp(t, UTC).strftime("%Y-%m-%d %H:%M:%S")


def fleet_pages(
    status: Mapping[str, Any],
    robots: Mapping[str, tuple[Sequence[BagRow], str]],
    reports: Mapping[str, Mapping[str, Any]],
    folder: Path,
    generated: str,
) -> dict[Path, str]:
    """Every page of the dashboard: ``status`` is ``odocal fleet status --json``; ``robots``
    maps each robot id to (its bags, with their calibration records; its history figure as SVG
    text); ``reports`` each calibrated bag's content hash to its report (its ``fit --json``)."""
    out = {folder / "index.html": _index(status, generated)}
    by_id = {r["robot_id"]: r for r in status["robots"]}
    for robot_id, (bags, svg) in robots.items():
        out[folder / robot_page_name(robot_id)] = _robot(by_id[robot_id], bags, svg)
        for b in bags:
            if b.record is not None:
                out[folder / bag_page_name(b.content_hash)] = _bag(
                    robot_id, b, reports[b.content_hash]
                )
    return out
