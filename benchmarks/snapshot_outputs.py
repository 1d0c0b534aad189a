"""Every command's outputs, for proving that a change altered none of them.

Runs every ``odocal`` command on fixed seeds and real data (``../shared/realdata``): its stdout
(text and ``--json``), stderr, exit status, and every file it writes (JSON, YAML, CSV, Markdown,
PNG), into one folder; ``diff`` compares two such folders byte for byte.

    .venv/bin/python benchmarks/snapshot_outputs.py run OUT_DIR     # about 2 minutes
    .venv/bin/python benchmarks/snapshot_outputs.py diff OLD_DIR NEW_DIR

Run it before and after a change (for instance in a worktree of the old commit) and diff.
Lines that carry a timing (``seconds``, ``elapsed``, ``took``) are left out of the comparison,
and the checkout's own path is written as ``{root}``; nothing else is masked.
"""

from __future__ import annotations

import hashlib
import re
import shutil
import subprocess
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
REAL = ROOT.parent / "shared" / "realdata"
OPTI = REAL / "optiodom_diff"
SQ = OPTI / "square"
MIT = REAL / "mit_csail"
HUSKY = REAL / "husky"
CENSI = REAL / "censi_calibration"
ROBOT = ROOT / "examples" / "tetra-ds2.yaml"

# (name, argv after "odocal"); "{out}" is the case's own output folder
CASES: list[tuple[str, list[str]]] = [
    ("design-json", ["design", "--trials", "300", "--seed", "3", "--json"]),
    ("design-text", ["design", "--trials", "300", "--seed", "3", "--plot", "{out}/fig"]),
    ("design-analytic", ["design", "--analytic", "--json"]),
    ("design-analytic-text", ["design", "--analytic"]),
    (
        "design-octagon",
        ["design", "--sides", "4", "--sides", "8", "--trials", "200", "--seed", "1"],
    ),
    (
        "design-new-robot",
        ["design", "--robot", "{out}/../robot-small.yaml", "--trials", "200", "--seed", "2"],
    ),
    ("design-robot-from", ["design", "--robot-from", str(SQ), "--trials", "200", "--seed", "2"]),
    ("simulate", ["simulate", "--seed", "5", "--runs", "5", "--out", "{out}/runs.csv", "--json"]),
    (
        "simulate-predict",
        ["simulate", "--seed", "6", "--runs", "3", "--predict", "--out", "{out}/runs.csv"],
    ),
    (
        "calibrate",
        [
            "calibrate",
            "{out}/../simulate/runs.csv",
            "--robot",
            str(ROBOT),
            "--json",
            "--out",
            "{out}/params.yaml",
            "--ros2",
            "{out}/ros2.yaml",
        ],
    ),
    ("calibrate-text", ["calibrate", "{out}/../simulate/runs.csv", "--robot", str(ROBOT)]),
    ("plan", ["plan", "--robot", str(ROBOT), "--out", "{out}/plan.csv", "--json"]),
    ("plan-text", ["plan", "--robot", "{out}/../robot-small.yaml", "--out", "{out}/plan.csv"]),
    ("noise", ["noise", str(SQ), "--json"]),
    ("noise-text", ["noise", str(SQ), "--ros2", "{out}/cov.yaml"]),
    ("fit-square", ["fit", str(SQ), "--json", "--out", "{out}/p.yaml", "--ros2", "{out}/r.yaml"]),
    ("fit-square-text", ["fit", str(SQ), "--plot", "{out}/fig"]),
    ("fit-mix", ["fit", str(SQ), str(OPTI / "circular"), "--motion-mix", "spot=0.3,wide=0.7"]),
    (
        "fit-banded",
        [
            "fit",
            str(SQ),
            str(OPTI / "circular"),
            "--wheelbase-model",
            "banded",
            "--json",
            "--plot",
            "{out}/fig",
        ],
    ),
    ("fit-segment", ["fit", str(SQ), "--residual", "segment", "--json"]),
    ("fit-linear", ["fit", str(SQ), "--method", "linear", "--json"]),
    ("fit-umbmark", ["fit", str(SQ), "--method", "umbmark"]),
    ("fit-heading", ["fit", str(SQ), "--method", "heading", "--json"]),
    ("fit-robot-out", ["fit", str(SQ), "--robot-out", "{out}/measured.yaml"]),
    ("fit-censi", ["fit", str(CENSI / "l90.tuple"), "--json"]),
    ("fit-censi-text", ["fit", str(CENSI / "lmov.tuple")]),
    ("fit-gyro", ["fit", str(HUSKY / "husky_test1.bag"), "--method", "gyro", "--json"]),
    (
        "fit-slam",
        [
            "fit",
            str(MIT / "csail_half1"),
            "--truth-frames",
            "map:base_link",
            "--robot",
            str(MIT / "robot_virtual.yaml"),
            "--json",
        ],
    ),
    (
        "fit-slam-text",
        [
            "fit",
            str(MIT / "csail_half2"),
            "--truth-frames",
            "map:base_link",
            "--robot",
            str(MIT / "robot_virtual.yaml"),
        ],
    ),
    (
        "fit-scan",
        [
            "fit",
            str(MIT / "csail_half1"),
            "--method",
            "scan",
            "--robot",
            str(MIT / "robot_virtual.yaml"),
            "--json",
        ],
    ),
    (
        "validate",
        [
            "validate",
            str(OPTI / "ivanjko"),
            "--params",
            "{out}/../fit-square/p.yaml",
            "--json",
            "--plot",
            "{out}/fig",
        ],
    ),
    (
        "validate-text",
        ["validate", str(OPTI / "ivanjko"), "--params", "{out}/../fit-square/p.yaml"],
    ),
    ("check", ["check", str(SQ), "--json"]),
    ("check-text", ["check", str(SQ), "--mounting"]),
    (
        "check-slam",
        [
            "check",
            str(MIT / "csail_half1"),
            "--truth-frames",
            "map:base_link",
            "--robot",
            str(MIT / "robot_virtual.yaml"),
        ],
    ),
    ("compare", ["compare", "--trials", "100", "--seed", "4", "--json"]),
    (
        "compare-text",
        [
            "compare",
            "--trials",
            "100",
            "--seed",
            "4",
            "--realdata",
            str(OPTI),
            "--plot",
            "{out}/fig",
        ],
    ),
    ("reproduce", ["reproduce", "--out", "{out}/rep", "--trials", "200", "--seed", "1", "--json"]),
    (
        "reproduce-real",
        [
            "reproduce",
            "--out",
            "{out}/rep",
            "--trials",
            "200",
            "--seed",
            "1",
            "--realdata",
            str(OPTI),
        ],
    ),
    (
        "ttest",
        ["ttest", "{out}/../simulate/runs.csv", "{out}/../simulate-predict/runs.csv", "--json"],
    ),
    ("bag-info", ["bag-info", str(HUSKY / "husky_test1.bag")]),
    ("bag-info-json", ["bag-info", str(MIT / "csail_half1"), "--json"]),
    ("no-args", []),
    ("bad-input", ["fit", "/nonexistent/run.csv"]),
]

SMALL_ROBOT = (
    "wheel_diameter_m: 0.066\nwheelbase_m: 0.160\n"
    "measurement: {sigma_xy_m: 0.01, sigma_theta_deg: 1.0}\n"
)
TEXT = (".txt", ".json", ".md", ".yaml", ".csv")
TIMING = re.compile(r"(seconds|elapsed|took [0-9.]+ s)", re.IGNORECASE)


def run(out: Path) -> None:
    """Run every case into ``out`` (emptied first)."""
    if out.exists():
        shutil.rmtree(out)
    out.mkdir(parents=True)
    (out / "robot-small.yaml").write_text(SMALL_ROBOT)
    odocal = str(Path(sys.executable).parent / "odocal")
    for name, argv in CASES:
        case = out / name
        case.mkdir()
        args = [a.replace("{out}", str(case)) for a in argv]
        p = subprocess.run([odocal, *args], capture_output=True, text=True, cwd=case)
        mask = str(case)
        (case / "stdout.txt").write_text(p.stdout.replace(mask, "{out}"))
        (case / "stderr.txt").write_text(p.stderr.replace(mask, "{out}"))
        (case / "status.txt").write_text(f"{p.returncode}\n")
        for f in case.rglob("*"):  # the checkout's own path is not an output
            if f.is_file() and f.suffix in TEXT:
                f.write_text(f.read_text().replace(str(ROOT), "{root}"))
        print(f"{name}: exit {p.returncode}", flush=True)


def digests(folder: Path) -> dict[str, str]:
    """Relative path -> sha256 of every file below ``folder`` (timing lines masked in text)."""
    result = {}
    for f in sorted(folder.rglob("*")):
        if f.is_file():
            data = f.read_bytes()
            if f.suffix in TEXT:
                lines = [
                    ln for ln in data.decode(errors="replace").splitlines() if not TIMING.search(ln)
                ]
                data = "\n".join(lines).encode()
            result[str(f.relative_to(folder))] = hashlib.sha256(data).hexdigest()
    return result


def diff(old: Path, new: Path) -> int:
    """Print the files that differ or exist on one side only; 0 when none."""
    a, b = digests(old), digests(new)
    bad = 0
    for k in sorted(set(a) | set(b)):
        if a.get(k) != b.get(k):
            bad += 1
            side = "only old" if k not in b else "only new" if k not in a else "differs"
            print(f"{side}: {k}")
    print(f"{len(a)} files old, {len(b)} new, {bad} different")
    return 1 if bad else 0


if __name__ == "__main__":
    if len(sys.argv) == 3 and sys.argv[1] == "run":
        run(Path(sys.argv[2]).resolve())
    elif len(sys.argv) == 4 and sys.argv[1] == "diff":
        sys.exit(diff(Path(sys.argv[2]), Path(sys.argv[3])))
    else:
        sys.exit(__doc__)
