"""Argument checks of the public functions (as pytransform3d's ``check_*``): each takes the
argument's name and value and returns the value as the type it must be (a Python float or int),
or raises :class:`~odocal.errors.ModelError` naming the argument, so that a string, None, an
array, a bool, a fraction where a count belongs or a negative seed never reaches numpy.

The command line parses its flags with the same bounds (:mod:`odocal.cli.common`); these are the
checks of a value passed from Python.

Numbers written as text (flags, CSV fields, tagged YAML values) are read by :func:`parse_float`
and :func:`parse_int`, the one parser: Python's ``float`` and ``int`` also read ``1_0`` as 10,
surround a number with any white space, and take the digits of every script, which nobody types
into a flag or a sheet on purpose.
"""

from __future__ import annotations

import math
import numbers
import re
from typing import Any

from ..errors import ModelError

__all__ = [
    "check_number",
    "check_positive_float",
    "check_nonnegative_float",
    "check_int",
    "check_seed",
    "parse_float",
    "parse_int",
]

# A plain decimal number: sign, ASCII digits with a decimal point, exponent; and the words
# float() reads as infinity or NaN (the callers refuse them with their own words).
_DECIMAL = re.compile(r"[+-]?(?:[0-9]+\.?[0-9]*|\.[0-9]+)(?:[eE][+-]?[0-9]+)?")
_NON_FINITE = re.compile(r"[+-]?(?:inf|infinity|nan)", re.IGNORECASE)
_INTEGER = re.compile(r"[+-]?[0-9]+")


def parse_float(text: str) -> float:
    """``text`` as a float when it is written as a plain decimal number (``1``, ``-0.5``,
    ``.5``, ``1e-6``; ``inf`` and ``nan`` as float() reads them); ValueError otherwise: digit
    separators (``0_1``, which float() reads as 1), white space around it, other scripts'
    digits. Callers that trim their fields (CSV) trim before."""
    if _DECIMAL.fullmatch(text) or _NON_FINITE.fullmatch(text):
        return float(text)
    raise ValueError(f"not a decimal number: {text!r}")


def parse_int(text: str) -> int:
    """``text`` as an int when it is a sign and ASCII digits; ValueError otherwise (int() also
    reads ``1_0`` as 10 and white space around it)."""
    if _INTEGER.fullmatch(text):
        return int(text)
    raise ValueError(f"not an integer: {text!r}")


def _what(value: Any) -> str:
    """How a refused value is shown: its repr and, when that does not say it, its type."""
    shown = repr(value)
    if len(shown) > 40:
        shown = shown[:37] + "..."
    if isinstance(value, str):
        return f"{shown} (a string: pass the number itself)"
    if value is None or isinstance(value, (bool, float, int)):
        return shown
    return f"{shown} (a {type(value).__name__})"


def check_number(
    name: str,
    value: Any,
    *,
    above: float | None = None,
    at_least: float | None = None,
    below: float | None = None,
    at_most: float | None = None,
    hint: str = "",
) -> float:
    """``value`` as a float: one real number (not a bool, string, None or array), finite and
    within the given bounds; else ModelError naming ``name`` (``hint`` ends the message, e.g.
    the unit)."""
    if isinstance(value, bool) or not isinstance(value, numbers.Real):
        raise ModelError(f"{name} must be a number, got {_what(value)}")
    v = float(value)
    if not math.isfinite(v):
        raise ModelError(f"{name} must be a finite number, got {value!r}")
    bad = (
        (above is not None and not v > above)
        or (at_least is not None and not v >= at_least)
        or (below is not None and not v < below)
        or (at_most is not None and not v <= at_most)
    )
    if bad:  # every bound, as the command line's flags say it
        parts = [
            f"{op} {bound:g}"
            for op, bound in ((">", above), (">=", at_least), ("<", below), ("<=", at_most))
            if bound is not None
        ]
        sign = " (negative)" if v < 0 else ""
        raise ModelError(f"{name} must be {' and '.join(parts)}{hint}, got {v:g}{sign}")
    return v


def check_positive_float(
    name: str, value: Any, *, at_most: float | None = None, hint: str = ""
) -> float:
    """``value`` as a float > 0 (and <= ``at_most``), finite; else ModelError naming ``name``."""
    return check_number(name, value, above=0.0, at_most=at_most, hint=hint)


def check_nonnegative_float(
    name: str, value: Any, *, at_most: float | None = None, hint: str = ""
) -> float:
    """``value`` as a float >= 0 (and <= ``at_most``), finite; else ModelError naming ``name``."""
    return check_number(name, value, at_least=0.0, at_most=at_most, hint=hint)


def check_int(
    name: str, value: Any, *, at_least: int | None = None, at_most: int | None = None
) -> int:
    """``value`` as an int: a whole number (an int or numpy integer, not a bool, float, string or
    None) within the bounds; else ModelError naming ``name``."""
    if isinstance(value, bool) or not isinstance(value, numbers.Integral):
        raise ModelError(f"{name} must be a whole number, got {_what(value)}")
    v = int(value)
    if at_least is not None and v < at_least:
        raise ModelError(f"{name} must be >= {at_least}, got {v}")
    if at_most is not None and v > at_most:
        raise ModelError(f"{name} must be <= {at_most}, got {v}")
    return v


def check_seed(name: str, value: Any) -> int:
    """A seed of :func:`numpy.random.default_rng`: a whole number >= 0."""
    return check_int(name, value, at_least=0)
