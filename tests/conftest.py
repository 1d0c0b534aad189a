"""Shared fixtures.

Real data live beside the project in ../shared/realdata (or $ODOCAL_REALDATA); they are never
copied into the project. Tests that use the ``realdata`` fixture are skipped with a visible reason
when the data are absent, except under CI (the CI environment variable set), where absence fails.
"""

from __future__ import annotations

import gc
import os
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]

# The tests already run on every core (pytest-xdist): odocal's own worker processes would only
# compete with them. Tests of the parallel paths set ODOCAL_THREADS themselves.
os.environ.setdefault("ODOCAL_THREADS", "1")
# Likewise BLAS: the matrices are small, and OpenBLAS threads spinning beside the other test
# worker made scipy's L-BFGS-B three times slower (set before any worker imports numpy).
for _var in ("OPENBLAS_NUM_THREADS", "OMP_NUM_THREADS", "MKL_NUM_THREADS"):
    os.environ.setdefault(_var, "1")


def _find_realdata() -> Path | None:
    env = os.environ.get("ODOCAL_REALDATA")
    candidates = [Path(env)] if env else []
    candidates.append(ROOT.parent / "shared" / "realdata")
    for c in candidates:
        if (c / "optiodom_diff").is_dir():
            return c
    return None


REALDATA = _find_realdata()
_MISSING = (
    "real data not found: set ODOCAL_REALDATA or place the shared folder beside the project "
    "(../shared/realdata)"
)


_last_file: list = [None]


def pytest_runtest_setup(item):
    # At each new test file: collect the garbage, then move everything that lives on (imported
    # modules, caches) out of the collector's sight (gc.freeze). Python's full collections
    # otherwise walk all of numpy, scipy and matplotlib's objects about twenty times per worker
    # (1.5-1.9 s per worker in all); now they walk what the current file made (0.5 s in all,
    # these collections included). The previous file's module fixtures are torn down by now;
    # anything frozen is still freed when its count drops.
    if item.path != _last_file[0]:
        _last_file[0] = item.path
        gc.collect()
        gc.freeze()


def pytest_unconfigure(config):
    # the test process (each xdist worker too) is about to exit: spare it the interpreter's last
    # garbage collection over everything the tests imported and made (0.3 s each; the odocal
    # command does the same, cli.main.entry)
    gc.freeze()


def pytest_collection_modifyitems(config, items):
    if REALDATA is not None or os.environ.get("CI"):
        return
    mark = pytest.mark.skip(reason=_MISSING)
    for item in items:
        if "realdata" in getattr(item, "fixturenames", ()):
            item.add_marker(mark)


@pytest.fixture(scope="session")
def realdata() -> Path:
    """Path of the shared real-data folder (holds optiodom_diff/ and husky/)."""
    if REALDATA is None:
        pytest.fail(_MISSING + " (required under CI)")
    return REALDATA


class CliResult(tuple):
    """(exit_status, stdout, stderr) of one ``odocal`` run, with the bad-input check."""

    def expect_error(self, *needles: str) -> None:
        """The bad-input contract: exit status 2, nothing on stdout, one line
        ``odocal: error: ...`` on stderr (no traceback) that contains every needle."""
        status, out, err = self
        assert status == 2, (status, err)
        assert out == "", out
        assert err.startswith("odocal: error: ") and err.count("\n") == 1, err
        assert "Traceback" not in err
        for n in needles:
            assert str(n) in err, (n, err)


@pytest.fixture
def cli(capsys):
    """Run ``odocal`` in-process: returns a CliResult (exit_status, stdout, stderr)."""
    from odocal.cli.main import main

    def run(*argv):
        try:
            status = main([str(a) for a in argv])
        except SystemExit as exc:  # argparse exits for --help and usage errors
            status = exc.code
        out, err = capsys.readouterr()
        return CliResult((status, out, err))

    return run


@pytest.fixture
def returned(monkeypatch):
    """Spy on an app function: ``returned(odocal.app.check, "check")`` is the list of what each
    later call of ``odocal.app.check.check`` returns. Every command imports its app function when
    it runs, so the spy sees the command's call: a CLI test checks that the command printed the
    typed result it got, computed once (the numbers themselves are tested in tests/app)."""

    def spy(module, name: str) -> list:
        results: list = []
        real = getattr(module, name)

        def record(*args, **kwargs):
            result = real(*args, **kwargs)
            results.append(result)
            return result

        monkeypatch.setattr(module, name, record)
        return results

    return spy
