"""Least-squares circle fit to tracked points (for BCPT radii).

Two algebraic fits and an optional geometric refinement, all vectorised over leading batch axes:

- Kasa (1976): minimise sum (x^2 + y^2 + a x + b y + c)^2, a linear least-squares problem. Fast;
  biased towards small radii on short, noisy arcs.
- Pratt (1987): the same algebraic distance under the constraint a^2 + b^2 - 4 c = 1 (solved as a
  4 x 4 generalised eigenproblem), nearly unbiased on arcs.
- Geometric refinement (default): Gauss-Newton on the orthogonal distances
  r_i = sqrt((x_i - x_c)^2 + (y_i - y_c)^2) - R, started from the algebraic fit. This is the
  maximum-likelihood fit for isotropic Gaussian point noise.

Points lying exactly on a circle give that circle to rounding error with any of the fits.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import ArrayLike

from ..core.model import ModelError

__all__ = ["CircleFit", "fit_circle", "CIRCLE_FITS"]

CIRCLE_FITS = ("kasa", "pratt")

# Pratt's constraint matrix for the parameter vector (A, B, C, D) of A (x^2 + y^2) + B x + C y + D.
_PRATT = np.array(
    [[0.0, 0.0, 0.0, -2.0], [0.0, 1.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [-2.0, 0.0, 0.0, 0.0]]
)


@dataclass(frozen=True)
class CircleFit:
    """A fitted circle; fields are floats, or arrays of the batch shape for batched input.

    Attributes
    ----------
    center_x_m, center_y_m : float or ndarray
        Centre (m), in the frame of the points.
    radius_m : float or ndarray
        Radius (m).
    rms_residual_m : float or ndarray
        Root-mean-square orthogonal distance of the points from the circle (m).
    """

    center_x_m: float | np.ndarray
    center_y_m: float | np.ndarray
    radius_m: float | np.ndarray
    rms_residual_m: float | np.ndarray


def _kasa(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    # Normal equations of [x y 1] p = x^2 + y^2, batched.
    ones = np.ones_like(x)
    a = np.stack([x, y, ones], axis=-1)  # (..., K, 3)
    rhs = x * x + y * y
    ata = np.einsum("...ki,...kj->...ij", a, a)
    atb = np.einsum("...ki,...k->...i", a, rhs)
    p = np.linalg.solve(ata, atb[..., None])[..., 0]
    xc, yc = 0.5 * p[..., 0], 0.5 * p[..., 1]
    r = np.sqrt(p[..., 2] + xc * xc + yc * yc)
    return xc, yc, r


def _pratt(x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    z = np.stack([x * x + y * y, x, y, np.ones_like(x)], axis=-1)  # (..., K, 4)
    m = np.einsum("...ki,...kj->...ij", z, z) / x.shape[-1]
    # M v = eta B v  <=>  B^-1 M v = eta v; the fit is the smallest non-negative eta.
    w, v = np.linalg.eig(np.linalg.solve(_PRATT, m))
    w = np.real(w)
    v = np.real(v)
    key = np.where(w >= -1e-12 * np.max(np.abs(w), axis=-1, keepdims=True), w, np.inf)
    idx = np.argmin(key, axis=-1)
    p = np.take_along_axis(v, idx[..., None, None], axis=-1)[..., 0]  # (..., 4)
    a, b, c, d = (p[..., i] for i in range(4))
    xc, yc = -b / (2 * a), -c / (2 * a)
    r = np.sqrt(b * b + c * c - 4 * a * d) / (2 * np.abs(a))
    return xc, yc, r


def _refine(
    x: np.ndarray, y: np.ndarray, xc: np.ndarray, yc: np.ndarray, r: np.ndarray, iterations: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    for _ in range(iterations):
        dx = x - xc[..., None]
        dy = y - yc[..., None]
        dist = np.hypot(dx, dy)
        res = dist - r[..., None]
        # d res / d (xc, yc, r) = (-dx/dist, -dy/dist, -1)
        jac = np.stack([-dx / dist, -dy / dist, -np.ones_like(dist)], axis=-1)
        jtj = np.einsum("...ki,...kj->...ij", jac, jac)
        jtr = np.einsum("...ki,...k->...i", jac, res)
        step = np.linalg.solve(jtj, -jtr[..., None])[..., 0]
        xc, yc, r = xc + step[..., 0], yc + step[..., 1], r + step[..., 2]
        if np.max(np.abs(step)) <= 1e-13 * max(1.0, float(np.max(np.abs(r)))):
            break
    return xc, yc, r


def fit_circle(
    points: ArrayLike, algebraic: str = "pratt", geometric: bool = True, iterations: int = 20
) -> CircleFit:
    """Fit a circle to points.

    Parameters
    ----------
    points : array_like, shape (..., K, 2)
        Point coordinates (m), K >= 3 per circle; leading axes are a batch.
    algebraic : {'pratt', 'kasa'}
        Algebraic fit used on its own (``geometric=False``) or as the starting point.
    geometric : bool
        Refine by Gauss-Newton on the orthogonal distances (default True).
    iterations : int
        Largest number of Gauss-Newton iterations.

    Returns
    -------
    CircleFit
    """
    p = np.asarray(points, dtype=float)
    if p.ndim < 2 or p.shape[-1] != 2:
        raise ModelError(f"points must have shape (..., K, 2), got {p.shape}")
    if p.shape[-2] < 3:
        raise ModelError(f"a circle fit needs at least 3 points, got {p.shape[-2]}")
    if not np.all(np.isfinite(p)):
        raise ModelError("points must be finite")
    if algebraic not in CIRCLE_FITS:
        raise ModelError(f"algebraic must be one of {', '.join(CIRCLE_FITS)}, got {algebraic!r}")
    # Work relative to the centroid for conditioning.
    c = p.mean(axis=-2, keepdims=True)
    x = p[..., 0] - c[..., 0]
    y = p[..., 1] - c[..., 1]
    with np.errstate(divide="ignore", invalid="ignore"):
        xc, yc, r = (_pratt if algebraic == "pratt" else _kasa)(x, y)
        if geometric:
            xc, yc, r = _refine(x, y, xc, yc, r, iterations)
        rms = np.sqrt(
            np.mean((np.hypot(x - xc[..., None], y - yc[..., None]) - r[..., None]) ** 2, -1)
        )
    if not np.all(np.isfinite(r)):
        raise ModelError("the points do not determine a circle (collinear or coincident?)")
    out = (xc + c[..., 0, 0], yc + c[..., 0, 1], r, rms)
    if p.ndim == 2:
        return CircleFit(*(float(v) for v in out))
    return CircleFit(*out)
