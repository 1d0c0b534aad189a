"""Inputs people really have are accepted: pipes and process substitution, /dev/stdin, files
from other editors (BOM, CRLF, CR), whole data folders; and the answers say where their numbers
come from (validate's nominal column), refuse absurd results unless forced, and say when a
method could calibrate nothing.
"""

from __future__ import annotations

import json
import os
import shutil
import subprocess
import sys
import threading
from pathlib import Path

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

BASH = shutil.which("bash")


def write(path: Path, text: str) -> Path:
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def odocal_sh(script: str, cwd: Path) -> subprocess.CompletedProcess:
    """Run a bash command line where ``odocal`` is this checkout's command."""
    env = {**os.environ, "PYTHONWARNINGS": "error::RuntimeWarning"}
    return subprocess.run(
        [BASH, "-c", f'odocal() {{ "{sys.executable}" -m odocal "$@"; }}; {script}'],
        cwd=cwd,
        capture_output=True,
        text=True,
        timeout=120,
        env=env,
    )


@pytest.fixture
def files(tmp_path) -> Path:
    for name, text in {
        "robot.yaml": ROBOT_YAML,
        "params.yaml": PARAMS_YAML,
        "track.yaml": TRACK_YAML,
        "runs.csv": RUNS_CSV,
        "a.csv": TTEST_A,
        "b.csv": TTEST_B,
        "m.tuple": tuples_text(),
        "run1.csv": generic_csv_text(1.5),
        "run2.csv": generic_csv_text(-1.0),
        "run3.csv": generic_csv_text(2.5),
    }.items():
        write(tmp_path / name, text)
    return tmp_path


# --- pipes, process substitution, /dev/stdin ----------------------------------------------------


class _Pipes:
    """Files given as pipes, as bash's ``<(cat FILE)`` gives them: ``path(name)`` is
    ``/dev/fd/N`` of a new pipe that a thread fills with the file's bytes (a pipe can be read
    once); ``close()`` closes every read end and waits for the writers."""

    def __init__(self, folder: Path):
        self.folder, self.fds, self.threads = folder, [], []

    def path(self, name: str) -> str:
        r, w = os.pipe()
        data = (self.folder / name).read_bytes()

        def fill():
            try:
                with os.fdopen(w, "wb") as fh:
                    fh.write(data)
            except BrokenPipeError:  # the reader stopped early: the numbers will tell
                pass

        t = threading.Thread(target=fill, daemon=True)
        t.start()
        self.fds.append(r)
        self.threads.append(t)
        return f"/dev/fd/{r}"

    def close(self) -> None:
        for r in self.fds:
            os.close(r)
        for t in self.threads:
            t.join(timeout=10)
            assert not t.is_alive()
        self.fds, self.threads = [], []


@pytest.mark.skipif(BASH is None, reason="needs bash for <(...)")
@pytest.mark.filterwarnings("error::RuntimeWarning")
def test_every_reader_reads_a_pipe_once(cli, files, monkeypatch):
    """Each command from files and with every input through a pipe (/dev/fd/N, what bash's
    <(cat ...) gives; in-process), the same numbers; and, through a real shell, standard input
    as a pipe and as a redirected file, and a process substitution."""
    commands = [
        "calibrate {runs.csv} --robot {robot.yaml} --side-length 4 --json",
        "simulate --robot {robot.yaml} --params {params.yaml} --track {track.yaml} --runs 2 --json",
        "fit {run1.csv} {run2.csv} {run3.csv} --method linear --robot {robot.yaml} --json",
        "validate {run1.csv} --params {params.yaml} --json",
        "ttest {a.csv} {b.csv} --json",
        "fit {m.tuple} --method relative --json",
    ]
    monkeypatch.chdir(files)
    for command in commands:
        words = command.split()
        plain = [w.strip("{}") for w in words]
        status, out, err = cli(*plain)
        assert status == 0, (plain, err)
        pipes = _Pipes(files)
        try:
            piped = [pipes.path(w.strip("{}")) if w.startswith("{") else w for w in words]
            p_status, p_out, p_err = cli(*piped)
        finally:
            pipes.close()
        assert p_status == 0 and "odocal: error" not in p_err, (piped, p_err)
        # the inputs' names differ (/dev/fd/N for a pipe); the numbers do not
        assert _numbers(json.loads(out)) == _numbers(json.loads(p_out)), command
    # a real shell: standard input as a pipe (with a process substitution beside it) and as a
    # redirected file, in fresh processes
    r = odocal_sh(
        "cat runs.csv | odocal calibrate /dev/stdin --robot <(cat robot.yaml) --side-length 4 "
        "--json; echo @@@; odocal simulate --robot /dev/stdin --runs 2 --json < robot.yaml",
        files,
    )
    assert r.returncode == 0 and "odocal: error" not in r.stderr, r.stderr
    piped_docs = [json.loads(t) for t in r.stdout.split("@@@")]
    shell_commands = [commands[0], "simulate --robot robot.yaml --runs 2 --json"]
    for command, b in zip(shell_commands, piped_docs, strict=True):
        status, out, err = cli(*command.replace("{", "").replace("}", "").split())
        assert status == 0, err
        assert _numbers(json.loads(out)) == _numbers(b), command


def _numbers(doc):
    """``doc`` with every text replaced by '' (names of inputs), numbers kept."""
    if isinstance(doc, dict):
        return {k: _numbers(v) for k, v in doc.items()}
    if isinstance(doc, list):
        return [_numbers(v) for v in doc]
    return "" if isinstance(doc, str) else doc


def test_a_dash_is_not_standard_input(cli, files, monkeypatch):
    # '-' is not a special name (use /dev/stdin): a file that does not exist, said in one line
    monkeypatch.chdir(files)
    cli("simulate", "--robot", "-").expect_error("-: no such file")


@pytest.mark.parametrize(
    "transform",
    [
        lambda b: b"\xef\xbb\xbf" + b,
        lambda b: b.replace(b"\n", b"\r\n"),
        lambda b: b.replace(b"\n", b"\r"),
        lambda b: b.replace(b",", b" , "),
    ],
    ids=["bom", "crlf", "cr", "spaces"],
)
def test_other_editors_files_give_the_same_numbers(cli, files, transform):
    runs, robot = files / "runs.csv", files / "robot.yaml"
    clean = cli("calibrate", runs, "--robot", robot, "--side-length", 4, "--json")
    runs.write_bytes(transform(runs.read_bytes()))
    robot.write_bytes(transform(robot.read_bytes()) if b"," not in robot.read_bytes() else b"")
    if not robot.read_bytes():
        robot.write_text(ROBOT_YAML)
    other = cli("calibrate", runs, "--robot", robot, "--side-length", 4, "--json")
    assert clean[0] == other[0] == 0, other[2]
    assert json.loads(clean[1]) == json.loads(other[1])


# --- whole data folders -------------------------------------------------------------------------


def test_a_collection_folder_is_walked(cli, tmp_path):
    top = tmp_path / "data"
    write_optiodom(top)  # data/square/111
    write(top / "README.md", "notes\n")
    write(top / "results.csv", "method,value\nx,1\n")  # not a run
    write(top / "raw" / "111" / "111_run-01_odo.csv", "1,2,3\n")  # no metadata: not a data set
    write(top / "mine" / "day1" / "r1.csv", generic_csv_text(1.0))
    params = write(tmp_path / "p.yaml", "wheel_diameter_right_m: 0.084\n")
    params.write_text(
        "wheel_diameter_right_m: 0.084\nwheel_diameter_left_m: 0.084\nwheelbase_m: 0.2\n"
    )
    status, out, err = cli("validate", top, "--params", params, "--json")
    assert status == 0, err
    names = [Path(r["path"]).name for r in json.loads(out)["runs"]]
    assert names == ["r1.csv", f"{OPTI_ID}_run-01.csv", f"{OPTI_ID}_run-02.csv"]
    # what was skipped is said, in one warning
    assert err.count("odocal: warning: ") == 1, err
    assert "skipped what holds no runs: README.md, raw/, results.csv" in err


def test_a_folder_of_runs_is_strict_about_its_csv_files(cli, tmp_path):
    runs = tmp_path / "runs"
    write(runs / "a.csv", generic_csv_text(1.0))
    write(runs / "b.csv", "tim_s,wheel_right_rad\n0,0\n")  # a typo in a run's header
    params = write(tmp_path / "p.yaml", PARAMS_YAML)
    cli("validate", runs, "--params", params).expect_error("b.csv", "time_s")


def test_the_whole_optiodom_folder(cli, realdata, tmp_path):
    params = write(
        tmp_path / "p.yaml",
        "wheel_diameter_right_m: 0.0837\nwheel_diameter_left_m: 0.0836\nwheelbase_m: 0.2006\n",
    )
    status, out, err = cli("validate", realdata / "optiodom_diff", "--params", params, "--json")
    assert status == 0, err
    doc = json.loads(out)
    assert len(doc["runs"]) == 129  # 44 squares, 66 Ivanjko runs, 12 circles, 7 free paths
    assert doc["nominal_source"] == "firmware"
    assert "raw_unsynchronised/" in err and "reference_results_diff.csv" in err


# --- validate: which "nominal", chosen and said ---------------------------------------------


def test_validate_says_and_lets_you_choose_the_nominal(cli, tmp_path):
    ds = write_optiodom(tmp_path / "data")
    params = write(
        tmp_path / "p.yaml",
        "wheel_diameter_right_m: 0.0838\nwheel_diameter_left_m: 0.0842\nwheelbase_m: 0.201\n",
    )
    robot = write(tmp_path / "r.yaml", "wheel_diameter_m: 0.085\nwheelbase_m: 0.21\n")

    def run(*extra):
        status, out, err = cli("validate", ds, "--params", params, *extra, "--json")
        assert status == 0, err
        text = cli("validate", ds, "--params", params, *extra)[1]
        return json.loads(out), text

    firmware, t_fw = run()
    robot_doc, t_robot = run("--robot", robot)
    chosen, _ = run("--nominal", "firmware")
    assert firmware["nominal_source"] == chosen["nominal_source"] == "firmware"
    assert robot_doc["nominal_source"] == "robot"
    assert firmware["runs"][0]["nominal_params"]["wheelbase_m"] == 0.2  # the metadata's Li
    assert robot_doc["runs"][0]["nominal_params"]["wheelbase_m"] == 0.21
    assert robot_doc["nominal_params"]["wheelbase_m"] == 0.21 and firmware["nominal_params"] is None
    assert firmware["mean_nominal_final_error_m"] != robot_doc["mean_nominal_final_error_m"]
    assert firmware["mean_final_error_m"] == robot_doc["mean_final_error_m"]
    assert "firmware columns: each run's firmware values" in t_fw and "firmware final mm" in t_fw
    assert "robot columns: ROBOT.yaml's nominal geometry" in t_robot
    cli("validate", ds, "--params", params, "--nominal", "robot").expect_error("needs --robot")
    cli("validate", ds, "--params", params, "--nominal", "firmware", "--robot", robot).expect_error(
        "--robot is not used"
    )
    bare = write(tmp_path / "bare.csv", generic_csv_text().replace("# wheelbase_m", "# x"))
    bare.write_text("\n".join(ln for ln in bare.read_text().splitlines() if "_m:" not in ln))
    cli("validate", bare, "--params", params, "--nominal", "firmware").expect_error(
        "does not say which parameters it ran with"
    )


# --- absurd results: exit 2 unless forced ------------------------------------------------------


def test_an_absurd_fit_is_refused_unless_forced(cli, tmp_path):
    ds = write_optiodom(tmp_path / "data")
    meta = ds / f"{OPTI_ID}_metadata.csv"
    meta.write_text(meta.read_text().replace("Di,0.084,0.084", "Di,0.84,0.84"))  # a unit slip
    out = tmp_path / "params.yaml"
    cli("fit", ds, "--out", out).expect_error("from nominal", "absurd", "--force")
    assert not out.exists()
    status, stdout, err = cli("fit", ds, "--out", out, "--force", "--json")
    assert status == 0 and out.is_file()
    doc = json.loads(stdout)
    assert any("absurd" in w for w in doc["warnings"]) and "odocal: warning: " in err


# --- a comparison that could calibrate nothing with a method says so -----------------------------


def test_compare_names_methods_without_data(cli, tmp_path):
    data = tmp_path / "optiodom_diff"
    write_optiodom(data)  # squares only: no Ivanjko runs, no circles
    free = data / "free" / "222"
    free.mkdir(parents=True)
    for f in (data / "square" / OPTI_ID).iterdir():
        shutil.copy(f, free / f.name.replace(OPTI_ID, "222"))
    status, out, err = cli("compare", "--realdata", data, "--trials", 2, "--json")
    assert status == 0, err
    real = json.loads(out)["realdata"]
    failed = {f["method"]: f["error"] for f in real["failures"]}
    assert "no data set it can calibrate from" in failed["ivanjko"]
    assert "no data set it can calibrate from" in failed["bcpt"]
    assert all(m["calibrations"] > 0 for m in real["methods"])  # no empty rows
    text = cli("compare", "--realdata", data, "--trials", 2)[1]
    assert "ivanjko: not calibrated: no data set it can calibrate from" in text
