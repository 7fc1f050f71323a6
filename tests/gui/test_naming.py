"""Issue 42: identifier templates (counter, date, operator, collection), *Next* counting on, a barcode scanner as
keyboard input ending with Enter, the Operator field remembered across adds."""
from __future__ import annotations

import datetime

import pytest
from PySide6.QtCore import Qt

from dualrgb.app.workflow.day.naming import TemplateError, expand

DAY = datetime.date(2026, 11, 28)


def test_templates_expand_their_tokens():
    assert expand("{collection}-{date}-{counter:04}", counter=7, collection="GEM", today=DAY) == "GEM-20261128-0007"
    assert expand("{operator}/{date:%Y-%m-%d}/{counter}", counter=12, operator="JD", today=DAY) == "JD/2026-11-28/12"
    assert expand("ACC-{counter:03}", counter=5) == "ACC-005"
    with pytest.raises(TemplateError, match=r"unknown token \{room\}"):
        expand("{room}-{counter}", counter=1)


def test_next_fills_the_identifier_and_counts_on(qtbot, make_window):
    w = make_window()
    org = w.originals
    org.template.setText("{collection}-{counter:04}")
    org.collection.setText("GEM")
    org.counter.setValue(7)
    qtbot.mouseClick(org.next_button, Qt.LeftButton)
    assert org.identifier.text() == "GEM-0007" and org.counter.value() == 8
    assert w.ctx.get("originals/counter", 0, int) == 8                          # remembered


def test_a_barcode_scanner_adds_with_its_enter_and_the_operator_stays(qtbot, make_window):
    w = make_window()
    org = w.originals
    w.show_panel("originals")
    org.operator.setText("J. Doe")
    org.identifier.setFocus()
    qtbot.keyClicks(org.identifier, "ACC-1902-07")                               # what a scanner types
    qtbot.keyClick(org.identifier, Qt.Key_Return)
    assert [r.identifier for r in w.ctx.workspace.queue.rows] == ["ACC-1902-07"]
    assert org.identifier.text() == "" and org.operator.text() == "J. Doe"


def test_a_collections_preset_applies_to_each_original_added(qtbot, make_window):
    """Issue 42: choosing a collection with a metadata preset says what it sets, takes its identifier template, and
    each original added carries its extra fields (the form's own values win) and credits; a bad preset file is one
    line naming the file and the field, and nothing is added."""
    from dualrgb.app.workflow.day.collection_presets import CollectionPreset, save_preset
    from dualrgb.core.metadata import Credits

    path = save_preset(CollectionPreset("GEM", Credits(("Example Museum",), "CC BY 4.0"),
                                        {"department": "Paintings"}, "GEM-{counter:03}"))
    w = make_window()
    org = w.originals
    org.collection.setText("GEM")
    assert "creator Example Museum" in org.collection_note.text() and "rights CC BY 4.0" in org.collection_note.text()
    assert org.template.text() == "GEM-{counter:03}"
    org.counter.setValue(4)
    qtbot.mouseClick(org.next_button, Qt.LeftButton)
    qtbot.mouseClick(org.add_button, Qt.LeftButton)
    (row,) = w.ctx.workspace.queue.rows
    assert row.identifier == "GEM-004" and row.original.collection == "GEM"
    assert row.original.credits == Credits(("Example Museum",), "CC BY 4.0")
    assert row.original.extra == {"department": "Paintings"}
    path.write_text('{"format": "dualrgb-collection/1", "rights": 5}', encoding="utf-8")
    org.collection.setText("gem")
    assert org.collection_note.text().startswith(f"preset not used: {path}: rights:")
    org.identifier.setText("GEM-005")
    qtbot.mouseClick(org.add_button, Qt.LeftButton)
    assert len(w.ctx.workspace.queue.rows) == 1                                   # refused: nothing added
    title, said = w.ctx.errors.current
    assert title == "Add an original" and said.startswith(f"{path}: rights: 5 is not of type 'string'")
    assert "\n" not in said
