"""Every value is checked where it enters, in every format (odocal.io.limits), and no run counts
twice.

Formats: ROBOT.yaml / PARAMS.yaml / track files (the YAML reader: duplicated keys, YAML 1.2
numbers, merge keys, alias bombs, deep nesting, tags, huge numbers), generic run CSVs and their
``#`` settings, OptiOdom metadata and run files, ROS bags, tuples, RUNS.csv, and every numeric
flag of the command line.
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
import time
from pathlib import Path

import numpy as np
import pytest

from odocal.errors import InputError
from odocal.io import limits
from odocal.io.yamlfile import MAX_DEPTH, load_yaml
from tests.support.boundary_files import (
    OPTI_ID,
    OPTI_METADATA,
    PARAMS_YAML,
    ROBOT_YAML,
    RUNS_CSV,
    TRACK_YAML,
    generic_csv_text,
    write_optiodom,
)

pytestmark = pytest.mark.filterwarnings("error::RuntimeWarning")

BASE = "wheel_diameter_m: 0.15\nwheelbase_m: 0.385\n"


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def yaml_doc(tmp_path, text):
    return load_yaml(write(tmp_path / "f.yaml", text))


# --- YAML: robot, parameter and track files --------------------------------------------------


def test_yaml_duplicated_keys_are_errors_naming_both_lines(cli, tmp_path):
    robot = write(tmp_path / "r.yaml", BASE + "wheelbase_m: 0.4\n")
    cli("simulate", "--robot", robot).expect_error("line 3", "'wheelbase_m'", "first on line 2")
    nested = write(tmp_path / "n.yaml", BASE + "systematic:\n  E_b: 1.01\n  E_b: 1.5\n")
    cli("simulate", "--robot", nested).expect_error("line 5", "'systematic.E_b'", "line 4")
    params = write(tmp_path / "p.yaml", PARAMS_YAML + "wheelbase_m: 0.5\n")
    cli("simulate", "--params", params).expect_error("'wheelbase_m'", "given twice")


@pytest.mark.parametrize(
    "text, value",
    [
        ("+.5", 0.5),
        ("-.5", -0.5),
        (".5", 0.5),
        (".5e-3", 0.5e-3),
        ("1e-6", 1e-6),
        ("2E3", 2000.0),
        ("1.5e+2", 150.0),
        ("012", 12),  # YAML 1.2: decimal (YAML 1.1 read an octal ten)
        ("0x1F", 31),
        ("0o17", 15),
        ("-7", -7),
    ],
)
def test_yaml_1_2_numbers(tmp_path, text, value):
    assert yaml_doc(tmp_path, f"v: {text}\n").data["v"] == value


@pytest.mark.parametrize("text", ["yes", "no", "on", "off", "2024-05-01", "1_000", "1:30"])
def test_yaml_1_1_oddities_stay_text(tmp_path, text):
    # YAML 1.1 turned these into booleans, a date, 1000 and a sexagesimal 90
    assert yaml_doc(tmp_path, f"v: {text}\n").data["v"] == text


def test_yaml_1_2_numbers_through_the_robot_file(cli, tmp_path):
    a = write(tmp_path / "a.yaml", "wheel_diameter_m: +.15\nwheelbase_m: .385\n")
    b = write(tmp_path / "b.yaml", BASE)
    ja, jb = (json.loads(cli("simulate", "--robot", p, "--json")[1]) for p in (a, b))
    ja.pop("robot", None), jb.pop("robot", None)
    assert ja == jb
    neg = write(tmp_path / "c.yaml", BASE + "nonsystematic: {k_r_m: -.5e-6}\n")
    cli("simulate", "--robot", neg).expect_error("nonsystematic.k_r_m", "must be >= 0")


def test_yaml_merge_keys(cli, tmp_path):
    doc = yaml_doc(
        tmp_path,
        "base: &b {x: 1, y: 2}\nmore: &m {z: 3}\n"
        "one:\n  <<: *b\n  y: 20\n"  # the mapping's own key wins over the merged one
        "two:\n  <<: [*b, *m]\n",
    )
    assert doc.data["one"] == {"x": 1, "y": 20}
    assert doc.data["two"] == {"x": 1, "y": 2, "z": 3}
    assert doc.lines["one.y"] == 5 and doc.lines["one.x"] == 1  # where each value was written
    robot = write(
        tmp_path / "r.yaml",
        "geometry: &g\n  wheel_diameter_m: 0.15\n  wheelbase_m: 0.385\n",
    )
    # a whole robot through a merge key: the unknown key 'geometry' is still refused
    cli("simulate", "--robot", robot).expect_error("geometry", "unknown key")
    robot.write_text("<<: {wheel_diameter_m: 0.15, wheelbase_m: 0.385}\n")
    assert cli("simulate", "--robot", robot, "--runs", 2)[0] == 0


def test_yaml_alias_bomb_is_refused_quickly(cli, tmp_path):
    text = "a0: &a0 [x, x, x, x, x, x, x, x, x]\n"
    for k in range(1, 10):
        text += f"a{k}: &a{k} [" + ", ".join([f"*a{k - 1}"] * 9) + "]\n"
    robot = write(tmp_path / "bomb.yaml", text + BASE)  # 9^10 values if expanded
    start = time.perf_counter()
    # a0 makes 10 values, a1 91, ... a4 66 430, a5 597 871: a5 (line 6) passes 200 000
    cli("simulate", "--robot", robot).expect_error("line 6:", "aliases are expanded")
    assert time.perf_counter() - start < 5.0
    many = write(tmp_path / "many.yaml", "d: &d 1\nv: [" + ", ".join(["*d"] * 1500) + "]\n")
    cli("simulate", "--robot", many).expect_error("more than 1000 aliases")
    # a few aliases are fine
    few = write(tmp_path / "few.yaml", "wheel_diameter_m: &d 0.15\nwheelbase_m: 0.385\n")
    few.write_text(few.read_text() + "believed: {wheel_diameter_right_m: *d, ")
    few.write_text(few.read_text() + "wheel_diameter_left_m: *d, wheelbase_m: 0.39}\n")
    assert cli("simulate", "--robot", few, "--runs", 2)[0] == 0


@pytest.mark.parametrize(
    "text",
    [
        "a: &a [1, 2, {b: 3, c: [4, 5]}]\nd: [*a, *a, {<<: {e: *a, f: 6}, g: *a}]\n",
        "base: &b {x: 1, y: [2, 3]}\nm: {<<: [*b, {z: 4, x: 5}], w: 6}\nn: [*b, [*b, *b]]\n",
        "s: &s x\nl: &l [*s, *s, [*s]]\nt: [*l, *l, *l]\n",
    ],
)
def test_the_expansion_is_counted_as_the_conversion_counts(text):
    """The alias-bomb bound is checked on the parsed graph before anything is expanded: it
    counts the values the conversion then makes, exactly."""
    from odocal.io import yamlfile

    loader = yamlfile._Loader(text, "t.yaml")
    node = loader.get_single_node()
    conv = yamlfile._Converter("t.yaml")
    conv.value(node, "", 0)
    assert yamlfile._values(node, {}) == conv.nodes > 10


@pytest.mark.parametrize(
    "text",
    [
        "v: " + "[" * 5000 + "]" * 5000 + "\n",
        "v: " + "{a: " * 3000 + "1" + "}" * 3000 + "\n",
        "".join("  " * k + f"k{k}:\n" for k in range(300)) + "  " * 300 + "x: 1\n",
        "loop: &l [*l]\n",
        "loop: &l {<<: *l}\n",
    ],
    ids=["flow-lists", "flow-maps", "block", "recursive-alias", "recursive-merge"],
)
def test_yaml_deep_nesting_is_an_error_not_a_crash(cli, tmp_path, text):
    robot = write(tmp_path / "deep.yaml", text + BASE)
    cli("simulate", "--robot", robot).expect_error(f"nested more than {MAX_DEPTH} levels")


@pytest.mark.parametrize(
    "value, needle",
    [
        ("!!python/object/apply:os.system [echo]", "unsupported tag"),
        ("!!binary aGVsbG8=", "unsupported tag"),
        ("1" + "0" * 400, "over-long number"),
        ("1e400", "too large for a float"),
        ("1.0e308", "implausible value"),
        (".nan", "must be finite"),
        ("-.inf", "must be finite"),
        ("nan", "text; and a value must be finite"),
        ("", "no value"),
        ("yes", "expected a number"),
        ("[0.4]", "expected a number"),
        ("0.385 m", "expected a number"),
    ],
)
def test_yaml_bad_numbers_name_file_line_and_key(cli, tmp_path, value, needle):
    robot = write(tmp_path / "r.yaml", f"wheel_diameter_m: 0.15\nwheelbase_m: {value}\n")
    cli("simulate", "--robot", robot).expect_error(str(robot), "line 2", "wheelbase_m", needle)


def test_yaml_size_and_key_kinds(cli, tmp_path):
    big = tmp_path / "big.yaml"
    big.write_bytes(BASE.encode() + b"# " + b"x" * (limits.MAX_YAML_BYTES + 10) + b"\n")
    cli("simulate", "--robot", big).expect_error("larger than")
    key = write(tmp_path / "k.yaml", BASE + "? [a, b]\n: 1\n")
    cli("simulate", "--robot", key).expect_error("a key must be a plain name")
    name = write(tmp_path / "n.yaml", BASE + "name: {first: a}\n")
    cli("simulate", "--robot", name).expect_error("'name'", "expected a name")


@pytest.mark.parametrize("direction", ["CW", "Ccw", "ccw", "FWD"])
def test_track_direction_in_any_case(cli, tmp_path, direction):
    track = write(
        tmp_path / "t.yaml", TRACK_YAML.replace("direction: ccw", f"direction: {direction}")
    )
    status, out, err = cli("simulate", "--track", track, "--runs", 2, "--json")
    assert status == 0, err
    assert list(json.loads(out)["by_direction"]) == [direction.lower()]


@pytest.mark.parametrize(
    "segment, needle",
    [
        ("- straight_m: 1.0e6", "segments[2].straight_m"),
        ("- turn_deg: 1.0e5", "segments[2].turn_deg"),
        ("- arc: {radius_m: 1.0e6, angle_deg: 90}", "segments[2].arc.radius_m"),
        ("- arc: {radius_m: -1, angle_deg: 90}", "must be >= 0"),
        ("- arc: {radius_m: 1, angle_deg: 1.0e9}", "segments[2].arc.angle_deg"),
        ("- arc: {radius_m: 1}", "arc needs radius_m and angle_deg"),
        ("- jump: 2", "unknown segment kind"),
        ("- {straight_m: 1, turn_deg: 90}", "each segment is one of"),
    ],
)
def test_track_segments_are_bounded_and_located(cli, tmp_path, segment, needle):
    track = write(tmp_path / "t.yaml", f"segments:\n  - straight_m: 1\n  {segment}\n")
    cli("simulate", "--track", track).expect_error(str(track), "line 3", needle)


def test_a_track_that_goes_nowhere(cli, tmp_path):
    track = write(tmp_path / "t.yaml", "segments:\n  - straight_m: 0\n  - turn_deg: 0\n")
    cli("simulate", "--track", track).expect_error("neither moves nor turns")


# --- generic run CSVs ----------------------------------------------------------------------


def _generic(tmp_path, edit=lambda t: t, name="run.csv") -> Path:
    return write(tmp_path / name, edit(generic_csv_text()))


@pytest.mark.parametrize(
    "setting, needle",
    [
        ("# wheelbase_m: 3850", "implausible value '3850'"),
        ("# side_m: 1e-7", "implausible value"),
        ("# ticks_per_rev: 0", "> 0"),
        ("# ticks_per_rev: 1e12", "implausible value"),
        ("# ticks_wrap: 1", "implausible value"),
        ("# wheelbase_m: nan", "must be finite"),
        ("# wheelbase_m: 1e400", "too large for a float"),
        ("# label: " + "x" * 300, "over-long value"),
    ],
)
def test_generic_csv_settings_are_checked(cli, tmp_path, setting, needle):
    def edit(text):
        lines = text.splitlines()
        key = setting.split(":")[0]
        lines = [ln for ln in lines if not ln.startswith(key + ":")]
        return "\n".join([lines[0], setting, *lines[1:]]) + "\n"

    run = _generic(tmp_path, edit)
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    cli("validate", run, "--params", params).expect_error(str(run), "line 2", needle)


def test_generic_csv_label_in_any_case(tmp_path):
    from odocal.io.generic_csv import load_generic_csv

    run = _generic(tmp_path, lambda t: t.replace("# label: ccw", "# label: CCW"))
    assert load_generic_csv(run).label == "ccw"
    free = _generic(tmp_path, lambda t: t.replace("# label: ccw", "# label: figure eight"), "b.csv")
    assert load_generic_csv(free).label == "figure eight"  # free text is kept as it is


@pytest.mark.parametrize(
    "column, value, needle",
    [
        ("x_m", "1e9", "implausibly large"),
        ("theta_rad", "1e7", "implausibly large"),
        ("time_s", "1e13", "implausibly large"),
        ("wheel_left_rad", "1e10", "implausibly large"),
        ("y_m", "-1e400", "too large for a float"),
        ("x_m", "inf", "must be finite"),
    ],
)
def test_generic_csv_values_are_bounded(cli, tmp_path, column, value, needle):
    def edit(text):
        lines = text.splitlines()
        header = next(i for i, ln in enumerate(lines) if ln.startswith("time_s"))
        j = lines[header].split(",").index(column)
        row = lines[header + 3].split(",")
        row[j] = value
        lines[header + 3] = ",".join(row)
        return "\n".join(lines) + "\n"

    run = _generic(tmp_path, edit)
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    cli("validate", run, "--params", params).expect_error(f"field '{column}'", needle)


def test_generic_csv_wheel_glitch_and_utm_coordinates(cli, tmp_path):
    params = write(tmp_path / "p.yaml", PARAMS_YAML)

    def glitch(text):
        lines = text.splitlines()
        header = next(i for i, ln in enumerate(lines) if ln.startswith("time_s"))
        row = lines[header + 5].split(",")
        row[1] = str(float(row[1]) + 5000)  # 5000 rad in one sample
        lines[header + 5] = ",".join(row)
        return "\n".join(lines) + "\n"

    cli("validate", _generic(tmp_path, glitch), "--params", params).expect_error(
        "wheel_right_rad", "in one sample", "glitch"
    )

    def utm(text):  # the same run in UTM coordinates (northing 4.6e6 m): accepted
        lines = text.splitlines()
        header = next(i for i, ln in enumerate(lines) if ln.startswith("time_s"))
        for i in range(header + 1, len(lines)):
            row = lines[i].split(",")
            row[3] = repr(float(row[3]) + 512_000.0)
            row[4] = repr(float(row[4]) + 4_600_000.0)
            lines[i] = ",".join(row)
        return "\n".join(lines) + "\n"

    a, b = _generic(tmp_path, name="a.csv"), _generic(tmp_path, utm, "b.csv")
    ra, rb = (json.loads(cli("validate", p, "--params", params, "--json")[1]) for p in (a, b))
    assert rb["mean_final_error_m"] == pytest.approx(ra["mean_final_error_m"], abs=1e-6)


# --- OptiOdom metadata and run files ---------------------------------------------------------


@pytest.mark.parametrize(
    "old, new, line, needle",
    [
        ("ngear,43.7", "ngear,0", 2, "> 0"),
        ("ngear,43.7", "ngear,1e300", 2, "implausible value"),
        ("ngear,43.7", "ngear,nan", 2, "must be finite"),
        ("ngear,43.7", "ngear,abc", 2, "not a number"),
        ("encRes,64", "encRes,0.5", 3, "implausible value"),
        ("encRes,64", "encRes,", 3, "'encRes' is missing"),
        ("Li,0.2", "Li,2000", 4, "implausible value"),
        ("Li,0.2", "Li,0.2,0.3", 4, "expected one value, got 2"),
        ("Li,0.2", "Li,0.2\nLi,0.3", 5, "given twice (first on line 4)"),
        ("Di,0.084,0.084", "Di,0.084,-0.084", 5, "> 0"),
        ("Di,0.084,0.084", "Di,0.084,0.084,0.09", 5, "at most 2 values"),
        ("L,0.75", "L,1e9", 8, "implausible value"),
        ("N,2", "N,1", 7, "must be 1, but there is run 2"),
        ("N,2", "N,2.5", 7, "whole number"),
    ],
)
def test_optiodom_metadata_is_checked(cli, tmp_path, old, new, line, needle):
    ds = write_optiodom(tmp_path)
    meta = write(ds / f"{OPTI_ID}_metadata.csv", OPTI_METADATA.replace(old, new))
    cli("fit", ds, "--method", "heading").expect_error(str(meta), f"line {line}", needle)


def test_optiodom_ticks_per_rev_product_is_checked(cli, tmp_path):
    ds = write_optiodom(tmp_path)
    write(ds / f"{OPTI_ID}_metadata.csv", OPTI_METADATA.replace("encRes,64", "encRes,1e8"))
    cli("fit", ds, "--method", "heading").expect_error("ngear x encRes", "implausible")


def test_optiodom_labels_follow_the_run_numbers(tmp_path):
    from odocal.io.recordings import load_recordings

    ds = write_optiodom(tmp_path)
    meta = ds / f"{OPTI_ID}_metadata.csv"
    meta.write_text(OPTI_METADATA.replace("N,2", "N,4"))
    # runs 1-2 CW, 3-4 CCW; run 2 (CW) was deleted and the CCW square is run 3
    (ds / f"{OPTI_ID}_run-02.csv").rename(ds / f"{OPTI_ID}_run-03.csv")
    runs = load_recordings(ds)
    assert [(r.meta["run"], r.label) for r in runs] == [(1, "cw"), (3, "ccw")]


@pytest.mark.parametrize(
    "edit, needle",
    [
        (lambda rows: rows[:10] + rows[11:], "a sample is missing"),
        (lambda rows: rows[:5] + [rows[5].replace(",", ",1e9,", 1)] + rows[6:], "6 fields"),
        (lambda rows: [rows[0], rows[1].rsplit(",", 1)[0] + ",1e8"] + rows[2:], "ticks_L"),
        (lambda rows: [rows[0]] + ["0.05,1e9,0,0,0,0"] + rows[2:], "x_gt_m"),
        (lambda rows: rows[:1], "at least two samples"),
    ],
    ids=["gap", "extra-field", "huge-ticks", "huge-position", "one-row"],
)
def test_optiodom_run_files_are_checked(cli, tmp_path, edit, needle):
    ds = write_optiodom(tmp_path)
    run = ds / f"{OPTI_ID}_run-02.csv"
    rows = run.read_text().splitlines()
    run.write_text("\n".join(edit(rows)) + "\n")
    cli("fit", ds, "--method", "heading").expect_error(str(run), needle)


# --- ROS bags ------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def bag_run():
    """A short run (a straight and a turn, 7.6 s: half the samples of bag_files.TRACK's): these
    tests are about values and stamps, not about what the robot drove."""
    from odocal.core.tracks import Track, spot_turn, straight
    from tests.support.bag_files import make_run

    return make_run(Track("a straight and a turn", (straight(1.0), spot_turn(math.pi / 2))))


@pytest.mark.parametrize(
    "what, needle",
    [
        ("joint", "a wheel position (rad) is implausibly large"),
        ("imu", "angular_velocity (rad/s) is implausibly large"),
        ("truth", "the position (m) is implausibly large"),
    ],
)
def test_bag_absurd_values_are_named(tmp_path, bag_run, what, needle):
    from odocal.io.bag_recording import load_bag_recording
    from tests.support.bag_files import write_bag

    kw: dict = {}
    if what == "joint":
        pos = np.column_stack([bag_run.right, bag_run.left])
        pos[40:, 0] += 1e12
        kw["positions"] = pos
    elif what == "truth":

        def far(w):
            for k, t in enumerate(bag_run.time_s):
                w.pose_stamped("/mocap/pose", t, 1e12 if k == 30 else 0.0, 0.0, 0.0)

        kw.update(truth=False, extra=far)
    else:

        def spin(w):
            for k, t in enumerate(bag_run.time_s):
                w.imu("/imu", t, (0.0, 1e6 if k == 20 else 0.0, 0.0))

        kw.update(imu=False, extra=spin)
    path = write_bag(tmp_path / "bad.bag", "ros1", bag_run, **kw)
    with pytest.raises(InputError, match=re.escape(needle)):
        load_bag_recording(path)


@pytest.mark.parametrize("start_s", [1e-6, 2.0e9], ids=["tiny", "huge"])
def test_bag_tiny_and_huge_stamps(tmp_path, bag_run, start_s):
    from odocal.io.bag_recording import load_bag_recording
    from tests.support.bag_files import write_bag

    shifted = dataclasses.replace(bag_run, time_s=bag_run.time_s - bag_run.time_s[0] + start_s)
    path = write_bag(tmp_path / "t.bag", "ros1", shifted, imu=False)
    rec = load_bag_recording(path)
    # times start at 0 and keep their 20 ms steps (to float precision at 2e9 s: 0.25 us)
    np.testing.assert_allclose(np.diff(rec.time_s), np.diff(bag_run.time_s), atol=1e-6)
    assert rec.time_s[0] == 0.0


def test_bag_clocks_that_do_not_overlap(tmp_path, bag_run):
    from odocal.io.bag_recording import load_bag_recording
    from tests.support.bag_files import write_bag

    # wheel joints stamped in simulated time (from 0 s), the ground truth in wall-clock time
    wall = dataclasses.replace(bag_run, time_s=bag_run.time_s + 1.7e9)
    path = write_bag(tmp_path / "c.bag", "ros1", wall, times=bag_run.time_s - 5.0 + 1e-3)
    with pytest.raises(InputError, match="hardly overlap in time"):
        load_bag_recording(path)


# --- tuples and RUNS.csv ---------------------------------------------------------------------


@pytest.mark.parametrize(
    "line, needle",
    [
        ('{"T": 1, "T": 2, "phi_l": 1, "phi_r": 1, "sm": [0, 0, 0]}', "duplicated key"),
        ('{"T": 1, "phi_l": 1' + "0" * 400 + ', "phi_r": 1, "sm": [0, 0, 0]}', "not a finite"),
        ('{"T": 1, "phi_l": NaN, "phi_r": 1, "sm": [0, 0, 0]}', "not a finite"),
        ('{"T": 1, "phi_l": 1e5, "phi_r": 1, "sm": [0, 0, 0]}', "absurd magnitude"),
        ('{"T": -1, "phi_l": 1, "phi_r": 1, "sm": [0, 0, 0]}', "must be > 0"),
    ],
)
def test_tuples_through_the_command_line(cli, tmp_path, line, needle):
    from tests.support.boundary_files import tuples_text

    f = write(tmp_path / "m.tuple", tuples_text(10) + line + "\n")
    cli("fit", f).expect_error(str(f), "line 11", needle)


def test_runs_csv_values_and_a_repeated_row(cli, tmp_path):
    runs = write(tmp_path / "runs.csv", RUNS_CSV.replace("-0.2531", "2e6"))
    cli(
        "calibrate", "--robot", "paper-fig5", runs, "--side-length", 4, "--method", "umbmark"
    ).expect_error("line 3", "x_m", "implausibly")
    rows = RUNS_CSV.splitlines()
    runs.write_text("\n".join([*rows, rows[3]]) + "\n")  # a row pasted twice
    status, out, err = cli("calibrate", "--robot", "paper-fig5", runs, "--side-length", 4)
    assert status == 0
    assert "odocal: warning: " in err and "line 9 repeats line 4" in err


# --- the same run given twice ----------------------------------------------------------------


def test_the_same_run_twice_is_refused(cli, tmp_path):
    runs = tmp_path / "runs"
    for name, turn in (("a", 1.5), ("b", -1.0), ("c", 2.5)):
        write(runs / f"{name}.csv", generic_csv_text(turn))
    (tmp_path / "alias").symlink_to(runs)
    a = runs / "a.csv"
    for paths in (
        [runs, a],  # a folder and a file inside it
        [a, runs / ".." / "runs" / "a.csv", runs / "b.csv", runs / "c.csv"],  # two spellings
        [runs, tmp_path / "alias"],  # a folder and a link to it
    ):
        cli("fit", *paths, "--method", "linear").expect_error("given", "count twice")
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    cli("validate", a, a, "--params", params).expect_error("given twice")
    from tests.support.boundary_files import tuples_text

    t = write(tmp_path / "m.tuple", tuples_text())
    cli("fit", t, tmp_path / "." / "m.tuple").expect_error("count twice")


def test_identical_copies_are_warned_about(cli, tmp_path):
    runs = tmp_path / "runs"
    for name, turn in (("a", 1.5), ("b", -1.0), ("c", 2.5)):
        write(runs / f"{name}.csv", generic_csv_text(turn))
    copy = write(tmp_path / "copy.csv", (runs / "a.csv").read_text())
    status, out, err = cli("fit", runs, copy, "--method", "linear")
    assert status == 0
    assert "copy.csv holds the same data as" in err and "a.csv" in err


# --- numeric flags ---------------------------------------------------------------------------

RUN = "RUN"  # replaced by a valid generic run CSV
ROBOT = "ROBOT"


@pytest.mark.parametrize(
    "argv, needle",
    [
        (["fit", RUN, "--ticks-per-rev", "0"], "--ticks-per-rev"),
        (["fit", RUN, "--ticks-per-rev", "1e12"], "ticks per wheel turn"),
        (["fit", RUN, "--ticks-per-rev", "nan"], "finite"),
        (["validate", RUN, "--params", "P", "--ticks-per-rev", "-5"], "--ticks-per-rev"),
        (["fit", RUN, "--heading-weight", "-1"], "--heading-weight"),
        (["fit", RUN, "--heading-weight", "1e4"], "m per rad"),
        (["fit", RUN, "--segment-length", "0"], "--segment-length"),
        (["fit", RUN, "--segment-length", "1e6"], "check the units"),
        (["fit", RUN, "--side-length", "inf"], "--side-length"),
        (["fit", RUN, "--scan-interval", "0"], "--scan-interval"),
        (["simulate", "--max-step", "0"], "--max-step"),
        (["simulate", "--max-step", "1e6"], "check the units"),
        (["simulate", "--runs", "0"], "--runs"),
        (["simulate", "--seed", "-1"], "--seed"),
        (["simulate", "--sides", "2"], "at least 3 sides"),
        (["compare", "--travel", "1e-3", "--trials", "2"], "--travel 0.001 m is too little"),
        (["compare", "--travel", "1e9"], "--travel"),
        (["compare", "--ivanjko-straight", "-4"], "--ivanjko-straight"),
        (
            ["calibrate", "--robot", "paper-fig5", "RUNS", "--method", "bcpt", "--radius", "0"],
            "--radius",
        ),
        (["design", "--alpha", "1"], "--alpha"),
        (["design", "--tolerance", "-0.1"], "--tolerance"),
        (["design", "--trials", "1"], "--trials"),
        (["plan", "--side-length", "-4"], "--side-length"),
        (["noise", "RUNS", "--track", "straight:0"], "--track"),
    ],
)
def test_numeric_flags_are_bounded_with_a_reason(cli, tmp_path, argv, needle):
    paths = {
        RUN: write(tmp_path / "run.csv", generic_csv_text()),
        ROBOT: write(tmp_path / "robot.yaml", ROBOT_YAML),
        "RUNS": write(tmp_path / "runs.csv", RUNS_CSV),
        "P": write(tmp_path / "p.yaml", PARAMS_YAML),
    }
    cli(*[paths.get(a, a) for a in argv]).expect_error(needle)


def test_flag_limits_agree_with_the_methods():
    from odocal.calibration.trajectory import MAX_HEADING_WEIGHT_M

    assert limits.HEADING_WEIGHT_MAX_M == MAX_HEADING_WEIGHT_M
    assert math.isclose(limits.TRACK_LENGTH_MAX_M, 1e5)
