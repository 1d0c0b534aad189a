"""``odocal fleet report --db FLEET_DB --html DIR``: the fleet's dashboard, static HTML
(:mod:`odocal.io.fleet_html`), with each robot's history figure (:mod:`odocal.plot.fleet`).
Written all or nothing (:class:`~odocal.io.outputs.OutputPlan`)."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

from ..io.fleet_db import BagRow, open_db
from ..io.fleet_html import fleet_pages
from ..io.outputs import OutputPlan
from .fleet import now_utc
from .fleet_status import acknowledged_alarms, robot_drift, robot_status

__all__ = ["ReportResult", "fleet_report"]


@dataclass(frozen=True)
class ReportResult:
    """The dashboard written: its index page, how many robots and bags."""

    index: Path
    robots: int
    bags: int
    written: tuple[Path, ...]

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fleet report --json``."""
        return {
            "index": str(self.index),
            "robots": self.robots,
            "bags": self.bags,
            "written": [str(p) for p in self.written],
        }


def fleet_report(db_path: str | Path, html_dir: str | Path) -> ReportResult:
    """Write the dashboard into the folder ``html_dir`` (module docstring)."""
    from ..plot._figure import require_matplotlib
    from ..plot.fleet import history_figure, svg_text

    require_matplotlib()
    plan = OutputPlan([Path(db_path)])
    folder = Path(html_dir)
    plan.folder(folder, "--html")
    plan.folder(folder / "robots", "--html")
    plan.folder(folder / "bags", "--html")
    with open_db(db_path, write=False) as db:
        ids = db.robots()
        acks = acknowledged_alarms(db)
        histories = {r: db.history(r) for r, _ in ids}
        reports = {
            b.content_hash: db.report(b.content_hash)
            for h in histories.values()
            for b in h
            if b.record is not None
        }
    rows = sorted(
        (robot_status(r, nom, histories[r], acks.get(r, ())) for r, nom in ids),
        key=lambda r: r.sort_key,
    )
    status = {"db": str(db_path), "robots": [r.as_dict() for r in rows]}
    pages: dict[str, tuple[list[BagRow], str]] = {}
    for robot_id, history in histories.items():
        fig = history_figure(robot_id, robot_drift(history).parameters)
        pages[robot_id] = (history, svg_text(fig))
    contents = fleet_pages(status, pages, {h: r for h, r in reports.items() if r}, folder,
                           now_utc())  # fmt: skip
    written = tuple(plan.commit(contents))
    n_bags = sum(len(h) for h in histories.values())
    return ReportResult(folder / "index.html", len(ids), n_bags, written)
