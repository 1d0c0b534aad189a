"""Run loaders: generic run CSV, OptiOdom folders, the dispatcher, and their bad-input errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from odocal.core.recording import Recording
from odocal.errors import InputError
from odocal.io.generic_csv import load_generic_csv, write_generic_csv
from odocal.io.recordings import expand_folders, load_recordings


def _write(path, text):
    path.write_text(text, encoding="utf-8")
    return path


def _recording():
    t = np.arange(6) * 0.05
    gt = np.column_stack([np.linspace(0, 0.5, 6), np.linspace(0, 0.1, 6), np.linspace(0, 0.3, 6)])
    return Recording(
        name="x",
        time_s=t,
        wheel_angle_right_rad=np.linspace(0, 3.0, 6),
        wheel_angle_left_rad=np.linspace(0, 2.5, 6),
        ground_truth=gt,
        gyro_yaw_rad=np.linspace(0, 0.29, 6),
        label="ccw",
        meta={"side_m": 4.0},
    )


def test_generic_csv_round_trip(tmp_path):
    rec = _recording()
    path = tmp_path / "run.csv"
    write_generic_csv(path, rec)
    back = load_generic_csv(path)
    np.testing.assert_allclose(back.wheel_angle_right_rad, rec.wheel_angle_right_rad)
    np.testing.assert_allclose(back.ground_truth, rec.ground_truth, atol=1e-12)
    np.testing.assert_allclose(back.gyro_yaw_rad, rec.gyro_yaw_rad)
    assert back.label == "ccw" and back.meta["side_m"] == 4.0


def test_ground_truth_is_expressed_in_the_start_frame(tmp_path):
    # the robot starts at (1, 2) heading +90 deg and drives 1 m forward: in the start frame
    # that is (1, 0, 0)
    path = _write(
        tmp_path / "r.csv",
        "time_s,wheel_right_rad,wheel_left_rad,x_m,y_m,theta_rad\n"
        f"0,0,0,1,2,{math.pi / 2}\n0.1,10,10,1,3,{math.pi / 2}\n",
    )
    rec = load_generic_csv(path)
    np.testing.assert_allclose(rec.ground_truth[-1], [1.0, 0.0, 0.0], atol=1e-12)


def test_ticks_with_ticks_per_rev_from_the_header(tmp_path):
    path = _write(
        tmp_path / "r.csv",
        "# ticks_per_rev: 1000\ntime_s,ticks_right,ticks_left\n0,500,500\n1,1500,1000\n",
    )
    rec = load_generic_csv(path)
    # cumulative counts, relative to the first row: 1000 and 500 counts = 1 and 0.5 revolutions
    assert rec.wheel_angle_right_rad[-1] == pytest.approx(2 * math.pi)
    assert rec.wheel_angle_left_rad[-1] == pytest.approx(math.pi)
    assert rec.ground_truth is None


def test_16_bit_wrap_around_is_unwrapped_with_the_modulus(tmp_path):
    # counter 65000 -> 65500 -> 464 (= 66000 mod 65536) -> 964: steady +500 per sample
    body = "time_s,ticks_right,ticks_left\n0,65000,0\n1,65500,500\n2,464,1000\n3,964,1500\n"
    path = _write(tmp_path / "r.csv", "# ticks_per_rev: 1000\n# ticks_wrap: 65536\n" + body)
    rec = load_generic_csv(path)
    np.testing.assert_allclose(rec.wheel_angle_right_rad, rec.wheel_angle_left_rad)
    # without the modulus the jump is refused, naming the line and the column
    path2 = _write(tmp_path / "r2.csv", "# ticks_per_rev: 1000\n" + body)
    with pytest.raises(InputError, match=r"r2.csv, line 5, field 'ticks_right'.*wrap-around"):
        load_generic_csv(path2)
    # the bits (16) for the modulus: values 65000 apart cannot come from a counter wrapping at 16
    path3 = _write(tmp_path / "r3.csv", "# ticks_per_rev: 1000\n# ticks_wrap: 16\n" + body)
    with pytest.raises(InputError, match=r"field 'ticks_right'.*not its bits"):
        load_generic_csv(path3)


@pytest.mark.parametrize(
    "text, match",
    [
        ("", "empty file"),
        ("# only a comment\n", "empty file"),
        ("time_s,wheel_right_rad\n0,0\n", "missing column 'wheel_left_rad'"),
        ("t,wheel_right_rad,wheel_left_rad\n0,0,0\n", "missing column 'time_s'"),
        ("time_s,a,b\n0,0,0\n", "missing wheel columns"),
        ("time_s,wheel_right_rad,wheel_left_rad,x_m,y_m\n0,0,0,0,0\n", "theta_rad"),
        ("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n", "at least two samples"),
        (
            "time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n0.1,nan,0\n",
            r"line 3, field 'wheel_right",
        ),
        ("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n0.1,x,0\n", r"line 3.*not a number"),
        ("time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n0.1,1\n", r"line 3.*expected 3 fields"),
        (
            "time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n0.2,1,1\n0.1,2,2\n",
            r"line 4, field 'time_s'.*not strictly increasing",
        ),
        ("time_s,ticks_right,ticks_left\n0,0,0\n1,5,5\n", "ticks_per_rev"),
        ("# ticks_per_rev: -3\ntime_s,ticks_right,ticks_left\n0,0,0\n", r"line 1.*> 0"),
        ("# wheelbase_m: 0.3\ntime_s,wheel_right_rad,wheel_left_rad\n0,0,0\n1,1,1\n", "all three"),
    ],
)
def test_generic_csv_bad_input_names_file_line_and_field(tmp_path, text, match):
    path = _write(tmp_path / "bad.csv", text)
    with pytest.raises(InputError, match=match) as info:
        load_generic_csv(path)
    assert "bad.csv" in str(info.value)


def test_large_files_are_read_in_chunks_with_the_same_numbers_and_line_numbers(
    tmp_path, monkeypatch
):
    # chunks of ~64 characters: every path of the vectorised reader is crossed by few lines
    monkeypatch.setattr("odocal.io.table._CHUNK_CHARS", 64)
    rows = [f"{0.1 * i:.1f},{i},{2 * i}" for i in range(40)]
    rows[7] = " " + rows[7] + " \r"  # spaces around fields, a CRLF line
    rows[12] = ""  # a blank line, counted for the line numbers
    head = "time_s,wheel_right_rad,wheel_left_rad\n"
    rec = load_generic_csv(_write(tmp_path / "ok.csv", head + "\n".join(rows) + "\n"))
    kept = [i for i in range(40) if i != 12]
    np.testing.assert_allclose(rec.wheel_angle_right_rad, kept)
    np.testing.assert_allclose(rec.time_s, [0.1 * i for i in kept])
    # Python's float() reads '2_1' as 21 (it was, where numpy's loadtxt refused the chunk);
    # the table refuses it, in every chunk (issue 27 item 19)
    rows[21] = f"{2.1:.1f},2_1,42"
    with pytest.raises(InputError, match=r"us.csv, line 23, field 'wheel_right_rad': not a num"):
        load_generic_csv(_write(tmp_path / "us.csv", head + "\n".join(rows) + "\n"))
    rows[21] = f"{2.1:.1f},21,42"
    # a bad value far down is named by its line (header on line 1: row i is on line i + 2)
    rows[30] = "3.0,1e999,60"
    with pytest.raises(InputError, match=r"bad.csv, line 32, field 'wheel_right_rad'"):
        load_generic_csv(_write(tmp_path / "bad.csv", head + "\n".join(rows) + "\n"))
    rows[30] = "3.0,30,60,7"  # a row of the wrong width, whose extra field numpy would ignore
    with pytest.raises(InputError, match=r"line 32: expected 3 fields"):
        load_generic_csv(_write(tmp_path / "bad.csv", head + "\n".join(rows) + "\n"))


def test_bad_input_through_the_cli_is_one_line_exit_2(tmp_path, cli):
    path = _write(tmp_path / "bad.csv", "time_s,wheel_right_rad,wheel_left_rad\n0,0,0\n0,1,1\n")
    out_file = tmp_path / "p.yaml"
    status, out, err = cli("fit", path, "--out", out_file)
    assert status == 2
    assert err.startswith("odocal: error: ") and err.count("\n") == 1
    assert "bad.csv, line 3, field 'time_s'" in err and "Traceback" not in err
    assert not out_file.exists()


def test_dispatcher_folder_of_generic_runs_and_errors(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    for i in range(3):
        write_generic_csv(folder / f"r{i}.csv", _recording())
    assert len(load_recordings([folder])) == 3
    assert len(load_recordings([folder / "r0.csv", folder / "r1.csv"])) == 2
    with pytest.raises(InputError, match="no such file"):
        load_recordings([tmp_path / "missing.csv"])
    empty = tmp_path / "empty"
    empty.mkdir()
    with pytest.raises(InputError, match="no runs found"):
        load_recordings([empty])
    other = _write(tmp_path / "notes.txt", "hello\n")
    with pytest.raises(InputError, match="unknown run file type"):
        load_recordings([other])
    # a .tuple file is accepted by fit only: not "unknown", and not listed as accepted here
    tuples = _write(tmp_path / "l90.tuple", '{"T": 1, "phi_l": 0, "phi_r": 0, "sm": [0, 0, 0]}\n')
    with pytest.raises(InputError, match="only 'odocal fit' reads it") as info:
        load_recordings([tuples])
    assert "unknown" not in str(info.value)


def test_optiodom_run_files_without_metadata_are_refused(tmp_path):
    folder = tmp_path / "123"
    folder.mkdir()
    _write(folder / "123_run-01.csv", "0,0,0,0,0,0\n0.05,0,0,0,1,1\n")
    with pytest.raises(InputError, match=r"123_metadata.csv is missing"):
        load_recordings([folder / "123_run-01.csv"])
    with pytest.raises(InputError, match="without a \\*_metadata.csv"):
        load_recordings([folder])
    _write(folder / "123_metadata.csv", "type,diff\nngear,43.7\nLi,0.2\nDi,0.084,0.084\nN,1\n")
    with pytest.raises(InputError, match="123_metadata.csv: metadata key 'encRes' is missing"):
        load_recordings([folder])


def test_optiodom_data_set_category_and_single_run(realdata):
    base = realdata / "optiodom_diff"
    runs = load_recordings([base / "square" / "230620202042"])
    assert [r.label for r in runs] == ["cw"] * 3 + ["ccw"] * 3
    assert runs[0].meta["ticks_per_rev"] == pytest.approx(43.7 * 64)
    assert runs[0].ran_with.wheelbase_m == 0.2 and runs[0].meta["side_m"] == 0.75
    one = load_recordings([base / "square" / "230620202042" / "230620202042_run-04.csv"])
    assert len(one) == 1 and one[0].label == "ccw" and one[0].meta["run"] == 4
    free = load_recordings([base / "free"])
    assert len(free) == 7 and {r.meta["dataset"] for r in free} == {
        "020120212354",
        "030120210001",
        "030120210006",
    }
    # the firmware parameters differ per data set and are kept per run
    sq = load_recordings([base / "square" / "230620202258"])
    assert sq[0].ran_with.diameter_right_m == 0.085 and sq[0].ran_with.wheelbase_m == 0.205


def test_the_data_set_of_a_run_is_one_rule():
    t = np.arange(3.0)
    z = np.zeros(3)
    opti = Recording("sq/2306/run-01.csv", t, z, z, meta={"dataset": "2306"})
    csv = Recording("runs/a/run-01.csv", t, z, z)
    bag = Recording("runs/b/x.bag:/joint_states#2", t, z, z, meta={"bag": "runs/b/x.bag"})
    assert opti.dataset == "2306"
    assert csv.dataset == "runs/a"
    assert bag.dataset == "runs/b"


def test_folders_of_bags_and_of_tuple_files_are_walked(tmp_path):
    # documented ("and folders of them"; "a folder of bags is one data set"), not walked before
    bags = tmp_path / "bags"
    (bags / "b_ros2").mkdir(parents=True)
    (bags / "b_ros2" / "metadata.yaml").write_text("x: 1\n")
    for name in ("c.mcap", "a.bag", "notes.txt"):
        (bags / name).write_text("")
    tuples = tmp_path / "tuples"
    tuples.mkdir()
    for name in ("l90_1.tuple", "l90_0.TUPLE", "README"):
        (tuples / name).write_text("")
    mixed = tmp_path / "mixed"
    mixed.mkdir()
    (mixed / "a.bag").write_text("")
    (mixed / "a.tuple").write_text("")
    assert expand_folders([bags, tuples, mixed, bags / "b_ros2"]) == [
        bags / "a.bag", bags / "b_ros2", bags / "c.mcap",
        tuples / "l90_0.TUPLE", tuples / "l90_1.tuple",
        mixed, bags / "b_ros2",
    ]  # fmt: skip


def test_a_bag_twice_is_refused_but_two_runs_on_one_clock_are_not(tmp_path):
    # a copy, and a part of the log (its second half), count twice: refused naming both; a
    # second run whose clock starts at the same instant (a simulator restarted at zero) is a
    # run of its own
    import shutil
    from dataclasses import replace

    from odocal.core.tracks import Track, spot_turn, straight
    from tests.support.bag_files import make_run, write_bag

    run = make_run(Track("out", (straight(0.5), spot_turn(math.pi / 2), straight(0.3))))
    bag = write_bag(tmp_path / "run.bag", "ros1", run, imu=False)
    shutil.copy(bag, tmp_path / "copy.bag")
    with pytest.raises(InputError, match="run.bag and .*copy.bag cover the same time.*twice"):
        load_recordings([bag, tmp_path / "copy.bag"])
    k = len(run.time_s) // 2
    half = replace(run, **{f: getattr(run, f)[k:] for f in ("time_s", "right", "left")},
                   true_pose=run.true_pose[k:], odo_pose=run.odo_pose[k:])  # fmt: skip
    write_bag(tmp_path / "half.bag", "ros1", half, imu=False)
    with pytest.raises(InputError, match="same wheel samples: one recording given twice"):
        load_recordings([bag, tmp_path / "half.bag"])
    other = replace(run, right=run.right * 1.01, left=run.left * 0.99)  # its own wheel samples
    write_bag(tmp_path / "other.bag", "ros1", other, imu=False)
    assert len(load_recordings([bag, tmp_path / "other.bag"])) == 2
