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


def joint_scale(values: np.ndarray, covs: list[np.ndarray], groups: list[str]) -> dict:
    """Realised / predicted as one number for all three parameters: Q = sum over parts of
    (x - mean)^T C^-1 (x - mean), the mean the inverse-covariance mean of the part's group
    (one group: all parts; sessions: each session its own mean), chi-square with
    3 (parts - groups) dof if the predicted covariances C are right; scale sqrt(Q / dof)."""
    q = 0.0
    for g in sorted(set(groups)):
        ix = [i for i, x in enumerate(groups) if x == g]
        inv = [np.linalg.inv(covs[i]) for i in ix]
        mean = np.linalg.solve(sum(inv), sum(w @ values[i] for w, i in zip(inv, ix, strict=True)))
        q += float(
            sum((values[i] - mean) @ w @ (values[i] - mean) for w, i in zip(inv, ix, strict=True))
        )
    dof = values.shape[1] * (len(values) - len(set(groups)))
    return {"q": q, "dof": dof, "scale": math.sqrt(q / dof),
            "scale_ci95": [math.sqrt(q / chi2.ppf(0.975, dof)),
                           math.sqrt(q / chi2.ppf(0.025, dof))]}  # fmt: skip


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
    parts_rows, parts_info = mit_parts(robot, frames)
    rows += parts_rows
    info = {
        "parts": parts_info,
        "halves_m": v.tolist(),
        "difference_m": diff.tolist(),
        "noise": notes,
        "joint": joint,
    }
    return rows, info


def shared_pose_covariance(m, geometry, model) -> np.ndarray:
    """The covariance of (D_R, D_L, b) of the relative-motion fit of the intervals ``m``, as
    ``check`` predicts it (weights S_i^-1, S_i = k C_i + the truth's noise, intervals taken as
    independent), but with the SLAM pose's noise SHARED by neighbouring intervals: the pose
    ending interval i starts interval i + 1, so its error enters both, with opposite signs
    (first order: E_i = d m_i / d eps_end = diag(R(theta_i), 1), F_i+1 = d m_i+1 / d eps_start
    = [[-I, -J t_i+1], [0, -1]]). The sandwich H^-1 (sum_ij J_i^T W_i Sigma_ij W_j J_j) H^-1.
    ``model``: the check's NoiseModel (k, and the pose noise per SLAM pose)."""
    from odocal.core.covariance import propagate_increments
    from odocal.core.model import NonSystematicError, WheelGeometry
    from odocal.core.odometry import dead_reckon_rows

    r, lft = m.increments
    p0 = np.array([geometry.diameter_right_m, geometry.diameter_left_m, geometry.wheelbase_m])
    jac = np.empty((len(r), 3, 3))
    for j in range(3):
        h = 1e-6 * p0[j]
        up, down = p0.copy(), p0.copy()
        up[j] += h
        down[j] -= h
        plus = dead_reckon_rows(r, lft, WheelGeometry.unchecked(*up))[:, :, -1].T
        minus = dead_reckon_rows(r, lft, WheelGeometry.unchecked(*down))[:, :, -1].T
        jac[:, :, j] = (plus - minus) / (2 * h)
    dr, dl = 0.5 * geometry.diameter_right_m * r, 0.5 * geometry.diameter_left_m * lft
    _, c = propagate_increments(dr, dl, geometry.wheelbase_m, NonSystematicError(0.5, 0.5))
    sxy, sth = model.measurement.sigma_xy_m, model.measurement.sigma_theta_rad
    rp = np.diag([sxy**2, sxy**2, sth**2])
    s_i = model.wheel.k_sum_m * c + 2 * rp[None]
    w = np.linalg.inv(s_i)
    wj = np.einsum("nij,njk->nik", w, jac)  # W_i J_i
    h_mat = np.einsum("nji,njk->ik", jac, wj)
    meat = h_mat.copy()  # the diagonal blocks: sum J^T W S W J = H
    mot = np.asarray(m.sensor_motion, dtype=float)
    adjacent = np.flatnonzero(np.abs(m.start_s[1:] - m.end_s[:-1]) < 1e-6)
    for i in adjacent:
        th = mot[i, 2]
        e = np.array([[math.cos(th), -math.sin(th), 0], [math.sin(th), math.cos(th), 0], [0, 0, 1]])
        t = mot[i + 1, :2]
        f = np.array([[-1.0, 0, t[1]], [0, -1.0, -t[0]], [0, 0, -1.0]])
        cross = e @ rp @ f.T  # Cov(dm_i, dm_i+1)
        term = wj[i].T @ cross @ wj[i + 1]
        meat += term + term.T
    hinv = np.linalg.inv(h_mat)
    return hinv @ meat @ hinv


def mit_parts(robot_path: Path, frames: tuple[str, str], counts=(2, 4, 6)) -> tuple[list, dict]:
    """The whole MIT log cut into ``counts`` contiguous parts of its SLAM intervals (the same
    time offset, estimated once on the whole log): each part fitted alone by the SLAM route's
    relative-motion fit (:func:`odocal.app.fit_relative.fit_relative`, its own covariance) and
    checked (:func:`odocal.calibration.slam_noise.slam_noise_model`: the noise from the part's
    own residuals and the covariance the fit would have, as ``odocal check --truth-frames``).
    Besides the per-parameter rows, a joint scale: Q = sum over parts of the deviation from
    the inverse-covariance mean in that part's predicted covariance, sqrt(Q / (3 (P - 1)))."""
    import dataclasses

    from odocal.app.fit_relative import fit_relative
    from odocal.app.slam_bags import load_slam_bags
    from odocal.calibration.slam_noise import slam_noise_model
    from odocal.io.bag_options import NO_BAG_OPTIONS
    from odocal.io.robot_file import load_robot

    robot = load_robot(robot_path)
    full = REAL / "mit_csail" / "csail_full"
    bag = load_slam_bags([full], frames, NO_BAG_OPTIONS, ran_with=robot.believed_geometry)[0]
    m = bag.relative_motions
    n = len(m.phi_right_rad)

    def part(lo: int, hi: int):
        def cut(a):
            return None if a is None else a[lo:hi]

        inc = None if m.increments is None else (m.increments[0][lo:hi], m.increments[1][lo:hi])
        return dataclasses.replace(
            m, phi_right_rad=m.phi_right_rad[lo:hi], phi_left_rad=m.phi_left_rad[lo:hi],
            sensor_motion=m.sensor_motion[lo:hi], increments=inc, start_s=cut(m.start_s),
            end_s=cut(m.end_s),
        )  # fmt: skip

    rows, info = [], {"intervals": n, "time_offset_s": bag.time_offset.applied_s}
    for count in counts:
        edges = np.linspace(0, n, count + 1).round().astype(int)
        shared = "check, pose noise shared by neighbouring intervals"
        vals, covs = [], {"check (log's own noise)": [], shared: [], "fit's own": []}
        for lo, hi in zip(edges[:-1], edges[1:], strict=True):
            p = part(int(lo), int(hi))
            res, _ = fit_relative([p], robot.nominal, sensor_pose=(0, 0, 0), force=True,
                                  source="slam")  # fmt: skip
            g = res.geometry
            vals.append([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m])
            covs["fit's own"].append(np.asarray(res.covariance)[:3, :3])
            noise = slam_noise_model(p, robot, g)
            covs["check (log's own noise)"].append(noise.covariance)
            covs[shared].append(shared_pose_covariance(p, g, noise.model))
        v = np.array(vals)
        sd = v.std(axis=0, ddof=1)
        label = f"MIT, {count} parts of the whole log"
        joint = {}
        for name, cs in covs.items():
            se = np.sqrt(np.mean([np.diag(c) for c in cs], axis=0))
            for i, q in enumerate(SHORT):
                rows.append(row(label, q, name, float(se[i]), float(sd[i]), count - 1, "mm", 1e3))
            joint[name] = joint_scale(v, cs, ["all"] * count)
        info[str(count)] = {"estimates_m": v.tolist(), "joint": joint}
    return rows, info


# ---------------------------------------------------------------------------------------------
# A2. Warthog recordings


def warthog() -> tuple[list[dict], dict]:
    from odocal.app.fit_skid import EXPORTED, truth_offsets
    from odocal.calibration.skid_steer import fit_skid_logs
    from odocal.io.bag_options import BagOptions
    from odocal.io.bag_skid import read_skid_log
    from odocal.io.robot_file import load_robot

    skid = REAL / "norlab_skid"
    robot = load_robot(skid / "robots" / "warthog.yaml")
    bags = sorted(skid.glob("warthog_wheels_grass*/*_bag"), key=_start_ns)
    opts = BagOptions(truth_topic="/icp_odom")
    logs = [read_skid_log(b, opts, robot.believed_geometry) for b in bags]
    offsets = truth_offsets(logs)
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
        covs: dict[str, list] = {"check, measured noise": [], "check, default noise": [],
                                 "fit's own": []}  # fmt: skip
        for name, recs in sets.items():
            f = fit_recordings(recs, "trajectory", nominal=NOMINAL)
            g = f.geometry
            est.append([g.diameter_right_m, g.diameter_left_m, g.wheelbase_m])
            p_fit.append([f.stderr[k] for k in KEYS])
            c_meas = check_recordings(recs, g, noise=measured)
            c_def = check_recordings(recs, g, noise=default)
            p_meas.append([c_meas.stderr[k] for k in KEYS])
            p_def.append([c_def.stderr[k] for k in KEYS])
            covs["check, measured noise"].append(np.asarray(c_meas.covariance)[:3, :3])
            covs["check, default noise"].append(np.asarray(c_def.covariance)[:3, :3])
            covs["fit's own"].append(np.asarray(f.covariance)[:3, :3])
            sess.append(session(name))
        est_a = np.array(est)
        info["sets"][cat] = {
            "names": list(sets), "estimates_m": est_a.tolist(), "sessions": sess,
            "joint": {k: joint_scale(est_a, c, ["all"] * len(est)) for k, c in covs.items()},
            "joint_within_session": {k: joint_scale(est_a, c, sess) for k, c in covs.items()},
        }  # fmt: skip
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
        for count, x in info["mit"]["parts"].items():
            if not isinstance(x, dict):
                continue
            for k, v in x["joint"].items():
                lo, hi = v["scale_ci95"]
                print(
                    f"  {count} parts, {k}: Q = {v['q']:.1f} on {v['dof']} dof, scale "
                    f"{v['scale']:.2f} (95 % {lo:.2f}-{hi:.2f})"
                )
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
        for cat, x in info["optiodom"]["sets"].items():
            for key, what in (("joint", "all sets"), ("joint_within_session", "within session")):
                for k, v in x[key].items():
                    lo, hi = v["scale_ci95"]
                    print(
                        f"  {cat}, {what}, {k}: joint Q = {v['q']:.1f} on {v['dof']} dof, "
                        f"scale {v['scale']:.2f} (95 % {lo:.2f}-{hi:.2f})"
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
    """B. Does the design, with noise measured from the robot's own runs, predict that the
    1.7 m squares beat the 0.75 m squares on the 19 held-out runs (the real result)?

    The heading method uses only the final headings of the square runs, and it is exact under
    the model: its estimate is the truth plus the noise of the mean CW and CCW final headings,
    alpha = (cw - ccw) / 8, beta = (cw + ccw) / 8. So a noise model enters the design only
    through the variance of one run's final heading, v(L) = 4 (k_r + k_l) L / b^2 (four legs)
    + 4 s_turn^2 (four spot turns) + s_theta^2 (tracker, start and end). Each model below gives
    v for both squares; E_b, E_d are drawn as truth + that noise (n CW + n CCW runs, the real
    counts), and the held-out runs' recorded wheel rotations are replayed through the model
    (``core.replay``, the design's own validation) with every draw, the two sizes with the same
    replay noise (the real comparison is paired: the same 19 runs).

    Models: 'today' = the design of ``odocal reproduce --realdata`` (k from the squares'
    scatter, no turn term); 'per-turn, per-speed' (RECONSTRUCTED) = k from the Ivanjko straight
    runs (the wheel noise of straight driving) plus a heading noise per spot turn measured for
    each square size from its own runs' scatter (the two sizes were turned at 0.38 and
    1.01 rad/s). The truth is the design's: the trajectory fit of squares + Ivanjko."""
    from bench_check import data_sets, measure_noise

    from odocal.app.measured import measure_robot
    from odocal.core.model import NonSystematicError
    from odocal.core.replay import chunk_rotations, replay_final_errors
    from odocal.design.real_experiment import heldout_errors, square_end_errors
    from odocal.design.real_motion import motion_profile
    from odocal.design.real_prediction import REPLAY_CHUNK_M
    from odocal.io.optiodom import load_optiodom_experiment

    data = REAL / "optiodom_diff"
    by_side, iv, held, _ = load_optiodom_experiment(data)
    sq = [r for v in by_side.values() for r in v]
    known = [r.ran_with for r in sq if r.ran_with is not None]
    ref = max(set(known), key=known.count)
    measured = measure_robot(sq + iv, ref, noise_recordings=sq)
    robot = measured.robot
    b = float(ref.wheelbase_m)
    k_today = robot.nonsystematic.k_r_m + robot.nonsystematic.k_l_m
    s_meas = robot.measurement.sigma_theta_rad
    _, facts = measure_noise(data_sets(data, "square"), data_sets(data, "ivanjko"), b)
    k_straight = 2 * facts["k_each_m"]

    real: dict[float, dict] = {}
    for side, runs in by_side.items():
        ends = square_end_errors(runs, ref)
        th = ends.errors[:, 2]
        dirs = np.array(ends.directions)
        groups: dict[tuple, list[float]] = {}
        for r, d, e in zip(runs, dirs, th, strict=True):
            groups.setdefault((r.dataset, d), []).append(float(e))
        ss = sum(float(np.sum((np.array(v) - np.mean(v)) ** 2)) for v in groups.values())
        dof = sum(len(v) - 1 for v in groups.values())
        cw, ccw = th[dirs == "cw"], th[dirs == "ccw"]
        alpha = (cw.mean() - ccw.mean()) / 8
        beta = (cw.mean() + ccw.mean()) / 8
        e_b, e_d = _heading_factors(alpha, beta, side, b)
        geo = ref.corrected(e_b, e_d)
        v_run = ss / dof
        real[side] = {
            "runs_cw": int(len(cw)),
            "runs_ccw": int(len(ccw)),
            "run_heading_sd_deg": math.degrees(math.sqrt(v_run)),
            "run_heading_sd_ci95_deg": [
                math.degrees(x) for x in sd_interval(math.sqrt(v_run), dof)
            ],
            "dof": dof,
            "alpha_deg": math.degrees(alpha),
            "alpha_se_deg": math.degrees(math.sqrt(v_run * (1 / len(cw) + 1 / len(ccw))) / 8),
            "E_b": e_b,
            "E_d": e_d,
            "heldout_error_mm": 1e3 * float(heldout_errors(held, geo).mean()),
            "spot_turn_rate_rad_s": motion_profile(runs, ref).spot_turn_rate_rad_s,
        }
    sides = sorted(real)
    # the per-turn heading noise of each size, from its own runs (RECONSTRUCTED)
    for side in sides:
        r = real[side]
        v_legs = 4 * k_straight * side / b**2 + s_meas**2
        v_run = math.radians(r["run_heading_sd_deg"]) ** 2
        lo, hi = (math.radians(x) ** 2 for x in r["run_heading_sd_ci95_deg"])
        r["turn_sd_deg"] = math.degrees(math.sqrt(max(0.0, (v_run - v_legs) / 4)))
        r["turn_sd_ci95_deg"] = [
            math.degrees(math.sqrt(max(0.0, (x - v_legs) / 4))) for x in (lo, hi)
        ]
    models = {
        "today (k from the squares' scatter)": (
            k_today,
            {s: 4 * k_today * s / b**2 + s_meas**2 for s in sides},
        ),
        "per-turn, per-speed (RECONSTRUCTED)": (
            k_straight,
            {
                s: 4 * k_straight * s / b**2
                + 4 * math.radians(real[s]["turn_sd_deg"]) ** 2
                + s_meas**2
                for s in sides
            },
        ),
    }
    rng = np.random.default_rng(seed)
    truth = robot.systematic
    chunk_rad = REPLAY_CHUNK_M / (0.5 * float(ref.mean_diameter_m))
    chunks = [
        chunk_rotations(r.wheel_angle_right_rad, r.wheel_angle_left_rad, chunk_rad) for r in held
    ]
    # what the heading method measures is the turning gain: a spot turn of psi really turns
    # psi E_s / E_b, so its E_b is E_b / E_s (the simulator's heading calibrations agree)
    a0, b0 = _heading_angles(truth.E_b / truth.E_s, truth.E_d, sides, b)
    out_models = {}
    for name, (k_sum, v) in models.items():
        e_b = np.empty((len(sides), trials))
        e_d = np.empty((len(sides), trials))
        for i, s in enumerate(sides):
            n = 1 / real[s]["runs_cw"] + 1 / real[s]["runs_ccw"]
            sd = math.sqrt(v[s] * n) / 8
            da, db = sd * rng.standard_normal((2, trials))
            e_b[i], e_d[i] = _heading_factors(a0[i] + da, b0[i] + db, s, b)
        geos = ref.corrected(e_b, e_d)
        noise = NonSystematicError(k_sum / 2, k_sum / 2)
        per_run = np.stack(
            [replay_final_errors(c, robot.true_geometry, noise, geos, rng) for c in chunks],
            axis=1,
        )  # (sides, runs, trials)
        mean = per_run.mean(axis=1)
        d = per_run[0] - per_run[1]  # first side minus second, per run
        t = d.mean(axis=0) / (d.std(axis=0, ddof=1) / math.sqrt(d.shape[0]))
        from scipy.stats import t as student

        pval = 2 * student.sf(np.abs(t), d.shape[0] - 1)
        diff = mean[0] - mean[1]
        out_models[name] = {
            "run_heading_sd_deg": {str(s): math.degrees(math.sqrt(v[s])) for s in sides},
            "E_b_sd": {str(s): float(e_b[i].std(ddof=1)) for i, s in enumerate(sides)},
            "predicted_error_mm": {
                str(s): 1e3 * float(mean[i].mean()) for i, s in enumerate(sides)
            },
            "predicted_error_sd_mm": {
                str(s): 1e3 * float(mean[i].std(ddof=1)) for i, s in enumerate(sides)
            },
            "difference_mm": 1e3 * float(diff.mean()),
            "difference_ci95_mm": [1e3 * float(x) for x in np.percentile(diff, [2.5, 97.5])],
            "share_second_better": float(np.mean(diff > 0)),
            "share_second_significantly_better": float(np.mean((pval < 0.05) & (diff > 0))),
            "share_first_significantly_better": float(np.mean((pval < 0.05) & (diff < 0))),
        }
    out_models["turn-rate gain (systematic) + per-turn noise (RECONSTRUCTED)"], rate_fit = (
        _rate_model(by_side, iv, held, ref, robot, real, models, trials, rng, chunks)
    )
    # corroboration from other runs: the Ivanjko spins' heading scatter per session (slow June,
    # fast December turns), each data set at its own trajectory fit
    spins = _spin_scatter(data)
    # the shortcut against the design's own simulator (today's model, the real run counts)
    from odocal.design.real_prediction import predict

    sim = predict(
        robot, held, {s: real[s]["runs_cw"] for s in sides}, sides, real[sides[0]]["runs_cw"],
        max(200, trials // 4), np.random.default_rng(seed + 1),
    )  # fmt: skip
    simulator = {
        str(s): {"E_b_sd": c.E_b_std, "predicted_error_mm": 1e3 * c.post_error_mean_m}
        for s, c in sim.real.items()
    }
    # the systematic per-turn difference the data show, and what a turn-rate rule would pick
    s0, s1 = sides
    z = (real[s1]["alpha_deg"] - real[s0]["alpha_deg"]) / math.hypot(
        real[s0]["alpha_se_deg"], real[s1]["alpha_se_deg"]
    )
    held_profile = motion_profile(held, ref)
    res = {
        "sides_m": sides,
        "k_today_m": k_today,
        "k_straight_m": k_straight,
        "tracker_heading_deg": math.degrees(s_meas),
        "real": {str(s): real[s] for s in sides},
        "models": out_models,
        "per_turn_bias_difference_deg": real[s1]["alpha_deg"] - real[s0]["alpha_deg"],
        "per_turn_bias_z": z,
        "heldout_spot_turn_rate_rad_s": held_profile.spot_turn_rate_rad_s,
        "trials": trials,
        "turn_rate_gain": rate_fit,
        "simulator_today": simulator,
        "ivanjko_spin_heading_sd": spins,
        "simulator_trials": max(200, trials // 4),
    }
    res["text"] = _design_text(res)
    return res


def _spin_scatter(data: Path) -> dict:
    """Final heading error sd (deg) of the Ivanjko spins, pooled within data set and direction,
    per session, each data set at its own trajectory fit; with the dof and the turn rate."""
    from bench_check import NOMINAL, data_sets, session

    from odocal.calibration.trajectory import fit_trajectory
    from odocal.core.odometry import dead_reckon
    from odocal.design.real_motion import motion_profile

    acc: dict[str, list] = {}
    for name, recs in data_sets(data, "ivanjko").items():
        g = fit_trajectory(recs, nominal=NOMINAL).geometry
        groups: dict[str, list[float]] = {}
        spins = [r for r in recs if r.label and r.label.startswith("spin")]
        for r in spins:
            odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, g)
            gt = r.ground_truth
            groups.setdefault(r.label, []).append(
                float((gt[-1, 2] - gt[0, 2]) - (odo[-1, 2] - odo[0, 2]))
            )
        a = acc.setdefault(session(name), [0.0, 0, []])
        for v in groups.values():
            x = np.array(v)
            a[0] += float(np.sum((x - x.mean()) ** 2))
            a[1] += len(x) - 1
        a[2] += spins
    return {
        k: {
            "sd_deg": math.degrees(math.sqrt(a[0] / a[1])),
            "dof": a[1],
            "spot_turn_rate_rad_s": motion_profile(a[2], NOMINAL).spot_turn_rate_rad_s,
        }
        for k, a in acc.items()
    }


def turn_rate(runs, ref) -> float:
    """Rotation-weighted mean |yaw rate| (rad/s) of ``runs`` from their wheels (``ref``
    geometry; 9-sample smoothing as :func:`odocal.design.real_motion.motion_profile`)."""
    num = den = 0.0
    for r in runs:
        dt = np.diff(np.asarray(r.time_s, dtype=float))
        wr = np.diff(r.wheel_angle_right_rad) * (0.5 * ref.diameter_right_m)
        wl = np.diff(r.wheel_angle_left_rad) * (0.5 * ref.diameter_left_m)
        dth = np.convolve((wr - wl) / ref.wheelbase_m, np.ones(9) / 9, "same")
        rate = np.abs(dth) / np.convolve(dt, np.ones(9) / 9, "same")
        num += float(np.sum(np.abs(dth) * rate))
        den += float(np.sum(np.abs(dth)))
    return num / den


def _rate_model(by_side, iv, held, ref, robot, real, models, trials, rng, chunks):
    """Model (iii): the turning gain mean(D)/b depends on the turn rate, linearly, as the
    training runs show it (each square data set and each Ivanjko data set's spins fitted alone,
    against its rotation-weighted turn rate); the model's truth for a square size and for each
    held-out run is the gain at its own turn rate (the held-out runs are used only for their
    wheel rotations, as the design uses any validation driving). Noise: the per-turn, per-speed
    model. Also returns the regression and, as a CHECK only (not used), the held-out runs' own
    fitted gain against the model's."""
    from odocal.calibration.trajectory import fit_trajectory
    from odocal.core.model import NonSystematicError, WheelGeometry
    from odocal.core.replay import replay_final_errors

    sets: dict[str, list] = {}
    for r in [r for v in by_side.values() for r in v]:
        sets.setdefault("square " + r.dataset, []).append(r)
    for r in iv:
        if r.label and r.label.startswith("spin"):
            sets.setdefault("spins " + r.dataset, []).append(r)
    pts = []
    for name, runs in sorted(sets.items()):
        g = fit_trajectory(runs, nominal=ref).geometry
        pts.append((name, turn_rate(runs, ref), float(g.mean_diameter_m / g.wheelbase_m)))
    x = np.array([p[1] for p in pts])
    y = np.array([p[2] for p in pts])
    slope, icpt = np.polyfit(x, y, 1)
    resid = y - (icpt + slope * x)
    se_slope = math.sqrt(np.sum(resid**2) / (len(x) - 2) / np.sum((x - x.mean()) ** 2))

    def gain(w):
        return icpt + slope * np.asarray(w)

    sides = sorted(real)
    d_mean = float(robot.true_geometry.mean_diameter_m)
    e_d = robot.systematic.E_d
    g_ref = float(ref.mean_diameter_m / ref.wheelbase_m)
    n = len(held)
    held_rates = np.array([turn_rate([r], ref) for r in held])
    # per held-out run its true geometry (diameters of the model robot, b from the gain)
    e_b = np.empty((len(sides), trials))
    e_dd = np.empty((len(sides), trials))
    _, v = models["per-turn, per-speed (RECONSTRUCTED)"]
    b = float(ref.wheelbase_m)
    for i, s in enumerate(sides):
        w = turn_rate(by_side[s], ref)
        a0, b0 = _heading_angles(g_ref / float(gain(w)), e_d, [s], b)
        nn = 1 / real[s]["runs_cw"] + 1 / real[s]["runs_ccw"]
        sd = math.sqrt(v[s] * nn) / 8
        da, db = sd * rng.standard_normal((2, trials))
        e_b[i], e_dd[i] = _heading_factors(a0[0] + da, b0[0] + db, s, b)
    geos = ref.corrected(e_b, e_dd)
    k_sum, _ = models["per-turn, per-speed (RECONSTRUCTED)"]
    noise = NonSystematicError(k_sum / 2, k_sum / 2)
    per_run = []
    for c, w in zip(chunks, held_rates, strict=True):
        t = robot.true_geometry
        true = WheelGeometry(t.diameter_right_m, t.diameter_left_m, d_mean / float(gain(w)))
        per_run.append(replay_final_errors(c, true, noise, geos, rng))
    per = np.stack(per_run, axis=1)
    mean = per.mean(axis=1)
    d = per[0] - per[1]
    from scipy.stats import t as student

    tt = d.mean(axis=0) / (d.std(axis=0, ddof=1) / math.sqrt(n))
    pval = 2 * student.sf(np.abs(tt), n - 1)
    diff = mean[0] - mean[1]
    held_gain = [
        float(
            fit_trajectory([r], nominal=ref).geometry.mean_diameter_m
            / fit_trajectory([r], nominal=ref).geometry.wheelbase_m
        )
        for r in held
    ]
    model = {
        "run_heading_sd_deg": {str(s): math.degrees(math.sqrt(v[s])) for s in sides},
        "E_b_sd": {str(s): float(e_b[i].std(ddof=1)) for i, s in enumerate(sides)},
        "predicted_error_mm": {str(s): 1e3 * float(mean[i].mean()) for i, s in enumerate(sides)},
        "predicted_error_sd_mm": {
            str(s): 1e3 * float(mean[i].std(ddof=1)) for i, s in enumerate(sides)
        },
        "difference_mm": 1e3 * float(diff.mean()),
        "difference_ci95_mm": [1e3 * float(q) for q in np.percentile(diff, [2.5, 97.5])],
        "share_second_better": float(np.mean(diff > 0)),
        "share_second_significantly_better": float(np.mean((pval < 0.05) & (diff > 0))),
        "share_first_significantly_better": float(np.mean((pval < 0.05) & (diff < 0))),
    }
    fit = {
        "points": [{"set": p[0], "turn_rate_rad_s": p[1], "gain": p[2]} for p in pts],
        "intercept": float(icpt),
        "slope_per_rad_s": float(slope),
        "slope_se": se_slope,
        "square_rates_rad_s": {str(s): turn_rate(by_side[s], ref) for s in sides},
        "heldout_rates_rad_s": held_rates.tolist(),
        "heldout_model_gain": gain(held_rates).tolist(),
        "heldout_fitted_gain_CHECK": held_gain,
        "heldout_names": [r.name for r in held],
    }
    return model, fit


def _heading_angles(e_b: float, e_d: float, sides, b: float) -> tuple[np.ndarray, np.ndarray]:
    """alpha (per turn) and beta (per leg) of the heading method for squares of ``sides``."""
    s = np.asarray(sides, dtype=float)
    alpha = (math.pi / 2) * (1 - 1 / e_b) * np.ones_like(s)
    q = (e_d - 1) / (e_d + 1)
    beta = q * 2 * s / (e_b * b)
    return alpha, beta


def _heading_factors(alpha, beta, side: float, b: float):
    """E_b, E_d of the heading method (model.md) from alpha, beta of a square of ``side``."""
    e_b = (math.pi / 2) / (math.pi / 2 - alpha)
    q = beta * e_b * b / (2 * side)
    return e_b, (1 + q) / (1 - q)


def _design_text(r: dict) -> str:
    s0, s1 = (str(s) for s in r["sides_m"])
    real = r["real"]
    lines = [
        "B. The OptiOdom design question: do the 1.7 m squares beat the 0.75 m squares?",
        "",
        "Real (heading method pooled per size; 19 held-out runs):",
        "| square | runs CW + CCW | spot turns (p90) | final heading sd per run (95 %) | "
        "per-turn heading sd, RECONSTRUCTED (95 %) | alpha per turn | E_b | held-out error |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for s in (s0, s1):
        x = real[s]
        lo, hi = x["run_heading_sd_ci95_deg"]
        tlo, thi = x["turn_sd_ci95_deg"]
        lines.append(
            f"| {s} m | {x['runs_cw']} + {x['runs_ccw']} | {x['spot_turn_rate_rad_s']:.2f} rad/s | "
            f"{x['run_heading_sd_deg']:.2f} deg ({lo:.2f}-{hi:.2f}; {x['dof']} dof) | "
            f"{x['turn_sd_deg']:.2f} deg ({tlo:.2f}-{thi:.2f}) | "
            f"{x['alpha_deg']:.3f} +- {x['alpha_se_deg']:.3f} deg | {x['E_b']:.5f} | "
            f"{x['heldout_error_mm']:.1f} mm |"
        )
    lines += [
        "",
        f"Noise: k_r + k_l {r['k_today_m']:.3g} m (today: the squares' scatter), "
        f"{r['k_straight_m']:.3g} m (Ivanjko straight runs); tracker heading "
        f"{r['tracker_heading_deg']:.2f} deg per final heading.",
        "",
        f"Predicted ({r['trials']} simulated experiments each, paired on the same replay noise):",
        "| model | run heading sd 0.75 / 1.7 m | E_b sd 0.75 / 1.7 m | predicted error 0.75 m | "
        "1.7 m | difference 0.75 - 1.7 (95 %) | 1.7 m better | 1.7 m significantly better "
        "(paired t, p < 0.05) |",
        "|---|---|---|---|---|---|---|---|",
    ]
    for name, m in r["models"].items():
        lo, hi = m["difference_ci95_mm"]
        lines.append(
            f"| {name} | {m['run_heading_sd_deg'][s0]:.2f} / {m['run_heading_sd_deg'][s1]:.2f} "
            f"deg | {100 * m['E_b_sd'][s0]:.3f} / {100 * m['E_b_sd'][s1]:.3f} % | "
            f"{m['predicted_error_mm'][s0]:.1f} +- {m['predicted_error_sd_mm'][s0]:.1f} mm | "
            f"{m['predicted_error_mm'][s1]:.1f} +- {m['predicted_error_sd_mm'][s1]:.1f} mm | "
            f"{m['difference_mm']:+.1f} mm ({lo:+.1f} to {hi:+.1f}) | "
            f"{100 * m['share_second_better']:.0f} % | "
            f"{100 * m['share_second_significantly_better']:.1f} % |"
        )
    sp = r["ivanjko_spin_heading_sd"]
    lines += [
        "",
        "Corroboration, the Ivanjko spins (half turns) per session: "
        + "; ".join(
            f"{k}: heading sd {v['sd_deg']:.2f} deg ({v['dof']} dof), turns at "
            f"{v['spot_turn_rate_rad_s']:.2f} rad/s"
            for k, v in sp.items()
        )
        + ".",
    ]
    sim = r["simulator_today"]
    lines += [
        "",
        f"The design's simulator (today's model, {r['simulator_trials']} trials): E_b sd "
        + " / ".join(f"{100 * sim[s]['E_b_sd']:.3f} %" for s in (s0, s1))
        + ", predicted error "
        + " / ".join(f"{sim[s]['predicted_error_mm']:.1f} mm" for s in (s0, s1))
        + " (the shortcut's first row).",
    ]
    f = r["turn_rate_gain"]
    hm, hf = np.array(f["heldout_model_gain"]), np.array(f["heldout_fitted_gain_CHECK"])
    lines += [
        "",
        f"Turn-rate gain (from {len(f['points'])} training sets: squares and Ivanjko spins, "
        f"each fitted alone): gain = {f['intercept']:.5f} {f['slope_per_rad_s']:+.5f} "
        f"(+- {f['slope_se']:.5f}) x rate; the squares turn at "
        + " / ".join(f"{w:.2f}" for w in f["square_rates_rad_s"].values())
        + f" rad/s, the held-out runs at {min(f['heldout_rates_rad_s']):.2f}-"
        f"{max(f['heldout_rates_rad_s']):.2f} rad/s. CHECK (not used by the prediction): the "
        f"model gives the held-out runs a gain of {hm.mean():.5f} on average, their own fits "
        f"{hf.mean():.5f} (run by run: model - own, sd {np.std(hm - hf, ddof=1):.5f}).",
    ]
    real_diff = real[s0]["heldout_error_mm"] - real[s1]["heldout_error_mm"]
    lines += [
        "",
        f"Real difference 0.75 - 1.7: {real_diff:+.1f} mm. The per-turn under-rotation alpha "
        f"differs between the sizes by {r['per_turn_bias_difference_deg']:+.3f} deg per turn, "
        f"z = {r['per_turn_bias_z']:+.1f} against the run-to-run noise: a systematic difference "
        "(session, controller, turn rate: confounded), which no zero-mean noise term can "
        f"predict. The held-out runs' spot turns (p90) run at "
        + (
            f"{r['heldout_spot_turn_rate_rad_s']:.2f} rad/s"
            if r["heldout_spot_turn_rate_rad_s"] is not None
            else "- (too few spot-turn samples: they drive arcs)"
        )
        + ".",
    ]
    return "\n".join(lines)


if __name__ == "__main__":
    raise SystemExit(main())
