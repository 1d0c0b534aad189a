"""``odocal reproduce``: regenerate the paper's simulations (figures and a Markdown report)."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path

from ..design.reproduce import Reproduction
from ..design.reproduce import reproduce as reproduce_paper
from ..design.sweep import Progress
from ..io.outputs import OutputPlan
from ..io.report import reproduce_markdown

__all__ = ["ReproduceResult", "reproduce"]


@dataclass(frozen=True)
class ReproduceResult:
    """The reproduction, the files written (REPORT.md and figures, by key) and the time the
    simulation took (s; reported on the terminal, never inside the report)."""

    reproduction: Reproduction
    report: Path
    figures: dict[str, Path]
    elapsed_s: float


def reproduce(
    out: str | Path, *, trials: int = 800, seed: int = 0, progress: Progress | None = None
) -> ReproduceResult:
    """Compute the paper's simulations, draw its figures and write them with REPORT.md into the
    folder ``out`` (all files or none)."""
    from ..plot._figure import require_matplotlib
    from ..plot.design import reproduce_figures

    # fail early, before the computation, when matplotlib is missing or the folder is unusable
    require_matplotlib()
    plan = OutputPlan()
    folder = plan.folder(out, "--out")
    start = time.perf_counter()
    rep = reproduce_paper(trials, seed, progress=progress)
    elapsed = time.perf_counter() - start
    figures = reproduce_figures(rep)
    names = {k: name for k, (name, _) in figures.items()}
    report = folder / "REPORT.md"
    contents: dict = {folder / name: fig for name, fig in figures.values()}
    contents[report] = reproduce_markdown(rep, names)
    plan.commit(contents)
    return ReproduceResult(rep, report, {k: folder / n for k, n in names.items()}, elapsed)
