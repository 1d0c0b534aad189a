"""The relative-motion tuple reader (io.tuples): rotations and line numbers, pipes, one-line
errors for every bad input."""

from __future__ import annotations

import os
import threading

import numpy as np
import pytest

from odocal.errors import InputError
from odocal.io.tuples import MAX_LINE_BYTES, read_tuples, refuse_repeated_tuples

LINE = '{ "T": 0.8, "phi_l": 0.5, "phi_r": -0.25, "sm": [ 0.001, -0.002, 0.05 ] }'


def test_reader_reads_rotations_and_line_numbers(tmp_path):
    # a blank line is skipped; two objects on one line (as in the authors' concatenated files)
    path = tmp_path / "ok.tuple"
    path.write_text(f"{LINE}\n\n{LINE} {LINE}\n")
    data = read_tuples(path)
    assert len(data) == 3 and data.line.tolist() == [1, 3, 3]
    np.testing.assert_allclose(data.phi_left_rad, 0.4)  # rad/s * s
    np.testing.assert_allclose(data.phi_right_rad, -0.2)
    np.testing.assert_allclose(data.sensor_motion[0], [0.001, -0.002, 0.05])
    np.testing.assert_allclose(data.duration_s, 0.8)


def test_reader_works_on_a_pipe():
    # non-seekable input (a pipe, as with <(...)): read once, sequentially
    r, w = os.pipe()

    def feed():
        with os.fdopen(w, "w") as fh:
            for _ in range(50):
                fh.write(LINE + "\n")

    thread = threading.Thread(target=feed)
    thread.start()
    try:
        data = read_tuples(f"/dev/fd/{r}")
    finally:
        thread.join()
        os.close(r)
    assert len(data) == 50


BAD = [
    ("invalid JSON", '{"T": 0.8, "phi_l": 0.5', 1, None),
    ("JSON object", "[0.8, 0.5, -0.25]", 1, None),
    ("missing key", '{"T": 0.8, "phi_l": 0.5, "sm": [0, 0, 0]}', 1, "phi_r"),
    ("duplicated key", '{"T": 0.8, "T": 0.9, "phi_l": 0.5, "phi_r": 0, "sm": [0, 0, 0]}', 1, "T"),
    ("not a finite", '{"T": 0.8, "phi_l": NaN, "phi_r": 0, "sm": [0, 0, 0]}', 1, "phi_l"),
    ("not a finite", '{"T": 0.8, "phi_l": 0, "phi_r": 0, "sm": [0, Infinity, 0]}', 1, "sm[1]"),
    ("not a finite", '{"T": 0.8, "phi_l": 1e999, "phi_r": 0, "sm": [0, 0, 0]}', 1, "phi_l"),
    ("expected a number", '{"T": "0.8", "phi_l": 0, "phi_r": 0, "sm": [0, 0, 0]}', 1, "T"),
    ("expected a number", '{"T": 0.8, "phi_l": true, "phi_r": 0, "sm": [0, 0, 0]}', 1, "phi_l"),
    ("must be > 0", '{"T": 0, "phi_l": 0, "phi_r": 0, "sm": [0, 0, 0]}', 1, "T"),
    ("must be > 0", '{"T": -1, "phi_l": 0, "phi_r": 0, "sm": [0, 0, 0]}', 1, "T"),
    ("3 numbers", '{"T": 0.8, "phi_l": 0, "phi_r": 0, "sm": [0, 0]}', 1, "sm"),
    ("3 numbers", '{"T": 0.8, "phi_l": 0, "phi_r": 0, "sm": 0.1}', 1, "sm"),
    ("absurd magnitude", '{"T": 0.8, "phi_l": 0, "phi_r": 0, "sm": [1e9, 0, 0]}', 1, "sm[0]"),
    ("absurd magnitude", '{"T": 0.8, "phi_l": 5e5, "phi_r": 0, "sm": [0, 0, 0]}', 1, "phi_l"),
    ("longer than", '{"pad": "' + "x" * MAX_LINE_BYTES + '"}', 1, None),
    ("empty", "", None, None),
    ("empty", "\n  \n", None, None),
]


@pytest.mark.parametrize(("needle", "text", "line", "field"), BAD)
def test_reader_bad_inputs_one_line_errors(tmp_path, needle, text, line, field):
    path = tmp_path / "bad.tuple"
    prefix = f"{LINE}\n" if line is not None else ""  # the problem sits on line 2
    path.write_text(prefix + text + "\n" if text.strip() else text)
    with pytest.raises(InputError) as info:
        read_tuples(path)
    msg = str(info.value)
    assert "\n" not in msg and needle in msg and str(path) in msg, msg
    if line is not None:
        assert f"line {line + 1}" in msg and info.value.line == line + 1, msg
    if field is not None:
        assert f"field '{field}'" in msg, msg


def test_reader_missing_file_and_folder(tmp_path):
    with pytest.raises(InputError, match="no such file"):
        read_tuples(tmp_path / "nope.tuple")
    with pytest.raises(InputError, match="directory"):
        read_tuples(tmp_path)


@pytest.mark.parametrize("end", ["\r", "\r\n", "\n"])
def test_reader_takes_cr_crlf_and_lf_line_ends(tmp_path, end):
    # CR-only (old Mac) line ends, as the README promises for every text file; 1000 lines cross
    # the reader's chunk boundary, so a CRLF split between two chunks is one line end
    rows = [LINE.replace("0.8", f"0.{k + 1000}") for k in range(1000)]
    path = tmp_path / "ends.tuple"
    path.write_bytes(end.join(rows).encode() + end.encode() + b"  " + end.encode())
    data = read_tuples(path)
    assert len(data) == 1000 and data.line[-1] == 1000
    np.testing.assert_allclose(data.duration_s[[0, -1]], [0.1, 0.1999])


def test_reader_counts_cr_only_lines_in_its_errors(tmp_path):
    path = tmp_path / "bad.tuple"
    path.write_bytes(f"{LINE}\r{LINE}\r{{nope\r".encode())
    with pytest.raises(InputError, match="line 3: invalid JSON"):
        read_tuples(path)


def _tuples(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    return read_tuples(path)


ROWS = [LINE.replace("0.5", f"0.{k + 10}") for k in range(6)]


@pytest.mark.parametrize(
    ("texts", "needle"),
    [
        ([ROWS + ROWS[2:3]], "bad.tuple, line 7: the same tuple as line 3"),  # a row copied
        ([ROWS + ROWS], "bad.tuple, line 7: the same tuple as line 1"),  # concatenated
        ([ROWS + ROWS[::2]], "line 7: the same tuple as line 1"),  # with its own decimation
        ([ROWS, ROWS], "other.tuple, line 1: the same tuple as "),  # a copy, another name
        ([ROWS[:2] + [ROWS[3] + " " + ROWS[3]]], "line 3: the same tuple as line 3"),
    ],
)
def test_the_same_interval_given_twice_is_refused(tmp_path, texts, needle):
    # it would count twice: standard errors sqrt 2 too small, without a word
    data = [
        _tuples(tmp_path, name, "\n".join(rows) + "\n")
        for name, rows in zip(("bad.tuple", "other.tuple"), texts, strict=False)
    ]
    with pytest.raises(InputError, match="would count twice") as info:
        refuse_repeated_tuples(data)
    assert needle in str(info.value)


def test_still_intervals_may_repeat_and_distinct_ones_pass(tmp_path):
    still = '{"T": 0.8, "phi_l": 0, "phi_r": 0, "sm": [0, 0, 0]}'
    data = _tuples(tmp_path, "ok.tuple", "\n".join([*ROWS, still, still]) + "\n")
    refuse_repeated_tuples([data])  # a robot standing still at a fixed rate
