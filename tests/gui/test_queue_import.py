"""The Originals step's *Import CSV...* (issue 19): the collection database's CSV goes through the workflow's
read_queue_csv (the CLI's --queue) and its plan (capture --queue --check); its refused rows are listed one per line
(row, column, problem) and never queued, and the valid rows are added only when the technician asks for it."""
from __future__ import annotations

from queue_rows import BAD, good_identifiers, write_queue_csv

from dualrgb.app.gui.panels.originals import CANCEL, add_valid


def test_import_lists_bad_rows_and_adds_the_valid_ones_on_request(qtbot, make_window, tmp_path):
    w = make_window()
    org, queue = w.originals, w.ctx.workspace.queue
    path = write_queue_csv(tmp_path / "originals.csv")
    org.csv_columns.setText("identifier=Inventarnummer")
    bad = [f"row {row}, column {column!r}: {problem}" for row, (column, problem) in sorted(BAD.items())]
    w.asker.scripted = [CANCEL]
    org.import_csv(path)
    qtbot.waitUntil(lambda: not w.asker.scripted)
    qtbot.wait(50)
    title, text = w.asker.history[-1]
    assert title == "Refused rows in the CSV" and all(line in text for line in bad)
    assert "Add the 17 valid rows and leave the 3 refused ones out" in text
    listed = [f"row {row}: " for row in BAD] + [problem for _column, problem in BAD.values()]
    assert queue.rows == [] and all(part in org.import_report.text() for part in listed)      # cancelled: none added
    w.asker.scripted = [add_valid(17)]
    org.import_csv(path)
    qtbot.waitUntil(lambda: len(w.ctx.workspace.queue.rows) == 17)
    rows = w.ctx.workspace.queue.rows
    assert [r.identifier for r in rows] == good_identifiers()
    assert rows[1].original.title == "Stillleben, mit Äpfeln 3" and rows[1].original.notes == "Zeile 1\nligne 2 (3)"
    assert rows[1].original.extra == {"Standort": "Depot 3; Regal 3"}
    assert org.table.rowCount() == 17 and "17 added" in org.import_report.text()
    assert all(part in org.import_report.text() for part in listed)


def test_a_file_that_is_not_a_queue_is_reported_in_one_line(make_window, tmp_path):
    w = make_window()
    path = tmp_path / "export.csv"
    path.write_bytes("Titel\nÖl auf Holz\n".encode("latin-1"))
    w.originals.import_csv(path)
    assert w.errors.history[-1][0] == "Import CSV" and "not UTF-8 text" in str(w.errors.history[-1][1])
    assert w.ctx.workspace.queue.rows == []
