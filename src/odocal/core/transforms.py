"""A tf2-like transform buffer on numpy/scipy, and planar (SE(2)) pose helpers.

A ROS bag holds the robot's frame tree as ``/tf`` (dynamic edges, each a time series of
``geometry_msgs/TransformStamped``) and ``/tf_static`` (constant edges). :class:`TransformBuffer`
stores both and answers "where is frame ``child`` in frame ``parent`` at times ``t``" for any two
connected frames, as tf2's ``lookupTransform`` does:

- every frame has at most one parent (a tree, as in tf2); an edge is stored as
  ``T_parent_child`` = translation (m) + unit quaternion (x, y, z, w), which maps coordinates in
  ``child`` into ``parent`` (= the pose of ``child`` in ``parent``);
- a lookup composes the chain from ``parent`` up to the two frames' common ancestor and down to
  ``child``, inverting the edges it walks upwards, and reports that chain;
- each dynamic edge is interpolated at the query times: translation linearly, rotation by slerp
  (the shorter arc), between the two samples around each time;
- a query before an edge's first sample or after its last one is refused unless it lies within
  ``max_extrapolation_s`` of it, where the nearest sample's value is held (no extrapolation of
  motion); ``max_gap_s`` also refuses interpolation across holes in an edge's data;
- queries are vectorised: ``time_s`` of shape (n,) gives n transforms at once.

Times are float seconds on one clock for all edges. Convert a bag's int nanosecond stamps at the
edge, relative to the bag start (``(stamp_ns - start_ns) * 1e-9``), so that float64 keeps
nanosecond resolution; absolute epoch seconds in float64 resolve only about 0.2 microseconds.

Frame names lose a leading ``/`` (ROS 1 style ``/base_link`` is ``base_link``).

Why not a library: pytransform3d's ``TemporalTransformManager`` is the closest, but it installs
matplotlib and lxml as hard dependencies (odocal's core depends on numpy, scipy and pyyaml only),
interpolates by screw motion (ScLERP) instead of tf2's linear translation + slerp, has no
extrapolation tolerance (it either raises or clips), and neither reports the chain used nor
enforces the one-parent tree. The buffer here is a few hundred lines on
``scipy.spatial.transform``.

Planar helpers (SE(2)), for a robot on the floor: :func:`planar_pose` projects 3D transforms to
(x_m, y_m, yaw_rad); :func:`se2_relative` gives the motion of pose b seen from pose a (in a's
frame); :func:`se2_compose`, :func:`se2_inverse`, :func:`se2_conjugate` (a motion seen from a
frame mounted on the moving body), :func:`wrap_angle`. Frames and signs follow
docs/conventions.md (REP-103: x forward, y left, z up, yaw counter-clockwise positive).

Errors: data problems (unknown frame, disconnected trees, times outside the data, a frame with two
parents, non-finite values) raise :class:`~odocal.errors.InputError`; misuse of the API (wrong
shapes, a negative tolerance) raises :class:`~odocal.errors.ModelError`.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numpy.typing import ArrayLike

from ..errors import InputError, ModelError

if TYPE_CHECKING:
    from scipy.spatial.transform import Rotation


def _rotation() -> type[Rotation]:
    """scipy's Rotation class, imported when first needed (scipy.spatial takes long to import)."""
    from scipy.spatial.transform import Rotation

    return Rotation


__all__ = [
    "RigidTransforms",
    "ChainStep",
    "EdgeInfo",
    "Lookup",
    "TransformBuffer",
    "planar_pose",
    "tilt_rad",
    "wrap_angle",
    "se2_compose",
    "se2_inverse",
    "se2_relative",
    "se2_conjugate",
]


def _readonly(a: np.ndarray) -> np.ndarray:
    a.flags.writeable = False
    return a


# --------------------------------------------------------------------------- rigid transforms


@dataclass(frozen=True, eq=False)
class RigidTransforms:
    """n rigid transforms T_parent_child (3D), e.g. the poses of one frame at n times.

    Attributes
    ----------
    translation_m : ndarray, shape (n, 3)
        Origin of the child frame in the parent frame (m).
    quaternion_xyzw : ndarray, shape (n, 4)
        Unit quaternion (x, y, z, w) rotating child coordinates into the parent frame (ROS and
        scipy order). Normalised on construction.

    ``a @ b`` composes (T_a_b @ T_b_c = T_a_c; n against n, or 1 against n); ``inverse()``;
    ``matrix()`` gives the homogeneous matrices, shape (n, 4, 4).
    """

    translation_m: np.ndarray
    quaternion_xyzw: np.ndarray

    def __post_init__(self) -> None:
        t = np.array(self.translation_m, dtype=float, ndmin=2)
        q = np.array(self.quaternion_xyzw, dtype=float, ndmin=2)
        if t.ndim != 2 or t.shape[1] != 3 or q.ndim != 2 or q.shape[1] != 4 or len(t) != len(q):
            raise ModelError(
                f"rigid transforms need translations of shape (n, 3) and quaternions of shape "
                f"(n, 4), got {np.shape(self.translation_m)} and {np.shape(self.quaternion_xyzw)}"
            )
        bad = ~(np.all(np.isfinite(t), axis=1) & np.all(np.isfinite(q), axis=1))
        if np.any(bad):
            raise InputError(f"transform {int(np.flatnonzero(bad)[0])} is not finite (NaN or inf)")
        norm = np.linalg.norm(q, axis=1)
        if np.any(norm < 1e-9):
            i = int(np.flatnonzero(norm < 1e-9)[0])
            raise InputError(f"transform {i} has a zero quaternion (x, y, z, w all 0)")
        object.__setattr__(self, "translation_m", _readonly(t))
        object.__setattr__(self, "quaternion_xyzw", _readonly(q / norm[:, None]))

    @classmethod
    def _trusted(cls, t: np.ndarray, q: np.ndarray) -> RigidTransforms:
        """Build from arrays already checked and normalised (inner loops)."""
        obj = object.__new__(cls)
        object.__setattr__(obj, "translation_m", _readonly(t))
        object.__setattr__(obj, "quaternion_xyzw", _readonly(q))
        return obj

    @classmethod
    def from_rotation(cls, translation_m: ArrayLike, rotation: Rotation) -> RigidTransforms:
        """From translations (m), shape (n, 3), and a scipy Rotation of n rotations."""
        t = np.array(translation_m, dtype=float, ndmin=2)
        q = np.atleast_2d(rotation.as_quat())
        if len(q) == 1 and len(t) > 1:
            q = np.repeat(q, len(t), axis=0)
        return cls(t, q)

    @classmethod
    def identity(cls, n: int = 1) -> RigidTransforms:
        """n identity transforms."""
        q = np.zeros((n, 4))
        q[:, 3] = 1.0
        return cls._trusted(np.zeros((n, 3)), q)

    @classmethod
    def from_matrix(cls, matrix: ArrayLike) -> RigidTransforms:
        """From homogeneous matrices, shape (n, 4, 4) or (4, 4)."""
        m = np.array(matrix, dtype=float)
        if m.ndim == 2:
            m = m[None]
        if m.ndim != 3 or m.shape[1:] != (4, 4):
            raise ModelError(f"matrices must have shape (n, 4, 4), got {np.shape(matrix)}")
        return cls(m[:, :3, 3], _rotation().from_matrix(m[:, :3, :3]).as_quat())

    def __len__(self) -> int:
        return len(self.translation_m)

    def __getitem__(self, index: int | slice | np.ndarray) -> RigidTransforms:
        t = np.array(self.translation_m[index], ndmin=2)
        q = np.array(self.quaternion_xyzw[index], ndmin=2)
        return RigidTransforms._trusted(t, q)

    @property
    def rotation(self) -> Rotation:
        """The rotations as one scipy ``Rotation`` (n rotations)."""
        # scipy's compiled routines refuse read-only buffers: hand them a copy
        return _rotation().from_quat(np.array(self.quaternion_xyzw))

    def matrix(self) -> np.ndarray:
        """Homogeneous matrices, shape (n, 4, 4)."""
        m = np.zeros((len(self), 4, 4))
        m[:, :3, :3] = self.rotation.as_matrix()
        m[:, :3, 3] = self.translation_m
        m[:, 3, 3] = 1.0
        return m

    def inverse(self) -> RigidTransforms:
        """T_child_parent for every T_parent_child."""
        r_inv = self.rotation.inv()
        return RigidTransforms._trusted(-r_inv.apply(np.array(self.translation_m)), r_inv.as_quat())

    def __matmul__(self, other: RigidTransforms) -> RigidTransforms:
        if not isinstance(other, RigidTransforms):
            return NotImplemented
        n, m = len(self), len(other)
        if n != m and 1 not in (n, m):
            raise ModelError(f"cannot compose {n} transforms with {m} (need equal counts or 1)")
        r_a = self.rotation
        t = self.translation_m + r_a.apply(np.array(other.translation_m))
        return RigidTransforms._trusted(np.atleast_2d(t), (r_a * other.rotation).as_quat())

    def apply(self, points_m: ArrayLike) -> np.ndarray:
        """Child-frame points (m), shape (n, 3) or (3,), expressed in the parent frame."""
        return self.rotation.apply(np.array(points_m, dtype=float)) + self.translation_m


# --------------------------------------------------------------------------- planar helpers


def wrap_angle(angle_rad: ArrayLike) -> np.ndarray:
    """Angles wrapped into [-pi, pi) (rad), same shape."""
    a = np.asarray(angle_rad, dtype=float)
    return (a + math.pi) % (2.0 * math.pi) - math.pi


def planar_pose(transforms: RigidTransforms) -> np.ndarray:
    """Planar poses (x_m, y_m, yaw_rad), shape (n, 3), of 3D transforms T_parent_child.

    x, y: the child origin in the parent frame; z is dropped. yaw: heading of the child's x axis
    projected onto the parent's x-y plane, atan2(R[1, 0], R[0, 0]), in [-pi, pi] (the Z-Y-X
    Euler yaw). This is right for a robot on a floor parallel to the parent's x-y plane; check
    :func:`tilt_rad` when in doubt.
    """
    m = transforms.rotation.as_matrix()
    yaw = np.arctan2(m[:, 1, 0], m[:, 0, 0])
    return np.column_stack([transforms.translation_m[:, :2], yaw])


def tilt_rad(transforms: RigidTransforms) -> np.ndarray:
    """Angle (rad) between the child's z axis and the parent's z axis, shape (n,)."""
    z = transforms.rotation.as_matrix()[:, 2, 2]
    return np.arccos(np.clip(z, -1.0, 1.0))


def _poses(p: ArrayLike, name: str) -> np.ndarray:
    a = np.asarray(p, dtype=float)
    if a.shape[-1:] != (3,) or a.ndim > 2:
        raise ModelError(
            f"{name} must have shape (n, 3) or (3,) (x_m, y_m, yaw_rad), got {a.shape}"
        )
    return a


def se2_compose(a: ArrayLike, b: ArrayLike) -> np.ndarray:
    """a (+) b: pose b, given in frame a, expressed in a's parent. Shapes (n, 3) or (3,)."""
    a, b = _poses(a, "a"), _poses(b, "b")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = a[..., 0] + c * b[..., 0] - s * b[..., 1]
    y = a[..., 1] + s * b[..., 0] + c * b[..., 1]
    return np.stack([x, y, a[..., 2] + b[..., 2]], axis=-1)


def se2_inverse(a: ArrayLike) -> np.ndarray:
    """The inverse pose (the parent's pose seen from a). Shape (n, 3) or (3,)."""
    a = _poses(a, "a")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    x = -c * a[..., 0] - s * a[..., 1]
    y = s * a[..., 0] - c * a[..., 1]
    return np.stack([x, y, -a[..., 2]], axis=-1)


def se2_relative(a: ArrayLike, b: ArrayLike, *, wrap: bool = True) -> np.ndarray:
    """Motion from pose a to pose b seen from a: (dx_m, dy_m, dyaw_rad) = a^-1 (+) b.

    dx, dy: b's position minus a's, rotated into a's frame (dx forward, dy left of a).
    dyaw = yaw_b - yaw_a, wrapped into [-pi, pi) unless ``wrap=False`` (use that when both
    headings are unwrapped and the rotation between them may exceed half a turn).
    Shapes (n, 3) or (3,), broadcast against each other.
    """
    a, b = _poses(a, "a"), _poses(b, "b")
    c, s = np.cos(a[..., 2]), np.sin(a[..., 2])
    dx, dy = b[..., 0] - a[..., 0], b[..., 1] - a[..., 1]
    dyaw = b[..., 2] - a[..., 2]
    return np.stack([c * dx + s * dy, -s * dx + c * dy, wrap_angle(dyaw) if wrap else dyaw], -1)


def se2_conjugate(motion: ArrayLike, frame: ArrayLike) -> np.ndarray:
    """frame^-1 (+) motion (+) frame: ``motion`` of a body seen by a frame mounted on it.

    ``frame`` is the pose of the mounted frame (a sensor, a tracker's marker body) in the body
    frame; ``motion`` a displacement of the body in its own frame at the start (a relative
    motion, or a pose in the body's start frame). The result is the mounted frame's displacement
    in its own frame at the start. Shapes (n, 3) or (3,), broadcast against each other.
    """
    return se2_compose(se2_inverse(frame), se2_compose(motion, frame))


# --------------------------------------------------------------------------- buffer


@dataclass(frozen=True)
class ChainStep:
    """One edge walked by a lookup: from frame ``frm`` to frame ``to``.

    ``inverted``: the stored edge is to -> frm (T_to_frm), walked upwards, so its inverse is
    used. ``static``: the edge comes from ``/tf_static`` (constant).
    """

    frm: str
    to: str
    inverted: bool
    static: bool

    @property
    def edge(self) -> str:
        """The stored edge, 'parent -> child'."""
        return f"{self.to} -> {self.frm}" if self.inverted else f"{self.frm} -> {self.to}"


@dataclass(frozen=True)
class EdgeInfo:
    """What the buffer holds for one stored edge.

    count: samples kept (1 for a static edge); first_s, last_s: their time span (s; NaN for a
    static edge); repeated_stamps: samples dropped because an earlier sample had the same time
    (as tf2, the first one is kept).
    """

    parent: str
    child: str
    static: bool
    count: int
    first_s: float
    last_s: float
    repeated_stamps: int


@dataclass(frozen=True, eq=False)
class Lookup:
    """The transform T_parent_child at n times, and how it was obtained.

    Attributes
    ----------
    parent, child : str
        The frames asked for (pose of ``child`` in ``parent``).
    time_s : ndarray, shape (n,)
        Query times (s).
    transform : RigidTransforms
        n transforms T_parent_child.
    steps : tuple of ChainStep
        The edges composed, from ``parent`` to ``child``.
    """

    parent: str
    child: str
    time_s: np.ndarray
    transform: RigidTransforms
    steps: tuple[ChainStep, ...]

    @property
    def chain(self) -> tuple[str, ...]:
        """Frames walked, from ``parent`` to ``child``."""
        return (self.parent, *(s.to for s in self.steps))

    def describe(self) -> str:
        """The chain as text: 'map -> odom -> base_link (dynamic: map -> odom, odom -> base_link)'
        names the frames walked and the edges interpolated in time."""
        dyn = [s.edge for s in self.steps if not s.static]
        path = " -> ".join(self.chain)
        return f"{path} (dynamic: {', '.join(dyn)})" if dyn else f"{path} (all static)"

    def planar(self) -> np.ndarray:
        """Planar poses (x_m, y_m, yaw_rad) of ``child`` in ``parent``, shape (n, 3)."""
        return planar_pose(self.transform)


class _Edge:
    """Samples of one stored edge; sorted and de-duplicated lazily."""

    def __init__(self, static: bool) -> None:
        self.static = static
        self._parts: list[tuple[np.ndarray, np.ndarray, np.ndarray]] = []
        self.time_s = np.zeros(0)
        self.translation_m = np.zeros((0, 3))
        self.rotation: Rotation | None = None
        self.quaternion_xyzw = np.zeros((0, 4))
        self.repeated = 0
        self._dirty = False

    def add(self, t: np.ndarray, tr: np.ndarray, q: np.ndarray) -> None:
        if self.static:
            self._parts = [(t, tr, q)]  # the latest static value wins, as in tf2
        else:
            self._parts.append((t, tr, q))
        self._dirty = True

    def finish(self) -> None:
        if not self._dirty:
            return
        t = np.concatenate([p[0] for p in self._parts])
        tr = np.concatenate([p[1] for p in self._parts])
        q = np.concatenate([p[2] for p in self._parts])
        order = np.argsort(t, kind="stable")
        t, tr, q = t[order], tr[order], q[order]
        keep = np.r_[True, np.diff(t) > 0]  # equal stamps: keep the first, as tf2 does
        self.repeated = int((~keep).sum())
        self.time_s, self.translation_m, self.quaternion_xyzw = t[keep], tr[keep], q[keep]
        self.rotation = _rotation().from_quat(self.quaternion_xyzw)
        self._dirty = False

    def at(
        self, time_s: np.ndarray, tol: float, max_gap: float | None, name: str, query: str
    ) -> tuple[np.ndarray, Rotation]:
        """Translations (n, 3) and Rotation (n) at ``time_s``; InputError outside the data."""
        self.finish()
        rot = self.rotation
        assert rot is not None  # set by finish()
        n = len(time_s)
        if self.static:
            return np.repeat(self.translation_m, n, axis=0), rot[np.zeros(n, dtype=int)]
        t = self.time_s
        lo, hi = t[0] - tol, t[-1] + tol
        out = (time_s < lo) | (time_s > hi)
        if np.any(out):
            first = int(np.flatnonzero(out)[0])
            raise InputError(
                f"cannot look up '{query}' at t = {time_s[first]:.6f} s: edge '{name}' has data "
                f"from {t[0]:.6f} to {t[-1]:.6f} s (tolerance {tol:g} s); {int(out.sum())} of {n} "
                "query times are outside"
            )
        if len(t) == 1:
            return np.repeat(self.translation_m, n, axis=0), rot[np.zeros(n, dtype=int)]
        i = np.clip(np.searchsorted(t, time_s, side="right") - 1, 0, len(t) - 2)
        w = np.clip((time_s - t[i]) / (t[i + 1] - t[i]), 0.0, 1.0)  # hold beyond the ends
        if max_gap is not None:
            gap = t[i + 1] - t[i]
            inside = (time_s > t[i]) & (time_s < t[i + 1])
            bad = inside & (gap > max_gap)
            if np.any(bad):
                k = int(np.flatnonzero(bad)[0])
                raise InputError(
                    f"cannot look up '{query}' at t = {time_s[k]:.6f} s: edge '{name}' has no "
                    f"data between {t[i[k]]:.6f} and {t[i[k] + 1]:.6f} s (a gap of "
                    f"{gap[k]:.3f} s, more than max_gap_s = {max_gap:g} s)"
                )
        tr = (1.0 - w)[:, None] * self.translation_m[i] + w[:, None] * self.translation_m[i + 1]
        r0 = rot[i]
        delta = (r0.inv() * rot[i + 1]).as_rotvec()  # angle <= pi: the shorter arc
        return tr, r0 * _rotation().from_rotvec(w[:, None] * delta)


def _frame(name: str, what: str) -> str:
    if not isinstance(name, str):
        raise ModelError(f"{what} frame must be a string, got {name!r}")
    f = name.strip().lstrip("/")
    if not f:
        raise InputError(f"empty {what} frame name")
    return f


def _listing(frames: Sequence[str], limit: int = 12) -> str:
    names = sorted(frames)
    more = f", ... ({len(names) - limit} more)" if len(names) > limit else ""
    return ", ".join(names[:limit]) + more


class TransformBuffer:
    """Time series of transforms on a frame tree, with tf2-style lookups (module docstring).

    Parameters
    ----------
    max_extrapolation_s : float
        Default tolerance (s, >= 0) for queries before the first or after the last sample of a
        dynamic edge; within it the nearest sample is held. 0 (default) refuses any query
        outside an edge's data, as tf2 does.
    """

    def __init__(self, max_extrapolation_s: float = 0.0) -> None:
        self.max_extrapolation_s = _tolerance(max_extrapolation_s, "max_extrapolation_s")
        self._edges: dict[tuple[str, str], _Edge] = {}
        self._parent: dict[str, str] = {}

    # ----------------------------------------------------------------- filling

    def _edge(self, parent: str, child: str, static: bool) -> _Edge:
        p, c = _frame(parent, "parent"), _frame(child, "child")
        if p == c:
            raise InputError(f"transform from frame '{p}' to itself")
        known = self._parent.get(c)
        if known is not None and known != p:
            raise InputError(
                f"frame '{c}' has two parents, '{known}' and '{p}'; a tf tree gives each frame one "
                "parent (two publishers disagree about it)"
            )
        edge = self._edges.get((p, c))
        if edge is None:
            if self._ancestor_is(p, c):  # the child is already above the new parent
                raise InputError(f"edge '{p} -> {c}' would close a loop in the frame tree")
            edge = _Edge(static)
            self._edges[(p, c)] = edge
            self._parent[c] = p
        elif edge.static != static:
            kinds = ("static", "dynamic") if edge.static else ("dynamic", "static")
            raise InputError(f"edge '{p} -> {c}' is published both as {kinds[0]} and {kinds[1]}")
        return edge

    def _ancestor_is(self, frame: str, candidate: str) -> bool:
        f = frame
        while f in self._parent:
            f = self._parent[f]
            if f == candidate:
                return True
        return False

    def add(
        self,
        parent: str,
        child: str,
        time_s: ArrayLike,
        translation_m: ArrayLike,
        quaternion_xyzw: ArrayLike,
    ) -> None:
        """Add samples of the dynamic edge T_parent_child.

        time_s : float or ndarray, shape (k,) -- sample times (s), any order.
        translation_m : ndarray, shape (k, 3) or (3,) -- child origin in parent (m).
        quaternion_xyzw : ndarray, shape (k, 4) or (4,) -- rotation child -> parent (normalised).
        Samples with the same time as an earlier one are dropped (tf2 keeps the first).
        """
        t = np.atleast_1d(np.asarray(time_s, dtype=float))
        if t.ndim != 1:
            raise ModelError(f"time_s must have shape (k,), got {np.shape(time_s)}")
        tr = RigidTransforms(np.asarray(translation_m, float), np.asarray(quaternion_xyzw, float))
        if len(tr) != len(t):
            raise ModelError(f"{len(t)} times for {len(tr)} transforms")
        if not np.all(np.isfinite(t)):
            raise InputError(f"edge '{parent} -> {child}': a sample time is not finite")
        if len(t):
            self._edge(parent, child, False).add(t, tr.translation_m, tr.quaternion_xyzw)

    def add_static(
        self, parent: str, child: str, translation_m: ArrayLike, quaternion_xyzw: ArrayLike
    ) -> None:
        """Add the constant edge T_parent_child (``/tf_static``); a later value replaces it."""
        tr = RigidTransforms(np.asarray(translation_m, float), np.asarray(quaternion_xyzw, float))
        if len(tr) != 1:
            raise ModelError(f"a static edge is one transform, got {len(tr)}")
        self._edge(parent, child, True).add(np.zeros(1), tr.translation_m, tr.quaternion_xyzw)

    # ----------------------------------------------------------------- inspecting

    @property
    def frames(self) -> tuple[str, ...]:
        """Every frame that appears in an edge, sorted."""
        names = set(self._parent) | set(self._parent.values())
        return tuple(sorted(names))

    def parent_of(self, frame: str) -> str | None:
        """The parent of ``frame`` in the tree, or None for a root."""
        f = _frame(frame, "the")
        self._check_known(f)
        return self._parent.get(f)

    def edges(self) -> tuple[EdgeInfo, ...]:
        """What is stored, one entry per edge, sorted by (parent, child)."""
        out = []
        for (p, c), e in sorted(self._edges.items()):
            e.finish()
            first = math.nan if e.static else float(e.time_s[0])
            last = math.nan if e.static else float(e.time_s[-1])
            out.append(EdgeInfo(p, c, e.static, len(e.time_s), first, last, e.repeated))
        return tuple(out)

    def samples(self, parent: str, child: str) -> tuple[np.ndarray, RigidTransforms]:
        """The stored samples of edge T_parent_child as published: times (s), shape (k,), and
        k transforms (sorted by time, repeated stamps removed). InputError if not stored."""
        p, c = _frame(parent, "parent"), _frame(child, "child")
        e = self._edges.get((p, c))
        if e is None:
            for f in (p, c):
                self._check_known(f)
            raise InputError(
                f"no stored edge '{p} -> {c}'; edges: "
                + ", ".join(f"{a} -> {b}" for a, b in sorted(self._edges))
            )
        e.finish()
        t = e.time_s.copy()
        return _readonly(t), RigidTransforms._trusted(
            e.translation_m.copy(), e.quaternion_xyzw.copy()
        )

    def _check_known(self, frame: str) -> None:
        if frame not in self._parent and frame not in self._parent.values():
            have = self.frames
            listing = f"frames: {_listing(have)}" if have else "the buffer holds no transforms"
            raise InputError(f"no frame '{frame}' in the transforms; {listing}")

    def _root_path(self, frame: str) -> list[str]:
        path = [frame]
        while path[-1] in self._parent:
            path.append(self._parent[path[-1]])
        return path

    def _tree(self, root: str) -> list[str]:
        return [f for f in self.frames if self._root_path(f)[-1] == root]

    def chain(self, parent: str, child: str) -> tuple[ChainStep, ...]:
        """The edges a lookup of T_parent_child walks, from ``parent`` to ``child``.

        InputError for an unknown frame (lists the known ones) or frames in different trees
        (names both trees by their root and frames).
        """
        p, c = _frame(parent, "parent"), _frame(child, "child")
        for f in (p, c):
            self._check_known(f)
        up, down = self._root_path(p), self._root_path(c)
        if up[-1] != down[-1]:
            t1, t2 = self._tree(up[-1]), self._tree(down[-1])
            raise InputError(
                f"frames '{p}' and '{c}' are not connected: '{p}' is in the tree of '{up[-1]}' "
                f"({_listing(t1, 8)}), '{c}' in the tree of '{down[-1]}' ({_listing(t2, 8)})"
            )
        common = next(f for f in up if f in set(down))
        steps: list[ChainStep] = []
        for f in up[: up.index(common)]:  # upwards: stored edge parent(f) -> f, inverted
            steps.append(
                ChainStep(f, self._parent[f], True, self._edges[(self._parent[f], f)].static)
            )
        downward = down[: down.index(common)][::-1]
        for f in downward:
            steps.append(
                ChainStep(self._parent[f], f, False, self._edges[(self._parent[f], f)].static)
            )
        return tuple(steps)

    # ----------------------------------------------------------------- lookups

    def lookup(
        self,
        parent: str,
        child: str,
        time_s: ArrayLike,
        *,
        max_extrapolation_s: float | None = None,
        max_gap_s: float | None = None,
    ) -> Lookup:
        """T_parent_child (pose of ``child`` in ``parent``) at ``time_s`` (s), shape (n,) or scalar.

        ``parent`` and ``child`` are any two connected frames (the direction asked for, not
        necessarily the tree's). ``max_extrapolation_s`` overrides the buffer's tolerance for
        queries beyond a dynamic edge's data; ``max_gap_s`` (s, default None: no limit) refuses
        interpolation between two samples of an edge further apart than that.
        """
        tol = self.max_extrapolation_s
        if max_extrapolation_s is not None:
            tol = _tolerance(max_extrapolation_s, "max_extrapolation_s")
        if max_gap_s is not None:
            max_gap_s = _tolerance(max_gap_s, "max_gap_s")
        t = np.atleast_1d(np.asarray(time_s, dtype=float))
        if t.ndim != 1:
            raise ModelError(f"time_s must be a scalar or shape (n,), got {np.shape(time_s)}")
        if not np.all(np.isfinite(t)):
            raise InputError("a query time is not finite")
        steps = self.chain(parent, child)
        p, c = _frame(parent, "parent"), _frame(child, "child")
        n = len(t)
        if n == 0:
            raise ModelError("no query times")
        trans = np.zeros((n, 3))
        rot = _rotation().identity(n)
        for s in steps:
            key = (s.to, s.frm) if s.inverted else (s.frm, s.to)
            tr_e, r_e = self._edges[key].at(
                t, tol, max_gap_s, f"{key[0]} -> {key[1]}", f"{p} -> {c}"
            )
            if s.inverted:
                r_e = r_e.inv()
                tr_e = -r_e.apply(tr_e)
            trans = trans + rot.apply(tr_e)
            rot = rot * r_e
        q = rot.as_quat().reshape(n, 4)
        return Lookup(p, c, _readonly(t.copy()), RigidTransforms._trusted(trans, q), steps)


def _tolerance(value: float, name: str) -> float:
    v = float(value)
    if not (math.isfinite(v) and v >= 0.0):
        raise ModelError(f"{name} must be a finite number >= 0 (s), got {value!r}")
    return v
