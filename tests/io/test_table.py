"""``odocal.io.table``: where lines end (LF, CR LF, CR and nowhere else)."""

from __future__ import annotations

import pytest

from odocal.io.table import read_table


@pytest.mark.parametrize("end", ["\n", "\r\n", "\r"])
def test_a_form_feed_in_a_comment_is_part_of_the_comment(tmp_path, end):
    # issue 20, hostile inputs: a form feed inside a '#' comment line broke the CSV (str.splitlines
    # broke the comment there, and its tail was read as a row or the header)
    lines = [
        "# sides: 4",
        "# a note\x0cwith a form feed, 1, 2",
        "a,b",
        "1,2",
        "# another\x0bnote\x1cand, more",
        "3,4",
    ]
    p = tmp_path / "t.csv"
    p.write_bytes(end.join(lines).encode() + end.encode())
    table = read_table(p, settings=("sides",))
    assert table.header == ("a", "b") and table.header_line == 3
    assert table.settings["sides"] == ("4", 1)
    assert [no for no, _ in table.rows] == [4, 6]
    assert table.numbers(["a", "b"]).tolist() == [[1.0, 2.0], [3.0, 4.0]]
