"""The Originals panel's form (issue 42: it fits a 1366x768 screen with the queue's buttons in view): *Add an
original* holds what changes per original - identifier (a barcode scanner types it and its Enter adds the
original), title, operator (remembered), notes, mode - *Next* fills the identifier from the template - and the
Add / Import CSV... buttons; *Options* holds what is set once a day (frames per exposure, resolution, rendering
light, sampling, the CSV's column names, the identifier template, collection and next number). The collection's
metadata preset (app.workflow.day.collection_presets: creator, rights, default extra fields, its identifier
template) is shown under it and applied to each original added (:func:`form_original`); *Edit preset…* beside it
makes or changes the preset (app.gui.preset_editor). Only building: the panel (app.gui.panels.originals) owns the
widgets and their actions."""
from __future__ import annotations

from typing import Any

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QComboBox,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QWidget,
)

from dualrgb.app.gui.stand_options import DeliveryOptions
from dualrgb.app.processing.masters import RESOLUTION_CHOICES
from dualrgb.app.workflow.day.collection_presets import PresetError, default_folder, find_preset, with_collection
from dualrgb.app.workflow.day.naming import TemplateError, expand
from dualrgb.core.metadata import MODES, Original

OPERATOR_KEY = "originals/operator"
TEMPLATE_KEY, COLLECTION_KEY, COUNTER_KEY = "originals/id_template", "originals/collection", "originals/counter"


def form_box(panel: Any) -> QGroupBox:
    """*Add an original*: the per-original fields and the Add / Import buttons, set on ``panel``."""
    box = QGroupBox("Add an original")
    form = QFormLayout(box)
    panel.identifier = QLineEdit()
    panel.identifier.setPlaceholderText("accession number, e.g. ACC-123")
    panel.identifier.setToolTip("Required: the accession number, e.g. ACC-123; it names every file. A barcode "
                                "scanner types it here and its Enter adds the original.")
    panel.identifier.textChanged.connect(lambda _t: panel._update_enabled())
    panel.identifier.returnPressed.connect(panel.add_original)
    panel.next_button = QPushButton("Next identifier")
    panel.next_button.setToolTip("Fill the identifier from the template (Options: Identifier template) and count on.")
    panel.next_button.clicked.connect(lambda: next_identifier(panel))
    panel.title_edit = QLineEdit()
    panel.operator = QLineEdit(panel.ctx.get(OPERATOR_KEY, "", str))
    panel.operator.setToolTip("Remembered for the next originals and the next session.")
    panel.operator.textChanged.connect(lambda t: panel.ctx.set(OPERATOR_KEY, t))
    panel.notes = QLineEdit()
    panel.mode = QComboBox()
    panel.mode.addItems(MODES)
    panel.mode.setToolTip("Reflective: paintings, prints on the stand. Transmissive: film on the light box.")
    panel.stand_in = QComboBox()
    panel.stand_in.addItems(panel.lab.virtual_originals())
    panel.stand_in.setToolTip("Virtual lab: which virtual original lies on the stand for this one (the shadow "
                              "needs an HDR bracket).")
    panel.add_button = QPushButton("Add to the queue")
    panel.add_button.clicked.connect(panel.add_original)
    panel.import_button = QPushButton("Import CSV…")
    panel.import_button.setToolTip("Add a day's originals from a CSV exported from the collection database "
                                   "(UTF-8; columns identifier, title, operator, notes, mode; other columns are "
                                   "kept as extra metadata). Every row is checked first; bad rows are listed.")
    panel.import_button.clicked.connect(panel.choose_csv)
    form.addRow("Identifier *", panel.identifier)
    for label, widget in (("Title", panel.title_edit), ("Operator", panel.operator), ("Notes", panel.notes),
                          ("Mode", panel.mode)):
        form.addRow(label, widget)
    panel.stand_in_label = QLabel("Virtual stand-in")
    form.addRow(panel.stand_in_label, panel.stand_in)
    buttons = QHBoxLayout()
    buttons.addWidget(panel.add_button)
    buttons.addWidget(panel.next_button)
    buttons.addWidget(panel.import_button)
    form.addRow(buttons)
    panel.import_report = QLabel("")
    panel.import_report.setWordWrap(True)
    panel.import_report.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
    panel.import_report.setToolTip("The last CSV import: its bad rows, one line each (row, column, problem).")
    form.addRow(panel.import_report)
    return box


def options_widget(panel: Any) -> QWidget:
    """*Options*: what is set once a day, set on ``panel``."""
    page = QWidget()
    form = QFormLayout(page)
    panel.frames = QSpinBox()
    panel.frames.setRange(1, 32)
    panel.frames.setToolTip("Frames averaged per exposure: noise / sqrt(N), light dose x N.")
    panel.resolution = QComboBox()
    for key, label in RESOLUTION_CHOICES.items():
        panel.resolution.addItem(label, key)
    panel.resolution.setCurrentIndex(max(0, panel.resolution.findData(panel.ctx.get("originals/resolution", "full",
                                                                                    str))))
    panel.resolution.setToolTip("Full: the sensor's pixels (each light's frames demosaiced, Malvar-He-Cutler, "
                                "linear). Half: one pixel per 2x2 Bayer cell, no interpolation (a quarter of the "
                                "pixels). Remembered.")
    panel.resolution.currentIndexChanged.connect(
        lambda _i: panel.ctx.set("originals/resolution", panel.resolution.currentData()))
    panel.csv_columns = QLineEdit(panel.ctx.get("originals/csv_columns", "", str))
    panel.csv_columns.setPlaceholderText("e.g. identifier=Accession No.")
    panel.csv_columns.setToolTip("Only if the header differs: which column of the collection database's CSV holds "
                                 "a field, when its header does not name it identifier, title, operator, notes or "
                                 "mode, e.g. identifier=Accession No.; title=Titel. Remembered.")
    panel.csv_columns.textChanged.connect(lambda t: panel.ctx.set("originals/csv_columns", t))
    form.addRow("Frames per exposure", panel.frames)
    form.addRow("Deliver at", panel.resolution)
    panel.delivery_options = DeliveryOptions(panel.ctx)      # rendering light, ppi (app.gui.stand_options)
    form.addRow(panel.delivery_options)
    form.addRow("CSV columns", panel.csv_columns)
    panel.template = remembered_edit(panel.ctx, TEMPLATE_KEY, "{collection}-{date}-{counter:04}",
                                     "Identifier template for Next: {counter} (e.g. {counter:04}), {date} (e.g. "
                                     "{date:%Y-%m-%d}), {operator}, {collection}. Remembered.")
    collection_row = collection_widgets(panel)
    panel.counter = QSpinBox()
    panel.counter.setRange(1, 999_999)
    panel.counter.setValue(panel.ctx.get(COUNTER_KEY, 1, int))
    panel.counter.setToolTip("The number {counter} gives next; Next counts on. Remembered.")
    panel.counter.valueChanged.connect(lambda v: panel.ctx.set(COUNTER_KEY, v))
    form.addRow("Identifier template", panel.template)
    form.addRow("Collection", collection_row)
    form.addRow(panel.collection_note)
    form.addRow("Next number", panel.counter)
    show_collection(panel)
    return page


def collection_widgets(panel: Any) -> QHBoxLayout:
    """*Collection* (remembered), *Edit preset…* beside it and the line under it, set on ``panel``."""
    panel.collection = remembered_edit(panel.ctx, COLLECTION_KEY, "e.g. GEM", "The collection, for {collection}; "
                                       "its metadata preset (creator, rights, extra fields; Edit preset… makes or "
                                       f"changes it, a file in {default_folder()}) is applied to each original "
                                       "added. Remembered.")
    panel.collection_note = QLabel("")
    panel.collection_note.setWordWrap(True)
    panel.collection.textChanged.connect(lambda _t: show_collection(panel))
    panel.preset_button = QPushButton("Edit preset…")
    panel.preset_button.setToolTip("Make or change this collection's metadata preset: creators, rights, credit "
                                   "line, source, default extra fields, identifier template.")
    panel.preset_button.clicked.connect(lambda: edit_preset(panel))
    row = QHBoxLayout()
    row.addWidget(panel.collection, 1)
    row.addWidget(panel.preset_button)
    return row


def show_collection(panel: Any) -> None:
    """Say under *Collection* what its preset sets (or that it has none, or what is wrong with its file); a
    preset's identifier template becomes the template."""
    name = panel.collection.text().strip()
    try:
        preset = find_preset(name)
    except PresetError as exc:
        panel.collection_note.setText(f"preset not used: {exc}")
        return
    if preset is None:
        panel.collection_note.setText(f"no preset for {name} (Edit preset… makes one)" if name else "")
        return
    panel.collection_note.setText(preset.summary())
    if preset.identifier_template:
        panel.template.setText(preset.identifier_template)


def edit_preset(panel: Any) -> QWidget:
    """*Edit preset…*: the collection's preset in its dialog (app.gui.preset_editor), one per form, shown again;
    after a save the *Collection* line says what it sets and the next original added gets it."""
    from dualrgb.app.gui.preset_editor import PresetEditor

    def saved(preset: Any) -> None:
        if panel.collection.text().strip() != preset.name:
            panel.collection.setText(preset.name)                       # show_collection runs on the change
        else:
            show_collection(panel)

    dialog = panel.findChild(PresetEditor)
    if dialog is None:
        dialog = PresetEditor(saved, panel)
    dialog.load(panel.collection.text())
    dialog.show()
    dialog.raise_()
    return dialog


def form_original(panel: Any) -> Original:
    """The original the form describes, under its collection's preset (the preset's extra fields and credits; the
    form's own values win): app.workflow.day.collection_presets.with_collection, as ``capture --queue``."""
    original = Original(panel.identifier.text(), panel.title_edit.text().strip(), panel.operator.text().strip(),
                        panel.notes.text().strip(), panel.mode.currentText())
    return with_collection(original, panel.collection.text().strip())


def remembered_edit(ctx: Any, key: str, placeholder: str, tip: str) -> QLineEdit:
    edit = QLineEdit(ctx.get(key, "", str))
    edit.setPlaceholderText(placeholder)
    edit.setToolTip(tip)
    edit.textChanged.connect(lambda t: ctx.set(key, t))
    return edit


def next_identifier(panel: Any) -> None:
    """The identifier field from the template and the counter; the counter counts on (app.workflow.day.naming)."""
    template = panel.template.text().strip() or panel.template.placeholderText()
    try:
        text = expand(template, counter=panel.counter.value(), operator=panel.operator.text().strip(),
                      collection=panel.collection.text().strip())
    except TemplateError as exc:
        panel.ctx.errors.report("Identifier template", exc)
        return
    panel.identifier.setText(text)
    panel.counter.setValue(panel.counter.value() + 1)
