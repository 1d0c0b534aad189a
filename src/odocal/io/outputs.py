"""The outputs of one command: checked against its inputs before any work, written all or none.

Every command that writes files goes through an :class:`OutputPlan`:

1. ``plan = OutputPlan(inputs)`` with every file or folder the command reads;
2. ``plan.file(path, "--out")`` / ``plan.folder(path, "--plot", files=NAMES)`` for every
   output, BEFORE the work: an output that is one of the inputs (the same file, also through a
   link), lies inside an input folder as an existing file, or names the same file as another
   output is refused with one line; so is an output whose folder cannot exist. The ``files`` a
   folder may hold whose names are known before the work (a report's ``params.yaml``, a
   figure) are checked then as files of their own: another output naming one of them
   (``--out D --ros2 D/params.yaml``) is two outputs in one file;
3. ``plan.commit({path: content})`` AFTER the work: every file is first staged as a temporary file
   beside its target, then all are renamed into place with SIGINT and SIGTERM held back, so that
   an interruption or a failure leaves either every output or none (and no temporary file, and
   no folder the plan created). The files a command names only then (inside an output folder)
   are checked as in step 2 before anything is written, and a rename that fails anyway undoes
   the renames before it (the files they replaced come back).

Contents are ``str`` (UTF-8 text), ``bytes``, an object with a matplotlib-like
``savefig(path, format="png", metadata=...)`` (a figure; written as PNG without a software
version or date, so that the same command writes the same bytes), or a function of no arguments
that returns one of these (called when its file is staged).
"""

from __future__ import annotations

import functools
import io
import os
import signal
import tempfile
from collections.abc import Callable, Iterable, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

from ..core.parallel import run_tasks, signals_held
from ..errors import InputError

__all__ = ["OutputPlan", "Savable", "Content"]


class Savable(Protocol):
    """What a figure output must offer: matplotlib's ``Figure.savefig``."""

    def savefig(self, fname: Any, *, format: str, metadata: dict) -> None:  # noqa: A002
        """Write the figure to ``fname`` in ``format`` with ``metadata`` (PNG text chunks)."""


#: PNG text chunks of every figure: none (matplotlib would write its version as 'Software').
PNG_METADATA: dict = {"Software": None}


Content = str | bytes | Savable | Callable[[], "str | bytes | Savable"]


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


# Most files of the input folders whose identity an output is checked against.
_MAX_WALKED_FILES = 200_000


def _same(a: Path, b: Path) -> bool:
    try:
        return a.exists() and b.exists() and os.path.samefile(a, b)
    except OSError:
        return False


def _within(path: Path, folder: Path) -> bool:
    try:
        path.resolve().relative_to(folder.resolve())
    except ValueError:
        return False
    return True


@dataclass(frozen=True)
class _Output:
    path: Path
    flag: str
    is_folder: bool

    @functools.cached_property
    def resolved(self) -> Path:
        """``path.resolve()``, once (when first asked, as before): a plan of many files (a fleet
        report's pages) compares each new output with every earlier one."""
        return self.path.resolve()


class _SigTerm(KeyboardInterrupt):
    pass


def _raise_sigterm(signum, frame):  # noqa: ARG001 - the signal module's API
    raise _SigTerm


@contextmanager
def _sigterm_unwinds():
    """While writing, a SIGTERM whose action is the default (a library caller; the command line
    installs its own handler) unwinds like Ctrl-C, so that no temporary file or created folder
    is left behind; the process then terminates as it was asked to."""
    try:
        ours = signal.getsignal(signal.SIGTERM) is signal.SIG_DFL
        if ours:
            signal.signal(signal.SIGTERM, _raise_sigterm)
    except ValueError:  # not the main thread
        ours = False
    if not ours:  # (a yield outside the try: an error thrown in at it goes on, as it should)
        yield
        return
    try:
        yield
    except _SigTerm:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)
        os.kill(os.getpid(), signal.SIGTERM)
        raise
    finally:
        signal.signal(signal.SIGTERM, signal.SIG_DFL)


class OutputPlan:
    """The outputs of one command (see the module docstring).

    Parameters
    ----------
    inputs : iterable of path-like
        Every file or folder the command reads (None entries and built-in names that are not
        paths are ignored when they do not exist).
    """

    def __init__(self, inputs: Iterable[Any] = ()):
        self._inputs = [Path(p) for p in inputs if p is not None]
        self._outputs: list[_Output] = []
        # the files output folders may hold (folder(files=...)): each with its folder's flag,
        # and its name there
        self._announced: list[tuple[_Output, str]] = []
        self._files_in_inputs: dict[tuple[int, int], Path] | None = None

    # ------------------------------------------------------------------ planning

    def _input_file_ids(self) -> dict[tuple[int, int], Path]:
        """(device, inode) of every file inside the input folders: an output elsewhere that is a
        hard link to one of them is the same file."""
        if self._files_in_inputs is None:
            ids: dict[tuple[int, int], Path] = {}
            for src in self._inputs:
                if not src.is_dir():
                    continue
                for root, _dirs, names in os.walk(src):
                    for name in names:
                        p = Path(root, name)
                        try:
                            st = p.stat()
                        except OSError:
                            continue
                        ids.setdefault((st.st_dev, st.st_ino), p)
                    if len(ids) > _MAX_WALKED_FILES:
                        break
            self._files_in_inputs = ids
        return self._files_in_inputs

    def _check_against_inputs(self, path: Path, flag: str, is_folder: bool) -> None:
        self._check_against_input_paths(path, flag, is_folder)
        if path.is_file():
            st = path.stat()
            inside = self._input_file_ids().get((st.st_dev, st.st_ino))
            if inside is not None:
                raise InputError(
                    f"{flag} would overwrite an input file of this command ({inside}, the same "
                    "file through a link); choose another output name",
                    path,
                )

    def _check_against_input_paths(self, path: Path, flag: str, is_folder: bool) -> None:
        for src in self._inputs:
            if not src.exists():
                continue
            if _same(path, src):
                what = "folder" if src.is_dir() else "file"
                raise InputError(
                    f"{flag} would overwrite an input {what} of this command; choose another "
                    "output name",
                    path,
                )
            if src.is_dir() and _within(path, src) and (path.exists() or is_folder):
                raise InputError(
                    f"{flag} lies inside the input folder {src}: an output there could replace "
                    "or mix with the inputs; choose another place",
                    path,
                )

    def _check_against_outputs(self, path: Path, flag: str, name: str | None = None) -> None:
        """Refuse ``path`` (of the output ``flag``; a file ``name`` its folder will hold) when
        another output, or a file another output folder will hold, is the same file."""
        resolved = path.resolve() if self._outputs else path
        who = flag if name is None else f"the {name} of {flag}"
        others = [(o, o.flag) for o in self._outputs] + [
            (o, f"the {n} of {o.flag}") for o, n in self._announced if o.flag != flag
        ]
        for o, what in others:
            if resolved == o.resolved or _same(path, o.path):
                raise InputError(
                    f"{who} names the same file as {what}; give each output its own name", path
                )

    def _planned_folder(self, folder: Path) -> _Output | None:
        """The registered output folder that is ``folder``, if any."""
        folders = [o for o in self._outputs if o.is_folder]
        if not folders:
            return None
        resolved = folder.resolve()
        return next((o for o in folders if o.resolved == resolved), None)

    def file(self, path: Any, flag: str) -> Path:
        """Register an output file (its folder must exist or be a registered output folder)."""
        path = Path(path)
        self._check_file(path, flag)
        self._outputs.append(_Output(path, flag, False))
        return path

    def _check_file(self, path: Path, flag: str, name: str | None = None) -> None:
        """Refuse an output file that cannot be written or would replace an input or another
        output (one line, before anything is written); ``name``: a file the output folder
        ``flag`` will hold."""
        if str(path) in ("", "."):
            raise InputError(f"{flag}: an empty output name", path)
        if path.is_dir():
            raise InputError(f"{flag}: is a directory, expected an output file name", path)
        if path.exists() and not path.is_file():
            # a device, FIFO or socket: renaming a file onto it would replace it
            raise InputError(
                f"{flag}: exists and is not a regular file; choose another output name", path
            )
        parent = path.parent
        planned_folder = self._planned_folder(parent) is not None
        if not parent.is_dir() and not planned_folder:
            raise InputError(f"{flag}: the output folder does not exist", parent)
        if parent.is_dir() and not os.access(parent, os.W_OK | os.X_OK):
            raise InputError(f"{flag}: cannot write into this folder (permission denied)", parent)
        self._check_against_inputs(path, flag, is_folder=False)
        self._check_against_outputs(path, flag, name)

    def folder(self, path: Any, flag: str, files: Iterable[str] = ()) -> Path:
        """Register an output folder (created at commit if missing, removed again on failure).

        ``files``: the names of the files it may hold that are known before the work; each is
        checked now as :meth:`file` checks (no other output may name it, before or after)."""
        path = Path(path)
        if path.exists() and not path.is_dir():
            raise InputError(f"{flag}: exists and is not a folder", path)
        if not path.exists():
            # the nearest existing ancestor must be a writable folder
            anc = path.parent
            while not anc.exists() and anc != anc.parent:
                anc = anc.parent
            if not anc.is_dir():
                raise InputError(f"{flag}: cannot create the output folder ({anc} is a file)", path)
            if not os.access(anc, os.W_OK | os.X_OK):
                raise InputError(
                    f"{flag}: cannot create the output folder (permission denied)", path
                )
        elif not os.access(path, os.W_OK | os.X_OK):
            raise InputError(f"{flag}: cannot write into this folder (permission denied)", path)
        self._check_against_inputs(path, flag, is_folder=True)
        self._outputs.append(_Output(path, flag, True))
        for name in files:
            self._check_file(path / name, flag, name)
            self._announced.append((_Output(path / name, flag, False), name))
        return path

    @property
    def files(self) -> list[Path]:
        """The registered output files (not the folders)."""
        return [o.path for o in self._outputs if not o.is_folder]

    # ------------------------------------------------------------------ writing

    def commit(self, contents: Mapping[Path, Content]) -> list[Path]:
        """Write every registered file (all of them or none); returns the paths written.

        ``contents`` maps each output file to its content; files inside a registered output
        folder are registered on the way, each checked as :meth:`file` checks (a folder or a
        device standing where it goes, an input, another output) before anything is written."""
        for path in contents:
            if not any(Path(path) == o.path for o in self._outputs if not o.is_folder):
                folder = self._planned_folder(Path(path).parent)
                if folder is None:
                    raise RuntimeError(f"output {path} was not planned")  # a programming error
                self._check_file(Path(path), folder.flag)
                self._outputs.append(_Output(Path(path), str(path), False))
        missing = [o.path for o in self._outputs if not o.is_folder and o.path not in contents]
        if missing:
            raise RuntimeError(f"no content for the planned output(s) {missing}")
        with _sigterm_unwinds():
            return self._write(contents)

    def _write(self, contents: Mapping[Path, Content]) -> list[Path]:
        created: list[Path] = []
        staged: list[tuple[Path, Path]] = []
        try:
            contents = _render_figures(contents)
            for o in self._outputs:
                if o.is_folder and not o.path.is_dir():
                    _make_folder(o.path, o.flag, created)
            for path, content in contents.items():
                try:
                    staged.append((_stage(Path(path), content), Path(path)))
                except OSError as exc:
                    raise InputError(f"cannot write: {exc.strerror or exc}", path) from None
            mode = 0o666 & ~_umask()
            with signals_held():
                for tmp, path in staged:
                    try:
                        os.chmod(tmp, mode)  # mkstemp creates 0600; give the usual mode
                    except OSError as exc:
                        raise InputError(f"cannot write: {exc.strerror or exc}", path) from None
                _replace_all(staged)
                # committed: a signal held back until here must not undo anything
                staged = []
                created = []
        finally:
            for tmp, _ in staged:
                tmp.unlink(missing_ok=True)
            for folder in reversed(created):
                try:
                    folder.rmdir()
                except OSError:
                    pass
        return list(contents)


def _replace_all(staged: list[tuple[Path, Path]]) -> None:
    """Rename every staged file onto its target; when one rename fails (the targets were checked
    before, but the file system may still refuse), undo the renames already done: the files they
    replaced come back (kept as hard links meanwhile), new ones are removed."""
    done: list[tuple[Path, Path | None]] = []  # (target, the previous file's backup or None)
    try:
        for tmp, path in staged:
            backup = _backup(path)
            try:
                os.replace(tmp, path)
            except OSError as exc:
                if backup is not None:
                    backup.unlink(missing_ok=True)
                raise InputError(
                    f"cannot write: {exc.strerror or exc}; no output written", path
                ) from None
            done.append((path, backup))
    except BaseException:
        for path, backup in reversed(done):
            try:
                if backup is None:
                    path.unlink()
                else:
                    os.replace(backup, path)
            except OSError:
                pass
        raise
    for _, backup in done:
        if backup is not None:
            backup.unlink(missing_ok=True)


def _backup(path: Path) -> Path | None:
    """A hard link to the file at ``path`` under a temporary name beside it (None when there is
    no file there, or the file system cannot link: the previous file then cannot come back)."""
    if not path.is_file():
        return None
    for _ in range(100):
        backup = path.with_name(f".{path.name}.{os.urandom(4).hex()}.bak")
        try:
            os.link(path, backup)
        except FileExistsError:
            continue
        except OSError:
            return None
        return backup
    return None


def _make_folder(path: Path, flag: str, created: list[Path]) -> None:
    """Create ``path`` and missing parents, appending each folder to ``created`` (outermost
    first) as soon as it exists, so that an interruption midway leaves none behind."""
    new = []
    p = path
    while not p.exists():
        new.append(p)
        p = p.parent
    for p in reversed(new):
        try:
            p.mkdir()
        except OSError as exc:
            raise InputError(
                f"{flag}: cannot create the output folder: {exc.strerror}", p
            ) from None
        created.append(p)


def _render_figures(contents: Mapping[Path, Content]) -> Mapping[Path, Content]:
    """``contents`` with its figures rendered to PNG bytes: several at once, each in a worker
    process of its own where there are cores for it (:func:`odocal.core.parallel.run_tasks`)."""
    figures = [p for p, c in contents.items() if not isinstance(c, str | bytes)]
    if len(figures) < 2:
        return contents
    pngs = run_tasks([functools.partial(_png, contents[p]) for p in figures])
    return {**contents, **dict(zip(figures, pngs, strict=True))}


def _png(content: Content) -> str | bytes:
    """Text or bytes as they are; a figure (or a function making one, called only now, so that
    many figures never sit in memory at once) as PNG bytes, without a software version or date
    inside: the same command writes the same bytes."""
    if callable(content) and not hasattr(content, "savefig"):
        content = content()
    if isinstance(content, str | bytes):
        return content
    buffer = io.BytesIO()
    content.savefig(buffer, format="png", metadata=PNG_METADATA)
    return buffer.getvalue()


def _stage(path: Path, content: Content) -> Path:
    content = _png(content)
    fd, name = tempfile.mkstemp(prefix=f".{path.name}.", suffix=".tmp", dir=path.parent)
    tmp = Path(name)
    try:
        if isinstance(content, str):
            with os.fdopen(fd, "w", encoding="utf-8", newline="\n") as fh:
                fh.write(content)
        else:
            with os.fdopen(fd, "wb") as fh:
                fh.write(content)
    except BaseException:
        tmp.unlink(missing_ok=True)
        raise
    return tmp
