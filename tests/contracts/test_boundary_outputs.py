"""Outputs never destroy inputs, are written all or none (also when interrupted), and are
reproducible byte for byte.

Every command with outputs is tried: an output that IS an input (the same path, another spelling,
a symbolic link, a hard link, a file inside an input folder), two outputs naming one file, an
interruption (Ctrl-C and SIGTERM) while the second of several files is staged and while they are
renamed, a full disk, and ``plan`` over a run sheet that holds measurements or notes.
"""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import pytest

from odocal.io import outputs
from tests.support.boundary_files import (
    PARAMS_YAML,
    ROBOT_YAML,
    RUNS_CSV,
    generic_csv_text,
    write_optiodom,
)


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def tree(folder: Path) -> dict[str, bytes]:
    """Every file below ``folder`` (relative name -> bytes), temporary files included."""
    return {
        str(p.relative_to(folder)): p.read_bytes() for p in sorted(folder.rglob("*")) if p.is_file()
    }


@pytest.fixture
def runs_dir(tmp_path) -> Path:
    """Three generic run CSVs that a linear fit can use."""
    folder = tmp_path / "runs"
    for name, turn in (("a", 1.5), ("b", -1.0), ("c", 2.5)):
        write(folder / f"{name}.csv", generic_csv_text(turn))
    return folder


# --- an output may never be an input -------------------------------------------------------


def test_output_equal_to_an_input_file_in_every_spelling(cli, tmp_path, runs_dir):
    robot = write(tmp_path / "robot.yaml", ROBOT_YAML)
    runs = write(tmp_path / "RUNS.csv", RUNS_CSV)
    before = tree(tmp_path)
    os.symlink(robot, tmp_path / "robot-link.yaml")
    os.link(runs, tmp_path / "runs-hardlink.csv")
    os.link(runs_dir / "a.csv", tmp_path / "a-hardlink.csv")
    cases = [
        (["simulate", "--robot", robot, "--out", robot], "--out would overwrite an input file"),
        (["simulate", "--robot", robot, "--out", tmp_path / "." / "robot.yaml"], "input file"),
        (["simulate", "--robot", robot, "--out", tmp_path / "robot-link.yaml"], "input file"),
        (["calibrate", "--robot", "paper-fig5", runs, "--out", runs], "input file"),
        (
            ["calibrate", "--robot", "paper-fig5", runs, "--out", tmp_path / "runs-hardlink.csv"],
            "input file",
        ),
        (["calibrate", runs, "--robot", robot, "--out", tmp_path / "robot-link.yaml"], "input"),
        # a hard link OUTSIDE the input folder to a run INSIDE it
        (["fit", runs_dir, "--method", "linear", "--out", tmp_path / "a-hardlink.csv"], "link"),
        (["fit", runs_dir, "--method", "linear", "--out", runs_dir / "a.csv"], "input folder"),
    ]
    for argv, needle in cases:
        cli(*argv).expect_error(needle)
    assert {k: v for k, v in tree(tmp_path).items() if "link" not in k} == before


def test_a_new_file_beside_the_runs_is_allowed_and_not_read_as_a_run(cli, runs_dir):
    # 'odocal fit . --out params.yaml' in the data folder: no input is touched, and the new
    # file is not a run the next time the folder is read
    params = runs_dir / "params.yaml"
    assert cli("fit", runs_dir, "--method", "linear", "--out", params)[0] == 0
    status, out, err = cli("fit", runs_dir, "--method", "linear", "--json")
    assert status == 0, err
    assert len(json.loads(out)["runs"]) == 3


def test_two_outputs_naming_one_file(cli, tmp_path, runs_dir):
    robot = write(tmp_path / "robot.yaml", ROBOT_YAML)
    out = tmp_path / "p.yaml"
    os.symlink(out, tmp_path / "p-link.yaml")  # dangling until written
    for ros2 in (out, tmp_path / "." / "p.yaml"):
        cli(
            "fit", runs_dir, "--method", "linear", "--robot", robot, "--out", out, "--ros2", ros2
        ).expect_error("--ros2 names the same file as --out")
    assert not out.exists()


def test_a_file_of_an_output_folder_named_by_another_output(cli, tmp_path, runs_dir):
    """Issue 27 item 19: `fit BAG --out D --ros2 D/params.yaml` replaced the ros2 file by the
    report's params.yaml (and `fit RUNS --plot D --out D/effective_wheelbase.png` the
    parameters by the figure): refused before any work (the bag here is not even a bag)."""
    robot = write(tmp_path / "robot.yaml", ROBOT_YAML)
    bag = write(tmp_path / "run.bag", "not read\n")
    report = tmp_path / "report"
    report.mkdir()
    cli(
        "fit", bag, "--robot", robot, "--out", report, "--ros2", report / "params.yaml"
    ).expect_error("the params.yaml of --out names the same file as --ros2")
    figure = report / "effective_wheelbase.png"
    cli("fit", runs_dir, "--robot", robot, "--plot", report, "--out", figure).expect_error(
        "the effective_wheelbase.png of --plot names the same file as --out"
    )
    assert list(report.iterdir()) == []


@pytest.mark.parametrize("where", ["same", "inside"])
def test_plot_folder_equal_to_or_inside_an_input_folder(cli, tmp_path, runs_dir, where):
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    before = tree(runs_dir)
    plot = runs_dir if where == "same" else runs_dir / "plots"
    cli("validate", runs_dir, "--params", params, "--plot", plot).expect_error("--plot")
    assert tree(runs_dir) == before


def test_compare_plot_into_the_real_data_folder_is_refused(cli, tmp_path):
    data = tmp_path / "optiodom"
    write_optiodom(data)
    before = tree(data)
    for plot in (data, data / "square", data / "figures"):
        cli("compare", "--realdata", data, "--trials", 2, "--plot", plot).expect_error(
            "--plot", "input folder"
        )
    assert tree(data) == before


def test_design_plot_and_reproduce_out_that_are_files(cli, tmp_path):
    f = write(tmp_path / "notes.txt", "mine\n")
    cli("design", "--analytic", "--side-lengths", "1:2:1", "--plot", f).expect_error("not a folder")
    cli("reproduce", "--out", f, "--trials", 5).expect_error("not a folder")
    assert f.read_text() == "mine\n"


def test_a_folder_where_the_last_figure_goes_leaves_no_figure(cli, tmp_path, runs_dir):
    """Every file of an output folder is checked before the first is written (issue #20)."""
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    design, valid = tmp_path / "design", tmp_path / "valid"
    (design / "design_share.png").mkdir(parents=True)  # the third figure of design
    (valid / "c.png").mkdir(parents=True)  # the figure of the third run
    cli("design", "--analytic", "--side-lengths", "1:3:1", "--plot", design).expect_error(
        "design_share.png: --plot: is a directory"
    )
    cli("validate", runs_dir, "--params", params, "--plot", valid).expect_error(
        "c.png: --plot: is a directory"
    )
    assert sorted(p.name for p in design.iterdir()) == ["design_share.png"]
    assert sorted(p.name for p in valid.iterdir()) == ["c.png"]


# --- plan never overwrites a run sheet that holds measurements --------------------------------


def test_plan_keeps_filled_sheets_and_replaces_blank_ones(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    default = tmp_path / "runs-template.csv"
    assert cli("plan")[0] == 0  # the default output name
    blank = default.read_text()
    assert cli("plan", "--side-length", 2)[0] == 0  # a blank sheet of ours: replaced
    assert "2 m" in default.read_text() and default.read_text() != blank

    filled = default.read_text().replace("cw,,,,1", "cw,-0.25,-0.27,7.5,1")
    default.write_text(filled)
    cli("plan").expect_error("default runs-template.csv", "already holds measured runs")
    assert default.read_text() == filled

    noted = blank.replace("direction,", "# battery low on run 3\ndirection,")
    default.write_text(noted)  # a note of the user's, no measurement yet
    cli("plan").expect_error("already holds")
    assert default.read_text() == noted

    other = write(tmp_path / "mine.csv", "direction,x_m,y_m,theta_deg,run,notes\ncw,,,,1,wet\n")
    cli("plan", "--out", other).expect_error("--out", "already holds")
    assert cli("plan", "--out", other, "--force")[0] == 0  # forced: replaced
    assert "notes" not in other.read_text()


def test_plan_default_output_is_checked_against_the_inputs(cli, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    robot = write(tmp_path / "runs-template.csv", ROBOT_YAML)  # a robot file with that name
    cli("plan", "--robot", robot).expect_error("default runs-template.csv", "input file")
    assert robot.read_text() == ROBOT_YAML


# --- all or none: failures and interruptions while writing -----------------------------------


def _fit_with_two_outputs(tmp_path, runs_dir):
    robot = write(tmp_path / "robot.yaml", ROBOT_YAML)
    out_dir = tmp_path / "new" / "deeper"  # does not exist: the command must not create it
    return (
        ["fit", runs_dir, "--method", "linear", "--robot", robot, "--force"],
        out_dir,
    )


def _stage_failing_on_second(monkeypatch, exc):
    real, calls = outputs._stage, []

    def stage(path, content):
        calls.append(path)
        if len(calls) == 2:
            raise exc
        return real(path, content)

    monkeypatch.setattr(outputs, "_stage", stage)
    return calls


@pytest.mark.parametrize(
    "exc, status, line",
    [
        (KeyboardInterrupt(), 130, "odocal: interrupted"),
        (OSError(28, "No space left on device"), 2, "odocal: error: "),
    ],
)
def test_interrupt_or_failure_while_staging_writes_nothing(
    cli, tmp_path, monkeypatch, exc, status, line
):
    # design writes three figures into a folder that does not exist yet
    plot = tmp_path / "figs" / "design"
    calls = _stage_failing_on_second(monkeypatch, exc)
    # each figure staged on its own (not all three rendered before), and not drawn: the
    # interruption comes while the second file is staged either way, whatever the files hold
    monkeypatch.setattr(outputs, "_render_figures", lambda contents: contents)
    monkeypatch.setattr(outputs, "_png", lambda content: b"a figure")
    res = cli("design", "--analytic", "--side-lengths", "1:3:1", "--plot", plot)
    assert len(calls) == 2
    assert res[0] == status and res[1] == ""
    assert res[2].startswith(line) and res[2].count("\n") == 1, res[2]
    assert not (tmp_path / "figs").exists()  # no folder left, no temporary file
    assert list(tmp_path.iterdir()) == []


def test_sigterm_while_staging_unwinds_like_ctrl_c(cli, tmp_path, runs_dir, monkeypatch):
    argv, _ = _fit_with_two_outputs(tmp_path, runs_dir)
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    out.write_text("previous calibration\n")
    real, calls = outputs._stage, []

    def stage(path, content):
        calls.append(path)
        if len(calls) == 2:
            os.kill(os.getpid(), signal.SIGTERM)  # delivered to the handler main() installs
        return real(path, content)

    monkeypatch.setattr(outputs, "_stage", stage)
    status, stdout, err = cli(*argv, "--out", out, "--ros2", ros2)
    assert status == 128 + signal.SIGTERM and stdout == ""
    assert err.startswith("odocal: terminated") and err.count("\n") == 1, err
    assert out.read_text() == "previous calibration\n" and not ros2.exists()
    assert not list(tmp_path.glob(".*.tmp"))
    assert signal.getsignal(signal.SIGTERM) is not None  # main() restored the handler


def test_a_signal_during_the_renames_waits_until_all_are_done(cli, tmp_path, runs_dir, monkeypatch):
    argv, _ = _fit_with_two_outputs(tmp_path, runs_dir)
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    real_replace, calls = os.replace, []

    def replace(a, b):
        calls.append(b)
        if len(calls) == 1:
            os.kill(os.getpid(), signal.SIGINT)  # held back until every rename is done
        real_replace(a, b)

    monkeypatch.setattr(outputs.os, "replace", replace)
    # a job started in the background (nohup ... &) inherits SIGINT ignored: restore Ctrl-C
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        status, _, err = cli(*argv, "--out", out, "--ros2", ros2)
    finally:
        signal.signal(signal.SIGINT, previous)
    monkeypatch.undo()
    assert len(calls) == 2
    assert status == 130 and err.startswith("odocal: interrupted")
    # all written, completely (the interruption came after the commit)
    assert "wheelbase_m" in out.read_text() and "wheel_separation" in ros2.read_text()
    assert not list(tmp_path.glob(".*.tmp"))


def test_an_error_of_the_interrupted_machinery_after_sigterm_is_still_terminated(
    cli, tmp_path, runs_dir, monkeypatch
):
    """SIGTERM interrupts some machinery, which then fails with an error of its own (a lock of
    multiprocessing released twice: 'generator didn't stop after throw()' out of the writer):
    the command still ends as terminated, one line, nothing written."""
    argv, _ = _fit_with_two_outputs(tmp_path, runs_dir)
    out, ros2 = tmp_path / "params.yaml", tmp_path / "ros2.yaml"
    real, calls = outputs._stage, []

    def stage(path, content):
        calls.append(path)
        if len(calls) == 2:
            try:
                os.kill(os.getpid(), signal.SIGTERM)
            finally:
                raise ValueError("semaphore or lock released too many times")
        return real(path, content)

    monkeypatch.setattr(outputs, "_stage", stage)
    status, stdout, err = cli(*argv, "--out", out, "--ros2", ros2)
    assert status == 143 and stdout == "", err
    assert err == "odocal: terminated (SIGTERM); nothing half-written\n"
    assert not out.exists() and not ros2.exists() and not list(tmp_path.glob(".*.tmp"))


#: Run odocal as the command line does, with a line on stderr once the work has begun (inside
#: the first run_tasks call: odocal's handlers are set, worker processes about to start).
_MARKED = """
import sys
from odocal.core import parallel
real = parallel.run_tasks
def marked(*args, **kwargs):
    print("odocal-test: working", file=sys.stderr, flush=True)
    return real(*args, **kwargs)
import odocal.design.reproduce  # its six simulations run on worker processes
odocal.design.reproduce.run_tasks = marked
from odocal.cli.main import entry
sys.argv[0] = "odocal"
entry()
"""


def test_real_sigterm_to_the_process_group_in_a_subprocess(tmp_path):
    """A real SIGTERM to the process group (the command and its worker processes) once the work
    has begun: exit 143, one line, no folder, no temporary file, no process left. No timing
    guess: the signal is sent when the command says it has begun (benchmarks/sigterm_stress.py
    sends it at random times, many runs)."""
    env = {**os.environ, "ODOCAL_THREADS": "2"}
    argv = ["reproduce", "--trials", "5", "--out", str(tmp_path / "figs")]
    proc = subprocess.Popen(
        [sys.executable, "-c", _MARKED, *argv],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
        env=env,
        start_new_session=True,  # its own process group
    )
    assert proc.stderr is not None
    marker = proc.stderr.readline()
    assert marker == "odocal-test: working\n", marker
    os.killpg(proc.pid, signal.SIGTERM)
    out, err = proc.communicate(timeout=120)
    assert proc.returncode == 143, (proc.returncode, err)
    assert out == "" and err == "odocal: terminated (SIGTERM); nothing half-written\n", err
    assert list(tmp_path.iterdir()) == []
    with pytest.raises(ProcessLookupError):  # no worker left behind (they are reaped first)
        os.killpg(proc.pid, 0)


# --- reproducible: the same command and seed write the same bytes -------------------------


def _run_twice(cli, tmp_path, make_argv):
    """The same command twice: in one process, then with its figures drawn on worker processes
    (ODOCAL_THREADS=2); the same bytes."""
    results = []
    for name, threads in (("first", "1"), ("second", "2")):
        folder = tmp_path / name
        folder.mkdir()
        before = os.environ.get("ODOCAL_THREADS")
        os.environ["ODOCAL_THREADS"] = threads
        try:
            status, out, err = cli(*make_argv(folder))
        finally:
            if before is None:
                del os.environ["ODOCAL_THREADS"]
            else:
                os.environ["ODOCAL_THREADS"] = before
        assert status == 0, err
        results.append(tree(folder))
    assert results[0] == results[1]
    assert results[0]  # something was written
    return results[0]


def _png_text_chunks(data: bytes) -> list[bytes]:
    chunks, i = [], 8
    while i < len(data):
        n = int.from_bytes(data[i : i + 4], "big")
        kind = data[i + 4 : i + 8]
        if kind in (b"tEXt", b"iTXt", b"zTXt", b"tIME"):
            chunks.append(data[i + 8 : i + 8 + n])
        i += 12 + n
    return chunks


def test_design_plot_is_byte_identical(cli, tmp_path):
    files = _run_twice(
        cli,
        tmp_path,
        lambda f: ["design", "--trials", 20, "--side-lengths", "1:2:1", "--plot", f / "figs"],
    )
    pngs = [v for k, v in files.items() if k.endswith(".png")]
    assert len(pngs) == 3
    # no software version, date or other text inside the PNGs
    assert all(_png_text_chunks(p) == [] for p in pngs)


def test_simulate_out_is_byte_identical(cli, tmp_path):
    _run_twice(
        cli, tmp_path, lambda f: ["simulate", "--runs", 4, "--seed", 7, "--out", f / "r.csv"]
    )


def test_validate_plot_is_byte_identical(cli, tmp_path, runs_dir):
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    (runs_dir / "c.csv").unlink()  # two runs: two figures, drawn on two workers the 2nd time
    files = _run_twice(
        cli, tmp_path, lambda f: ["validate", runs_dir, "--params", params, "--plot", f / "p"]
    )
    assert sorted(files) == ["p/a.png", "p/b.png"]


def test_compare_plot_and_json_are_byte_identical(cli, tmp_path):
    docs = []
    for name in ("first", "second"):
        # a folder two levels below one that exists: the command creates both (the figure of
        # tests/cli/test_compare.py's JSON test, tested here where it is drawn anyway)
        plot = tmp_path / name / "new" / "dir"
        status, out, err = cli("compare", "--trials", 3, "--seed", 5, "--plot", plot, "--json")
        assert status == 0, err
        doc = json.loads(out)
        assert doc.pop("plot") == str(plot / "compare.png")  # the only difference: where
        docs.append((doc, tree(plot)))
    assert docs[0] == docs[1] and docs[0][0]["seed"] == 5
    assert list(docs[0][1]) == ["compare.png"]
    png = docs[0][1]["compare.png"]
    assert png[:8] == b"\x89PNG\r\n\x1a\n" and len(png) > 10_000


def test_sigterm_in_library_use_cleans_up_then_terminates(tmp_path):
    """From Python (no command-line handler): SIGTERM while staging removes what was staged and
    the folder the plan created, then the process terminates as asked.

    The library's caller is a child forked from this test process, with SIGTERM at its default
    action as in any Python program that has not set it: the same calls as a fresh
    ``python -c`` running them, without the 0.9 s of CPU that interpreter spent importing numpy
    and odocal again."""
    from odocal.app.design import design
    from odocal.design.spec import DesignSpec

    spec = DesignSpec(side_lengths_m=(1.0, 2.0))
    plot = tmp_path / "f" / "g"
    r, w = os.pipe()
    pid = os.fork()
    if pid == 0:  # the child: never returns into pytest
        code = 3
        try:
            os.close(r)
            signal.signal(signal.SIGTERM, signal.SIG_DFL)
            real, calls = outputs._stage, []

            def stage(path, content):
                calls.append(path)
                if len(calls) == 2:
                    os.kill(os.getpid(), signal.SIGTERM)
                return real(path, content)

            # (the child's own copy of the module: nothing changes in this test process)
            outputs._stage = stage
            outputs._render_figures = lambda contents: contents  # each figure staged on its own
            # not drawn: what a figure's file holds is not the question here (drawing the first
            # one, with matplotlib's import, was 90 % of this test's time)
            outputs._png = lambda content: b"a figure"
            design(spec=spec, engine="analytic", plot=plot)
            os.write(w, b"not reached")
        except BaseException:
            import traceback

            os.write(w, traceback.format_exc().encode())
            code = 4
        finally:
            os._exit(code)
    os.close(w)
    deadline = time.monotonic() + 120
    while (done := os.waitpid(pid, os.WNOHANG))[0] == 0:
        if time.monotonic() > deadline:
            os.kill(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            pytest.fail("the library call did not end within 120 s")
        time.sleep(0.01)
    with os.fdopen(r, "rb") as fh:
        said = fh.read().decode(errors="replace")
    status = done[1]
    assert os.WIFSIGNALED(status) and os.WTERMSIG(status) == signal.SIGTERM, (status, said)
    assert said == ""  # neither "not reached" nor an error
    assert list(tmp_path.iterdir()) == []
