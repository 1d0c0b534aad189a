"""Real-data benchmark of the log check (``odocal.calibration.identifiability``) on OptiOdom.

1. A noise model for the OptiOdom robot, measured WITHOUT the calibration fits:
   - tracker: second differences of the ground truth while the wheels stand still
     (var of x[i+1] - 2 x[i] + x[i-1] is 6 sigma^2 for white noise);
   - wheel noise k: the spread of the final heading error of the Ivanjko straight runs within
     each data set (model.md, one-way straight runs: k_r + k_l = b^2 s_theta^2 / d);
   - turn noise: the spread of the final heading error of the Ivanjko spins within each data set
     and direction, less the wheel and tracker parts, per radian turned.
   The heading errors are taken at each data set's own trajectory fit.
2. Predicted against observed: every data set of ``square/`` (8) and ``ivanjko/`` (8) is fitted
   separately with ``fit_trajectory`` (pose and segment residuals); the standard deviation of
   the 8 results per parameter is compared with the root-mean-square of the 8 predicted standard
   errors (stated noise, and the noise scaled to each set's residuals: 'empirical'), for all 8
   and for each recording session (June 2020, December 2020) alone.
3. Flags on subsets: Ivanjko straight runs only, spins only, CW spins only, squares only, CCW
   squares only, all Ivanjko, squares + Ivanjko, and the held-out circles and free paths,
   linearised at the trajectory fit of squares + Ivanjko.

Usage::

    python benchmarks/bench_check.py [--data ../shared/realdata/optiodom_diff] [--json]
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from odocal.calibration.fit_settings import TrajectorySettings
from odocal.calibration.identifiability import NoiseModel, check_recordings
from odocal.calibration.trajectory import fit_trajectory
from odocal.core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.io.recordings import load_recordings

ROOT = Path(__file__).resolve().parents[1]
DEFAULT_DATA = ROOT.parent / "shared" / "realdata" / "optiodom_diff"
NOMINAL = WheelGeometry(0.084, 0.084, 0.200)
KEYS = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
SHORT = ("D_R", "D_L", "b")


def data_sets(data: Path, category: str) -> dict[str, list]:
    return {d.name: load_recordings([d]) for d in sorted((data / category).iterdir()) if d.is_dir()}


def session(name: str) -> str:
    """OptiOdom ids are DDMMYYYYhhmm: June or December 2020."""
    return {"06": "June 2020", "12": "December 2020"}.get(name[2:4], name[2:8])


# ---------------------------------------------------------------------------------------------
# 1. noise model


def tracker_noise(recordings) -> tuple[float, float]:
    """(sigma_xy_m, sigma_theta_rad) from second differences while both wheels stand still."""
    xy, th = [], []
    for r in recordings:
        d2 = r.ground_truth[2:] - 2 * r.ground_truth[1:-1] + r.ground_truth[:-2]
        dr = np.diff(r.wheel_angle_right_rad)
        dl = np.diff(r.wheel_angle_left_rad)
        still = (dr[1:] == 0) & (dr[:-1] == 0) & (dl[1:] == 0) & (dl[:-1] == 0)
        xy.append(d2[still, :2].ravel())
        th.append(d2[still, 2])
    xy, th = np.concatenate(xy), np.concatenate(th)
    return math.sqrt(np.mean(xy**2) / 6), math.sqrt(np.mean(th**2) / 6)


def heading_spreads(ivanjko: dict[str, list]):
    """Pooled within-group variance of the final heading error (rad^2) of the straight runs and
    of the spins, with the mean wheel travel (m) and turned angle (rad) of each kind."""
    out = {"straight": [0.0, 0, [], []], "spin": [0.0, 0, [], []]}
    for recs in ivanjko.values():
        g = fit_trajectory(recs, nominal=NOMINAL).geometry
        groups: dict[str, list] = {}
        for r in recs:
            odo = dead_reckon(r.wheel_angle_right_rad, r.wheel_angle_left_rad, g)
            travel = 0.25 * float(
                np.sum(np.abs(np.diff(r.wheel_angle_right_rad))) * g.diameter_right_m
                + np.sum(np.abs(np.diff(r.wheel_angle_left_rad))) * g.diameter_left_m
            )
            err = r.ground_truth[-1, 2] - odo[-1, 2]
            groups.setdefault(r.label, []).append((err, travel, abs(odo[-1, 2])))
        for label, rows in groups.items():
            if len(rows) < 2:
                continue
            e = np.array([x[0] for x in rows])
            acc = out["straight" if label == "straight" else "spin"]
            acc[0] += float(np.sum((e - e.mean()) ** 2))
            acc[1] += len(e) - 1
            acc[2] += [x[1] for x in rows]
            acc[3] += [x[2] for x in rows]
    return {
        k: (v[0] / v[1], v[1], float(np.mean(v[2])), float(np.mean(v[3]))) for k, v in out.items()
    }


def measure_noise(squares, ivanjko, b: float) -> tuple[NoiseModel, dict]:
    everything = [r for recs in list(squares.values()) + list(ivanjko.values()) for r in recs]
    s_xy, s_th = tracker_noise(everything)
    spreads = heading_spreads(ivanjko)
    var_st, dof_st, d_st, _ = spreads["straight"]
    var_sp, dof_sp, w_sp, psi_sp = spreads["spin"]
    k_sum = b**2 * var_st / d_st
    wheel_part = k_sum * w_sp / b**2
    turn = max(0.0, (var_sp - wheel_part - 2 * s_th**2) / psi_sp)
    noise = NoiseModel(
        NonSystematicError(k_sum / 2, k_sum / 2), MeasurementNoise(s_xy, s_th), turn_rad=turn
    )
    facts = {
        "sigma_xy_mm": 1e3 * s_xy,
        "sigma_theta_deg": math.degrees(s_th),
        "straight_heading_sd_deg": math.degrees(math.sqrt(var_st)),
        "straight_dof": dof_st,
        "straight_length_m": d_st,
        "k_each_m": k_sum / 2,
        "spin_heading_sd_deg": math.degrees(math.sqrt(var_sp)),
        "spin_dof": dof_sp,
        "spin_angle_deg": math.degrees(psi_sp),
        "turn_rad": turn,
    }
    return noise, facts


# ---------------------------------------------------------------------------------------------
# 2. predicted against observed


def agreement(sets: dict[str, list], noise: NoiseModel, residual: str) -> dict:
    rows = []
    for name, recs in sets.items():
        settings = TrajectorySettings(residual=residual)
        g = fit_trajectory(recs, nominal=NOMINAL, settings=settings).geometry
        stated = check_recordings(recs, g, noise=noise, residual=residual)
        emp = check_recordings(recs, g, noise=noise, residual=residual, residual_scale="empirical")
        rows.append(
            {
                "data_set": name,
                "session": session(name),
                "runs": len(recs),
                "estimate_m": [g.diameter_right_m, g.diameter_left_m, g.wheelbase_m],
                "stderr_stated_m": [stated.stderr[k] for k in KEYS],
                "stderr_empirical_m": [emp.stderr[k] for k in KEYS],
                "residual_scale": emp.residual_scale,
                "formal_fit_stderr_m": [
                    fit_trajectory(recs, nominal=NOMINAL, settings=settings).stderr[k] for k in KEYS
                ],
            }
        )
    groups = {"all": rows}
    for s in sorted({r["session"] for r in rows}):
        groups[s] = [r for r in rows if r["session"] == s]
    summary = {}
    for label, rs in groups.items():
        est = np.array([r["estimate_m"] for r in rs])
        observed = est.std(axis=0, ddof=1)

        def rms(key, rs=rs):
            return np.sqrt(np.mean(np.square([r[key] for r in rs]), axis=0))

        summary[label] = {
            "data_sets": len(rs),
            "observed_sd_m": observed.tolist(),
            "predicted_stated_m": rms("stderr_stated_m").tolist(),
            "predicted_empirical_m": rms("stderr_empirical_m").tolist(),
            "formal_fit_m": rms("formal_fit_stderr_m").tolist(),
            "mean_m": est.mean(axis=0).tolist(),
        }
    return {"per_data_set": rows, "summary": summary}


# ---------------------------------------------------------------------------------------------
# 3. flags


def flags(subsets: dict[str, list], geometry: WheelGeometry, noise: NoiseModel) -> dict:
    out = {}
    for name, recs in subsets.items():
        row = {"runs": len(recs)}
        for mounting in (False, True):
            c = check_recordings(recs, geometry, noise=noise, mounting=mounting)
            key = "with_mounting" if mounting else "geometry"
            row[key] = {
                "ok": c.ok,
                "codes": [d.code for d in c.degeneracies],
                "blind": list(c.blind_directions),
                "weakest": c.weakest_direction,
                "condition_number": c.condition_number,
                "relative_stderr": [c.stderr[k] / v for k, v in zip(KEYS, c.values, strict=False)],
                "suggestions": list(c.suggestions),
            }
            if not mounting:
                m = c.motion
                row["motion"] = {
                    "travel_m": m.travel_m,
                    "rotation_deg": math.degrees(m.rotation_rad),
                    "share_straight": m.share_straight,
                    "share_spot": m.share_spot,
                    "share_arc": m.share_arc,
                    "turning": m.turning,
                    "ratio_concentration": m.ratio_concentration,
                }
        out[name] = row
    return out


def _um(v) -> str:
    return "  ".join(f"{1e6 * x:8.1f}" for x in v)


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--data", type=Path, default=DEFAULT_DATA)
    p.add_argument("--json", action="store_true")
    args = p.parse_args(argv)
    t0 = time.time()
    squares = data_sets(args.data, "square")
    ivanjko = data_sets(args.data, "ivanjko")
    training = [r for recs in list(squares.values()) + list(ivanjko.values()) for r in recs]
    geometry = fit_trajectory(training, nominal=NOMINAL).geometry
    noise, facts = measure_noise(squares, ivanjko, float(geometry.wheelbase_m))
    results = {"noise": facts, "agreement": {}, "geometry_all": geometry.as_dict()}
    for residual in ("pose", "segment"):
        for cat, sets in (("square", squares), ("ivanjko", ivanjko)):
            results["agreement"][f"{cat}/{residual}"] = agreement(sets, noise, residual)
    iv = [r for recs in ivanjko.values() for r in recs]
    sq = [r for recs in squares.values() for r in recs]
    subsets = {
        "ivanjko straight runs only": [r for r in iv if r.label == "straight"],
        "ivanjko spins only": [r for r in iv if r.label.startswith("spin")],
        "ivanjko CW spins only": [r for r in iv if r.label == "spin-cw"],
        "one straight run": [r for r in iv if r.label == "straight"][:1],
        "squares only": sq,
        "CCW squares only": [r for r in sq if r.label == "ccw"],
        "ivanjko (straights + spins)": iv,
        "all training (squares + ivanjko)": sq + iv,
        "circular (held out)": load_recordings([args.data / "circular"]),
        "CCW circles only (held out)": [
            r for r in load_recordings([args.data / "circular"]) if r.label == "ccw"
        ],
        "free (held out)": load_recordings([args.data / "free"]),
    }
    results["flags"] = flags(subsets, geometry, noise)
    results["seconds"] = time.time() - t0
    if args.json:
        json.dump(results, sys.stdout, indent=1, default=float)
        print()
        return 0

    f = facts
    print("Stated noise (measured without the fits):")
    print(
        f"  tracker at rest: sigma_xy {f['sigma_xy_mm']:.3f} mm, sigma_theta "
        f"{f['sigma_theta_deg']:.3f} deg"
    )
    print(
        f"  straight runs: heading sd {f['straight_heading_sd_deg']:.3f} deg over "
        f"{f['straight_length_m']:.2f} m ({f['straight_dof']} dof) -> k = {f['k_each_m']:.3g} m "
        "per wheel"
    )
    print(
        f"  spins: heading sd {f['spin_heading_sd_deg']:.3f} deg per {f['spin_angle_deg']:.0f} "
        f"deg ({f['spin_dof']} dof) -> turn noise {f['turn_rad']:.3g} rad (variance per rad)"
    )
    print()
    print("Predicted standard error against the spread of per-data-set fits (micrometres):")
    for key, res in results["agreement"].items():
        for label, s in res["summary"].items():
            obs = np.array(s["observed_sd_m"])
            st = np.array(s["predicted_stated_m"])
            em = np.array(s["predicted_empirical_m"])
            fo = np.array(s["formal_fit_m"])
            print(f"  {key:17s} {label:14s} ({s['data_sets']} sets)   {'  '.join(SHORT)}")
            print(f"    observed sd           {_um(obs)}")
            print(f"    predicted (stated)    {_um(st)}   ratio {np.round(st / obs, 2)}")
            print(f"    predicted (empirical) {_um(em)}   ratio {np.round(em / obs, 2)}")
            print(f"    fit's formal stderr   {_um(fo)}   ratio {np.round(fo / obs, 2)}")
        scales = [r["residual_scale"] for r in res["per_data_set"]]
        print(f"    residual scales: {np.round(scales, 2).tolist()}")
        means = {
            k: np.round(1e3 * np.array(v["mean_m"]), 3).tolist() for k, v in res["summary"].items()
        }
        print(f"    mean estimates (mm): {means}")
    print()
    print(f"Flags (linearised at the fit of squares + ivanjko: {geometry})")
    for name, row in results["flags"].items():
        for key in ("geometry", "with_mounting"):
            r = row[key]
            rel = ", ".join(
                f"{s} {100 * v:.2g} %" for s, v in zip(SHORT, r["relative_stderr"], strict=True)
            )
            print(
                f"  {name:34s} {'+mount' if key == 'with_mounting' else '      '} "
                f"ok={str(r['ok']):5s} cond={r['condition_number']:9.3g}  {r['codes']}"
            )
            print(f"      stderr: {rel}; weakest: {r['weakest']}; blind: {r['blind']}")
        m = row["motion"]
        print(
            f"      motion: travel {m['travel_m']:.1f} m, rotation {m['rotation_deg']:.0f} deg, "
            f"straight/spot/arc {m['share_straight']:.2f}/{m['share_spot']:.2f}/"
            f"{m['share_arc']:.2f}, turning {m['turning']}, ratio concentration "
            f"{m['ratio_concentration']:.3f}"
        )
    print(f"\n{results['seconds']:.1f} s")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
