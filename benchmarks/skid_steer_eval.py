"""Skid-steer models on the real Norlab recordings (Warthog, Husky, Marmotte): issue 28 items 1, 4.

Data: ``realdata/norlab_skid`` (SOURCE.md): five Warthog logs on grass (three days: two on
2024-07-18, one on 2024-07-29, two on 2024-08-08), a Husky with deflated tyres on tile, a tracked
Marmotte in a boreal forest; wheel angles at 20 Hz and lidar-ICP poses at 4-10 Hz, stamped late.

What it prints (docs/skid-steer.md holds a run's output and what it means):

1. each log: truth rate, the ICP clock offset (s, block bootstrap), the 1 s intervals with
   motion and those rejected as ICP jumps;
2. nominal dead-reckoning drift (% of 10 m pieces of ICP path, median and mean; consecutive
   pieces, and evo's all-pairs);
3. per-log fits of the effective-track model (common and left/right wheel scales): the track
   multiplier with its standard error (cluster jackknife over 15 s blocks, plus the clock
   offset's share), the sandwich and a block bootstrap for comparison, and the error against
   the block length;
4. Warthog day-to-day and half-to-half agreement (z-scores);
5. held-out drift of every model (leave one day out; leave one log out), and the winner;
6. the turn-rate model against the single track: tables, and held-out heading errors per band
   of turn rate; does the track depend on curvature or speed at one turn rate (6b);
7. Husky and Marmotte: multipliers, first-half/second-half held-out drift;
8. held-out drift against minutes of calibration data;
9. the targets of the issue: met or not.

Usage::

    python benchmarks/skid_steer_eval.py [--data DIR] [--quick] [--json OUT.json]
        [--tum DIR]   # also write truth.tum / est.tum of one log and compare with evo if installed
"""

from __future__ import annotations

import argparse
import itertools
import json
import math
import os
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from odocal.calibration.skid_steer import (
    CANDIDATES,
    SkidIntervals,
    block_bootstrap,
    candidate_label,
    cross_validate,
    fit_skid_logs,
    fit_skid_steer,
    log_drift,
    predict_motion,
    skid_intervals,
    truth_clock_offset,
    windowed_truth_offset,
    z_score,
)
from odocal.core.model import WheelGeometry
from odocal.core.skid_steer import SkidSteerModel, dead_reckon_skid
from odocal.errors import CalibrationError
from odocal.io.norlab_csv import read_norlab_csv
from odocal.io.robot_file import load_robot

ROOT = Path(__file__).resolve().parents[1]
_ENV = os.environ.get("ODOCAL_REALDATA")
DEFAULT_DATA = (Path(_ENV) if _ENV else ROOT.parent / "shared" / "realdata") / "norlab_skid"
ALL_CANDIDATES = CANDIDATES + (("turn-rate", "common"), ("extended", "common"))
OUT: dict = {}


def short(name: str) -> str:
    """warthog_wheels_grass_2024_8_8_16h19s23 -> warthog 8_8_16h19."""
    robot = name.split("_")[0]
    if robot != "warthog":
        return robot
    tail = name.removeprefix("warthog_wheels_grass").strip("_")
    return f"warthog {tail[5:-3] if tail else '7_18 (undated)'}"


def load(data: Path) -> list[dict]:
    logs = []
    for csv in sorted(data.glob("*/*.csv")):
        rec = read_norlab_csv(csv)
        robot = rec.name.split("_")[0]
        nominal = load_robot(data / "robots" / f"{robot}.yaml").nominal
        log = rec.skid_log()
        off = truth_clock_offset(log)
        windowed = windowed_truth_offset(log)
        logs.append(
            {
                "rec": rec,
                "log": log,
                "robot": robot,
                "nominal": nominal,
                "offset": off,
                "windowed": windowed,
            }
        )
    return logs


def pm(v: float, se: float, digits: int = 3) -> str:
    return f"{v:.{digits}f} +- {se:.{digits}f}"


def header(title: str) -> None:
    print(f"\n## {title}\n", flush=True)


# --------------------------------------------------------------------------------- sections


def section_data(logs: list[dict]) -> None:
    header("1. Logs, truth clock offset, intervals")
    print(
        "| log | day | min | ICP Hz | offset ms | offset over 60 s windows ms | "
        "1 s intervals | rejected |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for e in logs:
        rec, off, w = e["rec"], e["offset"], e["windowed"]
        iv = skid_intervals(e["log"], offset_s=off.offset_s)
        fit = fit_skid_steer(iv, e["nominal"], wheel_scales="left-right")
        hz = len(rec.icp_time_s) / (rec.icp_time_s[-1] - rec.icp_time_s[0])
        e["intervals"] = iv
        print(
            f"| {short(rec.name)} | {rec.day} | {rec.time_s[-1] / 60:.1f} | {hz:.1f} | "
            f"{1e3 * off.offset_s:.0f} +- {1e3 * (off.stderr_s or 0):.0f} | "
            f"{1e3 * w.offset_s.min():.0f} to {1e3 * w.offset_s.max():.0f} "
            f"(+- {1e3 * w.typical_stderr_s:.0f}) | {len(iv)} | {fit.rejected} |"
        )
        OUT.setdefault("logs", {})[rec.name] = {
            "day": rec.day,
            "offset_s": off.offset_s,
            "offset_stderr_s": off.stderr_s,
            "intervals": len(iv),
            "rejected": fit.rejected,
            "windowed_offsets_s": w.offset_s.tolist(),
        }


def section_nominal(logs: list[dict]) -> None:
    header("2. Nominal drift (ideal differential drive, DRIVE geometry), % of 10 m of ICP path")
    print("| log | pieces | median % | mean % | heading deg/10 m | all-pairs median % |")
    print("|---|---|---|---|---|---|")
    for e in logs:
        model = SkidSteerModel.from_geometry(e["nominal"])
        off = e["offset"].offset_s
        d = log_drift(e["log"], model, offset_s=off)
        a = log_drift(e["log"], model, offset_s=off, mode="all-pairs")
        print(
            f"| {short(e['rec'].name)} | {d.pieces} | {d.median_pct:.1f} | {d.mean_pct:.1f} | "
            f"{d.median_heading_deg_per_10m:.1f} | {a.median_pct:.1f} |"
        )
        OUT["logs"][e["rec"].name]["nominal_drift"] = d.as_dict()


def section_per_log(logs: list[dict], replicates: int) -> None:
    header("3. Per-log effective-track fits (standard errors: jackknife + clock offset)")
    print(
        "| log | scales | track multiplier | scale right | scale left | sandwich se | "
        f"bootstrap se ({replicates}) | se @30 s / @60 s blocks | in-sample drift % |"
    )
    print("|---|---|---|---|---|---|---|---|---|")
    for e in logs:
        for scales in ("common", "left-right"):
            fit, _ = fit_skid_logs(
                [e["log"]], e["nominal"], wheel_scales=scales, offsets=[e["offset"]]
            )
            e[f"fit {scales}"] = fit
            iv = e["intervals"]
            sand = fit_skid_steer(iv, e["nominal"], wheel_scales=scales, covariance="sandwich")
            boot = block_bootstrap(iv, fit, replicates=replicates, rng=np.random.default_rng(0))
            longer = []
            for block in (30.0, 60.0):
                ivb = skid_intervals(e["log"], offset_s=e["offset"].offset_s, block_s=block)
                try:
                    refit = fit_skid_steer(ivb, e["nominal"], wheel_scales=scales)
                    longer.append(f"{refit.se('track_multiplier'):.3f}")
                except CalibrationError:
                    longer.append("-")
            m, se = fit.track_multiplier()
            drift = log_drift(e["log"], fit.model, offset_s=e["offset"].offset_s)
            if scales == "common":
                sr = sl = pm(fit.value("scale"), fit.se("scale"))
            else:
                sr = pm(fit.value("scale_right"), fit.se("scale_right"))
                sl = pm(fit.value("scale_left"), fit.se("scale_left"))
            k = fit.names.index("track_multiplier")
            print(
                f"| {short(e['rec'].name)} | {scales} | {pm(m, se)} | {sr} | {sl} | "
                f"{sand.se('track_multiplier'):.3f} | {boot[k]:.3f} | {' / '.join(longer)} | "
                f"{drift.median_pct:.2f} |"
            )
            OUT["logs"][e["rec"].name][f"effective-track ({scales})"] = {
                **fit.as_dict(),
                "bootstrap_stderr": boot.tolist(),
                "in_sample_drift": drift.as_dict(),
            }


def _pairs_z(items: list[tuple[str, float, float]]) -> list[tuple[str, str, float]]:
    return [
        (a, b, z_score(va, sa, vb, sb))
        for (a, va, sa), (b, vb, sb) in itertools.combinations(items, 2)
    ]


def section_agreement(logs: list[dict]) -> None:
    header("4. Do days, logs and halves agree? (effective-track model; days and logs: Warthog)")
    war = [e for e in logs if e["robot"] == "warthog"]
    nominal = war[0]["nominal"]
    days = sorted({e["rec"].day for e in war})
    out = OUT.setdefault("agreement", {})
    for scales in ("common", "left-right"):
        names = ["track_multiplier"] + (
            ["scale"] if scales == "common" else ["scale_right", "scale_left"]
        )
        print(f"\n{scales} wheel scale(s), one fit per day (its logs pooled):")
        print("| day | logs | " + " | ".join(names) + " | corr(multiplier, scales) |")
        print("|---|---|" + "---|" * (len(names) + 1))
        rows = []
        for day in days:
            members = [e for e in war if e["rec"].day == day]
            fit, _ = fit_skid_logs(
                [e["log"] for e in members],
                nominal,
                wheel_scales=scales,
                offsets=[e["offset"] for e in members],
            )
            rows.append((day, fit))
            sd = np.sqrt(np.diag(fit.covariance))
            corr = fit.covariance / np.outer(sd, sd)
            k = fit.names.index("track_multiplier")
            c = ", ".join(f"{corr[k, j]:+.2f}" for j in range(len(sd)) if j != k)
            print(
                f"| {day} | {len(members)} | "
                + " | ".join(pm(fit.value(n), fit.se(n)) for n in names)
                + f" | {c} |"
            )
        worst = 0.0
        for name in names:
            zs = _pairs_z([(d, f.value(name), f.se(name)) for d, f in rows])
            worst = max([worst, *(abs(z) for _, _, z in zs)])
            print(f"day-to-day z, {name}: " + ", ".join(f"{a} vs {b}: {z:+.1f}" for a, b, z in zs))
            out[f"days {scales} {name}"] = zs
        verdict = (
            "agree (every |z| <= 3)"
            if worst <= 3
            else f"DIFFER (|z| up to {worst:.1f}): the robot, its ground or the truth changed"
        )
        print(f"=> the days {verdict}")
        out[f"verdict {scales}"] = verdict
        per_log = [(short(e["rec"].name), e[f"fit {scales}"]) for e in war]
        zs = _pairs_z(
            [(n, f.value("track_multiplier"), f.se("track_multiplier")) for n, f in per_log]
        )
        print(
            "log-to-log z, track multiplier: "
            + ", ".join(f"{a} vs {b}: {z:+.1f}" for a, b, z in zs)
        )
        out[f"logs {scales} track_multiplier"] = zs
    print(
        "\nhalf-to-half z within each log (first vs second half of its time, left/right scales;"
        " each half with its own clock offset):"
    )
    zs_all = []
    for e in logs:
        log = e["log"]
        mid = 0.5 * (log.time_s[0] + log.time_s[-1])
        halves = [log.window(log.time_s[0], mid), log.window(mid, log.time_s[-1])]
        try:
            fits = [fit_skid_logs([h], e["nominal"], wheel_scales="left-right")[0] for h in halves]
        except CalibrationError as exc:
            print(f"- {short(log.name)}: {exc}")
            continue
        parts = []
        for name in ("track_multiplier", "scale_right", "scale_left"):
            z = z_score(
                fits[0].value(name), fits[0].se(name), fits[1].value(name), fits[1].se(name)
            )
            parts.append(f"{name} {z:+.1f}")
            zs_all.append(z)
            out.setdefault("halves", {}).setdefault(log.name, {})[name] = z
        print(f"- {short(log.name)}: " + ", ".join(parts))
    z = np.array(zs_all)
    print(
        f"RMS of these {len(z)} z-scores {np.sqrt(np.mean(z**2)):.2f} (1 if the errors are "
        f"right and the halves agree); |z| > 2: {int(np.sum(np.abs(z) > 2))}, > 3: "
        f"{int(np.sum(np.abs(z) > 3))}"
    )
    out["halves_rms_z"] = float(np.sqrt(np.mean(z**2)))


def _print_heldout(held, title: str, key: str) -> None:
    print(f"\n{title}: median drift % per held-out unit ({', '.join(held.held_out)}) and pooled")
    print("| model | " + " | ".join(held.held_out) + " | pooled | pieces | fallbacks |")
    print("|---|" + "---|" * (len(held.held_out) + 3))
    res = {}
    for label in held.labels:
        per = held.median_pct(label)
        print(
            f"| {label} | "
            + " | ".join(f"{v:.2f}" for v in per)
            + f" | {held.pooled_median_pct(label):.2f} | {len(held.pieces_pct(label))} | "
            + f"{held.fallbacks.get(label, 0)} |"
        )
        res[label] = {"per_unit": per.tolist(), "pooled": held.pooled_median_pct(label)}
    best = held.best()
    print(f"\nlowest pooled held-out drift: {best}")
    from scipy.stats import wilcoxon

    for ref in ("effective-track (common)", "effective-track (left-right)"):
        base = held.pieces_pct(ref)
        print(f"paired against {ref}, piece by piece:")
        for label in held.labels[1:]:
            if label == ref:
                continue
            other = held.pieces_pct(label)
            better = float(np.mean(other < base))
            p = float(wilcoxon(other, base).pvalue)
            print(f"- {label}: lower on {100 * better:.0f} % of pieces, Wilcoxon p = {p:.2g}")
            res[label][f"vs {ref}"] = {"share_lower": better, "wilcoxon_p": p}
    OUT.setdefault("heldout", {})[key] = {"best": best, "models": res}


def section_heldout(logs: list[dict]) -> None:
    header("5. Held-out drift, Warthog (models fitted on the other days / logs)")
    war = [e for e in logs if e["robot"] == "warthog"]
    nominal = war[0]["nominal"]
    offsets = [e["offset"] for e in war]
    by_day = cross_validate([e["log"] for e in war], nominal, ALL_CANDIDATES, offsets=offsets)
    _print_heldout(by_day, "leave one DAY out", "by_day")
    by_log = cross_validate(
        [replace(e["log"], group=e["log"].name) for e in war],
        nominal,
        ALL_CANDIDATES,
        offsets=offsets,
    )
    _print_heldout(
        by_log, "leave one LOG out (a same-day log may be in the training set)", "by_log"
    )
    windowed = cross_validate(
        [e["log"] for e in war], nominal, ALL_CANDIDATES, offsets=[e["windowed"] for e in war]
    )
    print(
        "\nleave one DAY out with the clock offset estimated per 60 s window (pooled median %): "
        + ", ".join(f"{lab} {windowed.pooled_median_pct(lab):.2f}" for lab in windowed.labels)
    )
    OUT["heldout"]["by_day_windowed_offsets"] = {
        lab: windowed.pooled_median_pct(lab) for lab in windowed.labels
    }
    alls = cross_validate(
        [e["log"] for e in war], nominal, [("effective-track", "left-right")], offsets=offsets
    )
    allp = [
        log_drift(e["log"], f.model, offset_s=e["offset"].offset_s, mode="all-pairs")
        for e in war
        for k, f in enumerate(alls.fits["effective-track (left-right)"])
        if alls.held_out[k] == e["rec"].day
    ]
    pieces = np.concatenate([d.error_pct for d in allp])
    print(
        f"effective-track (left-right), leave one day out, evo's all-pairs pieces: median "
        f"{np.median(pieces):.2f} % over {len(pieces)} overlapping pieces"
    )
    OUT["_by_day"] = by_day


def _band_errors(
    model: SkidSteerModel, iv: SkidIntervals, nominal: WheelGeometry, edges: list[float]
) -> list[tuple[int, float]]:
    rate = np.abs(iv.motion[:, 2]) / iv.duration_s  # the truth's own yaw rate
    err = iv.motion[:, 2] - predict_motion(model, iv)[:, 2]
    out = []
    for lo, hi in zip(edges[:-1], edges[1:], strict=True):
        sel = (rate >= lo) & (rate < hi)
        out.append(
            (int(sel.sum()), float(np.sqrt(np.mean(err[sel] ** 2))) if sel.any() else math.nan)
        )
    return out


BAND_LABELS = (
    "nominal",
    "effective-track (left-right)",
    "turn-rate (left-right)",
    "extended (left-right)",
)


def band_table(
    held, units: list[list[SkidIntervals]], nominal: WheelGeometry, edges: list[float]
) -> tuple[dict, np.ndarray]:
    """Print the RMS heading error (mrad) of each unit's held-out intervals, per band of the
    truth's yaw rate, for the models of BAND_LABELS fitted without that unit."""
    print(
        "| model | "
        + " | ".join(f"{a:g}-{b:g}" for a, b in zip(edges[:-1], edges[1:], strict=True))
        + " |"
    )
    print("|---|" + "---|" * (len(edges) - 1))
    table = {}
    ns = np.zeros(len(edges) - 1, dtype=int)
    for label in BAND_LABELS:
        sums = np.zeros(len(edges) - 1)
        ns = np.zeros(len(edges) - 1, dtype=int)
        for k, parts in enumerate(units):
            fit = None if label == "nominal" else held.fits[label][k]
            model = SkidSteerModel.from_geometry(nominal) if fit is None else fit.model
            for iv in parts:
                for b, (n, rms) in enumerate(_band_errors(model, iv, nominal, edges)):
                    if n:
                        sums[b] += n * rms**2
                        ns[b] += n
        rms = np.sqrt(sums / np.maximum(ns, 1))
        table[label] = rms.tolist()
        print(f"| {label} | " + " | ".join(f"{1e3 * v:.1f}" for v in rms) + " |")
    print("| intervals | " + " | ".join(str(n) for n in ns) + " |")
    single = np.array(table["effective-track (left-right)"])
    turn = np.array(table["turn-rate (left-right)"])
    print(
        "turn-rate vs single track (left/right scales), heading error by band: "
        + ", ".join(
            f"{100 * (t / s - 1):+.0f} %" if n else "-"
            for t, s, n in zip(turn, single, ns, strict=True)
        )
    )
    return table, ns


def section_turn_rate(logs: list[dict]) -> None:
    header("6. Turn-rate model against the single track")
    war = [e for e in logs if e["robot"] == "warthog"]
    groups = {"warthog (5 logs)": war, **{e["robot"]: [e] for e in logs if e["robot"] != "warthog"}}
    for name, members in groups.items():
        nominal = members[0]["nominal"]
        fit, _ = fit_skid_logs(
            [e["log"] for e in members],
            nominal,
            "turn-rate",
            wheel_scales="left-right",
            offsets=[e["offset"] for e in members],
            offset_variance=False,
        )
        print(
            f"\n{name}: track multiplier by wheel yaw rate (left/right scales "
            f"{fit.value('scale_right'):.3f}, {fit.value('scale_left'):.3f})"
        )
        print("| wheel yaw rate rad/s | true yaw rate rad/s | multiplier |")
        print("|---|---|---|")
        for r in fit.turn_rate_rows():
            mult = pm(r.multiplier, r.stderr)
            print(f"| {r.wheel_rate_rad_s:g} | {r.true_rate_rad_s:.3f} | {mult} |")
        OUT.setdefault("turn_rate_tables", {})[name] = [r.__dict__ for r in fit.turn_rate_rows()]
    # held-out heading error per band of the truth's yaw rate (leave one day out)
    edges = [0.0, 0.05, 0.1, 0.2, 0.4, 0.8, 10.0]
    held = OUT["_by_day"]
    days = held.held_out
    print(
        "\nWarthog, leave one day out: RMS heading error (mrad) of held-out 1 s intervals, "
        "by the truth's |yaw rate| (rad/s)"
    )
    units = [[e["intervals"] for e in war if e["rec"].day == day] for day in days]
    table, counts = band_table(held, units, war[0]["nominal"], edges)
    d_single = held.pooled_median_pct("effective-track (left-right)")
    d_turn = held.pooled_median_pct("turn-rate (left-right)")
    print(
        f"held-out drift: single track {d_single:.2f} %, turn-rate {d_turn:.2f} % "
        f"({100 * (d_turn / d_single - 1):+.0f} %; target: 30 % lower)"
    )
    OUT["turn_rate_heldout"] = {
        "edges": edges,
        "rms_rad": table,
        "counts": counts.tolist(),
        "drift_single": d_single,
        "drift_turn": d_turn,
    }


def _cluster_mean(values: np.ndarray, blocks: np.ndarray) -> tuple[float, float, int]:
    """Mean and its standard error from the block means (blocks as the independent units)."""
    ids = np.unique(blocks)
    if len(ids) < 3:
        return math.nan, math.nan, len(ids)
    means = np.array([values[blocks == b].mean() for b in ids])
    sizes = np.array([np.sum(blocks == b) for b in ids])
    mean = float(np.sum(means * sizes) / sizes.sum())
    se = float(np.sqrt(np.sum(sizes**2 * (means - mean) ** 2)) / sizes.sum())
    return mean, se, len(ids)


def section_curvature(logs: list[dict]) -> None:
    header("6b. Does the track depend on curvature or speed at one turn rate?")
    print(
        "ratio = ICP heading change / the turn-rate model's (left/right scales, fitted on all of "
        "the robot's logs), over 1 s intervals turning > 0.05 rad; 'spin': the centre moves less "
        "than a quarter of the track per radian (radius < b_n / 4), 'arc' otherwise; mean ratio "
        "+- its error over 15 s blocks; z of spin - arc, and of slow - fast arcs (split at the "
        "band's median speed)"
    )
    war = [e for e in logs if e["robot"] == "warthog"]
    groups = {"warthog": war, **{e["robot"]: [e] for e in logs if e["robot"] != "warthog"}}
    out = OUT.setdefault("curvature", {})
    for name, members in groups.items():
        nominal = members[0]["nominal"]
        fit, _ = fit_skid_logs(
            [e["log"] for e in members],
            nominal,
            "turn-rate",
            wheel_scales="left-right",
            offsets=[e["offset"] for e in members],
            offset_variance=False,
        )
        iv = SkidIntervals.concatenate([e["intervals"] for e in members])
        pred = predict_motion(fit.model, iv)
        turning = np.abs(pred[:, 2]) > 0.05
        ratio = iv.motion[turning, 2] / pred[turning, 2]
        radius = np.abs(pred[turning, 0]) / np.abs(pred[turning, 2])
        spin = radius < 0.25 * float(nominal.wheelbase_m)
        rate = np.abs(iv.wheel_yaw_rate(nominal)).mean(axis=1)[turning]
        speed = np.abs(pred[turning, 0]) / iv.duration_s[turning]
        blocks = iv.block[turning]
        print(f"\n{name}:")
        print(
            "| wheel yaw rate rad/s | spin: ratio (n) | arc: ratio (n) | z spin-arc | "
            "slow arcs | fast arcs | z slow-fast |"
        )
        print("|---|---|---|---|---|---|---|")
        edges = [0.05, 0.2, 0.4, 0.8, 1.6, 10.0]
        rows = []
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            band = (rate >= lo) & (rate < hi)
            cells = []
            stats = {}
            for label, sel in (("spin", band & spin), ("arc", band & ~spin)):
                m, se, g = _cluster_mean(ratio[sel], blocks[sel])
                stats[label] = (m, se)
                cells.append(f"{m:.3f} +- {se:.3f} ({int(sel.sum())})" if g >= 3 else "-")
            z1 = (
                (stats["spin"][0] - stats["arc"][0]) / math.hypot(stats["spin"][1], stats["arc"][1])
                if all(np.isfinite(v) for v in (*stats["spin"], *stats["arc"]))
                else math.nan
            )
            arcs = band & ~spin
            med = float(np.median(speed[arcs])) if arcs.any() else math.nan
            slow = _cluster_mean(ratio[arcs & (speed < med)], blocks[arcs & (speed < med)])
            fast = _cluster_mean(ratio[arcs & (speed >= med)], blocks[arcs & (speed >= med)])
            z2 = (
                (slow[0] - fast[0]) / math.hypot(slow[1], fast[1])
                if slow[2] >= 3 and fast[2] >= 3
                else math.nan
            )
            sl = f"{slow[0]:.3f} +- {slow[1]:.3f}" if slow[2] >= 3 else "-"
            fa = f"{fast[0]:.3f} +- {fast[1]:.3f}" if fast[2] >= 3 else "-"
            zs1 = f"{z1:+.1f}" if np.isfinite(z1) else "-"
            zs2 = f"{z2:+.1f}" if np.isfinite(z2) else "-"
            print(f"| {lo:g}-{hi:g} | {cells[0]} | {cells[1]} | {zs1} | {sl} | {fa} | {zs2} |")
            rows.append({"band": [lo, hi], "z_spin_arc": z1, "z_slow_fast": z2})
        out[name] = rows


def section_other_robots(logs: list[dict]) -> None:
    header("7. Husky (tile, deflated tyres) and Marmotte (tracks, boreal forest)")
    for e in logs:
        if e["robot"] == "warthog":
            continue
        fc, fl = e["fit common"], e["fit left-right"]
        print(
            f"\n{e['robot']}: track multiplier {pm(*fc.track_multiplier())} (common scale "
            f"{pm(fc.value('scale'), fc.se('scale'))}); with left/right scales "
            f"{pm(*fl.track_multiplier())} (right "
            f"{pm(fl.value('scale_right'), fl.se('scale_right'))}, left "
            f"{pm(fl.value('scale_left'), fl.se('scale_left'))})"
        )
        if e["robot"] == "husky":
            m, se = fc.track_multiplier()
            print(
                f"Clearpath's default 1.875: z = {(1.875 - m) / se:+.1f}; the issue's 1.84: "
                f"z = {(1.84 - m) / se:+.1f}"
            )
        ext = fit_skid_logs(
            [e["log"]], e["nominal"], "extended", wheel_scales="left-right", offsets=[e["offset"]]
        )[0]
        print(
            "extended model: "
            + ", ".join(
                f"{n} {pm(v, s)}" for n, v, s in zip(ext.names, ext.values, ext.stderr, strict=True)
            )
        )
        log = e["log"]
        mid = 0.5 * (log.time_s[0] + log.time_s[-1])
        halves = [
            log.window(log.time_s[0], mid, group="first half"),
            log.window(mid, log.time_s[-1], group="second half"),
        ]
        held = cross_validate(halves, e["nominal"], ALL_CANDIDATES, offsets=[e["offset"]] * 2)
        _print_heldout(
            held, f"{e['robot']}, fitted on one half, scored on the other", f"{e['robot']}_halves"
        )
        print(f"\n{e['robot']}, the other half's RMS heading error (mrad) per band of |yaw rate|:")
        units = [[skid_intervals(h, offset_s=e["offset"].offset_s)] for h in halves]
        band_table(held, units, e["nominal"], [0.0, 0.1, 0.2, 0.4, 0.8, 1.6, 10.0])
    war = [e for e in logs if e["robot"] == "warthog"]
    ext = fit_skid_logs(
        [e["log"] for e in war],
        war[0]["nominal"],
        "extended",
        wheel_scales="left-right",
        offsets=[e["offset"] for e in war],
    )[0]
    print(
        "\nwarthog (5 logs), extended model: "
        + ", ".join(
            f"{n} {pm(v, s)}" for n, v, s in zip(ext.names, ext.values, ext.stderr, strict=True)
        )
    )


def section_minutes(logs: list[dict], draws: int) -> None:
    header("8. Warthog held-out drift against minutes of calibration data (leave one day out)")
    war = [e for e in logs if e["robot"] == "warthog"]
    nominal = war[0]["nominal"]
    rng = np.random.default_rng(28)
    minutes = [1, 2, 4, 8]
    days = sorted({e["rec"].day for e in war})
    parts = {e["rec"].name: skid_intervals(e["log"], offset_s=e["offset"].offset_s) for e in war}
    print(
        f"training: 1 s intervals with motion from the other days' logs totalling the minutes, "
        f"either one contiguous run from a random start (one calibration drive) or drawn at "
        f"random over all of them (spread); {draws} draws per held-out day; the median "
        "over draws and days of each held-out day's median drift %; (n) = held-out days with "
        "that much training data"
    )
    print("| model | " + " | ".join(f"{m} min" for m in minutes) + " | all |")
    print("|---|" + "---|" * (len(minutes) + 1))
    res = {}
    variants = (
        (("effective-track", "common"), "contiguous"),
        (("effective-track", "left-right"), "contiguous"),
        (("effective-track", "left-right"), "spread"),
    )
    for cand, how in variants:
        cells = []
        for m in [*minutes, None]:
            vals, folds = [], 0
            for day in days:
                train = SkidIntervals.concatenate(
                    [parts[e["rec"].name] for e in war if e["rec"].day != day]
                )
                test = [e for e in war if e["rec"].day == day]
                total = float(train.duration_s.sum())
                if m is not None and total < 60 * m:
                    continue
                folds += 1
                for _ in range(1 if m is None else draws):
                    sub = train
                    if m is not None and how == "contiguous":
                        start = int(rng.integers(len(train)))
                        order = np.roll(np.arange(len(train)), -start)
                        n = int(np.searchsorted(np.cumsum(train.duration_s[order]), 60 * m)) + 1
                        sub = train.subset(np.sort(order[:n]))
                    elif m is not None:
                        order = rng.permutation(len(train))
                        n = int(np.searchsorted(np.cumsum(train.duration_s[order]), 60 * m)) + 1
                        sub = train.subset(np.sort(order[:n]))
                    try:
                        fit = fit_skid_steer(sub, nominal, cand[0], wheel_scales=cand[1])
                    except CalibrationError:
                        continue
                    pieces = np.concatenate(
                        [
                            log_drift(e["log"], fit.model, offset_s=e["offset"].offset_s).error_pct
                            for e in test
                        ]
                    )
                    vals.append(float(np.median(pieces)))
            cells.append((float(np.median(vals)) if vals else math.nan, folds))
        label = f"{candidate_label(cand)}, {how}"
        res[label] = cells
        print(f"| {label} | " + " | ".join(f"{v:.2f} ({n})" for v, n in cells) + " |")
    OUT["minutes"] = {"minutes": [*minutes, "all"], "median_drift_pct_and_days": res}


def section_targets() -> None:
    header("9. Targets of issue 28")
    day = OUT["heldout"]["by_day"]["models"]
    best = OUT["heldout"]["by_day"]["best"]
    v = day[best]["pooled"]
    two = day["effective-track (common)"]["pooled"]
    print(
        f"- Warthog held-out (leave one day out) median drift <= 2 % per 10 m: lowest "
        f"{best} {v:.2f} % -> {'MET' if v <= 2 else 'NOT MET'}; effective-track (left-right) "
        f"{day['effective-track (left-right)']['pooled']:.2f} %; the two-number model "
        f"{two:.2f} %; nominal {day['nominal']['pooled']:.1f} %"
    )
    t = OUT["turn_rate_heldout"]
    change = 100 * (t["drift_turn"] / t["drift_single"] - 1)
    print(
        f"- turn-rate model >= 30 % below the single track (both left/right scales): "
        f"{change:+.0f} % -> {'MET' if change <= -30 else 'NOT MET'}"
    )
    for scales in ("common", "left-right"):
        print(
            f"- day-to-day within 3 combined errors ({scales} scales): "
            f"{OUT['agreement'][f'verdict {scales}']}"
        )


def evo_check(logs: list[dict], folder: Path) -> None:
    header("evo check: TUM files of one log and evo's RPE against path_drift")
    from odocal.core.path_drift import path_drift
    from odocal.io.tum import write_tum

    e = next(e for e in logs if e["rec"].name.endswith("16h19s23"))
    log, off = e["log"], e["offset"].offset_s
    est = dead_reckon_skid(
        e["fit left-right"].model, log.angle_right_rad, log.angle_left_rad, log.time_s
    )
    q = log.truth_time_s - off
    inside = (q >= log.time_s[0]) & (q <= log.time_s[-1])
    at = np.column_stack([np.interp(q[inside], log.time_s, est[:, k]) for k in range(3)])
    folder.mkdir(parents=True, exist_ok=True)
    write_tum(folder / "truth.tum", log.truth_time_s[inside], log.truth_pose[inside])
    write_tum(folder / "est.tum", log.truth_time_s[inside], at)
    ours = {
        m: path_drift(log.truth_pose[inside], at, length_m=10.0, mode=m)
        for m in ("consecutive", "all-pairs")
    }
    print(f"wrote {folder}/truth.tum and est.tum ({short(log.name)}, effective track L/R)")
    try:
        from evo import main_rpe
        from evo.core import metrics, sync
        from evo.tools import file_interface
    except ImportError:
        print(
            "evo is not installed: compare by hand with\n  evo_rpe tum truth.tum est.tum "
            "--delta 10 --delta_unit m --pairs_from_reference [--all_pairs]"
        )
        return
    for mode, all_pairs in (("consecutive", False), ("all-pairs", True)):
        for from_ref in (True, False):
            # read afresh for every call: evo's rpe() reduces the trajectories it is given
            ref = file_interface.read_tum_trajectory_file(str(folder / "truth.tum"))
            est_t = file_interface.read_tum_trajectory_file(str(folder / "est.tum"))
            ref, est_t = sync.associate_trajectories(ref, est_t, max_diff=0.01)
            r = main_rpe.rpe(
                ref,
                est_t,
                metrics.PoseRelation.translation_part,
                delta=10.0,
                delta_unit=metrics.Unit.meters,
                all_pairs=all_pairs,
                pairs_from_reference=from_ref,
            )
            d = ours[mode]
            print(
                f"- {mode:11s} pairs from {'reference' if from_ref else 'estimate '}: evo "
                f"{len(r.np_arrays['error_array'])} pairs, mean {r.stats['mean']:.6f} m, median "
                f"{r.stats['median']:.6f} m | path_drift {d.pieces} pieces, mean "
                f"{d.error_m.mean():.6f} m, median {np.median(d.error_m):.6f} m"
            )


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", type=Path, default=DEFAULT_DATA)
    ap.add_argument("--quick", action="store_true", help="fewer bootstrap replicates and draws")
    ap.add_argument("--json", type=Path, help="write the numbers here")
    ap.add_argument("--tum", type=Path, help="write TUM files of one log here and compare with evo")
    args = ap.parse_args(argv)
    if not args.data.is_dir():
        print(f"no data at {args.data} (set ODOCAL_REALDATA or --data)", file=sys.stderr)
        return 2
    t0 = time.time()
    print(f"# skid_steer_eval on {args.data}")
    logs = load(args.data)
    section_data(logs)
    section_nominal(logs)
    section_per_log(logs, 30 if args.quick else 200)
    section_agreement(logs)
    section_heldout(logs)
    section_turn_rate(logs)
    section_curvature(logs)
    section_other_robots(logs)
    section_minutes(logs, 3 if args.quick else 10)
    section_targets()
    if args.tum:
        evo_check(logs, args.tum)
    print(f"\n({time.time() - t0:.0f} s)")
    if args.json:
        OUT.pop("_by_day", None)
        args.json.write_text(json.dumps(OUT, indent=1, default=float) + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
