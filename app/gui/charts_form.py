"""The calibration box's *Charts*: per target, the stand's own chart - its reference file (spectral CGATS or CSV),
its layout (ROWSxCOLS) and the patches to leave out - or nothing for the mode's packaged target. The same choice
as the command line's training and test chart options (app.workflow.calibration.charts,
which reads the files for both). Only wiring: the choices are kept in the settings.
"""
from __future__ import annotations

import logging

from PySide6.QtWidgets import QFileDialog, QFormLayout, QHBoxLayout, QLineEdit, QPushButton, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.workflow.calibration.charts import ROLES, ChartChoice

log = logging.getLogger(__name__)

FIELDS = ("file", "layout", "leave_out")
PLACEHOLDERS = {"file": "packaged target", "layout": "10x14", "leave_out": "A2,A3"}
TIPS = {"file": "The chart's reference file (the vendor's CGATS, ArgyllCMS .cie / .ti3, or a spectral CSV); empty: "
                "the mode's packaged target (no file).",
        "layout": "The chart's layout as ROWSxCOLS, e.g. 10x14; empty: the reference file's own layout.",
        "leave_out": "Patches to leave out of the fit and the check, e.g. A2,A3; empty: none."}
FILE_FILTER = "Chart references (*.txt *.cie *.ti3 *.sp *.cgats *.csv);;All files (*)"


class ChartsForm(QWidget):
    """Training and test chart rows (file + browse, layout, patches left out), persisted in the settings."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.edits: dict[str, dict[str, QLineEdit]] = {}
        form = QFormLayout(self)
        form.setContentsMargins(0, 0, 0, 0)
        for role in ROLES:
            what = "Training chart" if role == "train" else "Test chart"
            edits = {f: self._edit(role, f) for f in FIELDS}
            browse = QPushButton("…")
            browse.setToolTip(f"Choose the {what.lower()}'s reference file (the vendor's CGATS, ArgyllCMS .cie / "
                              ".ti3, or a spectral CSV).")
            browse.clicked.connect(lambda _=False, r=role: self.browse(r))
            row = QHBoxLayout()
            row.addWidget(edits["file"], 3)
            row.addWidget(browse)
            row.addWidget(edits["layout"], 1)
            row.addWidget(edits["leave_out"], 2)
            form.addRow(what, row)
            self.edits[role] = edits

    def _edit(self, role: str, field: str) -> QLineEdit:
        edit = QLineEdit(self.ctx.get(f"calibration/charts/{role}/{field}", "", str))
        edit.setPlaceholderText(PLACEHOLDERS[field])
        edit.setToolTip(TIPS[field] + " The stand's own chart: docs, how-to, own charts.")
        edit.setMinimumWidth(edit.fontMetrics().horizontalAdvance(PLACEHOLDERS[field]) + 16)
        edit.textChanged.connect(lambda text, r=role, f=field: self.ctx.set(f"calibration/charts/{r}/{f}", text))
        return edit

    def browse(self, role: str) -> None:
        start = self.edits[role]["file"].text() or str(self.ctx.captures_dir)
        path, _ = QFileDialog.getOpenFileName(self, "Chart reference file", start, FILE_FILTER)
        if path:
            self.edits[role]["file"].setText(path)

    def choices(self) -> dict[str, ChartChoice]:
        return {role: ChartChoice(*(self.edits[role][f].text().strip() for f in FIELDS)) for role in ROLES}

    def set_choice(self, role: str, choice: ChartChoice) -> None:
        for f in FIELDS:
            self.edits[role][f].setText(getattr(choice, f))

