"""``odocal fit FOLDERS --method auto`` on runs with ground truth: which procedure (method and
runs) to calibrate with, chosen by leave-one-data-set-out error within the given runs only.

1. **Candidates** (:func:`odocal.design.run_procedures.candidate_procedures`): the heading
   method and UMBmark on the squares (all, each side length), the trajectory fit on each kind
   of run, on each side's squares and on every run; each needs runs of two or more data sets.
2. **Score** (:func:`~odocal.design.run_procedures.lodo_table`): every data set left out once;
   each candidate is fitted on the others and dead-reckons the left-out set's runs; the score is
   the mean over folds of their mean final position error, with its standard error.
3. **Choose** (:func:`~odocal.design.run_procedures.choose`): the lowest score (``rule``
   'lowest'), or the simplest within one standard error ('one-se').
4. **Fit** the chosen procedure on all its runs (:func:`odocal.app.fit_runs.fit_runs`: exactly
   ``odocal fit RUNS --method M`` on them) and report the winner's score corrected for the
   optimism of the choice (:func:`~odocal.design.run_procedures.selection_corrected`).

No run other than those given is read: the folds are drawn from them only. A bag goes to the
bag route (:mod:`odocal.app.fit_auto`).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, replace
from pathlib import Path
from typing import Any

from ..core.model import Robot
from ..core.recording import Recording
from ..design.run_procedures import (
    ChoiceRule,
    LodoTable,
    ScoredProcedure,
    candidate_procedures,
    choose,
    lodo_table,
    selection_corrected,
    two_data_sets,
)
from ..errors import InputError
from ..io.bag_options import NO_BAG_OPTIONS, BagOptions
from ..io.outputs import OutputPlan
from ..io.recordings import load_recordings, require_ground_truth
from .common import (
    NO_EXPORTS,
    Exports,
    RobotSpec,
    nominal_geometry,
    optional_robot,
    refuse_still_runs,
)
from .fit_runs import FitResult, fit_runs
from .text import Presented, Text, written_lines

__all__ = ["RunsAutoResult", "fit_runs_auto", "fit_runs_auto_files"]


@dataclass(frozen=True)
class RunsAutoResult(Presented):
    """The procedures compared, the one chosen and its fit.

    Attributes
    ----------
    table : LodoTable
        Every candidate's leave-one-data-set-out errors.
    rule : {'lowest', 'one-se'}
    chosen : ScoredProcedure
    reason : str
        Why it was chosen, in words.
    corrected_m : float
        The chosen procedure's score with the optimism of the choice added (m;
        :func:`~odocal.design.run_procedures.selection_corrected`).
    fit : FitResult
        The chosen procedure fitted on all its runs.
    recordings : int
        Runs given.
    load_warnings : tuple of str
    written : tuple of Path
    """

    table: LodoTable
    rule: ChoiceRule
    chosen: ScoredProcedure
    reason: str
    corrected_m: float
    fit: FitResult
    recordings: int
    load_warnings: tuple[str, ...] = ()
    written: tuple[Path, ...] = ()

    @property
    def warnings(self) -> tuple[str, ...]:
        """The chosen fit's warnings."""
        return self.fit.warnings

    def text(self) -> str:
        """The text ``odocal fit FOLDERS --method auto`` prints."""
        return _text(self)

    def as_dict(self) -> dict[str, Any]:
        """The JSON of ``odocal fit FOLDERS --method auto --json``: ``method`` 'auto', ``table``
        (one row per candidate), ``choice`` (the procedure, the rule, the reason, its score and
        the corrected score) and ``fit`` (the chosen fit's JSON, as ``odocal fit --method M``)."""
        t = self.table

        def row(c: ScoredProcedure) -> dict[str, Any]:
            return {
                "procedure": c.procedure.label,
                **c.procedure.as_dict(),
                "runs": c.runs,
                "data_sets": c.data_sets,
                "lodo_mean_error_m": _num(c.mean_m),
                "lodo_stderr_m": _num(c.stderr_m),
                "lodo_run_weighted_error_m": _num(t.run_weighted_m(c)),
                "fold_errors_m": dict(zip(t.data_sets, c.fold_errors_m, strict=False)),
                "failed": c.failed,
            }

        c = self.chosen
        return {
            "method": "auto",
            "folds": [
                {"data_set": d, "runs": n, "kind": k}
                for d, n, k in zip(t.data_sets, t.runs_per_set, t.kinds, strict=True)
            ],
            "table": [row(x) for x in t.candidates],
            "choice": {
                "procedure": c.procedure.label,
                **c.procedure.as_dict(),
                "rule": self.rule,
                "reason": self.reason,
                "lodo_mean_error_m": _num(c.mean_m),
                "lodo_stderr_m": _num(c.stderr_m),
                "selection_corrected_error_m": _num(self.corrected_m),
                "selection_correction": "Tibshirani & Tibshirani 2009",
                "runs": [Path(n).name for n in self.fit.fit.runs],
            },
            "fit": self.fit.as_dict(),
            "warnings": list(self.load_warnings) + list(self.warnings),
            "written": [str(p) for p in self.written],
        }


def _num(x: float) -> float | None:
    return x if math.isfinite(x) else None


def fit_runs_auto(
    recordings: Sequence[Recording],
    *,
    robot: Robot | None = None,
    rule: ChoiceRule = "lowest",
    force: bool = False,
) -> RunsAutoResult:
    """Choose the calibration procedure for ``recordings`` by leaving one data set out, and fit
    it (module docstring). ``robot``: the nominal geometry (else the runs' most common ran-with
    parameters). InputError for runs without ground truth, of one data set only, or allowing
    no procedure."""
    if not recordings:
        raise InputError("--method auto: no runs given")
    require_ground_truth(recordings, "--method auto on runs")
    refuse_still_runs(recordings)
    two_data_sets(recordings)
    nominal = nominal_geometry(robot, recordings)
    if nominal is None:
        raise InputError(
            "--method auto on runs needs the nominal geometry: give --robot ROBOT.yaml"
        )
    procedures = candidate_procedures(recordings)
    if not procedures:
        raise InputError(
            "--method auto: no procedure has runs in two or more data sets to leave one out; "
            "give runs of two or more data sets (folders), or name the method"
        )
    ran_with = None if robot is None else robot.believed_geometry
    table = lodo_table(recordings, procedures, nominal, ran_with=ran_with)
    chosen, reason = choose(table, rule)
    fit = fit_runs(
        chosen.procedure.runs(recordings), chosen.procedure.method, robot=robot, force=force
    )
    return RunsAutoResult(
        table, rule, chosen, reason, selection_corrected(table, chosen), fit, len(recordings)
    )


def fit_runs_auto_files(
    paths: Sequence[str | Path],
    plan: OutputPlan,
    *,
    robot: RobotSpec = None,
    exports: Exports = NO_EXPORTS,
    bag: BagOptions = NO_BAG_OPTIONS,
    ticks_per_rev: float | None = None,
    rule: ChoiceRule = "lowest",
    force: bool = False,
) -> RunsAutoResult:
    """Load the runs in ``paths``, :func:`fit_runs_auto` them and write the chosen geometry's
    ``exports`` (checked against ``plan``'s inputs)."""
    notes: list[str] = []
    recordings = load_recordings(paths, ticks_per_rev=ticks_per_rev, warnings=notes, bag=bag)
    res = fit_runs_auto(recordings, robot=optional_robot(robot), rule=rule, force=force)
    fit = res.fit
    written = exports.write(
        plan, fit.fit.geometry, fit.nominal,
        record={"method": f"auto: {res.chosen.procedure.label}"}, doubts=fit.forced,
    )  # fmt: skip
    return replace(res, load_warnings=tuple(notes) + fit.load_warnings, written=written)


def _text(res: RunsAutoResult) -> str:
    out = Text()
    t = res.table
    kinds = sorted(set(t.kinds))
    out(
        f"--method auto: {len(t.candidates)} procedure(s) compared by leaving one data set out "
        f"({len(t.data_sets)} data sets, {res.recordings} runs; kinds: {', '.join(kinds)})"
    )
    rows: list[tuple] = [
        ("procedure", "runs", "data sets", "LODO mean (mm)", "std. error", "run-weighted", "")
    ]
    for c in sorted(t.candidates, key=lambda c: (c.failed is not None, c.mean_m)):
        if c.failed is not None:
            rows.append((c.procedure.label, c.runs, c.data_sets, "-", "-", "-", c.failed))
            continue
        mark = "<- chosen" if c.procedure == res.chosen.procedure else ""
        rows.append(
            (
                c.procedure.label,
                c.runs,
                c.data_sets,
                f"{1e3 * c.mean_m:.2f}",
                f"{1e3 * c.stderr_m:.2f}",
                f"{1e3 * t.run_weighted_m(c):.2f}",
                mark,
            )
        )
    out.table(
        rows,
        "mean final position error of the left-out data set's runs, each dead-reckoned with the "
        "procedure fitted on the other data sets:",
    )
    out(f"chosen: {res.chosen.procedure.label}, rule '{res.rule}': {res.reason}")
    out(
        f"estimate for runs like these: {1e3 * res.corrected_m:.2f} mm (its LODO score "
        f"{1e3 * res.chosen.mean_m:.2f} mm is optimistic, the lowest of "
        f"{len(t.scored())} noisy scores; corrected by Tibshirani & Tibshirani 2009). It says "
        "nothing of driving unlike the given runs: on OptiOdom the pick from squares and "
        "Ivanjko runs, estimated so at 10.1 mm, erred 31.5 mm on circles and free paths "
        "(docs/real-experiment.md); validate on driving like the robot's own"
    )
    out()
    out(res.fit.text())
    written_lines(out, res.written)
    return str(out)
