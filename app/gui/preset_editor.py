"""Originals -> Options -> *Edit preset…*: a collection's metadata preset made or changed without writing JSON
(issue 42), a thin view over app.workflow.day.collection_presets.

The dialog shows the collection's preset as it is (none yet: empty fields; a file that cannot be read: its line, and
saving replaces it): the collection's name, the creators (one per line), rights, credit line, source, the default
extra fields (a two-column table) and the identifier template. *Save* builds the preset with
:func:`~dualrgb.app.workflow.day.collection_presets.make_preset` - the same checks a preset file is read with - and
writes it with :func:`~dualrgb.app.workflow.day.collection_presets.save_preset` (atomically); a bad field is one line
in the dialog, the field is focused, and nothing is written. After a save the form is told (``on_saved``): the
*Collection* line says what the preset sets, and the next original added gets it.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QAbstractItemView,
    QDialog,
    QFormLayout,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPlainTextEdit,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.workflow.day.collection_presets import (
    CollectionPreset,
    PresetError,
    find_preset,
    load_preset,
    make_preset,
    preset_path,
    save_preset,
)

log = logging.getLogger(__name__)

TITLE = "Collection preset"
ERROR_STYLE = "color: #b00020;"


class PresetEditor(QDialog):
    """The fields of one collection's preset and its *Save* (module docstring)."""

    def __init__(self, on_saved: Callable[[CollectionPreset], None], parent: QWidget | None = None,
                 folder: Path | None = None):
        super().__init__(parent)
        self.setWindowTitle(TITLE)
        self.on_saved = on_saved
        self.folder = folder                        # None: the per-user presets folder
        self.loaded = ""                            # the collection whose preset the fields show
        self._build()

    # ------------------------------------------------------------------ building
    def _build(self) -> None:
        self.name = QLineEdit()
        self.name.setPlaceholderText("e.g. GEM")
        self.name.setToolTip("The collection; its preset file is named after it. Another name opens that "
                             "collection's preset.")
        self.name.editingFinished.connect(
            lambda: self.load(self.name.text(), keep=True) if self._renamed() else None)
        self.creator = QPlainTextEdit()
        self.creator.setPlaceholderText("one name per line")
        self.creator.setToolTip("The creators of the files (XMP dc:creator), one per line.")
        self.creator.setTabChangesFocus(True)
        self.creator.setFixedHeight(3 * self.fontMetrics().lineSpacing() + 14)
        self.rights, self.credit, self.source, self.template = (QLineEdit() for _ in range(4))
        self.rights.setToolTip("The rights statement (XMP dc:rights and the TIFF Copyright tag).")
        self.credit.setToolTip("The credit line (XMP photoshop:Credit).")
        self.source.setToolTip("The institution (XMP photoshop:Source).")
        self.template.setPlaceholderText("e.g. GEM-{date}-{counter:04}")
        self.template.setToolTip("The identifier template Next identifier uses for this collection: {counter} "
                                 "(e.g. {counter:04}), {date}, {operator}, {collection}. Empty: the form's own.")
        form = QFormLayout()
        for label, widget in (("Collection", self.name), ("Creators", self.creator), ("Rights", self.rights),
                              ("Credit line", self.credit), ("Source", self.source),
                              ("Identifier template", self.template)):
            form.addRow(label, widget)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addWidget(self._extra_box())
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.message.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        layout.addWidget(self.message)
        self.save_button, self.cancel_button = QPushButton("Save"), QPushButton("Cancel")
        self.save_button.setDefault(True)
        self.save_button.setToolTip("Check every field and write the preset; a bad field is said here and "
                                    "nothing is written.")
        self.save_button.clicked.connect(self.save)
        self.cancel_button.clicked.connect(self.reject)
        buttons = QHBoxLayout()
        buttons.addStretch(1)
        buttons.addWidget(self.save_button)
        buttons.addWidget(self.cancel_button)
        layout.addLayout(buttons)
        self.setMinimumWidth(460)

    def _extra_box(self) -> QWidget:
        """The default extra fields: a (field, value) table with Add / Remove."""
        box = QWidget()
        layout = QVBoxLayout(box)
        layout.setContentsMargins(0, 0, 0, 0)
        layout.addWidget(QLabel("Extra fields of each original (an original's own value wins)"))
        self.extra = QTableWidget(0, 2)
        self.extra.setHorizontalHeaderLabels(["Field", "Value"])
        self.extra.horizontalHeader().setSectionResizeMode(1, QHeaderView.ResizeMode.Stretch)
        self.extra.verticalHeader().setVisible(False)
        self.extra.setSelectionBehavior(QAbstractItemView.SelectionBehavior.SelectRows)
        self.extra.setFixedHeight(5 * self.extra.verticalHeader().defaultSectionSize() + 6)
        self.add_row, self.remove_row = QPushButton("Add field"), QPushButton("Remove field")
        self.add_row.clicked.connect(lambda: self.add_extra("", "", edit=True))
        self.remove_row.clicked.connect(self.remove_extra)
        row = QHBoxLayout()
        row.addWidget(self.add_row)
        row.addWidget(self.remove_row)
        row.addStretch(1)
        layout.addWidget(self.extra)
        layout.addLayout(row)
        return box

    # ------------------------------------------------------------------ the fields
    def add_extra(self, name: str, value: str, *, edit: bool = False) -> None:
        r = self.extra.rowCount()
        self.extra.insertRow(r)
        first = QTableWidgetItem(name)
        self.extra.setItem(r, 0, first)
        self.extra.setItem(r, 1, QTableWidgetItem(value))
        if edit:
            self.extra.setCurrentCell(r, 0)
            self.extra.editItem(first)

    def remove_extra(self) -> None:
        """The selected rows out (none selected: the current one)."""
        rows = sorted({i.row() for i in self.extra.selectedIndexes()} or {self.extra.currentRow()}, reverse=True)
        for r in rows:
            if r >= 0:
                self.extra.removeRow(r)

    def extra_pairs(self) -> list[tuple[str, str]]:
        """The table's (field, value) rows, as typed; wholly empty rows left out."""
        def text(r: int, c: int) -> str:
            item = self.extra.item(r, c)
            return item.text() if item is not None else ""

        cells = [(text(r, 0), text(r, 1)) for r in range(self.extra.rowCount())]
        return [(name, value) for name, value in cells if name.strip() or value.strip()]

    def show_preset(self, preset: CollectionPreset) -> None:
        self.creator.setPlainText("\n".join(preset.credits.creator))
        for edit, text in ((self.rights, preset.credits.rights), (self.credit, preset.credits.credit),
                           (self.source, preset.credits.source), (self.template, preset.identifier_template)):
            edit.setText(text)
        self.extra.setRowCount(0)
        for name, value in preset.extra.items():
            self.add_extra(name, value)

    def _renamed(self) -> bool:
        return self.name.text().strip().casefold() != self.loaded.casefold()

    def _say(self, text: str, error: bool = False) -> None:
        self.message.setText(text)
        self.message.setStyleSheet(ERROR_STYLE if error else "")

    def load(self, name: str, *, keep: bool = False) -> None:
        """Show collection ``name``'s preset: its fields, or why its file cannot be used, or none yet; ``keep``
        (the name changed in the dialog): the fields as typed stay unless that collection has a preset."""
        name = name.strip()
        self.name.setText(name)
        self.loaded = name
        if not keep:
            self.show_preset(CollectionPreset(name))
        try:
            preset = find_preset(name, self.folder) if name else None
        except PresetError as exc:
            self._say(f"{exc}; Save replaces it", error=True)
            return
        if preset is None:
            try:
                where = f" ({preset_path(name, self.folder)})" if name else ""
            except PresetError:
                where = ""
            self._say(f"a new preset{where}" if name else "name the collection")
            return
        self.name.setText(preset.name)
        self.loaded = preset.name
        self.show_preset(preset)
        self._say(f"the preset in {preset.path}")

    # ------------------------------------------------------------------ saving
    def field_widget(self, field: str) -> QWidget:
        """The widget of a preset's field (PresetError.field), to focus when it is bad."""
        return {"name": self.name, "creator": self.creator, "rights": self.rights, "credit": self.credit,
                "source": self.source, "extra": self.extra, "identifier_template": self.template}.get(field, self.name)

    def save(self) -> CollectionPreset | None:
        """Check every field (the preset file's own checks) and write the preset; a problem: one line here,
        the field focused, nothing written."""
        try:
            preset = make_preset(
                self.name.text(), creator=[t for t in self.creator.toPlainText().splitlines() if t.strip()],
                rights=self.rights.text(), credit=self.credit.text(), source=self.source.text(),
                extra=self.extra_pairs(), identifier_template=self.template.text())
        except PresetError as exc:
            self._say(str(exc), error=True)
            self.field_widget(exc.field).setFocus()
            return None
        try:
            path = save_preset(preset, self.folder)
        except (OSError, PresetError) as exc:
            self._say(f"not saved: {exc}", error=True)
            return None
        log.info("collection preset %s saved from the window: %s", preset.name, path)
        try:
            saved = load_preset(path)                     # its name as the file spells it (GEM.json for 'gem')
        except PresetError:                               # changed under us since: the form says so when it reads it
            saved = preset
        self.loaded = saved.name
        self._say(f"saved: {path}")
        self.on_saved(saved)
        self.accept()
        return saved
