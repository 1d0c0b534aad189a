"""Track files: custom tracks in YAML.

::

    name: L-shape            # optional
    direction: ccw           # optional label for RUNS.csv (default: from the total rotation)
    segments:
      - straight_m: 2.0              # forward 2 m (negative = backwards)
      - turn_deg: 90                 # spot turn, CCW positive
      - arc: {radius_m: 1.0, angle_deg: -180}   # forward arc, negative angle = right
"""

from __future__ import annotations

import math

from ..core.tracks import Segment, Track, arc, spot_turn, straight
from ..errors import InputError, ModelError
from .yamlfile import load_yaml

__all__ = ["load_track"]


def load_track(path) -> tuple[Track, str]:
    """The track in ``path`` and its direction label ('cw', 'ccw' or 'fwd')."""
    doc = load_yaml(path, "track file")
    doc.check_keys(doc.data, ("name", "direction", "segments"))
    items = doc.data.get("segments")
    if not isinstance(items, list) or not items:
        raise doc.error("segments", "expected a non-empty list of segments")
    segs: list[Segment] = []
    for i, item in enumerate(items, 1):
        where = f"segments[{i}]"
        if not isinstance(item, dict) or len(item) != 1:
            raise InputError(
                "each segment is one of straight_m: D, turn_deg: A, arc: {radius_m, angle_deg}",
                path,
                doc.lines.get("segments"),
                where,
            )
        ((kind, value),) = item.items()
        try:
            if kind == "straight_m":
                segs.append(straight(doc.number(where, value)))
            elif kind == "turn_deg":
                segs.append(spot_turn(math.radians(doc.number(where, value))))
            elif kind == "arc":
                if not isinstance(value, dict) or set(value) != {"radius_m", "angle_deg"}:
                    raise InputError("arc needs radius_m and angle_deg", path, None, where)
                segs.append(
                    arc(
                        doc.number(where, value["radius_m"], nonnegative=True),
                        math.radians(doc.number(where, value["angle_deg"])),
                    )
                )
            else:
                raise InputError(
                    f"unknown segment kind {kind!r}; expected straight_m, turn_deg or arc",
                    path,
                    None,
                    where,
                )
        except ModelError as exc:
            raise InputError(str(exc), path, None, where) from None
    track = Track(str(doc.data.get("name", path)), tuple(segs))
    direction = doc.data.get("direction")
    if direction is None:
        direction = track.direction_label
    if direction not in ("cw", "ccw", "fwd"):
        raise doc.error("direction", f"expected cw, ccw or fwd, got {direction!r}")
    return track, direction
