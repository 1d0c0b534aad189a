"""The method registry (comparison.methods): every method, in order, each with its real-data
route."""

from __future__ import annotations

from odocal.comparison.methods import METHOD_REGISTRY as METHODS

NAMES = [
    "heading",
    "umbmark-x",
    "umbmark-y",
    "umbmark-mean",
    "bcpt",
    "ivanjko",
    "linear",
    "trajectory",
]


def test_registry_holds_every_method():
    assert [m.name for m in METHODS] == NAMES
    assert all(m.real is not None for m in METHODS)
