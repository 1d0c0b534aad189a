"""odocal.core.checks: one set of argument checks, each naming the argument it refuses."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.core.checks import (
    check_int,
    check_nonnegative_float,
    check_number,
    check_positive_float,
    check_seed,
    parse_float,
    parse_int,
)
from odocal.errors import ModelError


def test_numbers_come_back_as_python_numbers():
    assert check_positive_float("x", np.float32(0.5)) == 0.5
    assert type(check_positive_float("x", np.float64(2))) is float
    assert check_nonnegative_float("k", 0) == 0.0
    assert check_int("n", np.int64(3)) == 3 and type(check_int("n", np.int64(3))) is int
    assert check_seed("seed", 0) == 0
    assert check_number("t", 0.05, at_least=0, below=1) == 0.05


@pytest.mark.parametrize(
    "check,value,needle",
    [
        (check_positive_float, "0.066", "a string"),
        (check_positive_float, None, "must be a number, got None"),
        (check_positive_float, np.array([0.066, 0.07]), "ndarray"),
        (check_positive_float, [0.066], "list"),
        (check_positive_float, True, "must be a number, got True"),
        (check_positive_float, float("nan"), "finite"),
        (check_positive_float, float("inf"), "finite"),
        (check_positive_float, -0.066, "must be > 0, got -0.066 (negative)"),
        (check_positive_float, 0.0, "must be > 0"),
        (check_nonnegative_float, -1e-9, "must be >= 0"),
        (check_int, 2.5, "whole number, got 2.5"),
        (check_int, 2.0, "whole number"),
        (check_int, "5", "a string"),
        (check_int, False, "whole number"),
        (check_seed, -1, "must be >= 0, got -1"),
        (check_seed, None, "whole number"),
    ],
)
def test_every_refusal_names_the_argument(check, value, needle):
    with pytest.raises(ModelError) as exc:
        check("the_arg", value)
    assert str(exc.value).startswith("the_arg must be ") and needle in str(exc.value)


def test_bounds_and_hints():
    with pytest.raises(ModelError, match=r"side_m must be > 0 and <= 100 m, got 1000"):
        check_number("side_m", 1000, above=0, at_most=100, hint=" m")
    with pytest.raises(ModelError, match="runs must be <= 10, got 11"):
        check_int("runs", 11, at_most=10)


# --- numbers written as text (flags, CSV fields, YAML tags): one parser ----------------------


@pytest.mark.parametrize(
    "text, value",
    [("1", 1.0), ("-0.5", -0.5), ("+.5", 0.5), ("1.", 1.0), ("1e-6", 1e-6), ("2E+3", 2000.0)],
)
def test_plain_decimal_numbers_are_read(text, value):
    assert parse_float(text) == value and type(parse_float(text)) is float


@pytest.mark.parametrize(
    "text",
    # Python's float() reads all of these (issue 27 item 19: '0_1' was 1.0 s of clock offset)
    ["0_1", "1_000.5", " 1", "1 ", "1\n", "\u0661", "\uff11", "0x10", "1e", "", "-", "."],
)
def test_what_float_reads_but_is_no_plain_number_is_refused(text):
    with pytest.raises(ValueError, match="not a decimal number"):
        parse_float(text)


def test_non_finite_words_are_left_to_the_caller():
    # read as float() reads them: each caller refuses them with its own words (the flag, the field)
    assert parse_float("inf") == float("inf") and parse_float("-Infinity") == -float("inf")
    assert parse_float("nan") != parse_float("nan")


def test_integers_are_plain_ascii_digits():
    assert parse_int("12") == 12 and parse_int("-3") == -3 and parse_int("+0") == 0
    for text in ("1_0", " 1", "1.0", "1e3", "\u0661", ""):
        with pytest.raises(ValueError, match="not an integer"):
            parse_int(text)
