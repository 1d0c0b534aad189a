"""The dashboard's pages as text: page names that fit, ids shown escaped."""

from __future__ import annotations

from odocal.io.fleet_html import MAX_NAME_BYTES, robot_page_name, shown_id


def test_a_robot_page_is_named_by_its_id_while_the_name_fits():
    assert robot_page_name("tb3-001") == "robots/tb3-001.html"
    assert robot_page_name("x" * 250) == f"robots/{'x' * 250}.html"  # 255 bytes: fits
    a, b = robot_page_name("x" * 251), robot_page_name("x" * 251 + "y")
    assert a != b and a.startswith(f"robots/{'x' * 200}-")
    for rid in ("x" * 251, "ü" * 126, "a\nb", "tab\there", "ü" * 300):
        name = robot_page_name(rid).removeprefix("robots/")
        assert len(name.encode()) <= MAX_NAME_BYTES and name.isprintable(), rid
    assert robot_page_name("a\nb") != robot_page_name("a_b")


def test_an_id_with_a_line_break_is_shown_escaped():
    assert shown_id("tb3-001") == "tb3-001"
    assert shown_id("a\nb") == "'a\\nb'"
