"""``odocal.io.norlab_csv``: the Norlab DRIVE recordings' CSV (realdata/norlab_skid/SOURCE.md)."""

from __future__ import annotations

import numpy as np
import pytest

from odocal.errors import InputError
from odocal.io.norlab_csv import read_norlab_csv

HEADER = (
    "t_s,left_wheel_rad_s,right_wheel_rad_s,left_wheel_rad,right_wheel_rad,cmd_v_m_s,"
    "cmd_omega_rad_s,icp_x_m,icp_y_m,icp_yaw_rad,imu_wz_rad_s,icp_update"
)


def _write(tmp_path, rows, comments=("# time: absolute t0 = 1723146950083472084 ns (ros_time)",)):
    p = tmp_path / "rec.csv"
    p.write_text("\n".join([*comments, HEADER, *rows]) + "\n")
    return p


def test_icp_rows_are_the_updates_and_empty_cells_are_allowed_before_the_first(tmp_path):
    p = _write(
        tmp_path,
        [
            "0,0,0,0,0,0,0,,,,0.01,0",
            "0.05,1,2,0.025,0.05,0.5,0.1,1.0,2.0,3.1,,1",
            "0.10,1,2,0.05,0.1,0.5,0.1,1.0,2.0,3.1,0.02,0",
            "0.15,1,2,0.075,0.15,0.5,0.1,1.1,2.0,-3.1,0.02,1",
        ],
    )
    rec = read_norlab_csv(p)
    assert rec.name == "rec" and rec.day == "2024-08-08"
    assert rec.angle_right_rad.tolist() == [0, 0.05, 0.1, 0.15]
    assert rec.rate_left_rad_s.tolist() == [0, 1, 1, 1]
    assert rec.icp_time_s.tolist() == [0.05, 0.15]
    # yaw unwrapped across +-pi
    assert rec.icp_pose[:, 2] == pytest.approx([3.1, 2 * np.pi - 3.1])
    assert np.isnan(rec.imu_wz_rad_s[1])
    log = rec.skid_log()
    assert log.group == "2024-08-08" and log.name == "rec" and len(log.truth_time_s) == 2


def test_problems_are_named(tmp_path):
    with pytest.raises(InputError, match="icp_update"):
        read_norlab_csv(_write(tmp_path, ["0,0,0,0,0,0,0,,,,0,0", "0.05,0,0,0,0,0,0,,,,0,0"]))
    with pytest.raises(InputError, match="increase"):
        read_norlab_csv(_write(tmp_path, ["0,0,0,0,0,0,0,1,1,1,0,1", "0,0,0,0,0,0,0,1,1,1,0,1"]))
    with pytest.raises(InputError, match="line 4"):
        read_norlab_csv(_write(tmp_path, ["0,0,0,0,0,0,0,1,1,1,0,1", "0.05,0,0,0,0,0,0,x,1,1,0,1"]))
    p = tmp_path / "bad.csv"
    p.write_text("t_s,left_wheel_rad_s\n0,0\n")
    with pytest.raises(InputError, match="missing column"):
        read_norlab_csv(p)


def test_a_real_recording(realdata):
    folder = realdata / "norlab_skid" / "warthog_wheels_grass_2024_7_29_14h46s15"
    if not folder.is_dir():  # the realdata folder is there (the fixture says so): it is broken
        pytest.fail(f"{folder} is missing from the real-data folder")
    rec = read_norlab_csv(folder / f"{folder.name}.csv")
    # SOURCE.md: 196 s, ICP at 8.0 Hz; the logger samples at 20 Hz
    assert rec.time_s[-1] == pytest.approx(196, abs=1)
    assert len(rec.icp_time_s) / (rec.icp_time_s[-1] - rec.icp_time_s[0]) == pytest.approx(
        8.0, abs=0.3
    )
    assert np.median(np.diff(rec.time_s)) == pytest.approx(0.05, abs=0.002)
    assert rec.day == "2024-07-29"
