"""The effective wheelbase as a function of the motion: one estimate per curvature band.

A real robot does not turn with one wheelbase. Tyre scrub, castor drag and slip depend on how it
turns: OptiOdom's robot turns about 0.5 % less per wheel rotation on arcs than on the spot, a
skid-steer robot's effective wheelbase is far from the geometric one and grows as the turn gets
tighter. This module measures it from tracked runs, per band of motion:

=============  =====================  ===========================================
band           spin fraction s        turn radius R of the axle centre
=============  =====================  ===========================================
``spot``       s >= 0.8               R <= 0.625 b (spot and pivot turns)
``tight``      0.2 <= s < 0.8         0.625 b < R <= 2.5 b
``wide``       0.04 <= s < 0.2        2.5 b < R <= 12.5 b
``straight``   s < 0.04               R > 12.5 b
=============  =====================  ===========================================

with s = |s_R - s_L| / (|s_R| + |s_L|) from the wheel travel s_R, s_L over a short window (R =
b / (2 s) for s < 1; s = 1 whenever the wheels turn in opposite directions or one stands still).
The window (``window_s``, default 0.5 s, centred) smooths the encoder quantisation, which would
otherwise throw single samples across the band edges and bias the estimate (a band selected on
noisy odometry keeps the samples whose noise happens to point its way).

Estimator. Each run is cut into *segments*: maximal stretches of consecutive samples in one band
(samples where the robot stands still end a segment). A segment counts when it lasts at least
``min_duration_s`` and turns at least ``min_rotation_rad`` in the odometry of the reference
geometry (its rotation must stand out against the tracker's heading noise and a sample of
time-alignment error at its ends). For the segments j of a band, with x_j the odometric rotation
(reference geometry) and y_j the true rotation (ground truth),

    G = sum x_j y_j / sum x_j^2,      b_eff = b_ref / G

(least squares through the origin: the true rotation per odometric radian). The reference's
diameters (their ratio and scale) stay fixed, so b_eff is the effective wheelbase AT the
reference's diameters, and the scale-free ``turning_gain`` mean(D_ref) / b_eff is what a closed
track can see. Interval: runs are the independent units (segments of one run share its slip and
the tracker's alignment), so the variance of G is the cluster-robust (sandwich) one over runs,

    var G = n/(n-1) sum_runs (sum_{j in run} x_j e_j)^2 / (sum x_j^2)^2,   e_j = y_j - G x_j,

and the 95 % interval uses Student's t with n - 1 degrees of freedom (n runs in the band).

A band is *excited* when it holds at least ``MIN_SEGMENTS`` segments from at least ``MIN_RUNS``
runs that turn at least ``MIN_ROTATION_RAD`` in all; only then is its estimate reported as one.
Near-straight driving turns too little to show a wheelbase: its band is normally not excited.

:func:`wheelbase_for_mix` gives the one wheelbase that is best for a stated mix of motions (the
share of the robot's rotation done in each band) and the heading error that one value costs per
band and overall (see its docstring); ``odocal fit --motion-mix`` applies it to the band
wheelbases of the banded model (:mod:`odocal.calibration.banded`), not to this table: the
table's estimates are at the constant fit's diameters and see only the segments' rotation.
"""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping
from dataclasses import dataclass, field

import numpy as np
from numpy.typing import ArrayLike

from ..core.checks import parse_float
from ..core.model import WheelGeometry
from ..core.recording import Recording
from ..core.stats import student_t_quantile
from ..errors import CalibrationError
from .fit_methods import BANDS

__all__ = [
    "BANDS",
    "BAND_EDGES",
    "MIN_SEGMENTS",
    "MIN_RUNS",
    "MIN_ROTATION_RAD",
    "BandEstimate",
    "EffectiveWheelbase",
    "band_of_increments",
    "nearest_estimated_band",
    "wheelbase_per_increment",
    "effective_wheelbase",
    "MixChoice",
    "wheelbase_for_mix",
    "parse_motion_mix",
    "disagreeing_bands",
]

# BANDS (odocal.calibration.fit_methods): the band names, from the tightest turning to straight.
#: Lower spin-fraction edge of each band in :data:`BANDS` (the last band starts at 0).
BAND_EDGES = (0.8, 0.2, 0.04, 0.0)
#: Excitation: segments, runs and total odometric rotation (rad) a band needs to be estimated.
MIN_SEGMENTS = 3
MIN_RUNS = 2
MIN_ROTATION_RAD = math.pi
# Wheel travel (m) over the smoothing window below which the robot counts as standing still.
_STILL_M = 2e-4


def _radius_range(index: int, wheelbase_m: float) -> tuple[float, float | None]:
    """Turn-radius range (m) of band ``index``: (lower, upper or None for unbounded)."""
    hi_s = 1.0 if index == 0 else BAND_EDGES[index - 1]
    lo_s = BAND_EDGES[index]
    lower = 0.0 if index == 0 else wheelbase_m / (2.0 * hi_s)
    upper = None if lo_s == 0.0 else wheelbase_m / (2.0 * lo_s)
    return lower, upper


def band_of_increments(
    angle_right_rad: ArrayLike,
    angle_left_rad: ArrayLike,
    time_s: ArrayLike,
    reference: WheelGeometry,
    window_s: float = 0.5,
) -> np.ndarray:
    """Band index (into :data:`BANDS`) of every increment of one run, shape (K - 1,); -1 where
    the robot stands still. ``angle_*``: cumulative wheel angles (rad), shape (K,)."""
    ds_r = np.diff(np.asarray(angle_right_rad, dtype=float)) * (0.5 * reference.diameter_right_m)
    ds_l = np.diff(np.asarray(angle_left_rad, dtype=float)) * (0.5 * reference.diameter_left_m)
    t = np.asarray(time_s, dtype=float)
    dt = float(np.median(np.diff(t))) if len(t) > 1 else 1.0
    w = max(1, int(round(window_s / dt)) if dt > 0 else 1)
    w += 1 - w % 2  # odd, centred
    kernel = np.ones(w)
    s_r = np.convolve(ds_r, kernel, mode="same")
    s_l = np.convolve(ds_l, kernel, mode="same")
    total = np.abs(s_r) + np.abs(s_l)
    with np.errstate(invalid="ignore", divide="ignore"):
        s = np.abs(s_r - s_l) / total
    band = np.full(len(ds_r), -1, dtype=int)
    moving = (total > _STILL_M) & ((np.abs(ds_r) + np.abs(ds_l)) > 0)
    for i in range(len(BANDS) - 1, -1, -1):  # straight first, tighter bands overwrite
        band[moving & (s >= BAND_EDGES[i])] = i
    return band


def nearest_estimated_band(estimated: Iterable[int]) -> list[int]:
    """For every band index, the index of the nearest band in ``estimated`` (indices into
    :data:`BANDS`; ties go to the tighter band): where a banded model takes a band's wheelbase
    when that band was not estimated."""
    est = sorted(int(i) for i in estimated)
    if not est:
        raise CalibrationError("no band of motion has an effective-wheelbase estimate")
    return [min(est, key=lambda j: (abs(j - i), j)) for i in range(len(BANDS))]


def wheelbase_per_increment(
    recording: Recording,
    band_wheelbases_m: Mapping[str, float | None],
    classify_with: WheelGeometry,
    window_s: float = 0.5,
) -> np.ndarray:
    """The wheelbase (m) a banded model uses for every increment of ``recording``, shape
    (K - 1,): the band's value from ``band_wheelbases_m`` (band name -> m), or the nearest
    band's where a band has none. ``classify_with`` gives the diameters that classify the
    motion (:func:`band_of_increments`). Use as ``WheelGeometry.unchecked(D_R, D_L, b)`` in
    :func:`odocal.core.odometry.dead_reckon`."""
    given = {name: v for name in BANDS if (v := band_wheelbases_m.get(name)) is not None}
    nearest = nearest_estimated_band(BANDS.index(name) for name in given)
    values = np.array([float(given[BANDS[nearest[i]]]) for i in range(len(BANDS))])
    band = band_of_increments(
        recording.wheel_angle_right_rad,
        recording.wheel_angle_left_rad,
        recording.time_s,
        classify_with,
        window_s,
    )
    # standing still: the wheelbase does not matter (no wheel travel); any band will do
    return values[np.where(band < 0, nearest[0], band)]


def _segments(band: np.ndarray) -> list[tuple[int, int, int]]:
    """(band, first increment, last increment + 1) of every maximal stretch of one band."""
    if len(band) == 0:
        return []
    change = np.flatnonzero(np.diff(band)) + 1
    starts = np.r_[0, change]
    ends = np.r_[change, len(band)]
    return [(int(band[a]), int(a), int(b)) for a, b in zip(starts, ends, strict=True)]


@dataclass(frozen=True)
class BandEstimate:
    """The effective wheelbase in one band of motion.

    Attributes
    ----------
    band : str
        One of :data:`BANDS`.
    radius_range_m : tuple
        (lower, upper) turn radius of the axle centre (m; upper None = unbounded).
    wheelbase_m : float or None
        Effective wheelbase at the reference diameters (m); None when no segment counts.
    ci95_m : tuple of float or None
        95 % interval of ``wheelbase_m`` (m), runs as the independent units.
    turning_gain : float or None
        mean(D_ref) / wheelbase_m (scale-free; what a closed track sees).
    segments, runs : int
        Segments that count and the runs they come from.
    rotation_rad : float
        Total |odometric rotation| of those segments (rad).
    rotation_share : float
        Share of ALL the runs' odometric rotation done in this band (every sample, counted or
        not): the runs' own motion mix.
    excited : bool
        Enough segments, runs and rotation to report an estimate (module docstring).
    """

    band: str
    radius_range_m: tuple[float, float | None]
    wheelbase_m: float | None
    ci95_m: tuple[float, float] | None
    turning_gain: float | None
    segments: int
    runs: int
    rotation_rad: float
    rotation_share: float
    excited: bool

    def as_dict(self) -> dict:
        """JSON-ready (one entry of ``bands`` in the ``effective_wheelbase`` object of ``odocal fit
        --json``)."""
        return {
            "band": self.band,
            "radius_range_m": list(self.radius_range_m),
            "wheelbase_m": self.wheelbase_m,
            "ci95_m": None if self.ci95_m is None else list(self.ci95_m),
            "turning_gain": self.turning_gain,
            "segments": self.segments,
            "runs": self.runs,
            "rotation_rad": self.rotation_rad,
            "rotation_share": self.rotation_share,
            "excited": self.excited,
        }


@dataclass(frozen=True)
class EffectiveWheelbase:
    """Effective wheelbase per band of motion (module docstring).

    Attributes
    ----------
    reference : WheelGeometry
        Geometry the odometric rotations were computed with (its diameters are kept).
    bands : tuple of BandEstimate
        One per entry of :data:`BANDS`.
    window_s, min_rotation_rad, min_duration_s : float
        Settings used.
    warnings : tuple of str
    """

    reference: WheelGeometry
    bands: tuple[BandEstimate, ...]
    window_s: float
    min_rotation_rad: float
    min_duration_s: float
    warnings: tuple[str, ...] = field(default_factory=tuple)

    def band(self, name: str) -> BandEstimate:
        """The estimate of band ``name`` (one of :data:`BANDS`; KeyError for another name)."""
        for b in self.bands:
            if b.band == name:
                return b
        raise KeyError(name)

    @property
    def excited(self) -> tuple[str, ...]:
        """Names of the excited bands, tightest first."""
        return tuple(b.band for b in self.bands if b.excited)

    @property
    def motion_mix(self) -> dict[str, float]:
        """Share of the runs' rotation per band (sums to 1 over the bands that turned)."""
        return {b.band: b.rotation_share for b in self.bands}

    def as_dict(self) -> dict:
        """JSON-ready (the ``effective_wheelbase`` object of ``odocal fit --json``)."""
        return {
            "reference": self.reference.as_dict(),
            "bands": [b.as_dict() for b in self.bands],
            "excited_bands": list(self.excited),
            "window_s": self.window_s,
            "min_rotation_rad": self.min_rotation_rad,
            "min_duration_s": self.min_duration_s,
            "warnings": list(self.warnings),
        }


def effective_wheelbase(
    recordings: Iterable[Recording],
    reference: WheelGeometry,
    *,
    window_s: float = 0.5,
    min_rotation_rad: float = 0.3,
    min_duration_s: float = 0.5,
) -> EffectiveWheelbase:
    """Effective wheelbase per band of motion from tracked runs (module docstring).

    Parameters
    ----------
    recordings : sequence of Recording
        Runs with ground truth (any motion).
    reference : WheelGeometry
        Diameters (kept) and wheelbase of the odometric rotations, e.g. a trajectory fit of the
        same runs; the estimates are relative to it.
    window_s : float
        Width of the centred window that classifies the motion (s).
    min_rotation_rad, min_duration_s : float
        What a segment must turn (rad, odometric; default 0.3 rad, 17 deg) and last (s) to
        count. One sample of time-alignment error at each end of a segment misplaces omega dt of
        rotation (0.05 rad at 1 rad/s and 20 Hz), so a segment must turn several times that; the
        default also leaves out the small heading corrections of straight legs.
    """
    for name, v in (
        ("window_s", window_s),
        ("min_rotation_rad", min_rotation_rad),
        ("min_duration_s", min_duration_s),
    ):
        if not (math.isfinite(v) and v >= 0):
            raise CalibrationError(f"{name} must be a finite number >= 0, got {v!r}")
    b_ref = float(reference.wheelbase_m)
    per_band: list[list[tuple[int, float, float]]] = [[] for _ in BANDS]  # (run, x, y)
    rotation_all = np.zeros(len(BANDS))
    for k, r in enumerate(recordings):
        if r.ground_truth is None:
            raise CalibrationError(f"{r.name}: the effective wheelbase needs ground truth")
        band = band_of_increments(
            r.wheel_angle_right_rad, r.wheel_angle_left_rad, r.time_s, reference, window_s
        )
        ds_r = np.diff(r.wheel_angle_right_rad) * (0.5 * reference.diameter_right_m)
        ds_l = np.diff(r.wheel_angle_left_rad) * (0.5 * reference.diameter_left_m)
        dth = (ds_r - ds_l) / b_ref
        for i in range(len(BANDS)):
            rotation_all[i] += float(np.abs(dth[band == i]).sum())
        gt = np.asarray(r.ground_truth[:, 2], dtype=float)
        t = np.asarray(r.time_s, dtype=float)
        for idx, a, b in _segments(band):
            if idx < 0 or t[b] - t[a] < min_duration_s:
                continue
            x = float(dth[a:b].sum())
            if abs(x) < min_rotation_rad:
                continue
            per_band[idx].append((k, x, float(gt[b] - gt[a])))
    total_rotation = float(rotation_all.sum())
    d_ref = float(reference.mean_diameter_m)

    estimates = []
    for i, name in enumerate(BANDS):
        rows = per_band[i]
        share = float(rotation_all[i] / total_rotation) if total_rotation > 0 else 0.0
        runs = sorted({k for k, _, _ in rows})
        rot = float(sum(abs(x) for _, x, _ in rows))
        b_eff = ci = gain = None
        if rows:
            xs = np.array([x for _, x, _ in rows])
            ys = np.array([y for _, _, y in rows])
            sxx = float(xs @ xs)
            g = float(xs @ ys) / sxx
            if g > 0:
                b_eff = b_ref / g
                gain = d_ref / b_eff
                if len(runs) >= 2:
                    e = ys - g * xs
                    run_of = np.array([k for k, _, _ in rows])
                    scores = np.array([float(xs[run_of == k] @ e[run_of == k]) for k in runs])
                    n = len(runs)
                    var = n / (n - 1) * float(scores @ scores) / sxx**2
                    half = student_t_quantile(0.975, n - 1) * math.sqrt(var)
                    lo_g, hi_g = g - half, g + half
                    ci = (b_ref / hi_g, b_ref / lo_g if lo_g > 0 else math.inf)
        excited = (
            b_eff is not None
            and len(rows) >= MIN_SEGMENTS
            and len(runs) >= MIN_RUNS
            and rot >= MIN_ROTATION_RAD
            and ci is not None
            and math.isfinite(ci[1])
        )
        estimates.append(
            BandEstimate(
                band=name,
                radius_range_m=_radius_range(i, b_ref),
                wheelbase_m=b_eff,
                ci95_m=ci,
                turning_gain=gain,
                segments=len(rows),
                runs=len(runs),
                rotation_rad=rot,
                rotation_share=share,
                excited=bool(excited),
            )
        )
    warnings = []
    if not any(e.excited for e in estimates):
        warnings.append(
            "no band of motion turns enough to estimate an effective wheelbase (each needs "
            f"{MIN_SEGMENTS} segments of at least {min_rotation_rad:g} rad from {MIN_RUNS} runs, "
            f"{MIN_ROTATION_RAD:.3g} rad in all)"
        )
    return EffectiveWheelbase(
        reference,
        tuple(estimates),
        float(window_s),
        float(min_rotation_rad),
        float(min_duration_s),
        tuple(warnings),
    )


def parse_motion_mix(text: str) -> dict[str, float]:
    """'spot=0.2,wide=0.8' -> {'spot': 0.2, 'wide': 0.8} (shares of rotation, normalised)."""
    out: dict[str, float] = {}
    for part in text.split(","):
        name, sep, value = part.partition("=")
        name = name.strip().lower()
        if not sep or name not in BANDS:
            raise CalibrationError(
                f"motion mix: expected BAND=SHARE with BAND one of {', '.join(BANDS)}, got "
                f"{part.strip()!r}"
            )
        if name in out:
            raise CalibrationError(f"motion mix: band {name!r} given twice")
        try:
            v = parse_float(value.strip())
        except ValueError:
            raise CalibrationError(f"motion mix: not a number: {value.strip()!r}") from None
        if not (math.isfinite(v) and v >= 0):
            raise CalibrationError(f"motion mix: a share must be >= 0, got {value.strip()!r}")
        out[name] = v
    total = sum(out.values())
    if total <= 0:
        raise CalibrationError("motion mix: the shares must not all be 0")
    return {k: v / total for k, v in out.items()}


@dataclass(frozen=True)
class MixChoice:
    """The one wheelbase that is best for a mix of motions, and what it costs.

    Attributes
    ----------
    wheelbase_m : float
        The single effective wheelbase (m) for ``mix`` (at the estimates' diameters).
    mix : dict
        Band -> share of the rotation (normalised over the bands used).
    heading_error_deg_per_turn : dict
        Band -> heading error (actual - odometric, deg) per full turn (360 deg) made in that
        band with the single value: 360 (1 - b_band / b).
    rms_heading_error_deg_per_turn : float
        The share-weighted RMS of those: the loss of using one value instead of one per band.
    unused : tuple of str
        Bands of the mix without an estimate (left out; their share is renormalised away).
    wheelbase_stderr_m : float or None
        Standard error of ``wheelbase_m`` (m) from the band wheelbases' covariance (delta
        method; :mod:`odocal.calibration.banded`); None where not computed.
    """

    wheelbase_m: float
    mix: dict[str, float]
    heading_error_deg_per_turn: dict[str, float]
    rms_heading_error_deg_per_turn: float
    unused: tuple[str, ...] = ()
    wheelbase_stderr_m: float | None = None

    def as_dict(self) -> dict:
        """JSON-ready (the ``motion_mix`` object of ``odocal fit --json``)."""
        return {
            "wheelbase_m": self.wheelbase_m,
            "wheelbase_stderr_m": self.wheelbase_stderr_m,
            "mix": dict(self.mix),
            "heading_error_deg_per_turn": dict(self.heading_error_deg_per_turn),
            "rms_heading_error_deg_per_turn": self.rms_heading_error_deg_per_turn,
            "unused_bands": list(self.unused),
        }


def wheelbase_for_mix(wheelbases_m: dict[str, float], mix: dict[str, float]) -> MixChoice:
    """The single wheelbase b minimising the share-weighted mean square heading error per radian
    turned, sum_j w_j (1 - b_j / b)^2, for per-band wheelbases ``wheelbases_m`` and a mix
    ``mix`` (band -> share of the rotation): with u = 1 / b, u = sum w_j b_j / sum w_j b_j^2.

    A robot that turns the true angle psi in band j moves its wheels psi b_j apart; odometry with
    b reads psi b_j / b, an error of psi (1 - b_j / b). Bands of ``mix`` missing from
    ``wheelbases_m`` are left out (``unused``); with no band left it is an error.
    """
    used = {k: w for k, w in mix.items() if w > 0 and wheelbases_m.get(k) is not None}
    unused = tuple(k for k, w in mix.items() if w > 0 and wheelbases_m.get(k) is None)
    total = sum(used.values())
    if not used or total <= 0:
        raise CalibrationError(
            "none of the bands of the motion mix ("
            + ", ".join(k for k, w in mix.items() if w > 0)
            + ") has an effective-wheelbase estimate"
        )
    w = {k: v / total for k, v in used.items()}
    num = sum(w[k] * wheelbases_m[k] for k in w)
    den = sum(w[k] * wheelbases_m[k] ** 2 for k in w)
    b = den / num
    errors = {k: 360.0 * (1.0 - wheelbases_m[k] / b) for k in w}
    rms = math.sqrt(sum(w[k] * errors[k] ** 2 for k in w))
    return MixChoice(float(b), w, errors, float(rms), unused)


def disagreeing_bands(table: EffectiveWheelbase) -> list[str]:
    """A warning for every two excited bands whose 95 % intervals do not overlap."""
    warnings = []
    excited = [(b, b.ci95_m) for b in table.bands if b.excited and b.ci95_m is not None]
    for i, (x, cx) in enumerate(excited):
        for y, cy in excited[i + 1 :]:
            if cx[1] < cy[0] or cy[1] < cx[0]:
                warnings.append(
                    f"the robot turns differently in band '{x.band}' (effective wheelbase "
                    f"{x.wheelbase_m:.5g} m) and band '{y.band}' ({y.wheelbase_m:.5g} m; 95 % "
                    "intervals apart): one wheelbase is a compromise; see --wheelbase-model "
                    "banded and --motion-mix"
                )
    return warnings
