"""Monte-Carlo execution of a track (model.md, "Executing a track").

The robot drives each segment open loop on its encoders: it turns the segment into wheel
rotations with the parameters it BELIEVES; the true wheel travel is that rotation times the TRUE
radius, plus Gaussian noise of variance k |ds| per increment; the true pose follows the midpoint
update (Siegwart eq. 5.6) over increments of at most ``max_step_m`` of wheel travel.

Everything is vectorised over a batch of runs and, within a segment, over its increments
(through cumulative sums), so there is no Python loop per increment. Geometry values and segment
values may be arrays of shape (runs,): one robot or one track size per run.

Random streams and workers: the runs are cut into blocks of about 2^18 run-increments, fixed by
the problem alone (runs and increments, never by the machine). Each block draws its wheel noise
from its own stream, seeded from two 63-bit integers drawn from the caller's generator and the
block's number; within a block, segment by segment and a few runs at a time (passes of about
2^14 run-increments), the right wheel's normals are drawn before the left wheel's. The blocks
run on as many workers as the process may use (``ODOCAL_THREADS`` to choose; see
:mod:`odocal.core.parallel`): forked worker processes writing into shared memory for large work
(2^22 run-increments and more), threads below. The same seed gives the same runs on any number
of cores.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .model import ModelError, NonSystematicError, Robot, WheelGeometry
from .parallel import can_fork, run_tasks, shared_zeros
from .parallel import workers as parallel_workers
from .pose import compose
from .tracks import Segment, Track

__all__ = [
    "SimulationResult",
    "simulate",
    "drive",
    "odometric_pose",
    "final_headings",
    "measure",
    "measure_track",
    "commanded_wheel_angles",
    "increments_per_segment",
]


@dataclass(frozen=True)
class SimulationResult:
    """Outcome of ``runs`` simulated runs of one track.

    Attributes
    ----------
    true_final : ndarray, shape (runs, 3)
        True final pose (x_m, y_m, theta_rad) in the start frame; theta unwrapped.
    odometric_final : ndarray, shape (3,) or (runs, 3)
        The pose the robot believes it reached (the commanded one).
    trajectory : ndarray, shape (runs, K + 1, 3) or None
        True pose after every increment, starting with the start pose (only on request).
    """

    true_final: np.ndarray
    odometric_final: np.ndarray
    trajectory: np.ndarray | None = None

    @property
    def errors(self) -> np.ndarray:
        """Final pose error, actual - odometric, shape (runs, 3) (x_m, y_m, theta_rad)."""
        return self.true_final - self.odometric_final


def odometric_pose(track: Track) -> np.ndarray:
    """The believed (commanded) final pose of ``track`` from the origin, shape (3,) or (runs, 3)
    when segment values are arrays."""
    values = [(seg.distance_m, seg.angle_rad) for seg in track.segments]
    if all(np.ndim(d) == 0 and np.ndim(a) == 0 for d, a in values):
        # one pose for the track, remembered (the design drives one track many times over)
        return _odometric_pose_of(tuple((float(d), float(a)) for d, a in values)).copy()
    pose = np.zeros(3)
    for d, a in values:
        pose = compose(pose, d, a)
    return pose


@functools.lru_cache(maxsize=256)
def _odometric_pose_of(values: tuple[tuple[float, float], ...]) -> np.ndarray:
    """:func:`odometric_pose` of the segments (distance m, angle rad), all scalars."""
    pose = np.zeros(3)
    for d, a in values:
        pose = compose(pose, d, a)
    return pose


# Bounds on the work of one simulation call, so that absurd lengths, steps or run counts are a
# clear error instead of a memory blow-up: increments per segment (1e6 = 10 km at the default
# 1 cm), and runs x increments over the whole track (about a minute of numpy work at the most).
MAX_STEPS_PER_SEGMENT = 1_000_000
MAX_RUN_INCREMENTS = 2_000_000_000


def increments_per_segment(
    s_r: float | np.ndarray,
    s_l: float | np.ndarray,
    max_step_m: float | None,
    steps_per_segment: int | None = None,
) -> int:
    """Increments a segment of wheel travel ``s_r``, ``s_l`` (m; scalars or arrays) is split into:
    ``steps_per_segment`` if given, else enough that no increment exceeds ``max_step_m`` (m)."""
    if steps_per_segment is not None:
        return int(steps_per_segment)
    if max_step_m is None or not max_step_m > 0:
        raise ModelError(f"max_step_m must be > 0, got {max_step_m!r}")
    longest = float(np.max(np.maximum(np.abs(s_r), np.abs(s_l))))
    ratio = longest / max_step_m
    if not ratio <= MAX_STEPS_PER_SEGMENT:  # also catches inf/NaN (an absurd length or step)
        raise ModelError(
            f"a segment of {longest:.3g} m of wheel travel in increments of at most "
            f"{max_step_m:.3g} m needs more than {MAX_STEPS_PER_SEGMENT} increments: "
            "use a shorter track or a larger maximum step"
        )
    return max(1, math.ceil(ratio - 1e-9))


def drive(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    runs: int,
    rng: np.random.Generator | None,
    *,
    max_step_m: float | None = 0.01,
    steps_per_segment: int | None = None,
    integration: str = "midpoint",
    trajectory: bool | Sequence[int] | np.ndarray = False,
) -> SimulationResult:
    """Drive ``track`` ``runs`` times open loop; see the module docstring.

    Parameters
    ----------
    true, believed : WheelGeometry
        True and believed geometry; values are scalars or arrays of shape (runs,).
    noise : NonSystematicError
        Wheel-travel noise (k in metres). Zero noise needs no ``rng``.
    runs : int
    rng : numpy.random.Generator or None
        Source of the noise (see the module docstring: it seeds one stream per block of runs).
    max_step_m : float
        Largest wheel travel (m) of one increment (default 1 cm, model.md).
    steps_per_segment : int, optional
        Fixed number of increments per segment (overrides ``max_step_m``).
    integration : {'midpoint', 'exact'}
        'midpoint' is eq. (8); 'exact' integrates each increment as an exact arc, which makes the
        deterministic part exact at any step size (used for fast design sweeps).
    trajectory : bool or sequence of int
        True: also return the pose after every increment (memory: runs x increments x 3
        doubles); a sorted sequence of increment counts (0 = the start, K = the end): the poses
        after those increments only.
    """
    options = (max_step_m, steps_per_segment, integration)
    pose, traj = _simulate(track, true, believed, noise, runs, rng, options, trajectory, False)
    return SimulationResult(pose, odometric_pose(track), traj)


def final_headings(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    runs: int,
    rng: np.random.Generator | None,
    *,
    max_step_m: float | None = 0.01,
    steps_per_segment: int | None = None,
    integration: str = "midpoint",
) -> np.ndarray:
    """The true final headings (rad, unwrapped), shape (runs,), of the drives :func:`drive`
    makes with the same arguments: the same random draws and the same sums, without the
    positions (what the heading-error method reads, at a fraction of the work)."""
    options = (max_step_m, steps_per_segment, integration)
    return _simulate(track, true, believed, noise, runs, rng, options, False, True)[0]


def _simulate(
    track: Track,
    true: WheelGeometry,
    believed: WheelGeometry,
    noise: NonSystematicError,
    runs: int,
    rng: np.random.Generator | None,
    options: tuple[float | None, int | None, str],
    trajectory: bool | Sequence[int] | np.ndarray,
    heading_only: bool,
) -> tuple[np.ndarray, np.ndarray | None]:
    """The true final poses (runs, 3) and the trajectory (or None) of :func:`drive`; with
    ``heading_only``, the final headings (runs,) of :func:`final_headings`."""
    max_step_m, steps_per_segment, integration = options
    if runs < 1:
        raise ModelError(f"runs must be >= 1, got {runs}")
    if integration not in ("midpoint", "exact"):
        raise ModelError(f"integration must be 'midpoint' or 'exact', got {integration!r}")
    if steps_per_segment is None and not (max_step_m and max_step_m > 0):
        raise ModelError(f"max_step_m must be > 0, got {max_step_m!r}")
    if not noise.is_zero and rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate noise")

    if runs * len(track.segments) > MAX_RUN_INCREMENTS:  # every segment takes >= 1 increment
        raise ModelError(
            f"{runs} runs is too much work (at most {MAX_RUN_INCREMENTS:.0e} increments in one "
            "simulation): use fewer runs"
        )

    def value(v: float | np.ndarray) -> np.ndarray:
        """``v`` as it is (one value, or one per run), once checked against the batch: the
        arithmetic below runs on the distinct values only and is broadcast after."""
        a = np.asarray(v, dtype=float)
        if a.ndim > 1 or (a.ndim == 1 and a.shape[0] not in (1, runs)):
            raise ValueError(f"a value of shape {a.shape} cannot be one per run of {runs} runs")
        if a.ndim == 1 and a.shape[0] > 1:
            # the same value for every run (bit for bit; e.g. one track size repeated): one
            # value, so that the arithmetic on it is done once
            bits = a.view(np.int64)
            if bits[0] == bits[-1] and bool(np.all(bits == bits[0])):
                return a[:1]
        return a

    # per-wheel travel factor true/believed and true wheelbase, shape (runs,)
    f_r = value(true.diameter_right_m / believed.diameter_right_m)
    f_l = value(true.diameter_left_m / believed.diameter_left_m)
    b_true = _rows(value(true.wheelbase_m), runs)
    b_hat = value(believed.wheelbase_m)

    # each segment's values (one, or one per run) and increments; its wheel travel is computed
    # block by block (arrays of all the runs would cost more in fresh memory than in arithmetic)
    segments = []
    for seg in track.segments:
        d, a = value(seg.distance_m), value(seg.angle_rad)
        n = steps_per_segment
        if n is None:
            s_hat_r, s_hat_l = Segment(d, a).wheel_travel(b_hat)
            n = increments_per_segment(s_hat_r * f_r, s_hat_l * f_l, max_step_m)
        segments.append((d, a, int(n)))
    total = sum(n for _, _, n in segments)
    if runs * total > MAX_RUN_INCREMENTS:
        raise ModelError(
            f"{runs} runs x {total} increments is too much work (at most "
            f"{MAX_RUN_INCREMENTS:.0e} increments in one simulation): use fewer runs, a shorter "
            "track or a larger maximum step"
        )
    record = _recorded(trajectory, total)
    # blocks of runs, each with its own random stream: fixed by the problem alone, so the result
    # is the same however many workers run them
    rows = max(1, _BLOCK_INCREMENTS // total)
    blocks = [(lo, min(runs, lo + rows)) for lo in range(0, runs, rows)]
    keys = None if noise.is_zero or rng is None else rng.integers(0, 2**63, size=2)
    workers = min(len(blocks), parallel_workers())
    # large work on worker processes (numpy's many short calls would hold threads back on
    # Python's lock), writing into shared memory; smaller work on threads
    processes = workers > 1 and can_fork() and runs * total >= _PROCESS_INCREMENTS
    zeros = shared_zeros if processes else np.zeros
    pose = zeros((runs,) if heading_only else (runs, 3))
    traj = None if record is None else zeros((runs, len(record), 3))

    def travel(lo: int, hi: int) -> list[tuple[np.ndarray, np.ndarray, int]]:
        """The true wheel travel (m) over each segment of runs lo..hi-1, and its increments."""

        def cut(v: np.ndarray) -> np.ndarray:
            return v[lo:hi] if v.ndim and v.shape[0] == runs else v

        out = []
        for d, a, n in segments:
            s_hat_r, s_hat_l = Segment(cut(d), cut(a)).wheel_travel(cut(b_hat))
            s_r = np.asarray(s_hat_r * cut(f_r), dtype=float)
            s_l = np.asarray(s_hat_l * cut(f_l), dtype=float)
            out.append((_rows(s_r, hi - lo), _rows(s_l, hi - lo), n))
        return out

    def run_block(i: int) -> None:
        lo, hi = blocks[i]
        stream = None
        if keys is not None and rng is not None:
            seed = np.random.SeedSequence([int(keys[0]), int(keys[1]), i])
            stream = np.random.Generator(type(rng.bit_generator)(seed))
        _drive_block(
            travel(lo, hi),
            b_true[lo:hi],
            noise,
            stream,
            integration == "exact",
            pose[lo:hi],
            record,
            None if traj is None else traj[lo:hi],
            heading_only,
        )

    def run_group(group: Iterable[int]) -> None:
        for i in group:
            run_block(i)

    if processes:
        # no more processes than the work pays for (a fork costs about 10 ms)
        procs = min(workers, runs * total // max(1, _PROCESS_INCREMENTS // 2))
        groups = np.array_split(np.arange(len(blocks)), procs)
        run_tasks([functools.partial(run_group, g) for g in groups], procs, share=True)
    elif workers > 1:
        from concurrent.futures import ThreadPoolExecutor

        with ThreadPoolExecutor(workers) as pool:
            list(pool.map(run_block, range(len(blocks))))
    else:
        run_group(range(len(blocks)))
    return pose, traj


# Work of one block of runs (runs x increments) with its own random stream; and the elements of
# one numpy pass (small enough to stay in the cache). Both fixed: they decide the random stream.
_BLOCK_INCREMENTS = 1 << 18
# Work (runs x increments) from which the blocks run on worker processes rather than threads;
# each process gets at least half of it.
_PROCESS_INCREMENTS = 1 << 22
_CHUNK = 1 << 14


def _recorded(trajectory: bool | Sequence[int] | np.ndarray, total: int) -> np.ndarray | None:
    """The increment counts whose poses are recorded (0 .. total), or None."""
    if trajectory is True:
        return np.arange(total + 1)
    if trajectory is False or trajectory is None:
        return None
    idx = np.asarray(trajectory, dtype=int).ravel()
    if idx.size == 0 or np.any(np.diff(idx) <= 0) or idx[0] < 0 or idx[-1] > total:
        raise ModelError(
            f"trajectory samples must be increasing increment counts within 0..{total}"
        )
    return idx


# Taylor coefficients of cos x, sin(x)/x in powers of x^2: 1/(2k)! and 1/(2k+1)! with signs.
_COS = np.array([(-1) ** k / math.factorial(2 * k) for k in range(10)])
_SINC = np.array([(-1) ** k / math.factorial(2 * k + 1) for k in range(10)])
# Polynomials replace cos, sin and sin(x)/x where every |x| of a pass is at most this.
_SMALL_ANGLE = 0.25


def _terms(largest: float, coefficients: np.ndarray) -> int:
    """Taylor terms after which the next one is below 2^-56 (relative: a sixteenth of the last
    bit of the sum, which is near 1) for |x| <= largest."""
    for t in range(1, len(coefficients)):
        if abs(coefficients[t]) * largest ** (2 * t) < 2.0**-56:
            return t
    return len(coefficients)


def _series(u: np.ndarray, coefficients: np.ndarray, out: np.ndarray) -> np.ndarray:
    """sum_k c_k u^k (Horner) into ``out``."""
    if len(coefficients) == 1:
        out.fill(coefficients[0])
        return out
    np.multiply(u, coefficients[-1], out=out)
    out += coefficients[-2]
    for c in coefficients[-3::-1]:
        out *= u
        out += c
    return out


def _accumulate(x: np.ndarray, out: np.ndarray | None = None) -> np.ndarray:
    """Cumulative sum along axis 0 (increments) of ``x`` (n, m), as a new array (or into
    ``out``): row by row where rows are long and few (numpy's cumsum does not vectorise across
    rows)."""
    if len(x) > _ROW_LOOP:
        return np.cumsum(x, axis=0, out=out)
    if out is None:
        out = x.copy()
    else:
        np.copyto(out, x)
    for k in range(1, len(out)):
        out[k] += out[k - 1]
    return out


# Segments of at most this many increments are accumulated row by row.
_ROW_LOOP = 32


def _distinct(a: np.ndarray) -> np.ndarray:
    """``a`` (shape (runs,)), or its one value (shape (1,)) where it is a broadcast scalar."""
    return a[:1] if a.ndim == 1 and a.size > 1 and a.strides[0] == 0 else a


def _rows(a: np.ndarray, rows: int) -> np.ndarray:
    """``a`` (shape (rows,) or (1,)) as shape (rows,), a read-only broadcast view where it has
    one value (made directly: ``np.broadcast_to`` costs more than the arithmetic here)."""
    if a.shape == (rows,):
        return a
    a = np.ascontiguousarray(a, dtype=float).reshape(-1)
    if a.shape != (1,):
        raise ValueError(f"cannot broadcast shape {a.shape} to ({rows},)")
    out = np.ndarray((rows,), dtype=float, buffer=a, strides=(0,))
    out.flags.writeable = False
    return out


def _wheel_noise(
    rng: np.random.Generator | None,
    k_m: float,
    scale: np.ndarray,
    n: int,
    buffer: np.ndarray | None = None,
) -> np.ndarray | None:
    """The noise of one wheel's travel over ``n`` increments: ``scale`` (m, sqrt(k |a|) for a
    mean travel a per increment; shape (runs,)) times standard normals, shape (n, runs), drawn
    into ``buffer`` where it has that shape (the same draws); None without noise."""
    if not (k_m > 0 and rng is not None):
        return None
    if buffer is not None and buffer.shape == (n, len(scale)):
        z = rng.standard_normal(out=buffer)
    else:
        z = rng.standard_normal((n, len(scale)))
    z *= scale
    return z


def _cos_sin(x: np.ndarray, scratch: _Scratch | None = None) -> tuple[np.ndarray, np.ndarray]:
    """cos x and sin x as new arrays (or arrays of ``scratch``): Taylor polynomials (accurate to
    the last bit) where every |x| is at most _SMALL_ANGLE, else numpy's."""
    largest = max(float(x.max()), -float(x.min()))

    def out(name: str) -> np.ndarray:
        return np.empty_like(x) if scratch is None else scratch.get(name, x.shape)

    if largest > _SMALL_ANGLE:
        return np.cos(x, out=out("cos")), np.sin(x, out=out("sin"))
    u = np.multiply(x, x, out=out("square"))
    sin_x = _series(u, _SINC[: _terms(largest, _SINC)], out("sin"))
    sin_x *= x
    return _series(u, _COS[: _terms(largest, _COS)], out("cos")), sin_x


class _Scratch:
    """Arrays a block reuses from pass to pass, by name: views of one buffer per name, grown
    when a pass needs more (fresh memory costs more than the arithmetic on it)."""

    def __init__(self) -> None:
        self._buffers: dict[str, np.ndarray] = {}

    def get(self, name: str, shape: tuple[int, ...]) -> np.ndarray:
        """An uninitialised C-contiguous array of ``shape`` (float), valid until the next
        ``get`` of ``name``."""
        size = math.prod(shape)
        flat = self._buffers.get(name)
        if flat is None or flat.size < size:
            flat = self._buffers[name] = np.empty(size)
        return flat[:size].reshape(shape)


def _drive_block(
    segments: list[tuple[np.ndarray, np.ndarray, int]],
    b_true: np.ndarray,
    noise: NonSystematicError,
    rng: np.random.Generator | None,
    exact: bool,
    pose: np.ndarray,
    record: np.ndarray | None,
    traj: np.ndarray | None,
    heading_only: bool,
) -> None:
    """Drive one block of runs (rows of ``pose``, updated in place) through ``segments``.

    Per segment of n increments, runs are taken a few at a time (passes of about _CHUNK
    increments, arrays of shape (n, runs), small enough to stay in the cache); for each pass the
    right wheel's normals are drawn, then the left wheel's (where k > 0). (Drawing and computing
    a segment's passes together was tried: no faster on two cores.)

    Each wheel's travel per increment is its mean a plus its noise; the heading change per
    increment is delta + eta, delta = (a_r - a_l) / b the same at every increment, eta the
    noise's part. The segment's heading change is therefore n delta + sum(eta) (what
    :func:`final_headings` reads, with no more work than the sums), and the mid heading of
    increment k, relative to the segment's start, is m_k = (k + 1/2) delta + e_k with
    e_k = sum_{j<k} eta_j + eta_k / 2. The displacement is rotated by the start heading th0 once
    per run: sum_k ds_k (cos, sin)(th0 + m_k) = R(th0) sum_k ds_k (cos m_k, sin m_k). Where
    delta is the same for every run, cos m_k and sin m_k are expanded around (k + 1/2) delta
    (one angle per increment, not per run): only e_k, which is small, is left per run, and its
    cos and sin are Taylor polynomials accurate to the last bit; likewise the sin(x)/x of the
    exact arcs and, on straight legs, cos and sin of the whole mid heading.

    This is the midpoint update of :mod:`odocal.core.odometry` (its one home), unrolled by
    segment for speed; tests/core/test_odometry.py equates the two.
    """
    rows = len(b_true)
    b_true = _distinct(b_true)
    # the pose of the block as contiguous columns (a column of ``pose`` is strided), written back
    # at the end; the same sums, in the same order
    th = (pose if heading_only else pose[:, 2]).copy()
    x = np.zeros(0) if heading_only else pose[:, 0].copy()
    y = np.zeros(0) if heading_only else pose[:, 1].copy()
    # halves of the wheelbase (exact halvings): the centre's travel is then u + v and the heading
    # change (u - v) / (b / 2), with u, v the halves of the wheels' noise
    half_b = _rows(0.5 * b_true, rows)
    # the arrays of a pass, the normals included (drawn into it: the same draws), reused
    scratch = _Scratch()
    start = 0  # increments driven before the segment
    for s_r, s_l, n in segments:
        step = max(1, _CHUNK // n)
        wanted = None
        if record is not None:
            inside = (record >= start + 1) & (record <= start + n)
            if inside.any():
                wanted = (np.flatnonzero(inside), record[inside] - start - 1)
        # per run: mean travel of each wheel per increment, the halves of the noise's scale
        # sqrt(k |a|), the heading change per increment without noise (computed on the distinct
        # values only where a value is the same for every run, then broadcast)
        a_r, a_l = _distinct(s_r) / n, _distinct(s_l) / n
        scale_r = _rows(0.5 * np.sqrt(noise.k_r_m * np.abs(a_r)), rows)
        scale_l = _rows(0.5 * np.sqrt(noise.k_l_m * np.abs(a_l)), rows)
        delta_one = (a_r - a_l) / _distinct(b_true)
        delta_all = _rows(delta_one, rows)
        turn_all = _rows(n * delta_one, rows)
        if not heading_only:
            middle = np.arange(n) + 0.5  # increment k's middle, in increments
            a_mean = _rows(0.5 * (a_r + a_l), rows)
        for lo in range(0, rows, step):
            hi = min(rows, lo + step)
            b = half_b[lo:hi]
            u = _wheel_noise(rng, noise.k_r_m, scale_r[lo:hi], n, scratch.get("u", (n, hi - lo)))
            v = _wheel_noise(rng, noise.k_l_m, scale_l[lo:hi], n, scratch.get("v", (n, hi - lo)))
            delta = delta_all[lo:hi]
            # the segment's heading change: n delta + (sum u - sum v) / (b / 2) (a sum over one
            # increment is that increment)
            turn = turn_all[lo:hi].copy()
            if u is not None:
                turn += (u[0] if n == 1 else u.sum(axis=0)) / b
            if v is not None:
                turn -= (v[0] if n == 1 else v.sum(axis=0)) / b
            if heading_only:
                th[lo:hi] += turn
                continue
            th0 = th[lo:hi].copy()
            th[lo:hi] += turn
            # ds (travel of the centre) and eta (noise part of the heading change)
            if u is None and v is None:
                ds = np.empty((n, hi - lo))
                ds[:] = a_mean[lo:hi]
                eta = np.zeros_like(ds)
            else:
                if v is None:
                    assert u is not None
                    ds, eta = u.copy(), u
                elif u is None:
                    ds, eta = v.copy(), np.negative(v, out=v)
                else:
                    ds = np.add(u, v, out=scratch.get("ds", u.shape))
                    eta = np.subtract(u, v, out=u)
                ds += a_mean[lo:hi]
                eta /= b
            if exact:
                # chord of the arc: ds sin(dth/2) / (dth/2), dth = delta + eta
                half = np.multiply(eta, 0.5, out=scratch.get("half", eta.shape))
                half += 0.5 * delta
                largest = max(float(half.max()), -float(half.min()))
                if largest <= _SMALL_ANGLE:
                    sq = np.multiply(half, half, out=half)
                    chord = scratch.get("chord", sq.shape)
                    ds *= _series(sq, _SINC[: _terms(largest, _SINC)], chord)
                else:
                    with np.errstate(invalid="ignore", divide="ignore"):
                        ds *= np.where(half == 0, 1.0, np.sin(half) / half)
            # sum_{j<=k} eta_j
            noise_heading = _accumulate(eta, scratch.get("noise_heading", eta.shape))
            e = np.multiply(eta, -0.5, out=eta)
            e += noise_heading
            c0, s0 = np.cos(th0), np.sin(th0)
            x0, y0 = x[lo:hi], y[lo:hi]
            if delta.strides[0] == 0:  # one value for every run
                uniform = bool(delta[0] == delta[0])
            else:
                uniform = bool(delta.min() == delta.max())
            if uniform:
                cos_m, sin_m = _cos_sin(e, scratch)
                mbar = middle * float(delta[0])
                col_c, col_s = np.cos(mbar), np.sin(mbar)
                cos_m *= ds
                sin_m *= ds
                # sums over the increments as matrix-vector products
                sx = col_c @ cos_m - col_s @ sin_m
                sy = col_s @ cos_m + col_c @ sin_m
                if wanted is not None:  # (cos, sin)(mbar + e) ds, increment by increment
                    cos_m, sin_m = (
                        cos_m * col_c[:, None] - sin_m * col_s[:, None],
                        sin_m * col_c[:, None] + cos_m * col_s[:, None],
                    )
            else:
                mid = np.multiply.outer(middle, delta, out=scratch.get("mid", e.shape))
                mid += e
                cos_m, sin_m = _cos_sin(mid, scratch)
                cos_m *= ds
                sin_m *= ds
                sx, sy = cos_m.sum(axis=0), sin_m.sum(axis=0)
            if wanted is not None and traj is not None:
                cols, at = wanted
                cx = _accumulate(cos_m)[at]
                cy = _accumulate(sin_m)[at]
                traj[lo:hi, cols, 0] = (x0 + c0 * cx - s0 * cy).T
                traj[lo:hi, cols, 1] = (y0 + s0 * cx + c0 * cy).T
                heading = np.multiply.outer(at + 1.0, delta)
                heading += noise_heading[at]
                traj[lo:hi, cols, 2] = (th0 + heading).T
            x[lo:hi] += c0 * sx - s0 * sy
            y[lo:hi] += s0 * sx + c0 * sy
        start += n
    if heading_only:
        pose[:] = th
    else:
        pose[:, 0] = x
        pose[:, 1] = y
        pose[:, 2] = th


def simulate(
    track: Track,
    robot: Robot,
    runs: int,
    rng: np.random.Generator | None,
    **options: Any,
) -> SimulationResult:
    """Drive ``track`` ``runs`` times with ``robot`` (true geometry from its systematic errors,
    believed geometry from ``robot.believed`` or nominal). Options as in :func:`drive`.
    Measurement noise is NOT applied here; see :func:`measure`."""
    return drive(
        track,
        robot.true_geometry,
        robot.believed_geometry,
        robot.nonsystematic,
        runs,
        rng,
        **options,
    )


def measure(errors: np.ndarray, robot: Robot, rng: np.random.Generator | None) -> np.ndarray:
    """Add the ground-truth instrument's noise to final pose errors, shape (..., 3)."""
    m = robot.measurement
    if m.is_zero:
        return np.asarray(errors, dtype=float)
    if rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate measurement noise")
    z = rng.standard_normal(np.shape(errors))
    scale = np.array([m.sigma_xy_m, m.sigma_xy_m, m.sigma_theta_rad])
    return errors + z * scale


def measure_track(poses: np.ndarray, robot: Robot, rng: np.random.Generator | None) -> np.ndarray:
    """Tracked poses as an instrument sees them: ``poses`` (..., 3) (x_m, y_m, theta_rad) plus the
    instrument's noise (``robot.measurement``) on every sample, independently. A new array.

    Draws the position noise, then the heading noise (only the parts whose sigma is > 0)."""
    out = np.array(poses, dtype=float)
    m = robot.measurement
    if m.is_zero:
        return out
    if rng is None:
        raise ModelError("a numpy.random.Generator is needed to simulate measurement noise")
    if m.sigma_xy_m > 0:
        out[..., :2] += m.sigma_xy_m * rng.standard_normal(out[..., :2].shape)
    if m.sigma_theta_rad > 0:
        out[..., 2] += m.sigma_theta_rad * rng.standard_normal(out[..., 2].shape)
    return out


def commanded_wheel_angles(
    track: Track, believed: WheelGeometry, max_step_m: float
) -> tuple[int, np.ndarray]:
    """The encoder readings of an open-loop drive of ``track``, sampled after every increment.

    One increment count ``n`` for every segment (enough that no increment exceeds ``max_step_m``
    of wheel travel); returns ``(n, angles)`` with ``angles`` the cumulative commanded wheel
    rotations (right, left; rad), shape (n * segments + 1, 2), starting at 0. Use with
    ``drive(..., steps_per_segment=n, trajectory=True)`` to pair readings with true poses.
    """
    b_hat = float(np.mean(believed.wheelbase_m))
    travel = [seg.wheel_travel(b_hat) for seg in track.segments]
    longest = max(max(abs(float(r)), abs(float(lft))) for r, lft in travel)
    n = increments_per_segment(longest, longest, max_step_m)
    d_r = float(np.mean(believed.diameter_right_m))
    d_l = float(np.mean(believed.diameter_left_m))
    inc = np.concatenate(
        [
            np.repeat([[2.0 * float(r) / d_r / n, 2.0 * float(lft) / d_l / n]], n, axis=0)
            for r, lft in travel
        ]
    )
    return n, np.vstack([np.zeros((1, 2)), np.cumsum(inc, axis=0)])
