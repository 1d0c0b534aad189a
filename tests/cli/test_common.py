"""odocal.cli.common: the printers never fail on what a result may hold."""

from __future__ import annotations

from odocal.cli.common import _motion_line

MOTION = {
    "travel_m": 0.0,
    "rotation_deg": 0.0,
    "rotation_left_deg": 0.0,
    "rotation_right_deg": 0.0,
    "share_straight": 0.5,
    "share_spot": 0.25,
    "share_arc": 0.25,
}


def test_the_motion_line_without_wheel_travel_says_so():
    """No wheel travel: the shares are None in the JSON (NaN); the text printer multiplied them
    (a traceback after fit had written PARAMS.yaml, issue #20)."""
    none = {**MOTION, "share_straight": None, "share_spot": None, "share_arc": None}
    assert _motion_line(none).endswith("; no wheel travel")
    assert _motion_line(MOTION).endswith("50 % straight, 25 % spot turns, 25 % arcs")
