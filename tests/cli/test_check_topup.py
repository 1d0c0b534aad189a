"""``odocal check BAG`` on synthetic bags: the degenerate motions by name and what to add
(``top_up``), in the text and the JSON (the search and its simulation check:
tests/calibration/test_topup.py)."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest

from odocal.core.tracks import Track, arc, polygon, spot_turn, straight
from tests.support.bag_files import NOMINAL, Run, make_run, write_bag

ROBOT = "wheel_diameter_m: 0.2\nwheelbase_m: 0.5\n"  # the bags' NOMINAL


def _bag(tmp_path, track, name):
    path = tmp_path / f"{name}.bag"
    return write_bag(path, "ros1", make_run(track), imu=False)


def test_a_straight_bag_is_flagged_by_name_and_gets_a_spin_at_its_own_wheel_speed(tmp_path, cli):
    robot = tmp_path / "robot.yaml"
    robot.write_text(ROBOT)
    # 3 m straight at 0.125 m/s (segments of 10 cm, 40 increments of 20 ms each)
    bag = _bag(tmp_path, Track("line", (straight(0.1),) * 30), "line")
    status, out, err = cli("check", bag, "--robot", robot, "--json")
    assert status == 3, err
    d = json.loads(out)
    named = {m["code"]: m for m in d["degenerate_motions"]}
    assert set(named) == {"pure-translation"}
    assert named["pure-translation"]["flag"] == "straight-only"
    top = d["top_up"]
    assert top["goal"] == "enough" and top["reached"] is True and top["ok_after"] is True
    assert top["maneuvers"] and top["duration_s"] > 0
    assert sum(m["duration_s"] for m in top["maneuvers"]) * top["runs"] == top["duration_s"]
    after = top["predicted_std_error"]["after"]
    assert after["wheelbase_m"] is not None and after["wheelbase_m"] < 5e-3 * 0.5
    before = top["predicted_std_error"]["before"]["wheelbase_m"]
    assert before is None or before > 10 * after["wheelbase_m"]
    # the robot never turned: its spins keep the wheels at the speed they drove (0.125 m/s)
    wheel_rate = 2 * 0.125 / NOMINAL.wheelbase_m
    for m in top["maneuvers"]:
        assert m["rate_rad_s"] <= wheel_rate * 1.05
        assert m["speed_m_s"] <= 0.125 * 1.05
    assert any(m["kind"] == "spin" or m["kind"] == "arc" for m in top["maneuvers"])
    status, text, err = cli("check", bag, "--robot", robot)
    assert status == 3, err
    assert "degenerate motion: pure translation" in text
    assert "what to add: adding a" in text and "makes the log enough" in text


def test_a_one_way_bag_is_flagged_and_an_enough_bag_gets_a_halving_top_up(tmp_path, cli):
    robot = tmp_path / "robot.yaml"
    robot.write_text(ROBOT)
    ccw = Track("ccw", polygon(4, 1.0, "ccw").segments * 2)
    status, out, err = cli("check", _bag(tmp_path, ccw, "ccw"), "--robot", robot, "--json")
    assert status == 0, err  # one sense of rotation is weak, not blind
    d = json.loads(out)
    assert {m["code"] for m in d["degenerate_motions"]} == {"one-axis-rotation"}
    assert d["top_up"]["goal"] == "enough"  # a top-up that clears the flag
    both = Track("both", polygon(4, 1.0, "ccw").segments + polygon(4, 1.0, "cw").segments)
    status, out, err = cli("check", _bag(tmp_path, both, "both"), "--robot", robot, "--json")
    assert status == 0, err
    d = json.loads(out)
    assert d["degenerate_motions"] == [] and d["degeneracies"] == []
    top = d["top_up"]
    assert top["goal"] == "halve" and top["weakest_parameter"] in d["stderr"]
    se = top["predicted_std_error"]
    k = top["weakest_parameter"]
    if top["reached"]:
        assert se["after"][k] <= 0.5 * se["before"][k] * (1 + 1e-9)
        assert "halves" in top["sentence"]
    else:
        assert "no top-up of up to" in top["sentence"]
    assert math.isfinite(se["after"][k])


ALONE = {
    "pure-rotation": Track("spins", (spot_turn(0.2),) * 32 + (spot_turn(-0.2),) * 32),
    "constant-velocity": Track("circle", (arc(0.5, 0.2),) * 63),
}


@pytest.mark.parametrize("code", list(ALONE))
def test_a_bag_of_one_degenerate_motion_is_flagged_by_its_name(tmp_path, cli, code):
    robot = tmp_path / "robot.yaml"
    robot.write_text(ROBOT)
    status, out, err = cli("check", _bag(tmp_path, ALONE[code], code), "--robot", robot, "--json")
    assert status == 3, err
    d = json.loads(out)
    assert code in {m["code"] for m in d["degenerate_motions"]}
    assert d["top_up"]["reached"] and d["top_up"]["ok_after"]


def test_a_bag_without_motion_is_refused_naming_it(tmp_path, cli):
    robot = tmp_path / "robot.yaml"
    robot.write_text(ROBOT)
    t = 5.0 + 0.02 * np.arange(200)
    zero = np.zeros(len(t))
    still = Run(t, zero, zero, np.zeros((len(t), 3)), np.zeros((len(t), 3)))
    bag = write_bag(tmp_path / "still.bag", "ros1", still, imu=False)
    status, out, err = cli("check", bag, "--robot", robot)
    assert status == 2 and "never moves" in err and out == ""
