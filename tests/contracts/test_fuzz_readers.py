"""Fuzz: seeded random mutations of valid files, thrown at every reader through the command line.

Every reader (RUNS.csv, generic run CSVs, OptiOdom metadata and run files, ROBOT.yaml,
PARAMS.yaml, track files, relative-motion tuples, t-test CSVs; ROS 1 and ROS 2 bags) gets every
kind of damage people and disks do (truncation, flipped bytes, binary junk, huge numbers, NaN and
inf, duplicated headers, keys and settings, deep YAML nesting, alias bombs, over-long lines, an
empty file, a BOM, CRLF or CR line ends, UTF-16, Latin-1; for bags, a length field gone wrong)
and a few random combinations of two. The contract,
whatever the input: exit 0, or exit 2 with exactly one line ``odocal: error: ...`` (warnings
aside), never a traceback, nothing on stdout on error, no output file and no temporary file left
behind on error, and on success a JSON document without NaN or infinity.

The generator is ours (numpy's default_rng, one seed per case): the cases are the same on every
run, and a failure names its reader, kind and seed. ``FUZZ_LOG=FILE`` appends one line per case
(reader, damage, exit status, last stderr line) for a person to read.
"""

from __future__ import annotations

import itertools
import json
import os
import re
from pathlib import Path

import numpy as np
import pytest

from tests.support.boundary_files import (
    OPTI_ID,
    PARAMS_YAML,
    ROBOT_YAML,
    RUNS_CSV,
    TRACK_YAML,
    TTEST_A,
    TTEST_B,
    generic_csv_text,
    tuples_text,
    write_optiodom,
)

# numpy overflow warnings on stderr are a silent wrong number in the making: fail on them
pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

_NUMBER = re.compile(rb"[-+]?(?:\d+\.?\d*|\.\d+)(?:[eE][-+]?\d+)?")
_BAD_NUMBERS = [
    b"nan",
    b"NaN",
    b"inf",
    b"-Infinity",
    b"1e400",
    b"-1e400",
    b"1e308",
    b"1e-400",
    b"9" * 400,
    b"",
    b"0x1F",
    b"1,5",
    b"+.5",
    b"-.5",
    b".5e-3",
    b"1_000",
    b"\xd9\xa3",  # an Arabic-Indic digit three
    b"1e-300",
    b"-0",
    b"12abc",
]


def _lines(data: bytes) -> list[bytes]:
    return data.split(b"\n")


def _pick_line(data: bytes, rng) -> tuple[list[bytes], int]:
    lines = _lines(data)
    return lines, int(rng.integers(len(lines)))


# --- generic damage: any file ------------------------------------------------------------------


def truncate(data, rng):
    return data[: int(rng.integers(len(data) + 1))]


def flip(data, rng):
    b = bytearray(data)
    for _ in range(int(rng.integers(1, 9))):
        if b:
            b[int(rng.integers(len(b)))] ^= int(rng.integers(1, 256))
    return bytes(b)


def junk(data, rng):
    at = int(rng.integers(len(data) + 1))
    return data[:at] + rng.bytes(int(rng.integers(1, 64))) + data[at:]


def empty(data, rng):
    return b""


def bom(data, rng):
    return b"\xef\xbb\xbf" + data


def crlf(data, rng):
    return data.replace(b"\n", b"\r\n")


def cr_only(data, rng):
    return data.replace(b"\n", b"\r")


def utf16(data, rng):
    return data.decode("utf-8", "replace").encode("utf-16")


def latin1(data, rng):
    lines, i = _pick_line(data, rng)
    lines[i] += " caf\xe9".encode("latin-1")
    return b"\n".join(lines)


def long_line(data, rng):
    lines, i = _pick_line(data, rng)
    lines.insert(i, b"1" * int(rng.integers(20_001, 40_000)))
    return b"\n".join(lines)


def long_field(data, rng):
    m = list(_NUMBER.finditer(data))
    if not m:
        return data + b"9" * 5000
    k = m[int(rng.integers(len(m)))]
    return data[: k.start()] + b"1" + b"0" * 5000 + data[k.end() :]


def dup_line(data, rng):
    lines, i = _pick_line(data, rng)
    lines.insert(i, lines[i])
    return b"\n".join(lines)


def del_line(data, rng):
    lines, i = _pick_line(data, rng)
    del lines[i]
    return b"\n".join(lines)


def bad_number(data, rng):
    m = list(_NUMBER.finditer(data))
    if not m:
        return data
    out = data
    for k in sorted(rng.choice(len(m), size=min(3, len(m)), replace=False), reverse=True):
        span = m[int(k)]
        bad = _BAD_NUMBERS[int(rng.integers(len(_BAD_NUMBERS)))]
        out = out[: span.start()] + bad + out[span.end() :]
    return out


def spaces(data, rng):
    return data.replace(b",", b" ,\t").replace(b": ", b":   ")


# --- tables -------------------------------------------------------------------------------------


def dup_header(data, rng):
    lines = _lines(data)
    i = next((k for k, ln in enumerate(lines) if ln and not ln.startswith(b"#")), 0)
    cols = lines[i].split(b",")
    cols.insert(int(rng.integers(len(cols) + 1)), cols[int(rng.integers(len(cols)))])
    lines[i] = b",".join(cols)
    return b"\n".join(lines)


def dup_setting(data, rng):
    lines = _lines(data)
    settings = [k for k, ln in enumerate(lines) if ln.startswith(b"#") and b":" in ln]
    if not settings:
        return b"# wheelbase_m: 0.4\n# wheelbase_m: 0.5\n" + data
    k = settings[int(rng.integers(len(settings)))]
    lines.insert(k, lines[k])
    return b"\n".join(lines)


def quote(data, rng):
    lines, i = _pick_line(data, rng)
    lines[i] = b'"' + lines[i]
    return b"\n".join(lines)


def extra_field(data, rng):
    lines, i = _pick_line(data, rng)
    lines[i] += b",1"
    return b"\n".join(lines)


# --- YAML ---------------------------------------------------------------------------------------


def deep(data, rng):
    # past MAX_DEPTH (32) for every reader; thousands of levels (past Python's recursion limit,
    # 0.3 s each: PyYAML's scanner is quadratic in the open brackets of a line) are
    # test_boundary_values' test_yaml_deep_nesting_is_an_error_not_a_crash, through the one
    # YAML loader all these readers share
    n = int(rng.integers(40, 400))
    return data + b"deep: " + b"[" * n + b"1" + b"]" * n + b"\n"


def deep_block(data, rng):
    n = int(rng.integers(40, 400))
    return data + b"".join(b"  " * k + b"k%d:\n" % k for k in range(n)) + b"  " * n + b"x: 1\n"


def alias_bomb(data, rng):
    fan = int(rng.integers(5, 10))
    text = b"a0: &a0 [x, x, x, x, x, x, x, x, x]\n"
    for k in range(1, 9):
        text += b"a%d: &a%d [" % (k, k) + b", ".join([b"*a%d" % (k - 1)] * fan) + b"]\n"
    return text + data


def dup_key(data, rng):
    lines = [ln for ln in _lines(data) if re.match(rb"^[A-Za-z_]+:", ln)]
    if not lines:
        return data
    return data + lines[int(rng.integers(len(lines)))] + b"\n"


def merge_key(data, rng):
    lines = _lines(data)
    keys = [k for k, ln in enumerate(lines) if re.match(rb"^[A-Za-z_]+: \S", ln)]
    if not keys:
        return data
    k = keys[int(rng.integers(len(keys)))]
    lines[k] = b"<<: {" + lines[k] + b"}"
    return b"\n".join(lines)


def tag(data, rng):
    tags = [b"!!python/object:os.system", b"!!binary", b"!!set", b"!custom", b"!!timestamp"]
    m = list(_NUMBER.finditer(data))
    if not m:
        return data
    k = m[int(rng.integers(len(m)))]
    return data[: k.start()] + tags[int(rng.integers(len(tags)))] + b" " + data[k.start() :]


def two_documents(data, rng):
    return data + b"---\n" + data


def recursive_alias(data, rng):
    return b"loop: &loop [*loop]\n" + data


GENERIC = [truncate, flip, junk, empty, bom, crlf, cr_only, utf16, latin1, long_line, long_field]
GENERIC += [dup_line, del_line, bad_number, bad_number, spaces]
TABLE = [dup_header, dup_setting, quote, extra_field]
YAML = [deep, deep_block, alias_bomb, dup_key, merge_key, tag, two_documents, recursive_alias]


# --- the readers, each through the command line ---------------------------------------------


def _setup_runs(tmp, data):
    (tmp / "runs.csv").write_bytes(data)
    return [
        "calibrate",
        "--robot",
        "paper-fig5",
        tmp / "runs.csv",
        "--out",
        tmp / "out" / "params.yaml",
    ]


def _setup_generic_validate(tmp, data):
    (tmp / "run.csv").write_bytes(data)
    (tmp / "p.yaml").write_text(PARAMS_YAML)
    return ["validate", tmp / "run.csv", "--params", tmp / "p.yaml"]


def _setup_generic_fit(tmp, data):
    runs = tmp / "runs"
    runs.mkdir()
    (runs / "a.csv").write_bytes(data)
    (runs / "b.csv").write_text(generic_csv_text(-1.0))
    (runs / "c.csv").write_text(generic_csv_text(2.5))
    return ["fit", runs, "--method", "linear", "--out", tmp / "out" / "params.yaml"]


def _setup_opti_meta(tmp, data):
    ds = write_optiodom(tmp)
    (ds / f"{OPTI_ID}_metadata.csv").write_bytes(data)
    (tmp / "p.yaml").write_text(PARAMS_YAML)
    return ["fit", ds, "--method", "heading", "--out", tmp / "out" / "params.yaml"]


def _setup_opti_run(tmp, data):
    ds = write_optiodom(tmp)
    (ds / f"{OPTI_ID}_run-02.csv").write_bytes(data)
    return ["fit", ds, "--method", "heading", "--out", tmp / "out" / "params.yaml"]


def _setup_robot(tmp, data):
    (tmp / "robot.yaml").write_bytes(data)
    return ["simulate", "--robot", tmp / "robot.yaml", "--runs", 2, "--out", tmp / "out" / "r.csv"]


def _setup_params(tmp, data):
    (tmp / "params.yaml").write_bytes(data)
    return [
        "simulate",
        "--params",
        tmp / "params.yaml",
        "--runs",
        2,
        "--out",
        tmp / "out" / "r.csv",
    ]


def _setup_track(tmp, data):
    (tmp / "track.yaml").write_bytes(data)
    return ["simulate", "--track", tmp / "track.yaml", "--runs", 2, "--out", tmp / "out" / "r.csv"]


def _setup_tuples(tmp, data):
    (tmp / "motion.tuple").write_bytes(data)
    return ["fit", tmp / "motion.tuple", "--out", tmp / "out" / "params.yaml"]


def _setup_ttest(tmp, data):
    (tmp / "a.csv").write_bytes(data)
    (tmp / "b.csv").write_text(TTEST_B)
    return ["ttest", tmp / "a.csv", tmp / "b.csv"]


READERS = {
    "runs-csv": (RUNS_CSV, _setup_runs, GENERIC + TABLE),
    "generic-csv-validate": (generic_csv_text(), _setup_generic_validate, GENERIC + TABLE),
    "generic-csv-fit": (generic_csv_text(), _setup_generic_fit, GENERIC + TABLE),
    "optiodom-metadata": (None, _setup_opti_meta, GENERIC + TABLE),
    "optiodom-run": (None, _setup_opti_run, GENERIC + TABLE),
    "robot-yaml": (ROBOT_YAML, _setup_robot, GENERIC + YAML),
    "params-yaml": (PARAMS_YAML, _setup_params, GENERIC + YAML),
    "track-yaml": (TRACK_YAML, _setup_track, GENERIC + YAML),
    "tuples": (tuples_text(30), _setup_tuples, GENERIC),
    "ttest-csv": (TTEST_A, _setup_ttest, GENERIC + TABLE),
}
COMBINED = 3  # cases per reader with two random kinds of damage on top of one each


def _valid_bytes(reader: str, tmp: Path) -> bytes:
    text = READERS[reader][0]
    if text is not None:
        return text.encode()
    ds = write_optiodom(tmp / "original")
    name = "metadata" if reader == "optiodom-metadata" else "run-02"
    return (ds / f"{OPTI_ID}_{name}.csv").read_bytes()


def _cases():
    for r, (_, _, kinds) in READERS.items():
        for i, kind in enumerate(kinds):
            yield pytest.param(r, (kind,), i, id=f"{r}-{kind.__name__}-{i}")
        for j in range(COMBINED):
            k = len(kinds) + j
            rng = np.random.default_rng([sorted(READERS).index(r), k])
            two = tuple(kinds[int(x)] for x in rng.choice(len(kinds), size=2, replace=False))
            yield pytest.param(r, two, k, id=f"{r}-{'+'.join(f.__name__ for f in two)}-{k}")


def _no_nan(text: str) -> None:
    def refuse(name):
        raise AssertionError(f"{name} in the JSON output")

    json.loads(text, parse_constant=refuse)


_case_numbers = itertools.count()


@pytest.fixture(scope="module")
def _cases_root(tmp_path_factory):
    return tmp_path_factory.mktemp("fuzz")


@pytest.fixture
def case_dir(_cases_root) -> Path:
    """An empty folder of the case's own, below one folder of the module's (pytest's tmp_path
    numbers each new folder after listing its base folder: 1.5 ms a case more, 250 cases)."""
    folder = _cases_root / f"case{next(_case_numbers)}"
    folder.mkdir()
    return folder


@pytest.mark.parametrize("reader, kinds, seed", list(_cases()))
def test_one_line_contract(cli, case_dir, reader, kinds, seed):
    tmp_path = case_dir
    rng = np.random.default_rng([sorted(READERS).index(reader), seed])
    data = _valid_bytes(reader, tmp_path)
    for kind in kinds:
        data = kind(data, rng)
    argv = READERS[reader][1](tmp_path, data)
    (tmp_path / "out").mkdir()
    status, out, err = cli(*argv, "--json")
    lines = err.splitlines()
    if os.environ.get("FUZZ_LOG"):  # a summary of what each case did, for people
        with open(os.environ["FUZZ_LOG"], "a") as fh:
            last = (lines or [""])[-1][:200]
            fh.write(f"{reader}\t{'+'.join(k.__name__ for k in kinds)}\t{status}\t{last}\n")
    assert "Traceback" not in err, err
    assert all(ln.startswith(("odocal: error: ", "odocal: warning: ")) for ln in lines), err
    if status == 0:
        assert not any(ln.startswith("odocal: error: ") for ln in lines), err
        _no_nan(out)
    else:
        assert status == 2, (status, err)
        assert out == "", out
        assert sum(ln.startswith("odocal: error: ") for ln in lines) == 1, err
        assert lines[-1].startswith("odocal: error: "), err
        assert list((tmp_path / "out").iterdir()) == []  # no output, no temporary file
    leftovers = [p for p in tmp_path.rglob("*.tmp")]
    assert leftovers == [], leftovers


# --- ROS bags: damaged bytes of a ROS 1 bag and a ROS 2 MCAP file -------------------------------


@pytest.fixture(scope="module")
def bags(tmp_path_factory):
    from tests.support.bag_files import TRACK, make_run, write_bag

    folder = tmp_path_factory.mktemp("bags")
    run = make_run(TRACK)
    ros1 = write_bag(folder / "run.bag", "ros1", run, imu=False)
    mcap = next(write_bag(folder / "run2", "mcap", run, imu=False).glob("*.mcap"))
    return {"ros1": ros1.read_bytes(), "mcap": mcap.read_bytes()}


def overwrite_length(data, rng):
    """A length field gone wrong: four bytes set to 2^31 - 1."""
    i = int(rng.integers(len(data) - 4))
    return data[:i] + b"\xff\xff\xff\x7f" + data[i + 4 :]


BAG_DAMAGE = [truncate, flip, junk, overwrite_length]


@pytest.mark.parametrize("kind", ["ros1", "mcap"])
@pytest.mark.parametrize("damage", BAG_DAMAGE, ids=[f.__name__ for f in BAG_DAMAGE])
def test_damaged_bags_keep_the_contract(cli, case_dir, bags, kind, damage):
    tmp_path = case_dir
    rng = np.random.default_rng([len(READERS), BAG_DAMAGE.index(damage), kind == "mcap"])
    bag = tmp_path / ("run.bag" if kind == "ros1" else "run.mcap")
    bag.write_bytes(damage(bags[kind], rng))
    (tmp_path / "out").mkdir()
    status, out, err = cli("fit", bag, "--method", "linear", "--out", tmp_path / "out" / "p.yaml")
    assert "Traceback" not in err
    assert status == 2 and out == "", (status, err)  # one run: a linear fit cannot succeed
    assert err.splitlines()[-1].startswith("odocal: error: ")
    assert sum(ln.startswith("odocal: error: ") for ln in err.splitlines()) == 1
    assert list((tmp_path / "out").iterdir()) == []
