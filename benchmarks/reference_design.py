"""The reference the design's speed is measured against: the same Monte-Carlo work as
``odocal design`` (heading method), written as a plain numpy loop over candidates and trials.

Written from the model (shared/mission/model.md, docs/design.md), not from odocal's simulator:
for every candidate side length and every trial it drives the n CW and n CCW test runs
(vectorised over the runs and the increments of one segment, as a numpy user would write it),
calibrates with the heading method, and drives the validation square once with the calibrated
parameters. The increments are those of the design's default setting: one exact increment per
segment for the heading-method test runs (their final heading does not depend on the
increments), ten exact-arc increments per segment for the validation runs.

``bench_speed.py`` times it on a few trials per candidate (the work is linear in the trials)
and checks that its post-calibration errors agree with the design's within the sampling error.
"""

from __future__ import annotations

import math

import numpy as np


def drive(segments, f_r, f_l, b_true, b_hat, k_r, k_l, runs, steps, rng):
    """Final true poses (runs, 3) of ``runs`` drives of ``segments`` [(distance_m, angle_rad)]
    (straight if angle 0, spot turn if distance 0), ``steps`` exact-arc increments each."""
    pose = np.zeros((runs, 3))
    for dist, ang in segments:
        s_hat_r = dist + 0.5 * b_hat * ang
        s_hat_l = dist - 0.5 * b_hat * ang
        dr = np.full((runs, steps), f_r * s_hat_r / steps)
        dl = np.full((runs, steps), f_l * s_hat_l / steps)
        dr = dr + np.sqrt(k_r * np.abs(dr)) * rng.standard_normal((runs, steps))
        dl = dl + np.sqrt(k_l * np.abs(dl)) * rng.standard_normal((runs, steps))
        ds = 0.5 * (dr + dl)
        dth = (dr - dl) / b_true
        after = pose[:, 2:3] + np.cumsum(dth, axis=1)
        mid = after - 0.5 * dth
        ds = ds * np.sinc(dth / (2 * math.pi))
        pose[:, 0] += np.sum(ds * np.cos(mid), axis=1)
        pose[:, 1] += np.sum(ds * np.sin(mid), axis=1)
        pose[:, 2] = after[:, -1]
    return pose


def polygon(sides: int, side_m: float, direction: str):
    turn = (2 * math.pi / sides) * (1 if direction == "ccw" else -1)
    out = []
    for _ in range(sides):
        out += [(side_m, 0.0), (0.0, turn)]
    return out


def circular_mean(a):
    d = a - a[0]
    return a[0] + math.atan2(np.mean(np.sin(d)), np.mean(np.cos(d)))


def design_loop(robot, side_lengths_m, trials: int, runs_per_direction: int = 5, seed: int = 0):
    """Post-calibration validation errors (m), shape (candidates, trials), of the heading
    method on the 4 m CCW validation square; one Python iteration per (candidate, trial)."""
    rng = np.random.default_rng(seed)
    true, bel = robot.true_geometry, robot.believed_geometry
    f_r = true.diameter_right_m / bel.diameter_right_m
    f_l = true.diameter_left_m / bel.diameter_left_m
    b_true, b_hat = true.wheelbase_m, bel.wheelbase_m
    k_r, k_l = robot.nonsystematic.k_r_m, robot.nonsystematic.k_l_m
    m = robot.measurement
    validation = polygon(4, 4.0, "ccw")
    out = np.empty((len(side_lengths_m), trials))
    for c, side in enumerate(side_lengths_m):
        cw, ccw = polygon(4, side, "cw"), polygon(4, side, "ccw")
        # the odometric (commanded) final heading of a closed polygon: -2 pi (CW), +2 pi (CCW)
        for t in range(trials):
            heading = []
            for track, target in ((cw, -2 * math.pi), (ccw, 2 * math.pi)):
                final = drive(track, f_r, f_l, b_true, b_hat, k_r, k_l, runs_per_direction, 1, rng)
                err = final[:, 2] - target
                if m.sigma_theta_rad > 0:
                    err = err + m.sigma_theta_rad * rng.standard_normal(runs_per_direction)
                heading.append(circular_mean(err))
            alpha = (heading[0] - heading[1]) / 8
            beta = (heading[0] + heading[1]) / 8
            E_b = (math.pi / 2) / (math.pi / 2 - alpha)
            q = beta * E_b * b_hat / (2 * side)
            E_d = (1 + q) / (1 - q)
            c_r, c_l = 2 * E_d / (E_d + 1), 2 / (E_d + 1)
            d_r, d_l, b = bel.diameter_right_m * c_r, bel.diameter_left_m * c_l, b_hat * E_b
            final = drive(
                validation,
                true.diameter_right_m / d_r,
                true.diameter_left_m / d_l,
                b_true,
                b,
                k_r,
                k_l,
                1,
                10,
                rng,
            )
            out[c, t] = math.hypot(final[0, 0], final[0, 1])
    return out
