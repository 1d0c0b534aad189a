"""Accuracy and speed of 2D scan matchers on the synthetic room (run from the repo root).

    .venv/bin/python benchmarks/scan_matchers.py [--pairs 100] [--packages]

Scans: Room.default() of tests/support/room.py, a 360 deg lidar of 720 rays (0.5 deg), 12 m range;
sensor poses drawn in the free middle, displacements up to 0.3 m and 0.3 rad, initial guesses
off by N(0, 5 cm) per axis and N(0, 2 deg) (odometry-like). Two sets: noise-free and 1 cm
Gaussian range noise. Prints, per matcher and set, matches per second, the position and
heading errors and the number of wrong matches (> 1 cm or > 0.3 deg).

odocal's matcher always runs. With --packages, the packaged matchers of docs/scan-matching.md
run too when they are installed (none is a dependency of odocal): small_gicp, open3d, kiss_icp,
point_cloud_registration. 3-D matchers get the scan at z = 0 or "extruded" (three copies at
z = -5, 0, 5 cm, so that walls become planes with horizontal normals).
"""

from __future__ import annotations

import argparse
import math
import platform
import sys
import time
from pathlib import Path

import numpy as np

from odocal.calibration.scan_matching import match_scans, prepare_scan, scan_points

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))  # the tests package
from tests.support.room import Room, ray_cast  # noqa: E402  (a test helper, not in the package)

ROOM = Room.default()
ANGLES = np.linspace(-math.pi, math.pi, 720, endpoint=False)
RANGE_MAX = 12.0


def relative(a, b):
    c, s = math.cos(a[2]), math.sin(a[2])
    dx, dy = b[0] - a[0], b[1] - a[1]
    return np.array([c * dx + s * dy, -s * dx + c * dy, b[2] - a[2]])


def make_pairs(n: int, sigma_m: float, seed: int):
    rng = np.random.default_rng(seed)
    pairs = []
    for _ in range(n):
        a = np.array([rng.uniform(2.5, 5.5), rng.uniform(1.8, 4.2), rng.uniform(-math.pi, math.pi)])
        b = a + np.array([*rng.uniform(-0.3, 0.3, 2), rng.uniform(-0.3, 0.3)])
        ranges = ray_cast(ROOM, np.array([a, b]), ANGLES, RANGE_MAX, rng, sigma_m)
        pa, pb = (scan_points(r, ANGLES[0], ANGLES[1] - ANGLES[0], 0.05, RANGE_MAX) for r in ranges)
        true = relative(a, b)
        guess = true + np.array([*rng.normal(0, 0.05, 2), rng.normal(0, math.radians(2))])
        pairs.append((pa, pb, true, guess))
    return pairs


def matrix(p):
    c, s = math.cos(p[2]), math.sin(p[2])
    t = np.eye(4)
    t[:2, :2] = [[c, -s], [s, c]]
    t[:2, 3] = p[:2]
    return t


def planar(t):
    return np.array([t[0, 3], t[1, 3], math.atan2(t[1, 0], t[0, 0])])


def z0(p):
    return np.column_stack([p, np.zeros(len(p))])


def extrude(p, h=0.05):
    return np.vstack([np.column_stack([p, np.full(len(p), z)]) for z in (-h, 0.0, h)])


def odocal_matcher(a, b, g):
    return match_scans(a, b, g).motion


def package_matchers():
    out = {}
    try:
        import small_gicp

        def sg(kind, lift):
            def run(a, b, g):
                r = small_gicp.align(
                    lift(a), lift(b), matrix(g), registration_type=kind,
                    downsampling_resolution=0.01, max_correspondence_distance=0.3,
                    max_iterations=50, translation_epsilon=1e-6, rotation_epsilon=1e-7,
                )  # fmt: skip
                return planar(r.T_target_source)

            return run

        out["small_gicp ICP, z = 0"] = sg("ICP", z0)
        out["small_gicp GICP, z = 0"] = sg("GICP", z0)
        out["small_gicp PLANE_ICP, extruded"] = sg("PLANE_ICP", extrude)
        out["small_gicp GICP, extruded"] = sg("GICP", extrude)
    except ImportError:
        print("(small_gicp not installed)")
    try:
        import open3d as o3d

        reg = o3d.pipelines.registration

        def o3d_p2p(a, b, g):
            pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(z0(a)))
            pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(z0(b)))
            crit = reg.ICPConvergenceCriteria(1e-9, 1e-9, 100)
            est = reg.TransformationEstimationPointToPoint()
            return planar(
                np.asarray(reg.registration_icp(pb, pa, 0.3, matrix(g), est, crit).transformation)
            )

        def o3d_p2l(a, b, g):
            pa = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(extrude(a)))
            pb = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(extrude(b)))
            pa.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(15))
            crit = reg.ICPConvergenceCriteria(1e-9, 1e-9, 100)
            est = reg.TransformationEstimationPointToPlane(reg.HuberLoss(0.02))
            return planar(
                np.asarray(reg.registration_icp(pb, pa, 0.3, matrix(g), est, crit).transformation)
            )

        out["open3d point-to-point, z = 0"] = o3d_p2p
        out["open3d point-to-plane, extruded"] = o3d_p2l
    except (ImportError, OSError) as exc:
        print(f"(open3d not usable: {exc})")
    try:
        from kiss_icp.mapping import VoxelHashMap
        from kiss_icp.registration import Registration

        def kiss(a, b, g):
            voxels = VoxelHashMap(voxel_size=0.1, max_distance=100.0, max_points_per_voxel=50)
            voxels.add_points(z0(a))
            reg = Registration(
                max_num_iterations=100, convergence_criterion=1e-6, max_num_threads=1
            )
            return planar(reg.align_points_to_map(z0(b), voxels, matrix(g), 0.3, 0.03))

        out["kiss_icp registration, z = 0"] = kiss
    except ImportError:
        print("(kiss_icp not installed)")
    try:
        from point_cloud_registration import PlaneICP

        def pcr(a, b, g):
            r = PlaneICP(max_iter=100, max_dist=0.3, tol=1e-7, k=15)
            r.set_target(extrude(a))
            return planar(r.align(extrude(b), init_T=matrix(g)))

        out["point_cloud_registration PlaneICP, extruded"] = pcr
    except ImportError:
        print("(point_cloud_registration not installed)")
    return out


def evaluate(name, matcher, pairs, tag):
    matcher(*pairs[0][0:2], pairs[0][3])  # warm up (imports, caches)
    errors, failed = [], 0
    t0 = time.perf_counter()
    for pa, pb, true, guess in pairs:
        try:
            errors.append(matcher(pa, pb, guess) - true)
        except Exception as exc:  # noqa: BLE001 (a package failing is a result)
            failed += 1
            print(f"  {name}: {type(exc).__name__}: {str(exc)[:80]}")
    seconds = time.perf_counter() - t0
    e = np.array(errors)
    pos = np.hypot(e[:, 0], e[:, 1])
    wrong = int(np.sum((pos > 0.01) | (np.abs(e[:, 2]) > math.radians(0.3))))
    pos_rms_mm = np.sqrt(np.mean(pos**2)) * 1e3
    heading_rms_deg = math.degrees(np.sqrt(np.mean(e[:, 2] ** 2)))
    print(
        f"{name:45s} {tag:6s} {len(pairs) / seconds:7.0f}/s  position rms {pos_rms_mm:7.4f} mm"
        f"  median {np.median(pos) * 1e3:7.4f} mm  heading rms {heading_rms_deg:.5f} deg"
        f"  wrong {wrong}  failed {failed}"
    )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--pairs", type=int, default=100)
    parser.add_argument("--packages", action="store_true", help="also run installed packages")
    args = parser.parse_args()
    print(f"python {platform.python_version()}, numpy {np.__version__}, {platform.machine()}")
    sets = {"clean": make_pairs(args.pairs, 0.0, 11), "1 cm": make_pairs(args.pairs, 0.01, 11)}
    matchers = {"odocal point-to-line ICP": odocal_matcher}
    if args.packages:
        matchers |= package_matchers()
    for name, matcher in matchers.items():
        for tag, pairs in sets.items():
            evaluate(name, matcher, pairs, tag)
    # the share of the time spent preparing the reference (tree and line fits)
    pairs = sets["1 cm"]
    prepared = [prepare_scan(pa) for pa, *_ in pairs]
    t0 = time.perf_counter()
    for ref, (_, pb, _, guess) in zip(prepared, pairs, strict=True):
        match_scans(ref, pb, guess)
    seconds = time.perf_counter() - t0
    print(f"odocal, reference prepared beforehand: {len(pairs) / seconds:.0f} matches/s")


if __name__ == "__main__":
    main()
