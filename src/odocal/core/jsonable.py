"""Numbers as JSON holds them: JSON has no NaN or infinity, so every ``--json`` writes an
undefined or unbounded number as null, through these (one home for the rule)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import ArrayLike

__all__ = ["finite_or_none", "finite_list", "jsonable"]


def finite_or_none(v: Any) -> float | None:
    """``v`` as a float, or None when it is None, NaN or infinite."""
    if v is None:
        return None
    f = float(v)
    return f if math.isfinite(f) else None


def finite_list(a: ArrayLike) -> list[Any]:
    """An array as nested lists of floats, its non-finite entries None."""
    return [finite_list(v) if np.ndim(v) else finite_or_none(v) for v in np.asarray(a, float)]


def jsonable(v: Any) -> Any:
    """``v`` with its numbers made JSON's: mappings and sequences (arrays too) walked, integers
    as int, other numbers as finite floats or None; text, booleans and None as they are."""
    if v is None or isinstance(v, (str, bool)):
        return v
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, dict):
        return {k: jsonable(x) for k, x in v.items()}
    if isinstance(v, (list, tuple, np.ndarray)):
        return [jsonable(x) for x in v]
    if isinstance(v, (int, np.integer)):
        return int(v)
    return finite_or_none(v)
