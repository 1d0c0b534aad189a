"""``odocal bag-info``: the topics, duration and frame tree of a ROS 1 or ROS 2 bag."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..io.bags import TopicInfo, bag_overview
from .text import Presented, Text, format_topics

__all__ = ["BagInfo", "bag_info"]


@dataclass(frozen=True)
class BagInfo(Presented):
    """The topics of one bag: its path and, per topic, the name, message type and count; its
    duration (s, first to last message) and the frame tree of ``/tf`` and ``/tf_static`` (each
    (parent, child, static) edge once)."""

    path: str
    topics: tuple[TopicInfo, ...]
    duration_s: float = 0.0
    frames: tuple[tuple[str, str, bool], ...] = ()

    def as_dict(self) -> dict:
        """The JSON of ``odocal bag-info --json``."""
        return {
            "path": self.path,
            "duration_s": self.duration_s,
            "topics": [{"name": t.name, "type": t.msgtype, "count": t.count} for t in self.topics],
            "frames": [{"parent": p, "child": c, "static": static} for p, c, static in self.frames],
        }

    def text(self) -> str:
        """The text of ``odocal bag-info``: the topics, the duration, the frame tree."""
        out = Text()
        out(f"{self.path}: {len(self.topics)} topics, {self.duration_s:.3f} s")
        out(format_topics(self.topics))
        if self.frames:
            out("frames (/tf and /tf_static):")
            for line in _tree(self.frames):
                out(f"  {line}")
        else:
            out("frames: none (no /tf or /tf_static)")
        return str(out)


def _tree(frames: tuple[tuple[str, str, bool], ...]) -> list[str]:
    """The frame tree as indented lines, roots first; a child under each parent that publishes
    it ('static' after a /tf_static edge)."""
    children: dict[str, list[tuple[str, bool]]] = {}
    for parent, child, static in frames:
        children.setdefault(parent, []).append((child, static))
    kids = {c for _, c, _ in frames}
    roots = [p for p in children if p not in kids] or list(children)[:1]
    lines: list[str] = []

    def walk(frame: str, depth: int, seen: frozenset[str]) -> None:
        for child, static in children.get(frame, []):
            tag = " (static)" if static else ""
            if child in seen:  # a loop in the tree: shown once, not followed
                lines.append(f"{'  ' * depth}-> {child}{tag} (loop)")
                continue
            lines.append(f"{'  ' * depth}-> {child}{tag}")
            walk(child, depth + 1, seen | {child})

    for root in roots:
        lines.append(root)
        walk(root, 1, frozenset({root}))
    return lines


def bag_info(bag: str | Path) -> BagInfo:
    """The topics (name, message type, count), duration and frame tree of ``bag``."""
    o = bag_overview(bag)
    return BagInfo(str(bag), tuple(o.topics), o.duration_s, o.frames)
