"""A day's queue from a collection database's CSV (issue 19): read and every row validated before anything is shot,
bad rows named by row (as a spreadsheet numbers them), column and problem; BOM, CRLF, quoted line breaks, other
separators, configurable column names, extra columns kept; the file-level problems in one line."""
from __future__ import annotations

import json
from pathlib import Path

import pytest
from queue_rows import BAD, good_identifiers, write_queue_csv

from dualrgb.app.workflow.day.day import OriginalsQueue
from dualrgb.app.workflow.day.queue_csv import column_option, read_queue_csv
from dualrgb.core.metadata import Original, xmp_property

ROOT = Path(__file__).resolve().parents[2]
COLUMNS = {"identifier": "Inventarnummer"}


@pytest.mark.parametrize("bom, crlf", [(True, True), (False, False), (True, False)])
def test_twenty_rows_three_bad_named_by_row_column_and_problem(tmp_path, bom, crlf):
    q = read_queue_csv(write_queue_csv(tmp_path / "q.csv", bom=bom, crlf=crlf), columns=COLUMNS)
    assert q.bad_rows == sorted(BAD)
    lines = q.bad_lines()
    assert len(lines) == 3
    for line, (row, (column, problem)) in zip(lines, sorted(BAD.items()), strict=True):
        assert line == f"row {row}, column {column!r}: {problem}", line
    assert [o.identifier for o in q.originals] == good_identifiers() and len(q.originals) == 17
    assert q.summary() == "q.csv: 20 rows, 17 valid, 3 bad (rows 6, 11, 17)"


def test_rows_keep_their_text_and_extra_columns(tmp_path):
    q = read_queue_csv(write_queue_csv(tmp_path / "q.csv"), columns=COLUMNS, default_mode="transmissive")
    first = {e.row: e.original for e in q.entries}
    assert first[3].notes == "Zeile 1\nligne 2 (3)"                   # the quoted line break, CRLF in the file -> LF
    assert first[5].identifier == "Q-4é" and first[10].identifier == "Q-9é"
    assert first[4].mode == "transmissive" and first[5].mode == "reflective"      # empty: the default
    assert first[2].title == "富嶽三十六景 2" and first[3].operator == "Jürgen Weiß"
    assert first[2].extra == {"Standort": "Depot 2; Regal 2"}
    assert q.columns == {"identifier": "Inventarnummer", "title": "Title", "operator": "operator", "notes": "Notes",
                         "mode": "mode"} and q.extra_columns == ["Standort"]


def test_the_example_file_reads_with_german_french_and_japanese_titles():
    q = read_queue_csv(ROOT / "docs" / "queue-example.csv")
    assert q.problems == [] and len(q.originals) == 6
    titles = " ".join(o.title for o in q.originals)
    assert "Öl auf Holz" in titles and "Étude pour « La Grève »" in titles and "神奈川沖浪裏" in titles
    assert q.originals[0].extra["Künstler / Artist"] == "Unbekannt (Köln)"
    assert q.originals[-1].mode == "transmissive" and "\n" in q.originals[-1].notes
    assert xmp_property("Künstler / Artist").startswith("Extra_Kunstler_Artist_")


def test_semicolons_and_case_insensitive_headers(tmp_path):
    path = tmp_path / "excel.csv"
    path.write_bytes("\ufeffIDENTIFIER;Titel;Title\r\nA-1;x;\"Ein; Bild\"\r\n\r\n;;\r\nA-2;y;z\r\n".encode())
    q = read_queue_csv(path)
    assert [(e.row, e.original.identifier, e.original.title) for e in q.entries] == [(2, "A-1", "Ein; Bild"),
                                                                                       (5, "A-2", "z")]
    assert q.originals[0].extra == {"Titel": "x"}                     # an unknown column: kept as extra metadata


@pytest.mark.fault("input")
@pytest.mark.parametrize("content, says", [
    (b"title,notes\nx,y\n", "no column 'identifier' for the identifier (the header has 'title', 'notes'); "
                            "name it with --column identifier=NAME"),
    (b"identifier,title,title\nA,b,c\n", "row 1: column 'title' appears twice (B and C)"),
    (b"identifier,Title,TITLE\nA,b,c\n", "columns 'Title', 'TITLE' all read as 'title'"),
    (b"identifier,title\nA,\"unterminated\n", "row 2: not CSV"),
    ("identifier,title\nA,Öl\n".encode("latin-1"), "not UTF-8 text (byte 0xD6 at offset 19); export the CSV as UTF-8"),
    (b"", "no header row"),
])
def test_a_file_that_is_not_a_queue_is_one_line(tmp_path, content, says):
    path = tmp_path / "bad.csv"
    path.write_bytes(content)
    with pytest.raises(ValueError) as info:
        read_queue_csv(path)
    assert says in str(info.value) and str(info.value).startswith(f"{path}: ") and "\n" not in str(info.value), \
        str(info.value)


@pytest.mark.fault("input")
@pytest.mark.parametrize("row, says", [
    ("A-1,ok,,x,film", "row 3, column 'mode': 'film': expected reflective or transmissive"),
    (",ok,,,", "row 3, column 'identifier': required"),
    ("\"A\n1\",ok,,,", "row 3, column 'identifier': line break U+000A at character 2"),
    ("A-2,\"a\x0bb\",\x00,,", "row 3, column 'operator': control character U+0000 at character 1"),
    ("a-0,dup,,,", "row 3, column 'identifier': 'a-0' is also row 2"),
])
def test_bad_rows(tmp_path, row, says):
    path = tmp_path / "q.csv"
    path.write_text(f"identifier,title,operator,notes,mode\na-0,first,,,\n{row}\n", encoding="utf-8")
    q = read_queue_csv(path)
    assert q.bad_lines() == [says] or q.bad_lines()[0].startswith(says), q.bad_lines()


def test_a_row_whose_folder_holds_another_original_is_bad(tmp_path):
    out = tmp_path / "deliverables"
    folder = out / Original("ACC-1").file_stem
    folder.mkdir(parents=True)
    (folder / "ACC-1.json").write_text(json.dumps({"format": "dualrgb-delivery/1",
                                                   "original": {"identifier": "ACC-1 (another)"}}))
    path = tmp_path / "q.csv"
    path.write_text("identifier\nACC-1\nACC-2\n", encoding="utf-8")
    q = read_queue_csv(path, out_dir=out)
    assert q.bad_rows == [2] and "holds the deliverables of 'ACC-1 (another)'" in q.bad_lines()[0]
    assert [o.identifier for o in q.originals] == ["ACC-2"]


def test_column_option_and_adding_to_the_queue(tmp_path):
    assert column_option("identifier=Accession No.") == ("identifier", "Accession No.")
    with pytest.raises(ValueError, match="expected FIELD=COLUMN NAME with FIELD one of identifier, title"):
        column_option("accession=Inv")
    q = OriginalsQueue()
    q.add(Original("Q-1"))
    left_out = q.add_many(read_queue_csv(write_queue_csv(tmp_path / "q.csv"), columns=COLUMNS).originals)
    assert left_out == ["Q-1 is already in the queue"] and len(q.rows) == 17


# ---- issue 27: unmapped columns never refuse a row ---------------------------------------------------------
def _museum_export(path: Path, n_extra: int, long_text: str) -> Path:
    """A collection export as large museums publish them: the mapped columns among dozens nobody maps, one of
    them a provenance text of thousands of characters, another with a control character."""
    header = ["Object Number", "Title", *(f"c{i}" for i in range(n_extra))]
    rows = []
    for r in range(12):
        extra = [f"value {r}-{i}" for i in range(n_extra)]
        extra[36 % n_extra] = long_text if r % 4 else "short"
        extra[1] = "bad\x01value" if r == 5 else extra[1]
        rows.append([f"M-{r}", f"Object {r}", *extra])
    import csv
    import io
    buf = io.StringIO(newline="")
    csv.writer(buf).writerows([header, *rows])
    path.write_text(buf.getvalue(), encoding="utf-8")
    return path


def test_a_museum_export_with_long_provenance_and_54_columns_stops_nothing(tmp_path):
    """Issue 27: 9 of 12 rows were refused for a 3565-character provenance column and a 54-column header was
    refused whole; now every row is read, the long values kept truncated with a marker, the bad value dropped,
    one summary line per column."""
    long_text = ("Provenance: " + "sold at auction, then by descent; " * 107)[:3564] + "."      # 3 565 characters
    path = _museum_export(tmp_path / "export.csv", 52, long_text)
    q = read_queue_csv(path, columns={"identifier": "Object Number"})
    assert q.problems == [] and len(q.originals) == 12 and len(q.extra_columns) == 52
    kept = q.originals[1].extra["c36"]
    assert 990 <= len(kept) <= 1000 and kept.endswith(" [… 3565 characters, truncated]")
    assert kept.startswith(long_text[:900]) and q.originals[0].extra["c36"] == "short"
    assert "c1" not in q.originals[5].extra and q.originals[4].extra["c1"] == "value 4-1"
    lines = q.column_lines()                                           # in header order
    assert lines[::-1] == ["column 'c36' (extra metadata): 9 values over 1000 characters (longest 3565) kept "
                           "truncated, marked '[… N characters, truncated]'",
                           "column 'c1' (extra metadata): 1 value dropped (control character U+0001 at character 4 "
                           "is not allowed)"]


def test_unnamed_and_unreadable_header_columns_are_left_out_with_one_line(tmp_path):
    path = tmp_path / "q.csv"
    path.write_bytes(b"identifier,,ti\x01tle,Notes 2,Notes 2\nA,x,y,n1,n2,surplus\nB,,,,\n")
    q = read_queue_csv(path)
    assert q.problems == [] and [o.identifier for o in q.originals] == ["A", "B"]
    assert q.originals[0].extra == {"Notes 2": "n1", "Notes 2 (E)": "n2"}
    assert sorted(q.column_lines()) == sorted([
        "column C: header: control character U+0001 at character 3 is not allowed; its values are not kept",
        "column 'Notes 2 (E)' (extra metadata): the header repeats 'Notes 2' (also column D): kept under this name",
        "column F: beyond the header's last named column; its values are not kept",
        "column B: no name in the header; its values are not kept"])


def test_mapped_fields_keep_their_strict_checks(tmp_path):
    path = tmp_path / "q.csv"
    path.write_text("identifier,title,c1\nA," + "x" * 501 + ",ok\nB,fine," + "y" * 5000 + "\n", encoding="utf-8")
    q = read_queue_csv(path)
    assert q.bad_lines() == ["row 2, column 'title': 501 characters, at most 500"]
    assert [o.identifier for o in q.originals] == ["B"] and len(q.originals[0].extra["c1"]) == 1000
