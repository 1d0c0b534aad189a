"""OutputPlan: every file is checked before anything is written, and a failed rename undoes the
renames before it (odocal.io.outputs)."""

from __future__ import annotations

import os
from pathlib import Path

import pytest

from odocal.errors import InputError
from odocal.io import outputs
from odocal.io.outputs import OutputPlan


def _names(folder: Path) -> list[str]:
    return sorted(p.name for p in folder.iterdir())


def test_a_folder_where_a_later_file_of_an_output_folder_goes_is_refused_first(tmp_path):
    out = tmp_path / "figs"
    (out / "c.png").mkdir(parents=True)
    plan = OutputPlan()
    plan.folder(out, "--plot")
    contents = {out / "a.png": b"a", out / "b.png": b"b", out / "c.png": b"c"}
    with pytest.raises(InputError, match="--plot: is a directory"):
        plan.commit(contents)
    assert _names(out) == ["c.png"]  # nothing written, no temporary file


def test_a_file_of_an_output_folder_that_is_an_input_is_refused(tmp_path):
    data = tmp_path / "data.csv"
    data.write_text("x\n")
    plan = OutputPlan([data])
    plan.folder(tmp_path, "--out")
    with pytest.raises(InputError, match="input file"):
        plan.commit({tmp_path / "a.md": "a", tmp_path / "data.csv": "replaced"})
    assert data.read_text() == "x\n" and _names(tmp_path) == ["data.csv"]


def test_a_failed_rename_undoes_the_renames_before_it(tmp_path, monkeypatch):
    old = tmp_path / "a.txt"
    old.write_text("previous\n")
    plan = OutputPlan()
    files = [plan.file(tmp_path / n, f"--{n}") for n in ("a.txt", "b.txt", "c.txt")]
    real, calls = os.replace, []

    def replace(src, dst):
        calls.append(Path(dst))
        if len(calls) == 3:  # the third rename: the first two are done
            raise OSError(5, "Input/output error")
        real(src, dst)

    monkeypatch.setattr(outputs.os, "replace", replace)
    with pytest.raises(InputError, match="c.txt: cannot write: Input/output error"):
        plan.commit(dict.fromkeys(files, "new\n"))
    assert calls[:3] == files
    # a.txt holds its previous content again, b.txt (new) is gone, nothing else is left
    assert old.read_text() == "previous\n"
    assert _names(tmp_path) == ["a.txt"]


def test_renames_that_succeed_leave_no_backup(tmp_path):
    (tmp_path / "a.txt").write_text("previous\n")
    plan = OutputPlan()
    files = [plan.file(tmp_path / n, f"--{n}") for n in ("a.txt", "b.txt")]
    plan.commit(dict.fromkeys(files, "new\n"))
    assert _names(tmp_path) == ["a.txt", "b.txt"]
    assert (tmp_path / "a.txt").read_text() == "new\n"


def test_a_file_an_output_folder_will_hold_cannot_be_another_output(tmp_path):
    """Issue 27 item 19: `fit BAG --out D --ros2 D/params.yaml` wrote the report's params.yaml
    over the ros2 file without a word. The names a folder will hold are known before the work:
    another output naming one of them is refused then, whichever is registered first."""
    report = tmp_path / "report"
    report.mkdir()
    plan = OutputPlan()
    plan.file(report / ".." / "report" / "params.yaml", "--ros2")  # another spelling
    with pytest.raises(InputError, match="the params.yaml of --out names the same file as --ros2"):
        plan.folder(report, "--out", files=("report.md", "params.yaml"))
    plan = OutputPlan()
    plan.folder(report, "--out", files=("report.md", "params.yaml"))
    with pytest.raises(InputError, match="--ros2 names the same file as the params.yaml of --out"):
        plan.file(report / "params.yaml", "--ros2")
    plan.file(report / "diff_drive.yaml", "--ros2")  # another name in the folder is fine
    written = plan.commit(
        {
            report / "diff_drive.yaml": "ros2\n",
            report / "params.yaml": "p\n",
            report / "report.md": "r\n",
        }
    )
    assert sorted(p.name for p in written) == ["diff_drive.yaml", "params.yaml", "report.md"]
    assert _names(report) == ["diff_drive.yaml", "params.yaml", "report.md"]


def test_a_file_an_output_folder_will_hold_is_checked_before_the_work(tmp_path):
    # an input there, or a folder standing where it goes, is refused when the folder is planned
    robot = tmp_path / "report" / "params.yaml"
    robot.parent.mkdir()
    robot.write_text("wheel_diameter_m: 0.1\nwheelbase_m: 0.3\n")
    with pytest.raises(InputError, match="input file"):
        OutputPlan([robot]).folder(robot.parent, "--out", files=("params.yaml",))
    with pytest.raises(InputError, match="report.md: --out: is a directory"):
        (robot.parent / "report.md").mkdir()
        OutputPlan().folder(robot.parent, "--out", files=("report.md",))
