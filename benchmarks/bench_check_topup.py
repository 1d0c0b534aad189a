"""What to add to a log (``odocal.calibration.topup``): the recommended top-up, simulated and added,
against its prediction; and the top-ups ``odocal check`` recommends on OptiOdom subsets.

1. Synthetic: for three logs (three 3 m straight runs: not enough, b blind; two runs of two
   CCW spins: not enough, scale blind; one CW and one CCW 1 m square: enough, so the top-up
   halves the weakest parameter), the top-up is found at the nominal geometry with the stated
   noise (k = 1e-6 m per wheel, tracker 1 mm and 0.2 deg), then the log and the top-up are
   driven ``--replicates`` times open loop by odocal's simulator (true wheels 83.8 / 83.9 /
   201.5 mm on a robot believing 84 / 84 / 200 mm), seen by the noisy tracker and fitted
   together by the trajectory fit (``fit_trajectory_trials``, the pose fit of
   ``fit_trajectory``). Printed: the predicted standard error after the top-up, the standard
   deviation of the fits, their ratio (and, for the halving case, the realised spread of the
   log alone against its prediction).
2. One long run against several short ones: the same 120 s of figure-eights added to the two
   squares as one run and as 6 runs of 20 s, predicted and realised.
3. Real: the top-up ``odocal check`` gives for the Ivanjko straight runs, spins and the whole
   data set 250620201738 (default noise).

Usage::

    python benchmarks/bench_check_topup.py [--replicates 1000] [--seed 1]
        [--data ../shared/realdata/optiodom_diff]
"""

from __future__ import annotations

import argparse
import math
import time
from pathlib import Path

import numpy as np

from odocal.calibration.identifiability import NoiseModel, judge, log_information
from odocal.calibration.topup import find_top_up
from odocal.calibration.trajectory import fit_trajectory_trials
from odocal.core import tracks as T
from odocal.core.model import MeasurementNoise, NonSystematicError, WheelGeometry
from odocal.core.odometry import dead_reckon
from odocal.core.recording import Recording
from odocal.core.simulate import commanded_wheel_angles, drive
from odocal.core.topup_motion import maneuver_recording, maneuver_track

NOMINAL = WheelGeometry(0.084, 0.084, 0.200)
TRUE = WheelGeometry(0.0838, 0.0839, 0.2015)
WHEEL = NonSystematicError(1e-6, 1e-6)
TRACKER = MeasurementNoise(1e-3, math.radians(0.2))
NOISE = NoiseModel(WHEEL, TRACKER)


def recorded(track: T.Track) -> tuple[Recording, int, np.ndarray]:
    n, ang = commanded_wheel_angles(track, NOMINAL, 0.01)
    rec = Recording(
        track.name, 0.02 * np.arange(len(ang)), ang[:, 0], ang[:, 1],
        dead_reckon(ang[:, 0], ang[:, 1], NOMINAL), ran_with=NOMINAL,
    )  # fmt: skip
    return rec, n, ang


def measured(gt: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    sd = [TRACKER.sigma_xy_m, TRACKER.sigma_xy_m, TRACKER.sigma_theta_rad]
    gt = gt + rng.standard_normal(gt.shape) * sd
    c, s = np.cos(gt[:, :1, 2]), np.sin(gt[:, :1, 2])
    d = gt[:, :, :2] - gt[:, :1, :2]
    return np.stack(
        [c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], gt[..., 2] - gt[:, :1, 2]],
        axis=-1,
    )


def simulated_fits(groups, m: int, rng: np.random.Generator) -> np.ndarray:
    """``groups``: (track, increments per segment, angles, runs). The fits of m replicates."""
    angles, truth = [], []
    for track, n, ang, runs in groups:
        res = drive(track, TRUE, NOMINAL, WHEEL, m * runs, rng, steps_per_segment=n,
                    trajectory=True)  # fmt: skip
        assert res.trajectory is not None
        truth.append(measured(res.trajectory, rng).reshape(m, runs, -1, 3))
        angles.append(ang)
    return fit_trajectory_trials(angles, truth, NOMINAL)


def synthetic(m: int, seed: int) -> None:
    logs = {
        "three 3 m straight runs": [T.straight_line(3.0)] * 3,
        "two runs of two CCW spins": [T.Track("spins", (T.spot_turn(4 * math.pi),))] * 2,
        "a CW and a CCW 1 m square": [T.polygon(4, 1.0, "cw"), T.polygon(4, 1.0, "ccw")],
    }
    keys = ("wheel_diameter_right_m", "wheel_diameter_left_m", "wheelbase_m")
    for i, (name, tracks) in enumerate(logs.items()):
        rng = np.random.default_rng([seed, i])
        made = [recorded(t) for t in tracks]
        recs = [r for r, _, _ in made]
        info = log_information(recs, NOMINAL, noise=NOISE)
        chk = judge(info, recs)
        t0 = time.perf_counter()
        top = find_top_up(info, chk, recs)
        search = time.perf_counter() - t0
        top_track = maneuver_track(top.maneuvers)
        top_rec, top_n = maneuver_recording(top.maneuvers, NOMINAL)
        top_ang = np.column_stack([top_rec.wheel_angle_right_rad, top_rec.wheel_angle_left_rad])
        groups = [(t, n, ang, 1) for t, (_, n, ang) in zip(tracks, made, strict=True)]
        t0 = time.perf_counter()
        fits = simulated_fits([*groups, (top_track, top_n, top_ang, top.runs)], m, rng)
        ok = np.all(np.isfinite(fits), axis=1)
        sd = fits[ok].std(axis=0, ddof=1)
        pred = np.array([top.after[k] for k in keys])
        print(f"\n{name}: {'enough' if chk.ok else 'NOT enough'} "
              f"({', '.join(d.code for d in chk.degeneracies) or 'no flags'}); "
              f"top-up found in {search:.2f} s")  # fmt: skip
        print(f"  {top.sentence()}")
        print(f"  {ok.sum()} of {m} fits in {time.perf_counter() - t0:.1f} s "
              "(um: D_R, D_L, b)")  # fmt: skip
        print("  predicted after:  " + ", ".join(f"{1e6 * v:8.1f}" for v in pred))
        print("  realised sd:      " + ", ".join(f"{1e6 * v:8.1f}" for v in sd))
        print("  realised / pred.: " + ", ".join(f"{v:8.3f}" for v in sd / pred))
        if chk.ok:
            alone = simulated_fits(groups, m, rng)
            sd0 = alone[np.all(np.isfinite(alone), axis=1)].std(axis=0, ddof=1)
            pred0 = np.array([chk.stderr[k] for k in keys])
            print("  log alone: predicted " + ", ".join(f"{1e6 * v:.1f}" for v in pred0)
                  + "; realised " + ", ".join(f"{1e6 * v:.1f}" for v in sd0)
                  + "; ratio " + ", ".join(f"{v:.3f}" for v in sd0 / pred0))  # fmt: skip


def one_long_run(m: int, seed: int) -> None:
    """The same 120 s of figure-eights added to the two squares as one run and as 6 runs of
    20 s: predicted and realised spread of b and D_R (the fit weighs a run by its travel and
    treats its pose samples as independent, so one long random-walk run can make it worse)."""
    from odocal.core.topup_motion import Maneuver

    tracks = [T.polygon(4, 1.0, "cw"), T.polygon(4, 1.0, "ccw")]
    made = [recorded(t) for t in tracks]
    recs = [r for r, _, _ in made]
    info = log_information(recs, NOMINAL, noise=NOISE)
    groups = [(t, n, ang, 1) for t, (_, n, ang) in zip(tracks, made, strict=True)]
    rng = np.random.default_rng([seed, 99])
    alone = simulated_fits(groups, m, rng).std(axis=0, ddof=1)
    p0 = info.stderr()
    print("\nthe two squares + 120 s of figure-eights (0.3 m/s, 1 m circles), um of b (D_R):")
    b0, d0 = 1e6 * p0["wheelbase_m"], 1e6 * p0["wheel_diameter_right_m"]
    print(f"  log alone: predicted {b0:.0f} ({d0:.0f}), "
          f"realised {1e6 * alone[2]:.0f} ({1e6 * alone[0]:.0f})")  # fmt: skip
    for length, runs in ((120.0, 1), (20.0, 6)):
        man = [
            Maneuver("arc", length / 2, speed_m_s=0.3, rate_rad_s=0.3),
            Maneuver("arc", length / 2, speed_m_s=0.3, rate_rad_s=-0.3),
        ]
        rec, n = maneuver_recording(man, NOMINAL)
        extra = log_information([rec], NOMINAL, noise=NOISE).times(runs)
        p = (info + extra).stderr()
        ang = np.column_stack([rec.wheel_angle_right_rad, rec.wheel_angle_left_rad])
        sd = simulated_fits([*groups, (maneuver_track(man), n, ang, runs)], m, rng).std(
            axis=0, ddof=1
        )
        print(f"  + {runs} x {length:.0f} s: predicted {1e6 * p['wheelbase_m']:.0f} "
              f"({1e6 * p['wheel_diameter_right_m']:.0f}), realised {1e6 * sd[2]:.0f} "
              f"({1e6 * sd[0]:.0f})")  # fmt: skip


def real(data: Path) -> None:
    from odocal.app.check import check

    d = data / "ivanjko" / "250620201738"
    if not d.is_dir():
        print(f"\n(no OptiOdom data at {data}: real part skipped)")
        return
    subsets = {
        "Ivanjko straight runs 1-5": range(1, 6),
        "Ivanjko spins 6-10": range(6, 11),
        "the whole data set (runs 1-15)": range(1, 16),
    }
    for name, runs in subsets.items():
        t0 = time.perf_counter()
        res = check([d / f"250620201738_run-{i:02d}.csv" for i in runs])
        assert res.top_up is not None
        print(f"\n{name} ({time.perf_counter() - t0:.1f} s): "
              f"{'enough' if res.check.ok else 'NOT enough'}")  # fmt: skip
        print(f"  {res.top_up.sentence()}")
        print(f"  speeds: {res.top_up.rates.source}")


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--replicates", type=int, default=1000)
    p.add_argument("--seed", type=int, default=1)
    p.add_argument("--data", type=Path, default=Path("../shared/realdata/optiodom_diff"))
    a = p.parse_args()
    synthetic(a.replicates, a.seed)
    one_long_run(a.replicates, a.seed)
    real(a.data)


if __name__ == "__main__":
    main()
