"""``odocal.io.table``: where lines end (LF, CR LF, CR and nowhere else)."""

from __future__ import annotations

import pytest

from odocal.errors import InputError
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


COMMA_SHEET = (
    "# sides: 4\n# side_m: 1.5\n# a note, with a comma\ndirection,x_m,y_m,theta_deg,run\n"
    "cw,-0.25,0.125,7.5,1\nccw,0.5,-1.25e-3,-12,2\n"
)
# the same sheet as LibreOffice saves it with a German locale: ';' separators, decimal commas,
# comment lines padded with separators
SEMICOLON_SHEET = (
    "# sides: 4;;;;\n# side_m: 1,5;;;;\n# a note, with a comma;;;;\n"
    "direction;x_m;y_m;theta_deg;run\n"
    "cw;-0,25;0,125;7,5;1\nccw;0,5;-1,25e-3;-12;2\n"
)


def test_a_semicolon_sheet_with_decimal_commas_reads_as_its_comma_twin(tmp_path):
    # issue 20.4: a spreadsheet's semicolon sheet got a misleading 'missing columns' error
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text(COMMA_SHEET)
    b.write_text(SEMICOLON_SHEET)
    ta, tb = (
        read_table(a, settings=("sides", "side_m")),
        read_table(b, settings=("sides", "side_m")),
    )
    assert tb.header == ta.header and tb.rows == ta.rows
    assert tb.settings == ta.settings == {"sides": ("4", 1), "side_m": ("1.5", 2)}
    cols = ["x_m", "y_m", "theta_deg"]
    assert tb.numbers(cols).tolist() == ta.numbers(cols).tolist()


@pytest.mark.parametrize(
    "text, line, needles",
    [
        ("a;b,c\n1;2\n", 1, ["mixes ';' and ','"]),
        ("a;b\n1,5;2\n3.25;4\n", 3, ["decimal commas (line 2)", "decimal points (line 3)"]),
        ("a;b\n1.234,5;2\n", 2, ["'1.234,5' groups thousands"]),
        ("a;b\n1;2\n1,5,2\n", 3, ["separated by ','", "one separator"]),
    ],
)
def test_an_ambiguous_semicolon_sheet_says_what_to_change(tmp_path, text, line, needles):
    p = tmp_path / "t.csv"
    p.write_text(text)
    with pytest.raises(InputError, match=f"line {line}") as info:
        read_table(p).numbers(["a", "b"])
    for n in needles:
        assert n in str(info.value)


def test_one_column_tables_split_in_the_vectorised_pass(tmp_path):
    p = tmp_path / "one.csv"
    p.write_text("a\n1\n\n2\n")
    (chunk,) = read_table(p).row_chunks(["a"])
    assert chunk.columns[0].tolist() == [b"1", b"2"] and chunk.lines.tolist() == [2, 4]
