"""Issue 42: a collection's metadata preset made and changed in the window (Originals -> Options -> *Edit preset…*)
without writing JSON: what the dialog saves is the preset the reader returns, a bad field is one line in the dialog
with nothing written, the *Collection* line and the next original added follow the saved preset, and the dialog
fits a 1366x768 screen with no clipped text."""
from __future__ import annotations

from PySide6.QtWidgets import QApplication

from dualrgb.app.workflow.day.collection_presets import (
    CollectionPreset,
    default_folder,
    find_preset,
    load_preset,
    save_preset,
)
from dualrgb.core.metadata import Credits
from tests.gui.conftest import click
from tests.gui.fit_check import clipped_texts

GEM = CollectionPreset("GEM", Credits(("Example Museum, Imaging Studio", "J. Doe"), "CC BY 4.0, Example Museum",
                                      "Gemäldegalerie, Example Museum", "Example Museum"),
                       {"collection": "Gemäldegalerie", "department": "Paintings"}, "GEM-{date}-{counter:04}")


def open_editor(qtbot, w, collection: str):
    from dualrgb.app.gui.preset_editor import PresetEditor

    org = w.originals
    w.show_panel("originals")
    org.left_tabs.setCurrentIndex(1)                                       # Options
    org.collection.setText(collection)
    click(qtbot, org.preset_button)
    dialog = org.findChild(PresetEditor)
    assert dialog is not None and dialog.isVisible()
    return dialog


def fill(dialog, preset: CollectionPreset) -> None:
    """Type the preset's fields as an archivist does (the table's rows one by one)."""
    dialog.creator.setPlainText("\n".join(preset.credits.creator))
    dialog.rights.setText(preset.credits.rights)
    dialog.credit.setText(preset.credits.credit)
    dialog.source.setText(preset.credits.source)
    dialog.template.setText(preset.identifier_template)
    for name, value in preset.extra.items():
        dialog.add_row.click()
        r = dialog.extra.rowCount() - 1
        dialog.extra.item(r, 0).setText(name)
        dialog.extra.item(r, 1).setText(value)


def test_the_dialog_writes_the_preset_the_reader_returns(qtbot, make_window):
    w = make_window()
    org = w.originals
    dialog = open_editor(qtbot, w, "GEM")
    assert dialog.name.text() == "GEM" and dialog.extra.rowCount() == 0 and "a new preset" in dialog.message.text()
    fill(dialog, GEM)
    dialog.add_row.click()                                  # an empty row left over: not a field
    click(qtbot, dialog.save_button)
    assert not dialog.isVisible()
    back = load_preset(default_folder() / "GEM.json")
    assert (back.name, back.credits, dict(back.extra), back.identifier_template) == \
        (GEM.name, GEM.credits, dict(GEM.extra), GEM.identifier_template)
    assert org.collection_note.text() == back.summary() and org.template.text() == GEM.identifier_template
    org.counter.setValue(3)
    click(qtbot, org.next_button)
    click(qtbot, org.add_button)                           # the next original added carries the preset's credits
    (row,) = w.ctx.workspace.queue.rows
    assert row.original.collection == "GEM" and row.original.credits == GEM.credits
    assert row.original.extra == dict(GEM.extra)

    dialog = open_editor(qtbot, w, "gem")                  # opened again: the saved fields, changed and saved
    assert dialog.name.text() == "GEM" and dialog.rights.text() == GEM.credits.rights
    assert dialog.creator.toPlainText().splitlines() == list(GEM.credits.creator)
    assert dialog.extra_pairs() == list(GEM.extra.items())
    dialog.extra.selectRow(0)
    click(qtbot, dialog.remove_row)
    dialog.rights.setText("Public domain")
    click(qtbot, dialog.save_button)
    again = find_preset("GEM")
    assert again is not None and dict(again.extra) == {"department": "Paintings"}
    assert again.credits.rights == "Public domain" and "rights Public domain" in org.collection_note.text()
    assert org.collection.text() == "GEM"


def test_a_bad_field_is_one_line_in_the_dialog_and_nothing_is_written(qtbot, make_window):
    w = make_window()
    save_preset(GEM)
    path = default_folder() / "GEM.json"
    before = path.read_bytes()
    dialog = open_editor(qtbot, w, "GEM")
    for bad, field, says in (
            (lambda d: d.rights.setText("CC BY\x01"), "rights", "rights: control character U+0001"),
            (lambda d: d.template.setText("{room}-{counter}"), "template", "identifier template: unknown token "
                                                                          "{room}"),
            (lambda d: d.extra.item(0, 0).setText(""), "extra", "extra: field name: empty"),
            (lambda d: d.extra.item(0, 0).setText("department"), "extra", "extra.department: named twice"),
            (lambda d: d.name.setText("a/b"), "name", "collection 'a/b': '/' cannot be in a file name")):
        dialog.load("GEM")
        bad(dialog)
        click(qtbot, dialog.save_button)
        text = dialog.message.text()
        assert dialog.isVisible() and text.startswith(says) and "\n" not in text, (field, text)
        assert dialog.save() is None and path.read_bytes() == before                      # nothing written
        assert sorted(p.name for p in default_folder().iterdir()) == ["GEM.json"]
    assert find_preset("GEM") == load_preset(path)


def test_a_preset_file_that_cannot_be_read_is_said_and_replaced(qtbot, make_window):
    w = make_window()
    path = default_folder() / "FILM.json"
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text('{"format": "dualrgb-collection/1", "rights": 5}', encoding="utf-8")
    dialog = open_editor(qtbot, w, "film")
    assert dialog.message.text().startswith(f"{path}: rights: 5 is not of type 'string'")
    assert dialog.message.text().endswith("Save replaces it")
    dialog.rights.setText("film rights")
    click(qtbot, dialog.save_button)
    assert load_preset(path).credits == Credits(rights="film rights")
    assert w.originals.collection_note.text().startswith("preset FILM: rights film rights")


def test_the_dialog_fits_a_small_screen(qtbot, make_window):
    w = make_window()
    w.resize(1366, 768)
    dialog = open_editor(qtbot, w, "GEM")
    fill(dialog, GEM)
    dialog.adjustSize()
    for _ in range(4):
        QApplication.processEvents()
    size = dialog.frameGeometry().size()
    assert size.width() <= 1366 and size.height() <= 700, size          # 768 less a panel
    assert clipped_texts(dialog) == []


def test_another_name_opens_that_collections_preset_and_a_new_one_keeps_the_typed_fields(qtbot, make_window):
    save_preset(GEM)
    w = make_window()
    dialog = open_editor(qtbot, w, "")
    assert dialog.name.text() == "" and dialog.message.text() == "name the collection"
    dialog.rights.setText("film rights")
    dialog.name.setText("FILM")
    dialog.name.editingFinished.emit()                      # a collection without a preset: the typed fields stay
    assert dialog.rights.text() == "film rights" and dialog.message.text().startswith("a new preset")
    dialog.name.setText("gem")
    dialog.name.editingFinished.emit()                      # one with a preset: its fields
    assert dialog.name.text() == "GEM" and dialog.rights.text() == GEM.credits.rights
    assert dialog.extra_pairs() == list(GEM.extra.items())
    click(qtbot, dialog.cancel_button)
    assert not dialog.isVisible() and find_preset("FILM") is None                   # Cancel writes nothing
