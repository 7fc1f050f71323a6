"""Originals: the day's queue, captured and delivered in one run of app.workflow.day.queue_run.capture_queue (as
``capture --queue``: metering, an HDR bracket when metering asks, the archival TIFFs, sidecar and QA line).

Each row shows its state (waiting / capturing / captured / delivered / failed) and QA line; the delivered TIFF and
its folder open from here, and the *Delivered* tab shows the selected original's spectral cube seen under a light of
choice, with the spectrum of a clicked pixel (app.gui.spectra_view). An original already in the session asks "re-shoot
/ keep" and reports "0 new, 2 kept". The calibration's check against the stand is shown above the Capture
button, before anything is shot. *Import CSV...* adds a day's originals from the collection database through
app.workflow.day.queue_csv.read_queue_csv (the CLI's ``--queue``) and shows the plan ``capture --queue --check``
prints (app.workflow.day.queue_plan): its refused rows (bad, or of another mode than the calibration's) are listed,
one line each, and never queued; the rows to shoot are added only on request when any row is refused. The
mode rule (app.workflow.stand.mode_rule): an original of another mode than the calibration's is marked and not shot
unless the technician chooses "Capture anyway" (said in its sidecar and QA line).
"""
from __future__ import annotations

import logging
from dataclasses import replace
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QLineEdit,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.image_viewer import ImageViewer
from dualrgb.app.gui.original_form import form_box, form_original, options_widget
from dualrgb.app.gui.sequence_view import SequenceView
from dualrgb.app.gui.spectra_view import DeliveredView
from dualrgb.app.gui.stand_options import DeliveryOptions
from dualrgb.app.gui.widgets import side_by_side
from dualrgb.app.gui.wording import add_valid, in_window_words, reshoot_question
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.workflow.day.day import OriginalsQueue, OriginalState, QueueRow
from dualrgb.app.workflow.day.day_file import restore_queue
from dualrgb.app.workflow.day.queue_clock import QueueClock
from dualrgb.app.workflow.day.queue_csv import QueueImport, column_options, read_queue_csv
from dualrgb.app.workflow.day.queue_plan import KEPT, REFUSED, SHOOT, plan_queue
from dualrgb.app.workflow.day.queue_run import (
    QUEUE_EVENT,
    QueueOutcome,
    capture_queue,
    delivered_sidecar,
    original_plan,
)
from dualrgb.app.workflow.stand.copystand import StandSettings, original_takes
from dualrgb.app.workflow.stand.defaults import SETTLE_S
from dualrgb.app.workflow.stand.mode_rule import mode_problem
from dualrgb.core.engine import Run, RunHooks
from dualrgb.core.vocabulary import EventKind

log = logging.getLogger(__name__)

COLUMNS = ("identifier", "state", "mode", "stand-in", "title", "QA")
STATE_COLOURS = {OriginalState.WAITING: "#fafafa", OriginalState.CAPTURING: "#e3f2fd",
                 OriginalState.CAPTURED: "#fff8e1", OriginalState.DELIVERED: "#e8f5e9",
                 OriginalState.FAILED: "#ffebee"}
RESHOOT, KEEP, CANCEL = "Re-shoot", "Keep", "Cancel"
QA_WIDTH = 180
OVERRIDE, LEAVE = "Capture anyway", "Leave it"


def qa_text(row: QueueRow) -> str:
    """The selected original under the table: its state, the calibration it was delivered with, its QA line and
    warnings."""
    made = f", calibration {row.calibration}" if row.calibration else ""
    return "\n".join([f"{row.identifier} ({row.state.value}{made}): {row.qa or '—'}", *row.warnings])


class OriginalsPanel(QWidget):
    title = "Originals"
    # made by app.gui.original_form (form_box, options_widget)
    identifier: QLineEdit
    title_edit: QLineEdit
    operator: QLineEdit
    notes: QLineEdit
    mode: QComboBox
    stand_in: QComboBox
    stand_in_label: QLabel
    add_button: QPushButton
    import_button: QPushButton
    import_report: QLabel
    frames: QSpinBox
    resolution: QComboBox
    csv_columns: QLineEdit
    delivery_options: DeliveryOptions
    next_button: QPushButton
    template: QLineEdit
    collection: QLineEdit
    collection_note: QLabel
    counter: QSpinBox

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab, self.ws = ctx, ctx.lab, ctx.workspace
        self.current: QueueRow | None = None
        self.batch: list[str] = []                  # identifiers still to ask about before the run starts
        self._chosen: list[str] = []                 # ... and those to capture in it
        self._reshoot: dict[str, bool] = {}          # the technician's answers: re-shoot (True) or keep (False)
        self._rows: list[QueueRow] = []              # the run's originals
        self.mode_overrides: set[str] = set()        # originals the technician chose to capture in another mode
        self.run: Run | None = None
        self._brackets: dict[str, dict[str, list[float]]] = {}    # per original: each light's metered bracket
        self.view = SequenceView(ctx)
        self.view.start_button.hide()
        self.view.run_event.connect(self._run_event)
        self.view.finished.connect(self._run_finished)
        self.delivered = DeliveredView(ctx)
        self._shown: tuple[Path | None, str] = (None, "")   # the sidecar and QA line the Delivered tab shows
        self.tabs = QTabWidget()
        self.tabs.addTab(self.view, "Capture")
        self.tabs.addTab(self.delivered, "Delivered")
        self.viewer = ImageViewer(ctx)                # the delivered master at full resolution (issue 42)
        self.tabs.addTab(self.viewer, "Viewer")
        left = QWidget()
        lv = QVBoxLayout(left)
        lv.addWidget(form_box(self))
        lv.addWidget(self._calibration_box())
        lv.addWidget(self._queue_box(), 1)
        self.left_tabs = QTabWidget()              # the day's options apart: the queue's buttons stay in view
        self.left_tabs.addTab(left, "Queue")
        self.left_tabs.addTab(options_widget(self), "Options")
        scroll = QScrollArea()                      # a short screen scrolls the column; no row is squeezed
        scroll.setWidget(self.left_tabs)
        scroll.setWidgetResizable(True)
        scroll.setHorizontalScrollBarPolicy(Qt.ScrollBarPolicy.ScrollBarAlwaysOff)
        scroll.setMinimumWidth(self.left_tabs.minimumSizeHint().width())
        side_by_side(self, scroll, self.tabs, stretch=(3, 2), sizes=[560, 540])
        self._connect()
        self._virtual_changed()
        self.show_calibration()
        self.fill_table()

    # ------------------------------------------------------------------ builders
    def _calibration_box(self) -> QGroupBox:
        box = QGroupBox("Calibration used")
        lay = QVBoxLayout(box)
        self.calibration_label = QLabel("")
        self.calibration_label.setWordWrap(True)
        self.calibration_label.setTextFormat(Qt.TextFormat.RichText)
        self.force = QCheckBox("use it although it does not match the stand (the deliverables say so)")
        self.force.setToolTip("A calibration made with another camera, ISO, aperture or a sphere at another "
                              "temperature gives wrong colours; this records a warning in every deliverable.")
        self.force.toggled.connect(lambda _on: self._update_enabled())
        lay.addWidget(self.calibration_label)
        lay.addWidget(self.force)
        return box

    def _queue_box(self) -> QGroupBox:
        box = QGroupBox("Queue")
        lay = QVBoxLayout(box)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.setSelectionBehavior(QTableWidget.SelectionBehavior.SelectRows)
        self.table.setEditTriggers(QTableWidget.EditTrigger.NoEditTriggers)
        header = self.table.horizontalHeader()          # readable at 1366 px: the title gives way, never the state
        for c, name in enumerate(COLUMNS):
            mode = QHeaderView.ResizeMode.Stretch if name == "title" else QHeaderView.ResizeMode.ResizeToContents
            header.setSectionResizeMode(c, QHeaderView.ResizeMode.Interactive if name == "QA" else mode)
        header.setStretchLastSection(False)
        header.setMinimumSectionSize(70)                # the title shows its start even in a narrow panel
        self.table.setTextElideMode(Qt.TextElideMode.ElideRight)
        self.table.setWordWrap(False)
        self.table.itemSelectionChanged.connect(self._update_enabled)
        buttons = QHBoxLayout()
        self.capture_button = QPushButton("Capture selected")
        self.capture_button.setToolTip("Meter, capture (an HDR bracket when metering asks) and deliver the selected "
                                       "originals with the calibration (Ctrl+Enter).")
        self.capture_button.clicked.connect(lambda: self.capture(self.selected()))
        self.capture_all_button = QPushButton("Capture all waiting")
        self.capture_all_button.clicked.connect(lambda: self.capture([r.identifier for r in self.ws.queue.waiting()]))
        self.remove_button = QPushButton("Remove")
        self.remove_button.setToolTip("Take the selected originals off the queue (their frames stay in the "
                                      "session).")
        self.remove_button.clicked.connect(self.remove_selected)
        self.open_tiff_button = QPushButton("Open TIFF")
        self.open_tiff_button.setToolTip("Open the delivered sRGB TIFF in the image viewer.")
        self.open_tiff_button.clicked.connect(lambda: self._open("file"))
        self.open_folder_button = QPushButton("Open folder")
        self.open_folder_button.setToolTip("Show the original's deliverables folder.")
        self.open_folder_button.clicked.connect(lambda: self._open("folder"))
        for w in (self.capture_button, self.capture_all_button, self.remove_button, self.open_tiff_button,
                  self.open_folder_button):
            buttons.addWidget(w)
        self.qa_label = QLabel("")
        self.qa_label.setWordWrap(True)
        self.qa_label.setToolTip("The QA line of the selected original (its sidecar has it too).")
        lay.addWidget(self.table, 1)
        lay.addWidget(self.qa_label)
        lay.addLayout(buttons)
        return box

    def _connect(self) -> None:
        self.ws.calibrationChanged.connect(self.show_calibration)
        self.ws.queueChanged.connect(self.fill_table)
        self.ws.runningChanged.connect(lambda _n: self._update_enabled())
        self.lab.virtualLabChanged.connect(self._virtual_changed)
        self.lab.sessionChanged.connect(self._session_changed)
        for sig in (self.lab.sphereChanged, self.lab.cameraChanged):
            sig.connect(self._update_enabled)

    # ------------------------------------------------------------------ queue
    def add_original(self) -> QueueRow | None:
        try:
            original = form_original(self)          # under the collection's metadata preset
            row = self.ws.queue.add(original, self.stand_in.currentText() if self.lab.is_virtual else "",
                                    self.frames.value())
        except ValueError as exc:
            self.ctx.errors.report("Add an original", exc)
            return None
        self.ctx.errors.clear("Add an original")
        for w in (self.identifier, self.title_edit, self.notes):
            w.clear()
        self.ws.queue_changed()
        return row

    def choose_csv(self) -> None:
        start = self.ctx.get("originals/csv_folder", str(Path.home()), str)
        path, _ = QFileDialog.getOpenFileName(self, "Import originals from a CSV", start,
                                              "CSV files (*.csv *.txt);;All files (*)")
        if path:
            self.import_csv(Path(path))

    def import_csv(self, path: Path) -> None:
        """Read and check a queue CSV (the workflow's read_queue_csv) and plan it as ``capture --queue --check`` does
        (app.workflow.day.queue_plan): a refused row (bad, or another mode than the calibration's) is listed and
        never queued; the rows to shoot are added at once when none is refused, else when the technician asks."""
        session = self.lab.session
        try:
            imported = read_queue_csv(Path(path), columns=column_options(self.csv_columns.text()),
                                      default_mode=self.mode.currentText(), collection=self.collection.text().strip(),
                                      out_dir=session.path / "deliverables" if session is not None else None)
        except ValueError as exc:
            self.ctx.errors.report("Import CSV", exc)
            return
        self.ctx.errors.clear("Import CSV")
        self.ctx.set("originals/csv_folder", str(Path(path).parent))
        plan = plan_queue(imported, self.ws.calibration, session=session)
        self.import_report.setText("\n".join(plan.lines()))
        refused, valid = len(plan.of(REFUSED)), len(plan.of(SHOOT))
        if not refused or not valid:                 # nothing to decide: the report lists what is refused
            self._add_imported(imported)
            return
        add = add_valid(valid)
        text = (f"{plan.summary()}:\n" + "\n".join(plan.refused_lines()) + f"\n\n{add} and leave "
                f"{'the refused one' if refused == 1 else f'the {refused} refused ones'} out, or cancel and fix the "
                "file?")
        self.ctx.asker.ask("Refused rows in the CSV", text, (add, CANCEL),
                           lambda choice: self._add_imported(imported) if choice == add else None, default=CANCEL)

    def _add_imported(self, imported: QueueImport) -> None:
        """Add the rows the plan shoots (under the calibration in use now): a refused row never, a row delivered in
        the session already (the plan's 'kept') is counted as delivered, not added again. The report and the log
        say the plan's counts and how many were added."""
        operator = self.operator.text().strip()
        plan = plan_queue(imported, self.ws.calibration, session=self.lab.session)
        originals = [o if o.operator or not operator else replace(o, operator=operator) for o in plan.to_shoot]
        left_out = self.ws.queue.add_many(originals, self.stand_in.currentText() if self.lab.is_virtual else "",
                                          self.frames.value())
        kept = plan.of(KEPT)
        lines = plan.lines()
        head = f"{lines[0]}; {len(originals) - len(left_out)} added" + (f", {len(kept)} delivered already"
                                                                           if kept else "")
        log.info("%s", head)
        self.import_report.setText("\n".join([head, *lines[1:], *left_out]))
        self.ws.queue_changed()

    def selected(self) -> list[str]:
        rows = sorted({i.row() for i in self.table.selectedIndexes()})
        return [self.ws.queue.rows[r].identifier for r in rows if r < len(self.ws.queue.rows)]

    def select(self, identifier: str) -> None:
        for r, row in enumerate(self.ws.queue.rows):
            if row.identifier == identifier:
                self.table.selectRow(r)

    def remove_selected(self) -> None:
        for ident in self.selected():
            if self.current is None or self.current.identifier != ident:
                self.ws.queue.remove(ident)
        self.ws.queue_changed()

    def fill_table(self) -> None:
        rows = self.ws.queue.rows
        self.table.setRowCount(len(rows))
        for r, row in enumerate(rows):
            o = row.original
            texts = (o.identifier, row.state.value, o.mode, row.stand_in or "—", o.title, row.qa)
            for c, text in enumerate(texts):
                item = QTableWidgetItem(text)
                item.setToolTip(text if c != 5 else "\n".join([text] + row.warnings))
                item.setBackground(QColor(STATE_COLOURS[row.state]))
                self.table.setItem(r, c, item)
        self.table.setColumnWidth(COLUMNS.index("QA"), QA_WIDTH)    # the whole line: its tooltip and under the table
        self.table.resizeRowsToContents()
        self._update_enabled()

    def _session_changed(self) -> None:
        session = self.lab.session
        if session is None:
            return
        keep = [r for r in self.ws.queue.rows if r.state is OriginalState.WAITING]

        def done(queue: OriginalsQueue) -> None:
            for row in keep:                     # waiting originals stay queued in the new session
                if all(r.identifier != row.identifier for r in queue.rows):
                    queue.rows.append(row)
            self.ws.queue = queue
            self.ws.queue_changed()
        # the session's delivered originals and its saved queue (app.workflow.day.day_file)
        self.ctx.runner.submit(lambda: restore_queue(session), pool="compute", name="list originals",
                               on_result=done, on_error=lambda exc: self.ctx.errors.report("Originals", exc))

    # ------------------------------------------------------------------ calibration and state
    def show_calibration(self) -> None:
        prof, check = self.ws.calibration, self.ws.calibration_check
        if prof is None:
            text = "<b>no calibration</b>: calibrate in Calibrate & capture, or load a saved one there"
        else:
            test = f", test ΔE00 {prof.test_mean:.2f}" if prof.test_mean is not None else ""
            text = f"{prof.id}: {prof.age_h():.1f}\u00a0h old, ISO {prof.camera.iso}{test}"
            if check is None:
                text += "<br>not checked against the stand yet"
            elif check.ok:
                text += "<br><span style='color:#2e7d32'>matches the stand</span>"
            else:
                text += f"<br><span style='color:#c62828; font-weight:bold'>does not match the stand: " \
                        f"{check.message()}</span>"
            text += "".join(f"<br><span style='color:#b26a00'>{w}</span>" for w in (check.warnings if check else []))
        self.calibration_label.setText(text)
        self.force.setVisible(self.ws.calibration_refused)
        self._update_enabled()

    def _virtual_changed(self) -> None:
        virtual = self.lab.is_virtual
        self.stand_in.setVisible(virtual)
        self.stand_in_label.setVisible(virtual)
        if self.lab.virtual_lab is not None:
            self.mode.setCurrentText(self.lab.virtual_lab.mode)

    def _update_enabled(self) -> None:
        running = bool(self.ws.running)
        ok = (self.ws.calibration is not None and self.lab.camera is not None and self.lab.sphere is not None
              and not running
              and (not self.ws.calibration_refused or self.force.isChecked()))
        sel = [self.ws.queue.row(i) for i in self.selected()]
        self.qa_label.setText(qa_text(sel[0]) if len(sel) == 1 else "")
        self.capture_button.setEnabled(ok and bool(sel))
        self.capture_all_button.setEnabled(ok and bool(self.ws.queue.waiting()))
        self.remove_button.setEnabled(bool(sel) and not running)
        self.add_button.setEnabled(bool(self.identifier.text().strip()))
        delivered = [r for r in sel if r.state is OriginalState.DELIVERED]
        self.open_tiff_button.setEnabled(len(delivered) == 1)
        self.open_folder_button.setEnabled(len(delivered) == 1)
        if len(delivered) == 1 and delivered[0].sidecar is not None:
            self.show_delivered(delivered[0])
        self.force.setEnabled(not running)
        why = self._why_not(running)
        self.capture_button.setToolTip(why or "Meter, capture (an HDR bracket when metering asks) and deliver the "
                                              "selected originals with the calibration (Ctrl+Enter).")

    def _why_not(self, running: bool) -> str:
        if running:
            return f"{self.ws.running} is running"
        if self.ws.calibration is None:
            return "calibrate first (Calibrate & capture), or load a saved calibration"
        if self.ws.calibration_refused and not self.force.isChecked():
            return "the calibration does not match the stand (see above)"
        if self.lab.camera is None or self.lab.sphere is None:
            return "connect the LED sphere and the camera (Devices)"
        return ""

    # ------------------------------------------------------------------ capture
    def capture_shortcut(self) -> None:
        if self.capture_button.isEnabled():
            self.capture(self.selected())

    def capture(self, identifiers: list[str]) -> None:
        """Ask what must be decided before anything is lit (another mode, already in the session), then capture
        and deliver the chosen originals in one run of the workflow's queue (app.workflow.day.queue_run)."""
        why = self._why_not(bool(self.ws.running))
        if why:
            self.ctx.errors.report("Capture originals", why)
            return
        self.batch, self._chosen, self._reshoot = list(identifiers), [], {}
        self.ctx.with_session(self._ask_next, "the originals")      # makes one when there is none

    def _ask_next(self) -> None:
        """One question at a time (answered later); an original asked about returns to the batch when it is shot."""
        session = self.lab.session
        while self.batch:
            ident = self.batch.pop(0)
            try:
                row = self.ws.queue.row(ident)
            except KeyError:
                continue
            if self._refused_mode(row):
                return
            takes = original_takes(session, row.original) if session is not None else []
            if takes and ident not in self._reshoot:
                self._ask_reshoot(row, takes)
                return
            self._chosen.append(ident)
        chosen, self._chosen = self._chosen, []
        if chosen:
            self._start([self.ws.queue.row(i) for i in chosen])

    def _refused_mode(self, row: QueueRow) -> bool:
        """The mode rule (app.workflow.stand.mode_rule): an original of another mode than the calibration's is marked
        and
        not shot, unless the technician overrides it (said in its sidecar and QA line)."""
        profile = self.ws.calibration
        problem = mode_problem(row.original.mode, profile.mode, profile.id) if profile is not None else ""
        if not problem or row.identifier in self.mode_overrides:
            return False
        row.state, row.qa = OriginalState.FAILED, f"not shot: {problem}"
        self.ws.queue_changed()
        said = in_window_words(problem).removesuffix(", or choose Capture anyway")
        text = (f"{row.identifier}: {said}.\n\nCapture it anyway with "
                "this calibration (its sidecar and QA line will say so), or leave it for a calibration of its mode?")

        def answer(choice: str) -> None:
            if choice == OVERRIDE:
                self.mode_overrides.add(row.identifier)
                self.batch.insert(0, row.identifier)
            self._ask_next()
        self.ctx.asker.ask("Another mode than the calibration's", text, (OVERRIDE, LEAVE), answer, default=LEAVE)
        return True

    def _ask_reshoot(self, row: QueueRow, takes: list[int]) -> None:
        session = self.lab.session
        text = reshoot_question(row.identifier, takes, session is not None
                                and delivered_sidecar(session, row.original) is not None)

        def answer(choice: str) -> None:
            if choice == CANCEL:
                self.batch, self._chosen = [], []
                return
            self._reshoot[row.identifier] = choice == RESHOOT
            self.batch.insert(0, row.identifier)
            self._ask_next()
        self.ctx.asker.ask("Already in the session", text, (RESHOOT, KEEP, CANCEL), answer, default=CANCEL)

    def _start(self, rows: list[QueueRow]) -> None:
        """One run: the workflow's queue loop (app.workflow.day.queue_run.capture_queue) on the copy stand."""
        profile, lab = self.ws.calibration, self.lab
        if profile is None:
            self.ctx.errors.report("Capture originals", "no calibration is loaded: calibrate, or load one")
            return
        latency = self.ctx.get("capture/latency_s", 0.0, float)
        settings = StandSettings(self.ctx.get("capture/settle_s", SETTLE_S, float), latency if latency > 0 else None,
                                 force=self.force.isChecked(), mode_overrides=frozenset(self.mode_overrides),
                                 resolution=str(self.resolution.currentData()), **self.delivery_options.stand_fields())
        originals, reshoot = [r.original for r in rows], dict(self._reshoot)
        frames, stand_ins = {r.identifier: r.frames for r in rows}, {r.identifier: r.stand_in for r in rows}

        self.current, self._rows, self._brackets = None, rows, {}
        clock = QueueClock([original_plan(profile, r.identifier, r.frames) for r in rows], settle_s=settings.settle_s,
                           overhead_s=self.view.overhead_s)           # one bar and its time left for the queue

        def work(hooks: RunHooks) -> list[QueueOutcome]:
            stand = lab.copy_stand(settings, hooks, stand_in=stand_ins)
            return capture_queue(stand, originals, profile, reshoot=reshoot, frames=frames, clock=clock)
        name = rows[0].identifier if len(rows) == 1 else f"{len(rows)} originals"
        self.run = Run(name, self._plan(), work, clock=clock)
        self.view.start(self.run)

    def _plan(self) -> list[PlannedFrame]:
        """The queue's frames: each original's (app.workflow.day.queue_run.original_plan), with its HDR bracket once
        metered."""
        profile = self.ws.calibration
        if profile is None:
            return []
        return [f for r in self._rows for f in original_plan(profile, r.identifier, r.frames,
                                                             self._brackets.get(r.identifier))]

    def _run_event(self, ev: ProgressEvent) -> None:
        if self.view.seq is not self.run or self.run is None:
            return
        what = ev.data.get(QUEUE_EVENT)
        if what is not None:
            self._queue_event(what, ev)
            return
        row = self.current
        if row is None:
            return
        if "exposures" in ev.data and "light" in ev.data:        # metering planned this light's exposures
            brackets = self._brackets.setdefault(row.identifier, {})
            brackets[ev.data["light"]] = list(ev.data["exposures"])
            calibration = self.ws.calibration
            if calibration is not None and len(brackets) == len(calibration.lights):
                self.view.replan(self._plan())
        if ev.kind in (EventKind.FRAME, EventKind.KEPT) and ev.total and ev.step >= ev.total:
            row.state = OriginalState.CAPTURED              # every frame is in the session; delivering
            self.ws.queue_changed()

    def _queue_event(self, what: str, ev: ProgressEvent) -> None:
        """The queue's own events (app.workflow.day.queue_run): an original starts, or it is delivered."""
        row = self.ws.queue.row(ev.data["original"])
        if what == "start":
            self.current, row.state, row.qa = row, OriginalState.CAPTURING, ""
        elif (outcome := ev.data.get("outcome")) is not None and (outcome.report is not None or outcome.error):
            row.delivered(outcome.report) if outcome.report else setattr(row, "state", OriginalState.FAILED)
            row.qa = outcome.summary() if outcome.error else row.qa      # a failed delivery: the queue went on
            self.view.message.setText(row.qa)
            self.current = None if self.current is row else self.current     # N+1 may be shot by now (issue 41)
        self.ws.queue_changed()
        self.ctx.bus.sessionUpdated.emit()

    def _run_finished(self, run: Run, outcome: str) -> None:
        if run is not self.run:
            return
        row, self.current = self.current, None
        if row is not None and outcome == "cancelled":
            row.state, row.qa = OriginalState.WAITING, "cancelled: its frames so far stay in the session"
        elif row is not None and outcome != "done":
            row.state = OriginalState.FAILED
            row.qa = self.ctx.errors.current[1] if self.ctx.errors.current else "failed"
        elif outcome == "done" and self._rows:
            self.view.message.setText(self._rows[-1].qa)
        self.ws.queue_changed()
        self.ctx.bus.sessionUpdated.emit()

    def show_delivered(self, row: QueueRow) -> None:
        """The Delivered tab (``row``'s cube under the chosen light, loaded in the compute pool) and the Viewer (its
        master); both loaded again when the row was delivered again (Tools -> Re-deliver: the same sidecar path, a
        new QA line)."""
        again = (row.sidecar, row.qa) != self._shown
        if again and ("spectral" in row.files or "channels_1" in row.files):     # the cube, or its channels (full
            self.delivered.show_delivery(row.sidecar)                            # resolution: made on demand)
        self._shown = (row.sidecar, row.qa)
        if row.sidecar is not None:
            self.viewer.show_master(row.sidecar, again=again)

    def _open(self, what: str) -> None:
        sel = [self.ws.queue.row(i) for i in self.selected()]
        row = next((r for r in sel if r.state is OriginalState.DELIVERED), None)
        if row is None:
            return
        path = row.main_file if what == "file" else row.folder
        if path is not None:
            self.ctx.open_path(path)

    def cancel_running(self) -> None:
        self.batch = []
        self.view.cancel()

    def shutdown(self) -> None:
        self.cancel_running()
