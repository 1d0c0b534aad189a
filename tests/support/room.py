"""A synthetic room of line segments and a simulated 2D lidar that ray-casts into it.

A test helper (tests/support), not part of the package: it tests scan matching and the
calibration routes that use a laser (docs/scan-matching.md). Frames follow docs/conventions.md:
the room's (world) frame has x, y in metres; a sensor pose is (x_m, y_m, theta_rad) of the
sensor in the room frame, heading CCW positive; a ray at angle ``a`` (rad, CCW from the sensor's
+x axis, as in ``sensor_msgs/LaserScan``) points along (cos(theta + a), sin(theta + a)) in the
room frame.

A ray that hits nothing within ``max_range_m`` returns ``inf`` (REP-117's "no return").
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from odocal.core.model import check_nonnegative, check_positive
from odocal.errors import ModelError

__all__ = ["Room", "box_segments", "ray_cast"]

# Work arrays of ray_cast hold at most about this many (pose, ray, wall) triples per chunk.
_MAX_ELEMENTS = 4_000_000


def box_segments(center_xy_m, size_xy_m, yaw_rad: float = 0.0) -> np.ndarray:
    """The four sides of a rectangle as segments, shape (4, 4) rows (x0, y0, x1, y1) in m.

    ``center_xy_m`` is the centre (m), ``size_xy_m`` the side lengths (m) along the box's own
    axes before the rotation by ``yaw_rad`` (rad, CCW) about the centre.
    """
    cx, cy = (float(v) for v in center_xy_m)
    sx, sy = (float(v) for v in size_xy_m)
    check_positive("box size", np.array([sx, sy]))
    half = 0.5 * np.array([[-sx, -sy], [sx, -sy], [sx, sy], [-sx, sy]])
    c, s = math.cos(yaw_rad), math.sin(yaw_rad)
    corners = half @ np.array([[c, s], [-s, c]]) + np.array([cx, cy])
    return np.hstack([corners, np.roll(corners, -1, axis=0)])


@dataclass(frozen=True)
class Room:
    """A 2D world made of line segments (walls, the sides of boxes).

    Attributes
    ----------
    segments_m : ndarray, shape (n, 4)
        One segment per row, (x0, y0, x1, y1) in metres in the room frame (read-only copy).
    name : str
        A label for messages and plots.
    """

    segments_m: np.ndarray
    name: str = "room"

    def __post_init__(self) -> None:
        seg = np.array(self.segments_m, dtype=float)  # a private copy
        if seg.ndim != 2 or seg.shape[1] != 4 or seg.shape[0] < 1:
            raise ModelError(
                f"room segments must have shape (n, 4) rows (x0, y0, x1, y1), got {seg.shape}"
            )
        if not np.all(np.isfinite(seg)):
            raise ModelError("room segments must be finite")
        length = np.hypot(seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1])
        if not np.all(length > 0):
            bad = int(np.flatnonzero(~(length > 0))[0])
            raise ModelError(f"room segment {bad} has zero length: {seg[bad].tolist()}")
        seg.setflags(write=False)
        object.__setattr__(self, "segments_m", seg)

    @classmethod
    def rectangle(
        cls,
        width_m: float,
        depth_m: float,
        boxes: tuple[tuple[tuple[float, float], tuple[float, float], float], ...] = (),
        name: str = "rectangle",
    ) -> Room:
        """Outer walls [0, width_m] x [0, depth_m] (m) plus boxes given as
        ((center_x_m, center_y_m), (size_x_m, size_y_m), yaw_rad)."""
        check_positive("room width", width_m)
        check_positive("room depth", depth_m)
        w, d = float(width_m), float(depth_m)
        walls = np.array([[0, 0, w, 0], [w, 0, w, d], [w, d, 0, d], [0, d, 0, 0]], dtype=float)
        parts = [walls] + [box_segments(c, s, yaw) for c, s, yaw in boxes]
        return cls(np.vstack(parts), name)

    @classmethod
    def default(cls) -> Room:
        """An 8 m x 6 m room with four boxes placed without symmetry, so that every pose sees a
        distinct scan. The free area around (4, 3) m fits tracks of about 2.5 m across."""
        return cls.rectangle(
            8.0,
            6.0,
            boxes=(
                ((1.0, 5.0), (0.8, 0.6), 0.0),
                ((7.0, 1.0), (0.6, 1.0), math.radians(20.0)),
                ((6.9, 5.1), (0.5, 0.5), math.radians(45.0)),
                ((0.9, 0.8), (0.5, 0.3), math.radians(-10.0)),
            ),
            name="default room 8 m x 6 m",
        )

    def distance_to_walls(self, points_xy_m) -> np.ndarray:
        """Shortest distance (m) from each point, shape (n, 2) in the room frame, to any
        segment; shape (n,)."""
        p = np.asarray(points_xy_m, dtype=float).reshape(-1, 2)
        a = self.segments_m[:, :2]
        e = self.segments_m[:, 2:] - a
        rel = p[:, None, :] - a[None, :, :]  # (n, s, 2)
        u = np.clip(np.einsum("nsk,sk->ns", rel, e) / np.einsum("sk,sk->s", e, e), 0.0, 1.0)
        nearest = a[None] + u[..., None] * e[None]
        return np.min(np.hypot(*(p[:, None, :] - nearest).transpose(2, 0, 1)), axis=1)


def _cross(ax, ay, bx, by):
    return ax * by - ay * bx


def ray_cast(
    room: Room,
    sensor_pose_xytheta,
    angles_rad,
    max_range_m: float,
    rng: np.random.Generator | None = None,
    sigma_m: float = 0.0,
) -> np.ndarray:
    """Ranges (m) a 2D lidar at ``sensor_pose_xytheta`` measures in ``room``.

    Parameters
    ----------
    room : Room
    sensor_pose_xytheta : array_like, shape (3,) or (P, 3)
        Sensor pose(s) (x_m, y_m, theta_rad) in the room frame.
    angles_rad : array_like, shape (n,)
        Ray angles (rad) in the sensor frame, CCW from its +x axis.
    max_range_m : float
        Largest range (m) the sensor reports; farther hits and misses give ``inf``.
    rng : numpy.random.Generator, optional
        Needed when ``sigma_m > 0``.
    sigma_m : float
        Standard deviation (m) of independent Gaussian noise added to every finite range.
        Noise never turns a hit into a miss or a negative range: noisy ranges are clipped to
        [0, max_range_m].

    Returns
    -------
    ndarray, shape (n,) or (P, n)
        The nearest hit along each ray (m), or ``inf``.
    """
    pose = np.asarray(sensor_pose_xytheta, dtype=float)
    single = pose.ndim == 1
    pose = np.atleast_2d(pose)
    if pose.ndim != 2 or pose.shape[1] != 3:
        raise ModelError(f"sensor pose must have shape (3,) or (P, 3), got {pose.shape}")
    if not np.all(np.isfinite(pose)):
        raise ModelError("sensor pose must be finite")
    ang = np.asarray(angles_rad, dtype=float).reshape(-1)
    if not np.all(np.isfinite(ang)):
        raise ModelError("ray angles must be finite")
    check_positive("max_range_m", max_range_m)
    check_nonnegative("sigma_m", sigma_m)
    if sigma_m > 0 and rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate range noise")

    seg = room.segments_m
    ax, ay = seg[:, 0], seg[:, 1]
    ex, ey = seg[:, 2] - ax, seg[:, 3] - ay
    n_rays, n_seg = ang.size, seg.shape[0]
    out = np.empty((pose.shape[0], n_rays))
    chunk = max(1, _MAX_ELEMENTS // max(1, n_rays * n_seg))
    for lo in range(0, pose.shape[0], chunk):
        p = pose[lo : lo + chunk]
        world = p[:, 2:3] + ang[None, :]  # (c, n)
        dx, dy = np.cos(world)[..., None], np.sin(world)[..., None]  # (c, n, 1)
        # ray  o + t d, segment  a + u e:  t = (a - o) x e / (d x e),  u = (a - o) x d / (d x e)
        rx = (ax[None, :] - p[:, 0:1])[:, None, :]  # (c, 1, s)
        ry = (ay[None, :] - p[:, 1:2])[:, None, :]
        denom = _cross(dx, dy, ex, ey)  # (c, n, s)
        with np.errstate(divide="ignore", invalid="ignore"):
            t = _cross(rx, ry, ex, ey) / denom
            u = _cross(rx, ry, dx, dy) / denom
        hit = (denom != 0) & (t > 0) & (u >= 0) & (u <= 1)
        out[lo : lo + chunk] = np.min(np.where(hit, t, np.inf), axis=2)
    out[out > max_range_m] = np.inf
    if sigma_m > 0:
        if rng is None:
            raise ModelError("a numpy.random.Generator is needed for range noise")
        finite = np.isfinite(out)
        noisy = out + sigma_m * rng.standard_normal(out.shape)
        out = np.where(finite, np.clip(noisy, 0.0, max_range_m), np.inf)
    return out[0] if single else out
