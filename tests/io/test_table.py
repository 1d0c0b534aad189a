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


def test_a_one_column_sheet_with_decimal_commas_reads_as_its_comma_twin(tmp_path):
    # issue 27 item 19: a spreadsheet saves one column without any separator; its decimal commas
    # were 'expected 1 fields as in the header, got 2'
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text("# note, with a comma\nerror_mm\n12.5\n-0.25\n\n3\n")
    b.write_text("# note, with a comma\nerror_mm\n12,5\n-0,25\n\n3\n")
    ta, tb = read_table(a), read_table(b)
    assert tb.header == ta.header == ("error_mm",) and tb.rows == ta.rows
    assert tb.numbers(["error_mm"]).tolist() == [[12.5], [-0.25], [3.0]]


@pytest.mark.parametrize(
    "text, line, needles",
    [
        ("e\n1,5\n2.5\n", 3, ["decimal commas (line 2)", "decimal points (line 3)"]),
        # a comma before three digits in every value: a decimal comma or a thousands separator
        ("e\n1,500\n12,250\n", 2, ["'1,500'", "thousands"]),
        ("e\n1,5,2\n", 2, ["not a number: '1,5,2'"]),
    ],
)
def test_an_ambiguous_one_column_sheet_says_what_to_change(tmp_path, text, line, needles):
    p = tmp_path / "t.csv"
    p.write_text(text)
    with pytest.raises(InputError, match=f"line {line}") as info:
        read_table(p).numbers(["e"])
    for n in needles:
        assert n in str(info.value)


def test_a_semicolon_sheet_padded_with_empty_columns_reads_as_its_comma_twin(tmp_path):
    # issue 27 item 19: a spreadsheet pads every line to the widest one ('cw;...;1;;'): the
    # header's empty names were refused
    a, b = tmp_path / "a.csv", tmp_path / "b.csv"
    a.write_text(COMMA_SHEET)
    padded = "".join(
        line + ";;\n" if line and not line.startswith("#") else line + "\n"
        for line in SEMICOLON_SHEET.splitlines()
    )
    b.write_text(
        padded.replace("direction;x_m;y_m;theta_deg;run;;", "direction;x_m;y_m;theta_deg;run;;;")
    )
    ta, tb = (read_table(p, settings=("sides", "side_m")) for p in (a, b))
    assert tb.header == ta.header and tb.rows == ta.rows and tb.settings == ta.settings
    # an empty field under a named column is still a field; text beyond the header is refused
    c = tmp_path / "c.csv"
    c.write_text("a;b;;\n1;;;\n")
    table = read_table(c)
    assert table.header == ("a", "b") and table.rows == [(2, ["1", ""])]
    c.write_text("a;b;;\n1;;;\n2;3;4;\n")
    with pytest.raises(InputError, match="line 3: expected 2 fields as in the header, got 3"):
        read_table(c).numbers(["a"])
