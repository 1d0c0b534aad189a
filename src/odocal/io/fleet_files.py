"""A fleet on disk (``odocal fleet ingest ROOT``): one folder per robot, ``ROOT/<robot_id>/``
with ``robot.yaml`` (its nominal geometry) and its bags anywhere below it: ROS 1 ``.bag``
files, ROS 2 bag folders (a ``metadata.yaml`` beside ``.db3``/``.mcap`` files) and lone
``.mcap``/``.db3`` files.

A bag's identity is the sha256 of its bytes (a ROS 2 folder: of its files in sorted order, their
names excluded), so a copy or a renamed bag is the same bag. A bag's :class:`Snapshot` (the
size and modification time of each of its files) taken before and after it is read tells a bag
still being written from a finished one.
"""

from __future__ import annotations

import errno
import hashlib
import os
import stat
from collections.abc import Collection
from dataclasses import dataclass
from pathlib import Path
from typing import BinaryIO

from ..errors import InputError, OdocalError, quote_path
from .bags import BAG_SUFFIXES

__all__ = [
    "RobotFolder",
    "RobotScan",
    "BagScan",
    "Snapshot",
    "find_robots",
    "find_bags",
    "snapshot",
    "content_hash",
    "bag_span_s",
]

ROBOT_FILE = "robot.yaml"
_CHUNK = 1 << 20


@dataclass(frozen=True)
class RobotFolder:
    """One robot of the fleet: its id (the folder's name), folder and robot file."""

    robot_id: str
    folder: Path
    robot_file: Path


@dataclass(frozen=True)
class RobotScan:
    """The robots of a fleet's root (:func:`find_robots`).

    Attributes
    ----------
    robots : tuple of RobotFolder
        The folders with a ``robot.yaml``, by id.
    failures : tuple of (Path, str)
        (folder, one-line reason naming it) of each folder that is not a usable robot.
    """

    robots: tuple[RobotFolder, ...]
    failures: tuple[tuple[Path, str], ...] = ()


@dataclass(frozen=True)
class BagScan:
    """The bags below one robot's folder (:func:`find_bags`).

    Attributes
    ----------
    bags : tuple of Path
        Sorted.
    failures : tuple of (Path, str)
        (path, one-line reason naming it) of each bag that cannot be read (a link to nothing).
    warnings : tuple of str
        What was skipped and why (a FIFO with a bag's name, a folder that cannot be listed).
    """

    bags: tuple[Path, ...]
    failures: tuple[tuple[Path, str], ...] = ()
    warnings: tuple[str, ...] = ()


@dataclass(frozen=True)
class Snapshot:
    """(relative name, size in bytes, modification time in ns) of each file of a bag."""

    files: tuple[tuple[str, int, int], ...]

    @property
    def size_bytes(self) -> int:
        """The bag's size (all its files)."""
        return sum(f[1] for f in self.files)

    @property
    def mtime_ns(self) -> int:
        """The latest modification time of its files."""
        return max((f[2] for f in self.files), default=0)


def find_robots(root: str | Path, *, skip: Collection[str | Path] = ()) -> RobotScan:
    """The robot folders of ``root`` (sorted by id) and the folders that are not usable robots.

    A folder without ``robot.yaml`` (a regular file) is a failure naming it, not an error for the
    whole fleet: the nominal geometry is what every calibration of that robot is held against,
    and the other robots go on. A folder without one that holds a file of ``skip`` (the fleet
    database given inside ROOT) is no robot and no failure. Hidden folders are skipped. A root
    without any sub-folder is an error."""
    r = Path(root)
    if not r.is_dir():
        raise InputError("not a folder (the fleet's root: one folder per robot)", r)
    skip_real = [os.path.realpath(s) for s in skip]
    robots, failures, folders = [], [], 0
    for sub in sorted(p for p in r.iterdir() if p.is_dir() and not p.name.startswith(".")):
        folders += 1
        f = sub / ROBOT_FILE
        if f.is_file():
            robots.append(RobotFolder(sub.name, sub, f))
        elif not any(_within(s, os.path.realpath(sub)) for s in skip_real):
            why = (
                f"robot folder without {ROBOT_FILE} (each robot's folder holds its nominal "
                "geometry: wheel_diameter_m, wheelbase_m; docs/fleet.md)"
            )
            failures.append((sub, f"{quote_path(sub)}: {why}"))
    if not folders:
        raise InputError("no robot folders (ROOT/<robot_id>/robot.yaml)", r)
    return RobotScan(tuple(robots), tuple(failures))


def _within(path: str, folder: str) -> bool:
    """Is the real path ``path`` ``folder`` or inside it?"""
    return path == folder or path.startswith(folder.rstrip(os.sep) + os.sep)


def _is_ros2_folder(p: Path) -> bool:
    return (p / "metadata.yaml").is_file()


def _not_regular(mode: int) -> str | None:
    """What a file of this ``st_mode`` is when it is neither a regular file nor a folder."""
    if stat.S_ISREG(mode) or stat.S_ISDIR(mode):
        return None
    for test, what in (
        (stat.S_ISFIFO, "a FIFO"),
        (stat.S_ISCHR, "a character device"),
        (stat.S_ISBLK, "a block device"),
        (stat.S_ISSOCK, "a socket"),
    ):
        if test(mode):
            return what
    return "not a regular file"


def _dead_link(p: Path) -> str:
    try:
        return f"a link to nothing ({quote_path(os.readlink(p))})"
    except OSError:
        return "a link to nothing"


def find_bags(
    folder: Path, *, others: Collection[str | Path] = (), skip: Collection[str | Path] = ()
) -> BagScan:
    """Every bag below ``folder`` (sorted): ROS 2 folders whole, ``.bag``/``.mcap``/``.db3``
    files that are not inside one; what cannot be a bag, said.

    Hidden files and folders are skipped. Linked folders are followed (bag storage linked into a
    robot's folder), each real folder once (no loop), but never into ``others`` (the other
    robots' folders: a path through another robot's folder is no claim on its bags) nor back up
    to a folder holding ``folder`` (the fleet's root, say). A file of ``skip`` (the fleet
    database and its companions) is no bag.

    With a bag's name: a FIFO, a device or a socket (reading it would wait for ever) is skipped
    with a warning, and so is a ROS 2 bag folder holding one; a link to nothing or a file that
    cannot be examined is a failure (path, one-line reason). A link to nothing without a bag's
    name is a warning (bag storage gone?); so is a folder that cannot be listed."""
    top = os.path.realpath(folder)
    fences = [os.path.realpath(o) for o in others]
    fences = [f for f in fences if not _within(top, f)]  # (one holding this one: an alias)
    skip_real = {os.path.realpath(s) for s in skip}
    bags: list[Path] = []
    failures: list[tuple[Path, str]] = []
    warnings: list[str] = []
    seen: set[str] = set()

    def unlisted(err: OSError) -> None:
        warnings.append(
            f"{quote_path(err.filename)}: cannot list the folder ({err.strerror}): the bags in "
            "it are not seen"
        )

    def fenced(real: str) -> bool:
        if any(_within(real, f) for f in fences):
            return True  # another robot's
        return real != top and _within(top, real)  # a link back up the tree

    for dirpath, dirnames, filenames in os.walk(folder, onerror=unlisted, followlinks=True):
        d = Path(dirpath)
        real = os.path.realpath(d)
        if real in seen or fenced(real):
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(n for n in dirnames if not n.startswith("."))
        if d != folder and _is_ros2_folder(d):
            dirnames[:] = []
            odd = _odd_member(d)
            if odd is None:
                bags.append(d)
            else:
                warnings.append(
                    f"{quote_path(d)}: a ROS 2 bag folder holding {odd}: skipped (reading it "
                    "could wait for ever)"
                )
            continue
        for n in sorted(filenames):
            if n.startswith("."):
                continue
            p = d / n
            is_bag = n.lower().endswith(BAG_SUFFIXES)
            try:
                st = p.stat()
            except FileNotFoundError:
                if p.is_symlink():
                    why = _dead_link(p)
                    if is_bag:
                        failures.append((p, f"{quote_path(p)}: {why}: nothing to read"))
                    else:
                        warnings.append(f"{quote_path(p)}: {why}: skipped (bag storage gone?)")
                continue  # (removed meanwhile)
            except OSError as exc:
                if is_bag:
                    why = f"cannot read the bag ({exc.strerror})"
                    failures.append((p, f"{quote_path(p)}: {why}"))
                continue
            if not is_bag:
                continue
            what = _not_regular(st.st_mode)
            if what is not None:
                warnings.append(
                    f"{quote_path(p)}: {what} with a bag's name, not a bag: skipped (reading "
                    "it could wait for ever)"
                )
                continue
            real_file = os.path.realpath(p)
            if real_file in skip_real or fenced(real_file):
                continue
            bags.append(p)
    return BagScan(tuple(sorted(bags)), tuple(failures), tuple(warnings))


def _odd_member(bag: Path) -> str | None:
    """A member of a ROS 2 bag folder that is neither a regular file nor a folder (named, with
    what it is), or None."""
    try:
        entries = sorted(bag.iterdir())
    except OSError:
        return None  # (its reading will fail and say so)
    for e in entries:
        if e.name.startswith("."):
            continue
        try:
            what = _not_regular(e.stat().st_mode)
        except OSError:
            continue
        if what is not None:
            return f"{e.name}, {what}"
    return None


def _files(bag: Path) -> list[Path]:
    if bag.is_dir():
        return sorted(p for p in bag.iterdir() if p.is_file() and not p.name.startswith("."))
    return [bag]


def snapshot(bag: Path) -> Snapshot:
    """The size and modification time of each file of ``bag``."""
    try:
        out = []
        for f in _files(bag):
            st = f.stat()
            out.append((f.name if bag.is_dir() else "", st.st_size, st.st_mtime_ns))
    except OSError as exc:
        raise InputError(f"cannot read the bag ({exc.strerror})", bag) from None
    return Snapshot(tuple(out))


def content_hash(bag: Path) -> str:
    """sha256 of the bag's bytes (a folder: its files' bytes in sorted order, names excluded)."""
    h = hashlib.sha256()
    try:
        for f in _files(bag):
            with _open_regular(f) as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
    except OSError as exc:
        raise InputError(f"cannot read the bag ({exc.strerror})", bag) from None
    return h.hexdigest()


def _open_regular(f: Path) -> BinaryIO:
    """``f`` opened for reading, refused (OSError) unless it is a regular file: opened without
    waiting, so that a FIFO put in a bag's place since the bags were found cannot hang the
    ingest."""
    fd = os.open(f, os.O_RDONLY | getattr(os, "O_NONBLOCK", 0))
    try:
        what = _not_regular(os.fstat(fd).st_mode)
        if what is not None:
            raise OSError(errno.EINVAL, f"{what}, not a regular file")
        os.set_blocking(fd, True)
        return os.fdopen(fd, "rb")
    except BaseException:
        os.close(fd)
        raise


def bag_span_s(bag: Path) -> tuple[float, float] | None:
    """(start, end) of the bag's messages (s since the epoch); None when it cannot be read."""
    from .bags import _Bag

    try:
        with _Bag(bag) as b:
            return int(b.reader.start_time) * 1e-9, int(b.reader.end_time) * 1e-9
    except (OdocalError, ValueError):
        return None
