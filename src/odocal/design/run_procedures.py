"""Which calibration procedure for recorded runs with ground truth: chosen by
leave-one-data-set-out error within the given runs (``odocal fit FOLDERS --method auto``).

A **procedure** is a method and the runs it uses: the heading method or UMBmark on the squares
(all, or those of one side length), the trajectory fit on one kind of run (``meta['kind']``, the
OptiOdom category folder: ``square``, ``ivanjko``, ...), on the squares of one side, or on every
run. :func:`candidate_procedures` lists those the given runs allow (a procedure needs runs of at
least two data sets, so that one can be left out).

**Leave one data set out** (:func:`lodo_table`): a data set is ``Recording.dataset`` (the
OptiOdom data set folder, else the folder holding the run). For every data set d of the given
runs, each procedure is fitted on its runs outside d and dead-reckons every run of d; the fold's
error is the mean final position error (m) of d's runs against their ground truth, the metric of
the held-out evaluation of docs/real-experiment.md
(:func:`odocal.design.real_experiment.heldout_errors`). Every procedure is scored on the same
folds: a procedure's score is the mean of its fold errors, with the standard error of that mean
(fold-to-fold spread / sqrt(folds)); the mean weighted by the runs per fold is reported beside
it.

**The choice** (:func:`choose`): rule ``lowest`` (default) takes the lowest score; ``one-se``
takes the simplest procedure (fewest runs to drive, then heading < UMBmark < trajectory) whose
score is within one standard error of the lowest (Breiman et al. 1984). The winner's own score is
optimistic: it was the minimum of several noisy scores. :func:`selection_corrected` adds the
Tibshirani & Tibshirani (2009) estimate of that bias: the mean over folds of the winner's fold
error minus the lowest fold error of any procedure in that fold.

Nothing here sees runs other than those given: the folds are drawn from them only.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Literal, get_args

import numpy as np

from ..calibration.squares import fit_recorded_squares
from ..calibration.trajectory import fit_trajectory_geometry
from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..errors import CalibrationError, InputError
from .real_experiment import heldout_errors

__all__ = [
    "ProcedureMethod",
    "Procedure",
    "ScoredProcedure",
    "LodoTable",
    "ChoiceRule",
    "CHOICE_RULES",
    "run_kind",
    "candidate_procedures",
    "fit_procedure",
    "lodo_table",
    "two_data_sets",
    "choose",
    "selection_corrected",
]

#: The methods a procedure may use (the runs' methods of ``odocal fit``; ``linear`` reads only
#: the final poses and is left out: docs/real-robots.md).
ProcedureMethod = Literal["heading", "umbmark", "trajectory"]
#: How the winner is chosen from the table (module docstring).
ChoiceRule = Literal["lowest", "one-se"]
CHOICE_RULES: tuple[ChoiceRule, ...] = get_args(ChoiceRule)

_SIMPLICITY = {"heading": 0, "umbmark": 1, "trajectory": 2}


def run_kind(r: Recording) -> str:
    """The kind of a run: the loader's (``meta['kind']``, the OptiOdom category), else
    'square' for a run with a side length, else 'runs'."""
    kind = r.meta.get("kind") if r.meta else None
    if kind:
        return str(kind)
    return "square" if _side(r) is not None else "runs"


def _side(r: Recording) -> float | None:
    side = r.meta.get("side_m") if r.meta else None
    return None if side is None else float(side)


@dataclass(frozen=True)
class Procedure:
    """A method and the runs it calibrates from.

    Attributes
    ----------
    method : {'heading', 'umbmark', 'trajectory'}
    kinds : tuple of str
        The kinds of run used (:func:`run_kind`); empty: every run.
    side_m : float or None
        Only squares of this side length (m).
    """

    method: ProcedureMethod
    kinds: tuple[str, ...] = ()
    side_m: float | None = None

    def uses(self, r: Recording) -> bool:
        """Does this procedure calibrate from run ``r``?"""
        if self.kinds and run_kind(r) not in self.kinds:
            return False
        return self.side_m is None or _side(r) == self.side_m

    def runs(self, recordings: Sequence[Recording]) -> list[Recording]:
        """The runs of ``recordings`` this procedure calibrates from."""
        return [r for r in recordings if self.uses(r)]

    @property
    def label(self) -> str:
        """'heading on square 1.7 m', 'trajectory on every run', ..."""
        what = "+".join(self.kinds) if self.kinds else "every run"
        side = "" if self.side_m is None else f" {self.side_m:g} m"
        return f"{self.method} on {what}{side}"

    def as_dict(self) -> dict:
        """``method``, ``kinds`` and ``side_m``."""
        return {"method": self.method, "kinds": list(self.kinds), "side_m": self.side_m}


def candidate_procedures(recordings: Sequence[Recording]) -> tuple[Procedure, ...]:
    """The procedures ``recordings`` allow, each with runs in at least two data sets: the
    trajectory fit on every run, on each kind and on the squares of each side; the heading
    method and UMBmark on all squares and on each side's. Procedures that would use the same
    runs with the same method are listed once."""
    kinds = sorted({run_kind(r) for r in recordings})
    sides = sorted({s for r in recordings if (s := _side(r)) is not None})
    square_kinds = tuple(sorted({run_kind(r) for r in recordings if _side(r) is not None}))
    wanted: list[Procedure] = [Procedure("trajectory")]
    wanted += [Procedure("trajectory", (k,)) for k in kinds]
    if square_kinds:
        for method in ("heading", "umbmark"):
            wanted.append(Procedure(method, square_kinds))
            wanted += [Procedure(method, square_kinds, s) for s in sides]
        wanted += [Procedure("trajectory", square_kinds, s) for s in sides]
    out: list[Procedure] = []
    seen: set[tuple[str, tuple[str, ...]]] = set()
    for p in wanted:
        runs = p.runs(recordings)
        key = (p.method, tuple(r.name for r in runs))
        if key in seen or len({r.dataset for r in runs}) < 2:
            continue
        seen.add(key)
        out.append(p)
    return tuple(out)


def fit_procedure(
    procedure: Procedure,
    recordings: Sequence[Recording],
    nominal: WheelGeometry,
    ran_with: WheelGeometry | None = None,
) -> WheelGeometry:
    """Calibrate with ``procedure`` from its runs among ``recordings``: the trajectory fit
    (:func:`~odocal.calibration.trajectory.fit_trajectory_geometry`, default settings) or the
    heading method / UMBmark per data set, pooled
    (:func:`~odocal.calibration.squares.fit_recorded_squares`). CalibrationError when it has no
    runs or cannot fit them."""
    runs = procedure.runs(recordings)
    if not runs:
        raise CalibrationError(f"{procedure.label}: no runs")
    if procedure.method == "trajectory":
        return fit_trajectory_geometry(runs, nominal)
    return fit_recorded_squares(runs, procedure.method, ran_with=ran_with, nominal=nominal).geometry


@dataclass(frozen=True)
class ScoredProcedure:
    """One procedure's leave-one-data-set-out errors.

    Attributes
    ----------
    procedure : Procedure
    runs : int
        The runs it uses among all given.
    data_sets : int
        The data sets they come from.
    fold_errors_m : tuple of float
        Per fold (the table's ``data_sets`` order): the mean final position error (m) of the
        left-out data set's runs; empty when it failed.
    failed : str or None
        Why it could not be scored (a fold's fit failed).
    """

    procedure: Procedure
    runs: int
    data_sets: int
    fold_errors_m: tuple[float, ...] = ()
    failed: str | None = None

    @property
    def mean_m(self) -> float:
        """The mean over folds of the left-out data set's mean final error (m); nan if failed."""
        return float(np.mean(self.fold_errors_m)) if self.fold_errors_m else math.nan

    @property
    def stderr_m(self) -> float:
        """The standard error (m) of :attr:`mean_m`: fold spread / sqrt(folds)."""
        e = np.asarray(self.fold_errors_m)
        return float(e.std(ddof=1) / math.sqrt(e.size)) if e.size > 1 else math.nan


@dataclass(frozen=True)
class LodoTable:
    """Every candidate's leave-one-data-set-out errors on the same folds.

    Attributes
    ----------
    data_sets : tuple of str
        The folds: each data set left out once, in this order.
    runs_per_set : tuple of int
        The runs of each.
    kinds : tuple of str
        The kind of each data set's runs (:func:`run_kind`; joined with '+' if mixed).
    candidates : tuple of ScoredProcedure
    """

    data_sets: tuple[str, ...]
    runs_per_set: tuple[int, ...]
    kinds: tuple[str, ...]
    candidates: tuple[ScoredProcedure, ...] = field(default_factory=tuple)

    def scored(self) -> list[ScoredProcedure]:
        """The candidates that were scored on every fold."""
        return [c for c in self.candidates if c.failed is None]

    def run_weighted_m(self, c: ScoredProcedure) -> float:
        """``c``'s fold errors weighted by the runs per fold (the mean over runs), m."""
        if c.failed is not None:
            return math.nan
        w = np.asarray(self.runs_per_set, dtype=float)
        return float(np.dot(w, c.fold_errors_m) / w.sum())


def _data_sets(recordings: Sequence[Recording]) -> list[str]:
    out: list[str] = []
    for r in recordings:
        if r.dataset not in out:
            out.append(r.dataset)
    return out


def two_data_sets(recordings: Sequence[Recording]) -> list[str]:
    """The data sets of ``recordings`` in order of appearance; InputError for fewer than two
    (nothing can be left out)."""
    sets = _data_sets(recordings)
    if len(sets) < 2:
        raise InputError(
            f"--method auto compares procedures by leaving one data set out, and the runs come "
            f"from {len(sets)} data set ({', '.join(sets) or 'none'}): give runs of two or more "
            "data sets (folders), or name the method"
        )
    return sets


def lodo_table(
    recordings: Sequence[Recording],
    procedures: Sequence[Procedure],
    nominal: WheelGeometry,
    *,
    ran_with: WheelGeometry | None = None,
    fit: Callable[..., WheelGeometry] = fit_procedure,
) -> LodoTable:
    """Leave each data set of ``recordings`` out once, fit every procedure on the rest and
    dead-reckon the left-out runs (module docstring). ``fit(procedure, runs, nominal, ran_with)``
    is the calibration (default :func:`fit_procedure`). InputError for fewer than two data sets."""
    sets = two_data_sets(recordings)
    left_out = {d: [r for r in recordings if r.dataset == d] for d in sets}
    errors: dict[Procedure, list[float]] = {p: [] for p in procedures}
    failed: dict[Procedure, str] = {}
    for d in sets:
        rest = [r for r in recordings if r.dataset != d]
        for p in procedures:
            if p in failed:
                continue
            try:
                geometry = fit(p, rest, nominal, ran_with)
            except CalibrationError as exc:
                failed[p] = f"without {d}: {exc}"
                continue
            errors[p].append(float(np.mean(heldout_errors(left_out[d], geometry))))
    scored = tuple(
        ScoredProcedure(
            p,
            len(p.runs(recordings)),
            len({r.dataset for r in p.runs(recordings)}),
            () if p in failed else tuple(errors[p]),
            failed.get(p),
        )
        for p in procedures
    )
    kinds = tuple("+".join(sorted({run_kind(r) for r in left_out[d]})) for d in sets)
    return LodoTable(tuple(sets), tuple(len(left_out[d]) for d in sets), kinds, scored)


def choose(table: LodoTable, rule: ChoiceRule = "lowest") -> tuple[ScoredProcedure, str]:
    """The winner of ``table`` under ``rule`` and why, in words. CalibrationError when no
    candidate could be scored."""
    scored = table.scored()
    if not scored:
        why = "; ".join(f"{c.procedure.label}: {c.failed}" for c in table.candidates)
        raise CalibrationError(f"no procedure could be scored by leaving one data set out ({why})")
    best = min(scored, key=lambda c: c.mean_m)
    if rule == "lowest":
        return best, (
            f"lowest mean error over the {len(table.data_sets)} left-out data sets "
            f"({1e3 * best.mean_m:.2f} +- {1e3 * best.stderr_m:.2f} mm)"
        )
    if rule != "one-se":
        raise InputError(f"unknown choice rule {rule!r} (one of {', '.join(CHOICE_RULES)})")
    limit = best.mean_m + (best.stderr_m if math.isfinite(best.stderr_m) else 0.0)
    near = [c for c in scored if c.mean_m <= limit]
    pick = min(near, key=lambda c: (c.runs, _SIMPLICITY[c.procedure.method], c.mean_m))
    return pick, (
        f"the simplest (fewest runs, then heading < umbmark < trajectory) within one standard "
        f"error of the lowest ({best.procedure.label}, {1e3 * best.mean_m:.2f} + "
        f"{1e3 * best.stderr_m:.2f} mm)"
    )


def selection_corrected(table: LodoTable, winner: ScoredProcedure) -> float:
    """The winner's leave-one-data-set-out error (m) with the optimism of choosing it added:
    Tibshirani & Tibshirani (2009), the mean over folds of the winner's fold error minus the
    lowest fold error of any scored candidate."""
    scored = table.scored()
    folds = np.array([c.fold_errors_m for c in scored])  # (candidates, folds)
    bias = float(np.mean(np.asarray(winner.fold_errors_m) - folds.min(axis=0)))
    return winner.mean_m + bias
