"""``odocal fit FOLDERS --method auto`` on OptiOdom: which procedure leave-one-data-set-out (LODO)
picks from ``square/`` and ``ivanjko/``, and what it gives on the 19 held-out runs.

The held-out runs (``circular/`` 12 and ``free/`` 7) and the metric (mean final position error of
dead reckoning against motion capture) are those of ``bench_realdata.py`` and
docs/real-experiment.md. No choice below reads a held-out run: every criterion is computed from
the LODO table of the calibration runs alone; the held-out errors are evaluated afterwards, and
the per-candidate held-out column is hindsight, for the reader only.

Criteria (all from the LODO table):

- ``lowest``: the lowest mean over folds (``odocal fit --method auto``'s rule);
- ``one-se``: the simplest (fewest runs, then heading < umbmark < trajectory) within one standard
  error of the lowest;
- ``run-weighted``: the lowest mean over runs (folds weighted by their runs);
- ``other-kind``: each candidate scored only on the folds whose left-out runs are of a kind (and
  square side) it does not calibrate from, as the held-out runs are; candidates without such
  folds are not scored;
- ``square-folds``: only the folds that leave out squares (the Ivanjko folds hardly separate the
  candidates).

``--nested`` also runs the whole choice (rule ``lowest``) inside each LODO fold: the honest
estimate of the procedure "choose by LODO, then fit" on runs like the calibration runs.
``--heading-metric`` also scores every candidate by LODO with the final HEADING error (deg) of
the left-out runs instead of the position error (a check of the metric, not a rule).
``--only PREFIX`` keeps the data sets whose name starts with PREFIX (e.g. ``2312``: December).

Usage::

    python benchmarks/bench_runs_auto.py [--data ../shared/realdata/optiodom_diff] [--nested]
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import numpy as np

from odocal.app.fit_runs import fit_runs
from odocal.app.fit_runs_auto import fit_runs_auto
from odocal.core.odometry import dead_reckon
from odocal.design.real_experiment import heldout_errors
from odocal.design.run_procedures import (
    LodoTable,
    Procedure,
    ScoredProcedure,
    choose,
    fit_procedure,
    run_kind,
)
from odocal.io.recordings import load_recordings

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"


def _group(r) -> str:
    side = r.meta.get("side_m")
    return run_kind(r) + ("" if side is None else f" {side:g} m")


def other_kind_scores(table: LodoTable, recordings) -> dict[Procedure, float]:
    """Each candidate's mean over the folds whose left-out data set is of a group (kind and
    side) the candidate does not calibrate from."""
    group_of = {r.dataset: _group(r) for r in recordings}
    out = {}
    for c in table.scored():
        trains = {_group(r) for r in c.procedure.runs(recordings)}
        errs = [
            e
            for d, e in zip(table.data_sets, c.fold_errors_m, strict=True)
            if group_of[d] not in trains
        ]
        if errs:
            out[c.procedure] = float(np.mean(errs))
    return out


def square_fold_scores(table: LodoTable) -> dict[Procedure, float]:
    keep = [k == "square" for k in table.kinds]
    return {
        c.procedure: float(np.mean([e for e, k in zip(c.fold_errors_m, keep, strict=True) if k]))
        for c in table.scored()
    }


def heading_metric(table: LodoTable, recordings, nominal) -> dict[str, float]:
    """Each candidate's LODO score by the mean absolute final heading error (deg)."""
    out = {}
    for c in table.scored():
        folds = []
        for d in table.data_sets:
            g = fit_procedure(c.procedure, [r for r in recordings if r.dataset != d], nominal)
            errs = []
            for r in recordings:
                if r.dataset == d:
                    odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, g)
                    errs.append(abs(r.ground_truth[-1, 2] - odo[-1, 2]))
            folds.append(np.mean(errs))
        out[c.procedure.label] = float(np.degrees(np.mean(folds)))
    return out


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA, help="optiodom_diff folder")
    ap.add_argument("--nested", action="store_true", help="nested LODO of rule 'lowest'")
    ap.add_argument("--heading-metric", action="store_true", help="LODO by final heading error")
    ap.add_argument("--only", default="", help="keep data sets whose name starts with this")
    ap.add_argument("--json", action="store_true", help="print JSON instead of Markdown")
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    train = [
        r
        for r in load_recordings([args.data / "square", args.data / "ivanjko"])
        if r.dataset.startswith(args.only)
    ]
    held = load_recordings([args.data / "circular", args.data / "free"])
    assert not {r.dataset for r in train} & {r.dataset for r in held}

    res = fit_runs_auto(train)  # the command's own answer (rule 'lowest')
    table, nominal = res.table, res.fit.nominal
    assert nominal is not None

    fitted: dict[Procedure, float] = {}

    def heldout_of(p: Procedure) -> float:
        """The held-out mean final error (m) of ``p`` fitted on all calibration runs, as the
        command fits it (fit_runs). Evaluated after the choice, never used by it."""
        if p not in fitted:
            g = fit_runs(p.runs(train), p.method).fit.geometry
            fitted[p] = float(np.mean(heldout_errors(held, g)))
        return fitted[p]

    scored = table.scored()
    by_proc = {c.procedure: c for c in scored}
    criteria: dict[str, ScoredProcedure] = {}
    for rule in ("lowest", "one-se"):
        criteria[rule] = choose(table, rule)[0]  # type: ignore[arg-type]
    criteria["run-weighted"] = min(scored, key=table.run_weighted_m)
    other = other_kind_scores(table, train)
    criteria["other-kind"] = by_proc[min(other, key=other.__getitem__)]
    sq = square_fold_scores(table)
    criteria["square-folds"] = by_proc[min(sq, key=sq.__getitem__)]

    nested = None
    if args.nested:
        errs, picks = [], []
        for d in table.data_sets:
            rest = [r for r in train if r.dataset != d]
            inner = fit_runs_auto(rest)
            errs.append(float(np.mean(heldout_errors([r for r in train if r.dataset == d],
                                                     inner.fit.fit.geometry))))  # fmt: skip
            picks.append(inner.chosen.procedure.label)
        nested = {"mean_m": float(np.mean(errs)),
                  "stderr_m": float(np.std(errs, ddof=1) / math.sqrt(len(errs))),
                  "picks": picks}  # fmt: skip

    heading = heading_metric(table, train, nominal) if args.heading_metric else None
    out = {
        "heading_metric_deg": heading,
        "data_sets": list(table.data_sets),
        "kinds": list(table.kinds),
        "runs_per_set": list(table.runs_per_set),
        "candidates": [
            {
                "procedure": c.procedure.label,
                "runs": c.runs,
                "lodo_mean_m": c.mean_m,
                "lodo_stderr_m": c.stderr_m,
                "lodo_run_weighted_m": table.run_weighted_m(c),
                "other_kind_m": other.get(c.procedure),
                "square_folds_m": sq.get(c.procedure),
                "fold_errors_m": list(c.fold_errors_m),
                "heldout_hindsight_m": heldout_of(c.procedure),
            }
            for c in scored
        ],
        "criteria": {
            k: {"procedure": c.procedure.label, "heldout_m": heldout_of(c.procedure)}
            for k, c in criteria.items()
        },
        "command": {
            "procedure": res.chosen.procedure.label,
            "lodo_mean_m": res.chosen.mean_m,
            "selection_corrected_m": res.corrected_m,
            "heldout_m": float(np.mean(heldout_errors(held, res.fit.fit.geometry))),
        },
        "nested_lodo": nested,
        "seconds": time.perf_counter() - t0,
    }
    if args.json:
        print(json.dumps(out, indent=1))
        return 0
    mm = 1e3
    print(f"calibration runs: {len(train)} in {len(table.data_sets)} data sets; held out: "
          f"{len(held)} runs\n")  # fmt: skip
    print("| procedure | runs | LODO mean (mm) | SE | run-weighted | other-kind | square folds "
          "| held out (hindsight) |")  # fmt: skip
    print("|---|---:|---:|---:|---:|---:|---:|---:|")
    for c in out["candidates"]:
        ok = "-" if c["other_kind_m"] is None else f"{mm * c['other_kind_m']:.2f}"
        cells = [c["lodo_mean_m"], c["lodo_stderr_m"], c["lodo_run_weighted_m"]]
        first = " | ".join(f"{mm * x:.2f}" for x in cells)
        last = f"{mm * c['square_folds_m']:.2f} | {mm * c['heldout_hindsight_m']:.2f}"
        print(f"| {c['procedure']} | {c['runs']} | {first} | {ok} | {last} |")
    print("\n| criterion | picks | held out (mm) |\n|---|---|---:|")
    for k, v in out["criteria"].items():
        print(f"| {k} | {v['procedure']} | {mm * v['heldout_m']:.2f} |")
    cmd = out["command"]
    print(f"\ncommand: {cmd['procedure']}, LODO {mm * cmd['lodo_mean_m']:.2f} mm, "
          f"selection-corrected {mm * cmd['selection_corrected_m']:.2f} mm, held out "
          f"{mm * cmd['heldout_m']:.2f} mm")  # fmt: skip
    if nested:
        picks = sorted(set(nested["picks"]))
        print(f"nested LODO of the choice: {mm * nested['mean_m']:.2f} +- "
              f"{mm * nested['stderr_m']:.2f} mm; picks: {picks}")  # fmt: skip
    if heading:
        print("\nLODO by final heading error (deg): " + ", ".join(
            f"{k} {v:.3f}" for k, v in sorted(heading.items(), key=lambda kv: kv[1])))  # fmt: skip
    print("\nper fold (mm):")
    print("| data set | kind | runs | " + " | ".join(c["procedure"] for c in out["candidates"])
          + " |")  # fmt: skip
    print("|---|---|---:|" + "---:|" * len(out["candidates"]))
    for i, d in enumerate(table.data_sets):
        row = " | ".join(f"{mm * c['fold_errors_m'][i]:.1f}" for c in out["candidates"])
        print(f"| {d} | {table.kinds[i]} | {table.runs_per_set[i]} | {row} |")
    print(f"\n({out['seconds']:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
