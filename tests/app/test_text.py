"""odocal.app.text: a result reads as the command prints it (``str``, notebook Markdown), and a
command called from Python emits its warnings through :mod:`warnings`, once each; the command
line prints them itself, once, with no Python warning noise."""

from __future__ import annotations

import warnings

import pytest

import odocal
from odocal.app import calibrate as app_calibrate
from odocal.app import check as app_check
from odocal.app import design as app_design
from odocal.app import fit as app_fit
from odocal.app import simulate as app_simulate
from odocal.app import validate as app_validate
from odocal.app.text import Text, _motion_line, table_lines
from odocal.core.model import SystematicError
from odocal.io.generic_csv import write_generic_csv
from odocal.io.robot_file import params_yaml
from tests.support.recorded_runs import NOMINAL, mixed_runs

# headings only: hand-made positions beside them would contradict them (calibrate holds the
# headings against the positions: calibration/heading_check.py)
SHEET = """# sides: 4
# side_m: 2
direction,x_m,y_m,theta_deg
cw,,,1.1
cw,,,1.1
cw,,,1.3
ccw,,,-0.4
ccw,,,-0.5
"""


@pytest.fixture
def sheet(tmp_path):
    path = tmp_path / "runs.csv"
    path.write_text(SHEET)
    return path


@pytest.fixture
def runs_dir(tmp_path):
    folder = tmp_path / "runs"
    folder.mkdir()
    for r in mixed_runs()[:3]:
        write_generic_csv(folder / f"{r.name}.csv", r)
    return folder


def test_a_python_call_warns_once_per_warning_and_keeps_them_in_the_result(sheet):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        res = odocal.calibrate(sheet, "paper-fig5")
    said = [str(w.message) for w in caught if issubclass(w.category, odocal.OdocalWarning)]
    assert said == list(res.warnings) and len(said) == 1
    assert "line 5 repeats line 4" in said[0]
    assert caught[0].filename == __file__  # points at the caller, not into odocal
    assert issubclass(odocal.OdocalWarning, UserWarning)


def test_the_command_line_prints_each_warning_once_and_no_python_warning(cli, sheet):
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        status, out, err = cli("calibrate", sheet, "--robot", "paper-fig5")
    assert status == 0, err
    assert not [w for w in caught if issubclass(w.category, odocal.OdocalWarning)]
    assert err.count("repeats line 4") == 1 and err.startswith("odocal: warning: ")
    assert "OdocalWarning" not in err and "warnings.warn" not in err


def _same_text(cli, returned, module, name, *argv):
    results = returned(module, name)
    status, out, err = cli(*argv)
    assert status in (0, 3), err
    text = str(results[0])
    assert out == text + "\n"  # one home for the words: the command prints the result's str
    md = results[0]._repr_markdown_()
    assert f"```text\n{text}\n```" in md
    return text


def test_calibrate_reads_as_its_command(cli, returned, sheet):
    text = _same_text(
        cli, returned, app_calibrate, "calibrate", "calibrate", sheet, "--robot", "paper-fig5"
    )
    assert "ran with" in text and "E_b" in text and "CalibrateResult(" not in text
    with pytest.warns(odocal.OdocalWarning, match="repeats line 4"):
        md = odocal.calibrate(sheet, "paper-fig5")._repr_markdown_()
    assert md.startswith("**warning:** ") and "repeats line 4" in md


def test_simulate_and_design_read_as_their_commands(cli, returned, tmp_path):
    text = _same_text(
        cli, returned, app_simulate, "simulate", "simulate", "--robot", "paper-fig5", "--runs", 2
    )
    assert text.startswith("4-gon, side 4 m: 2 run(s) per direction, seed 0")
    argv = ("design", "--robot", "paper-fig5", "--analytic", "--side-lengths", "1:3:1")
    text = _same_text(cli, returned, app_design, "design", *argv)
    assert "Recommended:" in text and "Rule:" in text


def test_fit_validate_and_check_read_as_their_commands(cli, returned, runs_dir, tmp_path):
    text = _same_text(cli, returned, app_fit, "fit", "fit", runs_dir, "--method", "linear")
    assert "fit from 3 run(s)" in text and "wheelbase_m" in text
    params = tmp_path / "params.yaml"
    params.write_text(params_yaml(NOMINAL.with_systematic(SystematicError(1.01, 1.0))))
    text = _same_text(
        cli, returned, app_validate, "validate", "validate", runs_dir, "--params", params
    )
    assert f"parameters from {params}" in text and text.count("\n") >= 5
    text = _same_text(cli, returned, app_check, "check", "check", runs_dir)
    assert text.startswith("Is this log enough? 3 run(s)")


def test_the_table_is_written_in_one_place():
    out = Text()
    out("title")
    out.table([("", "a", "bb"), ("row", "1", "2")])
    assert str(out) == "title\n" + "\n".join(table_lines([("", "a", "bb"), ("row", "1", "2")]))
    assert table_lines([("", "a", "bb"), ("row", "1", "2")]) == ["       a  bb", "  row  1   2"]


MOTION = {
    "travel_m": 0.0,
    "rotation_deg": 0.0,
    "rotation_left_deg": 0.0,
    "rotation_right_deg": 0.0,
    "share_straight": 0.5,
    "share_spot": 0.25,
    "share_arc": 0.25,
}


def test_the_motion_line_without_wheel_travel_says_so():
    """No wheel travel: the shares are None in the JSON (NaN); the text printer multiplied them
    (a traceback after fit had written PARAMS.yaml, issue #20)."""
    none = {**MOTION, "share_straight": None, "share_spot": None, "share_arc": None}
    assert _motion_line(none).endswith("; no wheel travel")
    assert _motion_line(MOTION).endswith("50 % straight, 25 % spot turns, 25 % arcs")
