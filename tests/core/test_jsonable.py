"""JSON's numbers: NaN and infinity become null, integers stay integers, text and booleans stay."""

import json
import math

import numpy as np

from odocal.core.jsonable import finite_list, finite_or_none, jsonable


def test_undefined_numbers_are_null_and_the_rest_is_a_float():
    assert finite_or_none(None) is None
    assert finite_or_none(math.nan) is None and finite_or_none(-math.inf) is None
    v = finite_or_none(np.float32(0.5))
    assert v == 0.5 and type(v) is float


def test_nested_arrays_keep_their_shape():
    a = np.array([[1.0, np.nan], [np.inf, -2.0]])
    assert finite_list(a) == [[1.0, None], [None, -2.0]]


def test_a_mixed_record_becomes_valid_json():
    record = {
        "name": "run 1",
        "ok": np.bool_(True),
        "flag": False,
        "n": np.int64(3),
        "values": (np.float64(1.5), math.nan),
        "nested": {"cov": np.array([[np.inf, np.nan], [np.nan, -np.inf]])},
        "none": None,
    }
    out = jsonable(record)
    assert out == {
        "name": "run 1",
        "ok": True,
        "flag": False,
        "n": 3,
        "values": [1.5, None],
        "nested": {"cov": [[None, None], [None, None]]},
        "none": None,
    }
    assert type(out["n"]) is int and type(out["ok"]) is bool
    json.dumps(out, allow_nan=False)


def test_python_integers_and_booleans_keep_their_json_type():
    # a count written as 3.0, or a flag as 0, is another JSON value to a reader
    out = jsonable({"n": 3, "big": 2**60 + 1, "flag": False, "ok": [True]})
    assert out == {"n": 3, "big": 2**60 + 1, "flag": False, "ok": [True]}
    assert [type(out[k]) for k in ("n", "big", "flag")] == [int, int, bool]
    assert type(out["ok"][0]) is bool
    assert json.dumps(out) == '{"n": 3, "big": 1152921504606846977, "flag": false, "ok": [true]}'
