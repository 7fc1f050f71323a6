"""*File -> Import raw files...*: ``dualrgb import`` in the window (issue 37), a thin view over the Qt-free import
(app.workflow.raw_import.raw_import, import_roles, import_template).

The folder's files fill the roles table (*Guess roles*: the roles template, app.workflow.raw_import.import_template; or
*Open
roles file...*: a ROLES.csv); every cell can be edited. *Check* runs every check the command runs (one line per
problem, below the table; nothing is written); *Import* copies, calibrates and delivers into the session (a new
dated one in the captures folder unless one is chosen), on the compute thread with progress and Cancel. The preset
(none: the lights are unknown), the mode and the targets' corners are the command's --preset, --mode and
--target-corners.
"""
from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtWidgets import (
    QComboBox,
    QDialog,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QListWidget,
    QProgressBar,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.workers import TaskHandle
from dualrgb.common.progress import Cancelled

log = logging.getLogger(__name__)

TITLE = "Import raw files"
NO_PRESET = "none: the lights are unknown"


class ImportDialog(QDialog):
    """The roles table, the import's choices, its check and its run (module docstring)."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.setWindowTitle(TITLE)
        self.ctx = ctx
        self.handle: TaskHandle | None = None
        self.plan = None                       # the last checked plan (app.workflow.raw_import.raw_import.ImportPlan)
        self.imported = None                   # the last import's ImportResult
        self.header: list[str] = []
        self._build()
        self._update()

    # ------------------------------------------------------------------ building
    def _build(self) -> None:
        from dualrgb.app.workflow.stand.defaults import MODES
        from dualrgb.simulation.presets import packaged_presets

        self.folder, self.session = QLineEdit(), QLineEdit()
        self.session.setPlaceholderText("a new dated session in the captures folder")
        self.preset = QComboBox()
        self.preset.addItem(NO_PRESET, "")
        for path in packaged_presets():
            self.preset.addItem(path.stem, str(path))
        self.mode = QComboBox()
        self.mode.addItems(list(MODES))
        self.corners = {name: QLineEdit() for name in ("train", "test")}
        for name, edit in self.corners.items():
            edit.setPlaceholderText("X,Y,X,Y,X,Y,X,Y: top-left, top-right, bottom-right, bottom-left in the raw "
                                    "file's pixels" + (" (a 24-patch chart: may be left empty)" if name == "test"
                                                       else ""))
        self.guess_button, self.open_button = QPushButton("Guess roles"), QPushButton("Open roles file…")
        self.check_button, self.import_button = QPushButton("Check"), QPushButton("Import")
        self.cancel_button = QPushButton("Cancel")
        self.guess_button.clicked.connect(self.guess)
        self.open_button.clicked.connect(self._ask_roles)
        self.check_button.clicked.connect(self.check)
        self.import_button.clicked.connect(self.start)
        self.cancel_button.clicked.connect(self.cancel_running)
        self.table = QTableWidget(0, 0)
        self.table.itemChanged.connect(lambda _item: self._edited())
        self.problems = QListWidget()
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self._lay_out()

    def _lay_out(self) -> None:
        form = QFormLayout()
        form.addRow("Raw files", self._with_button(self.folder, "Folder…", self._ask_folder))
        form.addRow("Session", self._with_button(self.session, "Folder…", self._ask_session))
        form.addRow("Preset", self.preset)
        form.addRow("Mode", self.mode)
        form.addRow("Training target corners", self.corners["train"])
        form.addRow("Test target corners", self.corners["test"])
        buttons = QHBoxLayout()
        for b in (self.guess_button, self.open_button, self.check_button, self.import_button, self.cancel_button):
            buttons.addWidget(b)
        buttons.addWidget(self.progress, 1)
        layout = QVBoxLayout(self)
        layout.addLayout(form)
        layout.addLayout(buttons)
        layout.addWidget(self.table, 3)
        layout.addWidget(QLabel("Problems (nothing is written while there are any):"))
        layout.addWidget(self.problems, 1)
        layout.addWidget(self.message)

    def _with_button(self, edit: QLineEdit, text: str, slot) -> QHBoxLayout:
        row = QHBoxLayout()
        row.addWidget(edit, 1)
        button = QPushButton(text)
        button.clicked.connect(slot)
        row.addWidget(button)
        return row

    def _ask_folder(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Folder of raw files", self.folder.text())
        if path:
            self.folder.setText(path)

    def _ask_session(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Session folder (new or empty)", str(self.ctx.captures_dir))
        if path:
            self.session.setText(path)

    def _ask_roles(self) -> None:
        path, _ = QFileDialog.getOpenFileName(self, "Roles file", self.folder.text(), "CSV (*.csv *.txt)")
        if path:
            self.open_roles(Path(path))

    # ------------------------------------------------------------------ the table
    def set_table(self, header: list[str], rows: list[list[str]]) -> None:
        self.table.blockSignals(True)
        self.header = list(header)
        self.table.clear()
        self.table.setColumnCount(len(header))
        self.table.setHorizontalHeaderLabels(self.header)
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            for c in range(len(header)):
                self.table.setItem(r, c, QTableWidgetItem(row[c] if c < len(row) else ""))
        self.table.blockSignals(False)
        self._edited()

    def cells(self) -> list[list[str]]:
        def text(r: int, c: int) -> str:
            item = self.table.item(r, c)
            return item.text() if item is not None else ""
        return [[text(r, c) for c in range(len(self.header))] for r in range(self.table.rowCount())]

    def open_roles(self, path: Path) -> None:
        from dualrgb.app.workflow.raw_import.import_roles import read_records

        try:
            records = read_records(path)
        except ValueError as exc:
            self.ctx.errors.report(TITLE, exc)
            return
        self.set_table(records[0], records[1:])

    def guess(self) -> None:
        from dualrgb.app.workflow.raw_import.import_template import template_table

        folder = Path(self.folder.text())
        if not self.folder.text().strip() or not folder.is_dir():
            self.ctx.errors.report(TITLE, f"{self.folder.text() or 'no folder'}: choose the folder of raw files")
            return
        self.message.setText(f"reading {folder} …")
        self._submit(lambda: template_table(folder), lambda t: self.set_table(*t), "guess roles")

    def _edited(self) -> None:
        self.plan = None
        self._update()

    # ------------------------------------------------------------------ check and import
    def settings(self):
        """The import's settings from the window's choices (ValueError, one line, for a bad one)."""
        from dualrgb.app.workflow.raw_import.import_checks import ImportSettings, corner_grid, parse_corners
        from dualrgb.app.workflow.stand.folders import dated_name
        from dualrgb.simulation.presets import load_preset

        preset = load_preset(Path(self.preset.currentData())) if self.preset.currentData() else None
        mode = self.mode.currentText()
        if preset is not None:
            preset.mode = mode
        grids = {n: corner_grid(mode, n, parse_corners(e.text())) for n, e in self.corners.items() if e.text().strip()}
        captures = Path(self.ctx.captures_dir)
        session = Path(self.session.text()) if self.session.text().strip() else captures / dated_name(captures)
        return ImportSettings(mode, preset, {}, grids, session)

    def check(self) -> None:
        from dualrgb.app.workflow.raw_import.raw_import import plan_table

        try:
            folder, settings = Path(self.folder.text()), self.settings()
        except ValueError as exc:
            self.show_problems([str(exc)])
            return
        header, rows = list(self.header), self.cells()
        self.message.setText("checking …")
        self._submit(lambda: plan_table(folder, header, rows, settings), self._checked, "check import")

    def _checked(self, plan) -> None:
        self.plan = plan
        self.show_problems([])
        self.message.setText(f"ready: {len(plan.frames)} files, {len(plan.originals)} original"
                             f"{'s' if len(plan.originals) != 1 else ''}, into {plan.settings.session}"
                             + "".join(f"; note: {n}" for n in plan.notes))
        self._update()

    def show_problems(self, lines: list[str]) -> None:
        self.problems.clear()
        self.problems.addItems(lines)
        if lines:
            self.message.setText(f"{len(lines)} problem{'s' if len(lines) > 1 else ''}: nothing was written")

    def start(self) -> None:
        from dualrgb.app.workflow.raw_import.raw_import import ImportOptions, run_import

        plan = self.plan
        if plan is None:
            return
        self.progress.setValue(0)
        self.handle = self.ctx.runner.submit(
            lambda progress, cancel: run_import(plan, ImportOptions(), progress=progress, cancel=cancel),
            pool="compute", name="import raw files", pass_progress=True, pass_cancel=True, on_result=self._done,
            on_error=self._failed, on_progress=self._progress, on_finished=self._finished)
        self._update()

    def _progress(self, fraction: float, message: str) -> None:
        self.progress.setValue(int(round(1000 * fraction)))
        self.message.setText(message)

    def _done(self, result) -> None:
        self.imported = result
        self.message.setText(f"imported into {result.session}: calibration {result.profile.id}; "
                             + "; ".join(d.qa.text() for d in result.deliveries))
        self.ctx.errors.clear(TITLE)

    def _failed(self, exc: BaseException) -> None:
        from dualrgb.app.workflow.raw_import.import_checks import ImportRefused

        if isinstance(exc, ImportRefused):
            self.show_problems(exc.lines)
        elif isinstance(exc, Cancelled):
            self.message.setText("cancelled: the files copied so far stay in the session (importing again resumes)")
        else:
            self.message.setText(f"failed: {exc}")
            self.ctx.errors.report(TITLE, exc)

    def _finished(self) -> None:
        self.handle = None
        self._update()

    def _submit(self, fn, on_result, name: str) -> None:
        self.handle = self.ctx.runner.submit(fn, pool="compute", name=name, on_result=on_result,
                                             on_error=self._failed, on_finished=self._finished)
        self._update()

    def cancel_running(self) -> None:
        if self.handle is not None:
            self.handle.cancel()
            self.message.setText("cancelling …")

    def _update(self) -> None:
        busy = self.handle is not None
        for b in (self.guess_button, self.open_button, self.check_button):
            b.setEnabled(not busy)
        self.import_button.setEnabled(not busy and self.plan is not None)
        self.import_button.setToolTip("" if self.plan is not None else "Check first: the import runs once every check "
                                                                       "passes")
        self.cancel_button.setEnabled(busy)
