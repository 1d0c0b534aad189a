"""Predicted standard errors against the realised spread of independent parts of real data
(issue 29 item 4), and the OptiOdom design question (does a richer noise model make the design
predict that the 1.7 m squares beat the 0.75 m squares?).

    .venv/bin/python benchmarks/predictions_real.py [--trials 4000] [--seed 0] [--json]

A. Predicted against realised, for three sets of independent parts:

1. MIT CSAIL, the two time halves (``../shared/realdata/mit_csail/csail_half{1,2}``), SLAM route
   (truth ``map -> base_link``): predicted = ``odocal check --truth-frames`` (Fisher information
   with the noise measured from the log's own residuals, the SLAM route's relative-motion fit)
   and the fit's own standard error; realised = the difference of the halves.
2. The five Warthog recordings (``../shared/realdata/norlab_skid``), skid-steer fit
   (``--kinematics skid-steer``: the exported left/right model, and the two-number common-scale
   model): predicted = each recording's own jackknife standard error of the track multiplier;
   realised = the scatter of the five, and within the two days that have two recordings each.
3. OptiOdom (``../shared/realdata/optiodom_diff``): every data set of ``square/`` and of
   ``ivanjko/`` fitted alone (trajectory fit, pose residuals, the default); predicted =
   ``check`` with the noise measured from the runs without the fits (benchmarks/bench_check.py),
   ``check`` with its default noise (what ``odocal check`` states without a robot file), and the
   fit's own standard error; realised = the scatter of the 8 data sets, and within each
   recording session (June / December 2020).

The realised standard deviation s of n independent estimates has n - 1 degrees of freedom; its
95 % interval is s sqrt((n-1) / chi2_{0.975, n-1}) .. s sqrt((n-1) / chi2_{0.025, n-1}). Two
halves give one difference d: s = |d| / sqrt(2) (one dof). ratio = realised / predicted; the
prediction "holds within +-20 %" when the ratio is in 0.8-1.2, and is "consistent" when the
realised interval holds the prediction.

B. OptiOdom design question: see ``design_question``.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.stats import chi2

ROOT = Path(__file__).resolve().parents[1]
REAL = ROOT.parent / "shared" / "realdata"
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
SHORT = ("D_R", "D_L", "b")

sys.path.insert(0, str(Path(__file__).resolve().parent))


def sd_interval(s: float, dof: int) -> tuple[float, float]:
    """95 % interval of a standard deviation s estimated with ``dof`` degrees of freedom."""
    return (
        s * math.sqrt(dof / chi2.ppf(0.975, dof)),
        s * math.sqrt(dof / chi2.ppf(0.025, dof)),
    )


def row(
    part: str,
    quantity: str,
    predictor: str,
    predicted: float,
    realised: float,
    dof: int,
    unit: str,
    scale: float,
) -> dict:
    lo, hi = sd_interval(realised, dof)
    ratio = realised / predicted if predicted > 0 else math.nan
    return {
        "part": part,
        "quantity": quantity,
        "predictor": predictor,
        "predicted": predicted * scale,
        "realised": realised * scale,
        "realised_ci95": [lo * scale, hi * scale],
        "dof": dof,
        "unit": unit,
        "ratio": ratio,
        "ratio_ci95": [lo / predicted, hi / predicted],
        "within_20pct": bool(0.8 <= ratio <= 1.2),
        "consistent": bool(lo <= predicted <= hi),
    }


def pooled_within(values: np.ndarray, groups: list[str]) -> tuple[np.ndarray, int]:
    """Pooled within-group standard deviation (per column) and its degrees of freedom."""
    ss = np.zeros(values.shape[1])
    dof = 0
    for g in sorted(set(groups)):
        v = values[[i for i, x in enumerate(groups) if x == g]]
        if len(v) < 2:
            continue
        ss += np.sum((v - v.mean(axis=0)) ** 2, axis=0)
        dof += len(v) - 1
    return np.sqrt(ss / dof), dof


# ---------------------------------------------------------------------------------------------
# A1. MIT halves


def mit() -> tuple[list[dict], dict]:
    from odocal.app.check import check
    from odocal.app.fit import fit

    base = REAL / "mit_csail"
    robot = base / "robot_virtual.yaml"
    frames = ("map", "base_link")
    vals, fit_se, chk_se, chk_cov, fit_cov, notes = [], [], [], [], [], []
    for h in ("csail_half1", "csail_half2"):
        f = fit(base / h, robot=robot, truth_frames=frames, force=True).fit
        c = check(base / h, robot=robot, truth_frames=frames)
        d = f.as_dict()
        vals.append([d[k] for k in KEYS])
        fit_se.append([d["stderr"][k] for k in KEYS])
        fit_cov.append(np.asarray(f.covariance)[:3, :3])
        chk_se.append([c.check.stderr[k] for k in KEYS])
        chk_cov.append(np.asarray(c.check.covariance)[:3, :3])
        notes.append(c.noise_source)
    v = np.array(vals)
    diff = v[0] - v[1]
    rows = []
    for i, name in enumerate(SHORT):
        realised = abs(diff[i]) / math.sqrt(2)  # one half's sd, one dof
        for label, se in (("check (log's own noise)", chk_se), ("fit's own", fit_se)):
            pred = math.sqrt((se[0][i] ** 2 + se[1][i] ** 2) / 2)
            rows.append(row("MIT halves", name, label, pred, realised, 1, "mm", 1e3))
    joint = {}
    for label, cov in (("check", chk_cov), ("fit", fit_cov)):
        q = float(diff @ np.linalg.solve(cov[0] + cov[1], diff))
        joint[label] = {
            "mahalanobis_q": q,
            "dof": 3,
            "scale": math.sqrt(q / 3),
            "scale_ci95": [math.sqrt(q / chi2.ppf(0.975, 3)), math.sqrt(q / chi2.ppf(0.025, 3))],
        }
    info = {
        "halves_m": v.tolist(),
        "difference_m": diff.tolist(),
        "noise": notes,
        "joint": joint,
    }
    return rows, info


# ---------------------------------------------------------------------------------------------
# A2. Warthog recordings


def warthog() -> tuple[list[dict], dict]:
    from odocal.app.fit_skid import EXPORTED, _offsets
    from odocal.calibration.skid_steer import fit_skid_logs
    from odocal.io.bag_options import BagOptions
    from odocal.io.bag_skid import read_skid_log
    from odocal.io.robot_file import load_robot

    skid = REAL / "norlab_skid"
    robot = load_robot(skid / "robots" / "warthog.yaml")
    bags = sorted(skid.glob("warthog_wheels_grass*/*_bag"), key=_start_ns)
    opts = BagOptions(truth_topic="/icp_odom")
    logs = [read_skid_log(b, opts, robot.believed_geometry) for b in bags]
    offsets = _offsets(logs)
    days = [_day(b) for b in bags]
    rows, info = [], {"recordings": [b.parent.name for b in bags], "days": days, "models": {}}
    for label, scales in (("left/right (exported)", EXPORTED[1]), ("common scale", "common")):
        m, se = [], []
        for log, o in zip(logs, offsets, strict=True):
            f, _ = fit_skid_logs(
                [log], robot.nominal, EXPORTED[0], offsets=[o], wheel_scales=scales
            )
            a, b = f.track_multiplier()
            m.append(a)
            se.append(b)
        m, se = np.array(m), np.array(se)
        info["models"][label] = {"multiplier": m.tolist(), "stderr": se.tolist()}
        # the standard errors differ 10-fold between recordings (the first is short), so the
        # scatter is measured in each recording's own standard errors: sqrt(Q / dof), Q the
        # chi-square of the deviations from the inverse-variance mean (1 if the errors hold)
        w = 1 / se**2
        mean = float(np.sum(w * m) / np.sum(w))
        q = float(np.sum(w * (m - mean) ** 2))
        info["models"][label]["chi2_weighted"] = {"q": q, "dof": 4, "p": float(chi2.sf(q, 4))}
        rows.append(
            row(
                "Warthog, 5 recordings",
                f"multiplier, {label} (in own SEs)",
                "fit's own (jackknife)",
                1.0,
                math.sqrt(q / 4),
                4,
                "",
                1.0,
            )
        )
        pairs = [(i, j) for i in range(len(m)) for j in range(i + 1, len(m)) if days[i] == days[j]]
        qd = sum((m[i] - m[j]) ** 2 / (se[i] ** 2 + se[j] ** 2) for i, j in pairs)
        rows.append(
            row(
                "Warthog, same-day pairs",
                f"multiplier, {label} (in own SEs)",
                "fit's own (jackknife)",
                1.0,
                math.sqrt(qd / len(pairs)),
                len(pairs),
                "",
                1.0,
            )
        )
        dm = {d: [i for i in range(len(m)) if days[i] == d] for d in dict.fromkeys(days)}
        means = np.array([np.sum(w[ix] * m[ix]) / np.sum(w[ix]) for ix in dm.values()])
        dse = np.array([1 / math.sqrt(np.sum(w[ix])) for ix in dm.values()])
        wd = 1 / dse**2
        qday = float(np.sum(wd * (means - np.sum(wd * means) / np.sum(wd)) ** 2))
        rows.append(
            row(
                "Warthog, 3 days",
                f"multiplier, {label} (in own SEs)",
                "fit's own (jackknife)",
                1.0,
                math.sqrt(qday / (len(dm) - 1)),
                len(dm) - 1,
                "",
                1.0,
            )
        )
        info["models"][label]["days"] = {
            "names": list(dm),
            "mean": means.tolist(),
            "stderr": dse.tolist(),
        }
    return rows, info


def _start_ns(bag: Path) -> int:
    import yaml

    meta = yaml.safe_load((bag / "metadata.yaml").read_text())
    return int(meta["rosbag2_bagfile_information"]["starting_time"]["nanoseconds_since_epoch"])


def _day(bag: Path) -> str:
    return time.strftime("%Y-%m-%d", time.gmtime(_start_ns(bag) / 1e9))


# ---------------------------------------------------------------------------------------------
# A3. OptiOdom data sets


def optiodom() -> tuple[list[dict], dict]:
    from bench_check import NOMINAL, data_sets, measure_noise, session

    from odocal.app.check import noise_model
    from odocal.app.fit_runs import fit_recordings
    from odocal.calibration.identifiability import check_recordings
    from odocal.calibration.trajectory import fit_trajectory

    data = REAL / "optiodom_diff"
    squares = data_sets(data, "square")
    ivanjko = data_sets(data, "ivanjko")
    training = [r for recs in list(squares.values()) + list(ivanjko.values()) for r in recs]
    geometry = fit_trajectory(training, nominal=NOMINAL).geometry
    measured, facts = measure_noise(squares, ivanjko, float(geometry.wheelbase_m))
    default, default_source = noise_model(None)
    rows, info = [], {"noise_measured": facts, "noise_default": default_source, "sets": {}}
    for cat, sets in (("square", squares), ("ivanjko", ivanjko)):
        est, p_meas, p_def, p_fit, sess = [], [], [], [], []
        for name, recs in sets.items():
            f = fit_recordings(recs, "trajectory", nominal=NOMINAL)
            g = f.geometry
            est.append([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m])
            p_fit.append([f.stderr[k] for k in KEYS])
            p_meas.append([check_recordings(recs, g, noise=measured).stderr[k] for k in KEYS])
            p_def.append([check_recordings(recs, g, noise=default).stderr[k] for k in KEYS])
            sess.append(session(name))
        est_a = np.array(est)
        info["sets"][cat] = {"names": list(sets), "estimates_m": est_a.tolist(), "sessions": sess}
        observed = est_a.std(axis=0, ddof=1)
        within, dof_w = pooled_within(est_a, sess)
        for i, q in enumerate(SHORT):
            for label, p in (
                ("check, measured noise", p_meas),
                ("check, default noise", p_def),
                ("fit's own", p_fit),
            ):
                pred = float(np.sqrt(np.mean(np.square(np.array(p, dtype=float)[:, i]))))
                n = len(est)
                rows.append(
                    row(
                        f"OptiOdom {cat}, {n} sets",
                        q,
                        label,
                        pred,
                        float(observed[i]),
                        n - 1,
                        "mm",
                        1e3,
                    )
                )
                rows.append(
                    row(
                        f"OptiOdom {cat}, within session",
                        q,
                        label,
                        pred,
                        float(within[i]),
                        dof_w,
                        "mm",
                        1e3,
                    )
                )
    return rows, info


# ---------------------------------------------------------------------------------------------


def table(rows: list[dict]) -> str:
    out = [
        "| part | quantity | predictor | predicted | realised (95 %) | dof | ratio real/pred "
        "(95 %) | within +-20 % | consistent |",
        "|---|---|---|---:|---|---:|---|---|---|",
    ]
    for r in rows:
        u = f" {r['unit']}" if r["unit"] else ""
        lo, hi = r["realised_ci95"]
        rlo, rhi = r["ratio_ci95"]
        out.append(
            f"| {r['part']} | {r['quantity']} | {r['predictor']} | {r['predicted']:.4g}{u} | "
            f"{r['realised']:.4g} ({lo:.3g}-{hi:.3g}) | {r['dof']} | {r['ratio']:.2f} "
            f"({rlo:.2f}-{rhi:.2f}) | {'yes' if r['within_20pct'] else 'no'} | "
            f"{'yes' if r['consistent'] else 'no'} |"
        )
    return "\n".join(out)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--json", action="store_true")
    p.add_argument("--parts", default="mit,warthog,optiodom,design")
    p.add_argument("--trials", type=int, default=4000)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args(argv)
    parts = args.parts.split(",")
    t0 = time.time()
    rows: list[dict] = []
    info: dict = {}
    for name, fn in (("mit", mit), ("warthog", warthog), ("optiodom", optiodom)):
        if name in parts:
            t = time.time()
            r, i = fn()
            rows += r
            info[name] = i | {"seconds": time.time() - t}
    if "design" in parts:
        t = time.time()
        info["design"] = design_question(args.trials, args.seed) | {"seconds": time.time() - t}
    info["seconds"] = time.time() - t0
    if args.json:
        json.dump({"rows": rows, "info": info}, sys.stdout, indent=1, default=float)
        print()
        return 0
    print("A. Predicted standard errors against the realised spread of independent parts\n")
    print(table(rows))
    if "mit" in info:
        j = info["mit"]["joint"]
        print(
            "\nMIT halves, joint (D_R, D_L, b): realised / predicted scale from the Mahalanobis "
            "distance of the difference (3 dof):"
        )
        for k, v in j.items():
            print(
                f"  {k}: Q = {v['mahalanobis_q']:.2f}, scale {v['scale']:.2f} "
                f"(95 % {v['scale_ci95'][0]:.2f}-{v['scale_ci95'][1]:.2f})"
            )
        print(f"  noise: {info['mit']['noise']}")
    if "warthog" in info:
        w = info["warthog"]
        print(
            "\nWarthog recordings (day):",
            ", ".join(f"{n} ({d})" for n, d in zip(w["recordings"], w["days"], strict=True)),
        )
        for k, v in w["models"].items():
            cells = ", ".join(
                f"{m:.4f} +- {s:.4f}" for m, s in zip(v["multiplier"], v["stderr"], strict=True)
            )
            c = v["chi2_weighted"]
            print(f"  {k}: {cells}; weighted chi2 {c['q']:.1f} on {c['dof']} dof, p {c['p']:.2g}")
    if "optiodom" in info:
        f = info["optiodom"]["noise_measured"]
        print(
            f"\nOptiOdom measured noise: k {f['k_each_m']:.3g} m per wheel, turn "
            f"{f['turn_rad']:.3g} rad, tracker {f['sigma_xy_mm']:.3f} mm / "
            f"{f['sigma_theta_deg']:.3f} deg; default: {info['optiodom']['noise_default']}"
        )
    if "design" in info:
        print()
        print(info["design"]["text"])
    print(
        f"\nseed {args.seed}, trials {args.trials}; runtime {info['seconds']:.0f} s "
        + ", ".join(f"{k} {v['seconds']:.0f} s" for k, v in info.items() if isinstance(v, dict))
    )
    return 0


def design_question(trials: int, seed: int) -> dict:
    return {"text": "B. (not yet)"}


if __name__ == "__main__":
    raise SystemExit(main())
