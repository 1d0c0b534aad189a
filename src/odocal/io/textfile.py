"""Reading text inputs and writing outputs atomically."""

from __future__ import annotations

import os
import tempfile
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

from ..errors import InputError
from .limits import MAX_TEXT_BYTES

__all__ = ["read_text", "atomic_write", "atomic_path"]

_CHUNK = 1 << 20


def read_text(path, *, max_bytes: int = MAX_TEXT_BYTES) -> str:
    """The whole file as UTF-8 text (a leading BOM is dropped); InputError if unreadable or
    larger than ``max_bytes``. Read once, sequentially: a pipe or ``<(...)`` works."""
    path = Path(path)
    chunks: list[bytes] = []
    size = 0
    try:
        with open(path, "rb") as fh:
            # in pieces, so that a binary file (or /dev/zero) is refused at its first NUL byte
            while chunk := fh.read(min(_CHUNK, max_bytes + 1 - size)):
                if b"\x00" in chunk:
                    raise InputError("binary data, expected a text file", path)
                chunks.append(chunk)
                size += len(chunk)
                if size > max_bytes:
                    raise InputError(
                        f"larger than {max_bytes} bytes: not the expected kind of file?", path
                    )
        raw = b"".join(chunks)
    except FileNotFoundError:
        raise InputError("no such file", path) from None
    except IsADirectoryError:
        raise InputError("is a directory, expected a file", path) from None
    except OSError as exc:
        raise InputError(f"cannot read: {exc.strerror}", path) from None
    if b"\x00" in raw:
        raise InputError("binary data, expected a text file", path)
    try:
        text = raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        line = raw[: exc.start].count(b"\n") + 1
        raise InputError("not UTF-8 text", path, line) from None
    return text


def _umask() -> int:
    mask = os.umask(0)
    os.umask(mask)
    return mask


@contextmanager
def atomic_path(path: str | Path) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; rename it onto ``path`` only if the block succeeds.

    A failure leaves no partial output (and any previous file untouched).
    """
    target = Path(path)
    parent = target.parent if str(target.parent) else Path(".")
    if not parent.is_dir():
        raise InputError("the output folder does not exist", parent)
    if target.is_dir():
        raise InputError("is a directory, expected an output file name", target)
    if target.exists() and not target.is_file():
        # a device, FIFO or socket: renaming a file onto it would replace it
        raise InputError("exists and is not a regular file; choose another output name", target)
    try:
        fd, name = tempfile.mkstemp(prefix=f".{target.name}.", suffix=".tmp", dir=parent)
    except OSError as exc:
        raise InputError(f"cannot write here: {exc.strerror}", target) from None
    os.close(fd)
    tmp = Path(name)
    try:
        yield tmp
        try:
            os.chmod(tmp, 0o666 & ~_umask())  # mkstemp creates 0600; give the usual mode
            os.replace(tmp, target)
        except OSError as exc:
            raise InputError(f"cannot write: {exc.strerror}", target) from None
    finally:
        if tmp.exists():
            tmp.unlink()


def atomic_write(path: str | Path, text: str) -> None:
    """Write ``text`` to ``path`` atomically (temporary file + rename)."""
    with atomic_path(path) as tmp:
        try:
            tmp.write_text(text, encoding="utf-8")
        except OSError as exc:  # e.g. the disk is full
            raise InputError(f"cannot write: {exc.strerror}", path) from None
