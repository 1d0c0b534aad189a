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
from .limits import TRACK_LENGTH_MAX_M, TURN_MAX_DEG
from .yamlfile import load_yaml

__all__ = ["load_track"]


def load_track(path) -> tuple[Track, str]:
    """The track in ``path`` and its direction label ('cw', 'ccw' or 'fwd'; the file's
    ``direction`` in any case, e.g. ``CCW``).

    Lengths are at most :data:`~odocal.io.limits.TRACK_LENGTH_MAX_M` and angles at most
    :data:`~odocal.io.limits.TURN_MAX_DEG` in magnitude; a track that neither moves nor turns is
    an error."""
    doc = load_yaml(path, "track file")
    doc.check_keys(doc.data, ("name", "direction", "segments"))
    items = doc.data.get("segments")
    if not isinstance(items, list) or not items:
        raise doc.error("segments", "expected a non-empty list of segments")
    segs: list[Segment] = []
    for i, item in enumerate(items, 1):
        where = f"segments[{i}]"
        line = doc.lines.get(where)
        if not isinstance(item, dict) or len(item) != 1:
            raise InputError(
                "each segment is one of straight_m: D, turn_deg: A, arc: {radius_m, angle_deg}",
                path,
                line,
                where,
            )
        ((kind, value),) = item.items()
        key = f"{where}.{kind}"
        try:
            if kind == "straight_m":
                segs.append(straight(doc.number(key, value, at_most=TRACK_LENGTH_MAX_M)))
            elif kind == "turn_deg":
                segs.append(spot_turn(math.radians(doc.number(key, value, at_most=TURN_MAX_DEG))))
            elif kind == "arc":
                if not isinstance(value, dict) or set(value) != {"radius_m", "angle_deg"}:
                    raise InputError(
                        "arc needs radius_m and angle_deg", path, doc.lines.get(key), key
                    )
                radius = doc.number(
                    f"{key}.radius_m",
                    value["radius_m"],
                    nonnegative=True,
                    at_most=TRACK_LENGTH_MAX_M,
                )
                angle = doc.number(f"{key}.angle_deg", value["angle_deg"], at_most=TURN_MAX_DEG)
                segs.append(arc(radius, math.radians(angle)))
            else:
                raise InputError(
                    f"unknown segment kind {kind!r}; expected straight_m, turn_deg or arc",
                    path,
                    doc.lines.get(key, line),
                    where,
                )
        except ModelError as exc:
            raise InputError(str(exc), path, line, where) from None
    name = doc.text("name", doc.data["name"]) if "name" in doc.data else str(path)
    track = Track(name, tuple(segs))
    if float(track.travel_m) == 0 and float(track.rotation_rad) == 0:
        raise doc.error("segments", "the track neither moves nor turns")
    direction = doc.data.get("direction")
    if direction is None:
        direction = track.direction_label
    if not isinstance(direction, str) or direction.lower() not in ("cw", "ccw", "fwd"):
        raise doc.error("direction", f"expected cw, ccw or fwd, got {direction!r}")
    return track, direction.lower()
