"""Synthetic relative motions of a robot (for the checks of the relative-motion routes)."""

from __future__ import annotations

import numpy as np

from odocal.calibration.relative_motions import RelativeMotions
from odocal.core.model import WheelGeometry
from odocal.core.odometry import dead_reckon_rows

NOMINAL = WheelGeometry(0.2, 0.2, 0.5)
TRUE = WheelGeometry(0.203, 0.199, 0.52)


def motions(n=300, k=10, noise=(0.002, 0.002, 0.002), seed=0, true=TRUE) -> RelativeMotions:
    """n consecutive 1 s intervals of k wheel samples of mixed motion (the wheels' rotations,
    rad); the base's motion of a robot of geometry ``true`` measured with white noise of
    ``noise`` (m, m, rad)."""
    rng = np.random.default_rng(seed)
    seg = np.repeat(rng.uniform(-1.0, 1.0, size=(n // 5 + 1, 2)), 5, axis=0)[:n]
    base = rng.uniform(0.5, 2.0, size=(n, 1))
    inc_r = np.repeat(base + seg[:, :1], k, axis=1) / k
    inc_l = np.repeat(base + seg[:, 1:], k, axis=1) / k
    motion = dead_reckon_rows(inc_r, inc_l, true)[:, :, -1].T.copy()
    motion += rng.standard_normal(motion.shape) * np.asarray(noise)
    start = np.arange(n, dtype=float)
    return RelativeMotions(
        inc_r.sum(axis=1), inc_l.sum(axis=1), motion, (inc_r, inc_l), start, start + 1.0
    )


def tuple_text(
    n=60, geometry=TRUE, sensor_pose=(0.1, 0.05, 0.3), seed=0, speed_scale=1.0, noise=1e-4
) -> str:
    """A ``.tuple`` file's text (docs/censi.md): n intervals of about 0.8 s of mixed motion of a
    robot of ``geometry`` seen by a sensor at ``sensor_pose``, its wheel speeds (rad/s) times
    ``speed_scale`` (180/pi: written in deg/s)."""
    from odocal.calibration.censi import predict_sensor_motion

    rng = np.random.default_rng(seed)
    t = rng.uniform(0.7, 0.9, n)
    w_r = rng.uniform(-1.0, 2.0, n)
    w_l = rng.uniform(-1.0, 2.0, n)
    sm = predict_sensor_motion(geometry, sensor_pose, w_r * t, w_l * t)
    sm = sm + rng.standard_normal(sm.shape) * noise
    rows = np.column_stack([t, w_l * speed_scale, w_r * speed_scale, sm]).tolist()
    return "".join(
        f'{{"T": {a!r}, "phi_l": {b!r}, "phi_r": {c!r}, "sm": [{x!r}, {y!r}, {z!r}]}}\n'
        for a, b, c, x, y, z in rows
    )
