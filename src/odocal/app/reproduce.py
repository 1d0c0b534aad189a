"""``odocal reproduce``: regenerate the paper's simulations (figures and a Markdown report) and,
with ``realdata``, run its experiment on a real robot from recordings."""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from .._version import __version__
from ..core.checks import check_int, check_seed
from ..design.reproduce import Reproduction
from ..design.reproduce import reproduce as reproduce_paper
from ..design.sweep import Progress
from ..design.verdict import judge_experiment
from ..io.outputs import Content, OutputPlan
from ..io.real_experiment_report import experiment_dict, real_experiment_markdown
from ..io.report import reproduce_markdown

if TYPE_CHECKING:
    from ..design.real_experiment import RealExperiment
    from ..design.verdict import Verdict

__all__ = ["ReproduceResult", "reproduce", "real_experiment"]


@dataclass(frozen=True)
class ReproduceResult:
    """The reproduction (None when only the real experiment ran), the real experiment and its
    verdict (None without ``realdata``), the files written (REPORT.md and figures, by key;
    None/empty without ``out``) and the time the computation took (s; reported on the terminal,
    never inside the report)."""

    reproduction: Reproduction | None
    report: Path | None
    figures: dict[str, Path]
    elapsed_s: float
    real: RealExperiment | None = None
    trials: int = 800
    seed: int = 0
    verdict: Verdict | None = None

    def as_dict(self) -> dict:
        """The JSON of ``odocal reproduce --json``: ``paper`` (the recommended sizes of Figs. 5,
        6, 9) and, with --realdata, ``real_experiment`` (docs/real-experiment.md)."""
        out: dict = {"trials": self.trials, "seed": self.seed}
        rep = self.reproduction
        if rep is not None:
            out["paper"] = {
                name: {
                    "recommended_side_m": c.recommended.side_m,
                    "recommended_travel_m": c.recommended.travel_m,
                    "post_error_mean_m": c.recommended.post_error_mean_m,
                    "floor_m": c.floor.mean_m,
                }
                for name, c in (("fig5", rep.fig5), ("fig6", rep.fig6), ("fig9", rep.fig9))
            }
        if self.real is not None:
            out["real_experiment"] = experiment_dict(self.real, self.verdict)
        out["written"] = [str(p) for p in ([self.report] if self.report else [])] + [
            str(p) for p in self.figures.values()
        ]
        return out


def real_experiment(
    realdata: str | Path, *, trials: int = 800, seed: int = 0, n_boot: int | None = None
) -> RealExperiment:
    """The paper's experiment on the OptiOdom robot from an ``optiodom_diff`` folder
    (:mod:`odocal.design.real_experiment`; the split: :func:`load_optiodom_experiment`)."""
    from ..app.measured import measure_robot
    from ..calibration.trajectory import fit_trajectory
    from ..design.real_experiment import (
        BOOTSTRAP,
        GainPoint,
        heldout_errors,
        run_real_experiment,
    )
    from ..io.optiodom import load_optiodom_experiment, read_published

    by_side, ivanjko, heldout, split = load_optiodom_experiment(realdata)
    squares = [r for runs in by_side.values() for r in runs]
    known = [r.ran_with for r in squares if r.ran_with is not None]
    reference = max(set(known), key=known.count)  # the nominal geometry most data sets ran with
    measured = measure_robot(squares + ivanjko, reference, noise_recordings=squares)
    default = measured.fit.geometry  # odocal fit (trajectory) on squares + Ivanjko
    extra = []
    published = read_published(realdata)
    if published is not None:
        extra.append(
            GainPoint(
                "published OptiOdom parameters (all 171 runs)",
                published,
                float(heldout_errors(heldout, published).mean()),
                False,
            )
        )
    in_sample = fit_trajectory(heldout, nominal=reference).geometry
    extra.append(
        GainPoint(
            "trajectory fit on the held-out runs themselves",
            in_sample,
            float(heldout_errors(heldout, in_sample).mean()),
            False,
        )
    )
    return run_real_experiment(
        by_side,
        heldout,
        reference,
        measured.robot,
        np.random.default_rng(seed),
        trials=trials,
        heldout_split=split,
        default_fit=default,
        extra_points=tuple(extra),
        n_boot=BOOTSTRAP if n_boot is None else n_boot,
    )


def _import_plotting() -> None:
    from ..plot._figure import require_matplotlib
    from ..plot.design import reproduce_figures  # noqa: F401
    from ..plot.real_experiment import real_figures  # noqa: F401

    require_matplotlib()


def reproduce(
    out: str | Path | None,
    *,
    trials: int = 800,
    seed: int = 0,
    progress: Progress | None = None,
    realdata: str | Path | None = None,
    paper: bool = True,
) -> ReproduceResult:
    """Compute the paper's simulations (``paper``) and, with ``realdata`` (an ``optiodom_diff``
    folder), its experiment on the real robot; draw the figures and write them with REPORT.md
    into the folder ``out`` (all files or none; nothing without ``out``)."""
    trials = check_int("trials", trials, at_least=2)
    seed = check_seed("seed", seed)
    plan = OutputPlan([realdata] if realdata is not None else [])
    folder = None
    warm_up = None
    if out is not None:
        from ..plot._figure import require_matplotlib

        # fail early, before the computation, when matplotlib is missing or the folder is
        # unusable; import it while worker processes compute
        require_matplotlib(load=False)
        folder = plan.folder(out, "--out")
        warm_up = _import_plotting
    start = time.perf_counter()
    rep = reproduce_paper(trials, seed, progress=progress, meanwhile=warm_up) if paper else None
    real = real_experiment(realdata, trials=trials, seed=seed) if realdata is not None else None
    elapsed = time.perf_counter() - start
    verdict = judge_experiment(real) if real is not None else None
    if folder is None:
        return ReproduceResult(rep, None, {}, elapsed, real, trials, seed, verdict)
    report, figures = _write(plan, folder, rep, real, verdict)
    return ReproduceResult(rep, report, figures, elapsed, real, trials, seed, verdict)


def _write(
    plan: OutputPlan,
    folder: Path,
    rep: Reproduction | None,
    real: RealExperiment | None,
    verdict: Verdict | None,
) -> tuple[Path, dict[str, Path]]:
    """Draw the figures and write them with REPORT.md into ``folder`` (all or none); the report
    and the figures written, by key."""
    from ..plot.design import reproduce_figures
    from ..plot.real_experiment import real_figures

    figures = reproduce_figures(rep) if rep is not None else {}
    if real is not None:
        figures.update(real_figures(real))
    names = {k: name for k, (name, _) in figures.items()}
    report = folder / "REPORT.md"
    contents: dict[Path, Content] = {folder / name: fig for name, fig in figures.values()}
    text = reproduce_markdown(rep, names, __version__) if rep is not None else ""
    if real is not None:
        text += ("\n" if text else "") + real_experiment_markdown(
            real, names, heading_level=2 if rep is not None else 1, verdict=verdict
        )
    contents[report] = text
    plan.commit(contents)
    return report, {k: folder / n for k, n in names.items()}
