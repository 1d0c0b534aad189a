"""``odocal bag-info``: the topics of a ROS 1 or ROS 2 bag."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from ..io.bags import TopicInfo, list_topics

__all__ = ["BagInfo", "bag_info"]


@dataclass(frozen=True)
class BagInfo:
    """The topics of one bag: its path and, per topic, the name, message type and count."""

    path: str
    topics: tuple[TopicInfo, ...]

    def as_dict(self) -> dict:
        """The JSON of ``odocal bag-info --json``."""
        return {
            "path": self.path,
            "topics": [{"name": t.name, "type": t.msgtype, "count": t.count} for t in self.topics],
        }


def bag_info(bag: str | Path) -> BagInfo:
    """The topics (name, message type, count) of ``bag``."""
    return BagInfo(str(bag), tuple(list_topics(bag)))
