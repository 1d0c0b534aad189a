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

import hashlib
import os
from dataclasses import dataclass
from pathlib import Path

from ..errors import InputError, OdocalError
from .bags import BAG_SUFFIXES

__all__ = [
    "RobotFolder",
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


def find_robots(root: str | Path) -> list[RobotFolder]:
    """The robot folders of ``root`` (sorted by id). A folder without ``robot.yaml`` is an
    error naming it: the nominal geometry is what every calibration is held against."""
    r = Path(root)
    if not r.is_dir():
        raise InputError("not a folder (the fleet's root: one folder per robot)", r)
    robots = []
    for sub in sorted(p for p in r.iterdir() if p.is_dir() and not p.name.startswith(".")):
        f = sub / ROBOT_FILE
        if not f.is_file():
            raise InputError(
                f"robot folder without {ROBOT_FILE} (each robot's folder holds its nominal "
                "geometry: wheel_diameter_m, wheelbase_m; docs/fleet.md)",
                sub,
            )
        robots.append(RobotFolder(sub.name, sub, f))
    if not robots:
        raise InputError("no robot folders (ROOT/<robot_id>/robot.yaml)", r)
    return robots


def _is_ros2_folder(p: Path) -> bool:
    return (p / "metadata.yaml").is_file()


def find_bags(folder: Path) -> list[Path]:
    """Every bag below ``folder`` (sorted): ROS 2 folders whole, ``.bag``/``.mcap``/``.db3``
    files that are not inside one. Hidden files and folders are skipped; linked folders are
    followed (bag storage linked into a robot's folder), each real folder once (no loop)."""
    out: list[Path] = []
    seen: set[str] = set()
    for dirpath, dirnames, filenames in os.walk(folder, followlinks=True):
        d = Path(dirpath)
        real = os.path.realpath(d)
        if real in seen:
            dirnames[:] = []
            continue
        seen.add(real)
        dirnames[:] = sorted(n for n in dirnames if not n.startswith("."))
        if d != folder and _is_ros2_folder(d):
            out.append(d)
            dirnames[:] = []
            continue
        out += [
            d / n
            for n in sorted(filenames)
            if n.lower().endswith(BAG_SUFFIXES) and not n.startswith(".")
        ]
    return sorted(out)


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
            with f.open("rb") as fh:
                while chunk := fh.read(_CHUNK):
                    h.update(chunk)
    except OSError as exc:
        raise InputError(f"cannot read the bag ({exc.strerror})", bag) from None
    return h.hexdigest()


def bag_span_s(bag: Path) -> tuple[float, float] | None:
    """(start, end) of the bag's messages (s since the epoch); None when it cannot be read."""
    from .bags import _Bag

    try:
        with _Bag(bag) as b:
            return int(b.reader.start_time) * 1e-9, int(b.reader.end_time) * 1e-9
    except (OdocalError, ValueError):
        return None
