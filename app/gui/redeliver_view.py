"""Re-deliver a session's originals with another calibration: ``dualrgb process SESSION [--calibration FILE]
[--force] [--ppi N] [--render-illuminant L] [--resolution full|half]`` in the window (issue 30).

It calls what the command calls (app.workflow.delivery.redelivery: ``newest_by_mode`` without a calibration, the mode
rule
and ``force`` with one; every original's current deliverables move to its ``previous/`` folder as its new set is
swapped in) on the compute thread, with progress and Cancel (checked between originals and between the bands of
one: an original cut short keeps its previous set, app.workflow.delivery.delivery_folder.staged). The session is opened
read-only, as the command does; it does not start while a sequence is writing to the session. The results are
listed one row per original: delivered (its QA line), not delivered (why), refused by the mode rule, or - after
Cancel - not done (it keeps its previous set); the rows delivered before Cancel stay listed. The Originals queue
takes the new QA lines and calibration of the current session's originals delivered again (issue 42).
"""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path

from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.stand_options import MAX_PPI, PPI_KEY, given, number_spin, render_combo, resolution_combo
from dualrgb.app.gui.widgets import PathLabel
from dualrgb.app.gui.workers import TaskHandle
from dualrgb.app.workflow.delivery.redelivery import Redelivered
from dualrgb.common.progress import Cancelled, CancelToken, ProgressCallback

log = logging.getLogger(__name__)

NEWEST, CURRENT, FILE = "newest", "current", "file"
COLUMNS = ("identifier", "result", "QA line / reason")
DELIVERED, NOT_DELIVERED, REFUSED, NOT_DONE = "delivered", "not delivered", "refused (mode)", "not done"
NOT_DONE_WHY = "cancelled before it was delivered again: it keeps its previous deliverables"
RUN_NAME = "re-delivery"


@dataclass
class RedeliveryRequest:
    """What ``dualrgb process`` is given: the session, the calibration (None: the session's newest of each mode),
    and its options."""

    session: Path
    calibration: Path | None
    use_current: bool = False
    force: bool = False
    ppi: float | None = None
    render_illuminant: str = "D65"
    resolution: str = "full"


@dataclass
class RedeliveryResult:
    """What the re-delivery did (filled as it goes on the compute thread, read when it has ended): a cancelled one
    still lists the originals delivered again, and the rest as not done."""

    done: Redelivered = field(default_factory=Redelivered)
    cancelled: bool = False

    def rows(self) -> list[tuple[str, str, str]]:
        d = self.done
        rows = ([(x.original.identifier, DELIVERED, x.qa.text()) for x in d.delivered]
                + [(u.identifier, NOT_DELIVERED, u.reason) for u in d.undelivered]
                + [(line.partition(":")[0], REFUSED, line) for line in d.refused])
        return rows + ([(i, NOT_DONE, NOT_DONE_WHY) for i in d.not_done()] if self.cancelled else [])

    def summary(self) -> str:
        d = self.done
        text = (f"{len(d.delivered)} delivered, {len(d.undelivered)} not delivered, {len(d.refused)} refused by the "
                "mode rule")
        if self.cancelled:
            return f"cancelled: {text}, {len(d.not_done())} not done (they keep their previous deliverables)"
        return text


def run_redelivery(request: RedeliveryRequest, current: object, progress: ProgressCallback | None,
                   cancel: CancelToken | None, out: RedeliveryResult | None = None) -> RedeliveryResult:
    """The work ``dualrgb process`` does (app.commands.process.main without the printing); on the compute
    thread. ``current``: the window's calibration (a CalibrationProfile) when ``request.use_current``; ``out``
    is filled as it goes (what a cancelled run did)."""
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile, load_profile
    from dualrgb.app.workflow.delivery.redelivery import newest_by_mode, redeliver
    from dualrgb.app.workflow.stand.folders import open_session

    profiles: CalibrationProfile | dict[str, CalibrationProfile]
    out = out if out is not None else RedeliveryResult()
    with open_session(request.session, readonly=True) as session:
        if request.use_current:
            if not isinstance(current, CalibrationProfile):
                raise ValueError("no calibration is loaded in the window: calibrate, load one, or choose a file")
            profiles = current
        else:
            profiles = load_profile(request.calibration) if request.calibration else newest_by_mode(session)
        redeliver(session, profiles, session.path / "deliverables", ppi=request.ppi, progress=progress,
                  cancel=cancel, render_illuminant=request.render_illuminant, force=request.force,
                  resolution=request.resolution, tally=out.done)
    if not (out.done.delivered or out.done.undelivered or out.done.refused):
        raise ValueError(f"{request.session}: no originals to deliver again")
    return out


class RedeliverView(QWidget):
    """The Tools panel's *Re-deliver* tab."""

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab, self.ws = ctx, ctx.lab, ctx.workspace
        self.chosen_session: Path | None = None
        self.calibration_file: Path | None = None
        self.handle: TaskHandle | None = None
        self.result: RedeliveryResult | None = None
        self.request_running: RedeliveryRequest | None = None
        self.outcome = ""                           # '' while running / before; 'done' | 'cancelled' | 'failed'
        self._build()
        self.lab.sessionChanged.connect(self._update)
        self.ws.calibrationChanged.connect(self._update)
        self.ws.runningChanged.connect(lambda _n: self._update())
        self._update()

    def _build(self) -> None:
        self.session_label = PathLabel("")
        self.session_button = QPushButton("Other session…")
        self.session_button.setToolTip("Re-deliver another session's originals (default: the current session).")
        self.session_button.clicked.connect(self._ask_session)
        self.calibration = QComboBox()
        self.calibration.addItem("the session's newest of each original's mode", NEWEST)
        self.calibration.addItem("the calibration loaded in the window", CURRENT)
        self.calibration.addItem("a calibration file…", FILE)
        self.calibration.setToolTip("None chosen: each original with the session's newest "
                                    "calibration of its mode; with one, originals of its other mode are refused "
                                    "unless 'also the other mode' is ticked.")
        self.calibration.activated.connect(self._calibration_chosen)
        self.calibration.currentIndexChanged.connect(lambda _i: self._update())
        self.file_label = PathLabel("")
        self.force = QCheckBox("also originals of the other mode (said in the sidecar and QA line)")
        self.resolution, self.render_light = resolution_combo(self.ctx), render_combo(self.ctx)
        self.ppi = number_spin(self.ctx, PPI_KEY, MAX_PPI, "\u00a0ppi", "the calibration's",
                               "Sampling written into the deliverables.")
        self.start_button = QPushButton("Re-deliver")
        self.start_button.clicked.connect(self.start)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.clicked.connect(self.cancel_running)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.table = QTableWidget(0, len(COLUMNS))
        self.table.setHorizontalHeaderLabels(list(COLUMNS))
        self.table.horizontalHeader().setStretchLastSection(True)
        self._lay_out()

    def _lay_out(self) -> None:
        form = QFormLayout()
        session_row = QHBoxLayout()
        session_row.addWidget(self.session_label, 1)
        session_row.addWidget(self.session_button)
        form.addRow("Session", session_row)
        form.addRow("Calibration", self.calibration)
        form.addRow("", self.file_label)
        form.addRow(self.force)
        form.addRow("Deliver at", self.resolution)
        form.addRow("Rendering light", self.render_light)
        form.addRow("Sampling", self.ppi)
        buttons = QHBoxLayout()
        buttons.addWidget(self.start_button)
        buttons.addWidget(self.cancel_button)
        buttons.addWidget(self.progress, 1)
        layout = QVBoxLayout(self)
        note = QLabel("Every original of the session is delivered again from its raw frames; its "
                      "current deliverables move to its previous/ folder.")
        note.setWordWrap(True)
        layout.addWidget(note)
        layout.addLayout(form)
        layout.addLayout(buttons)
        layout.addWidget(self.message)
        layout.addWidget(self.table, 1)

    # ------------------------------------------------------------------ choices
    def session_path(self) -> Path | None:
        if self.chosen_session is not None:
            return self.chosen_session
        return self.lab.session.path if self.lab.session is not None else None

    def _ask_session(self) -> None:
        path = QFileDialog.getExistingDirectory(self, "Session to re-deliver", str(self.ctx.captures_dir))
        if path:
            self.choose_session(Path(path))

    def choose_session(self, path: Path | None) -> None:
        self.chosen_session = path
        self._update()

    def _calibration_chosen(self, _index: int) -> None:
        if self.calibration.currentData() == FILE:
            path, _ = QFileDialog.getOpenFileName(self, "Calibration", str(self.ctx.captures_dir),
                                                  "Calibration (cal-*.json *.json)")
            if path:
                self.choose_calibration_file(Path(path))

    def choose_calibration_file(self, path: Path) -> None:
        self.calibration_file = path
        self.calibration.setCurrentIndex(self.calibration.findData(FILE))
        self._update()

    def request(self) -> RedeliveryRequest:
        session = self.session_path()
        if session is None:
            raise ValueError("no session: open or make one (Calibrate & capture), or choose one here")
        which = self.calibration.currentData()
        if which == FILE and self.calibration_file is None:
            raise ValueError("choose the calibration file first")
        return RedeliveryRequest(session, self.calibration_file if which == FILE else None,
                                 use_current=which == CURRENT, force=self.force.isChecked(), ppi=given(self.ppi),
                                 render_illuminant=str(self.render_light.currentData()),
                                 resolution=str(self.resolution.currentData()))

    # ------------------------------------------------------------------ run
    def _why_not(self) -> str:
        if self.handle is not None:
            return "re-delivering"
        if self.ws.running:
            return f"{self.ws.running} is running: it writes to the session"
        if self.session_path() is None:
            return "no session yet: open or make one, or choose one here"
        which = self.calibration.currentData()
        if which == CURRENT and self.ws.calibration is None:
            return "no calibration loaded in the window"
        if which == FILE and self.calibration_file is None:
            return "choose the calibration file"
        return ""

    def _update(self) -> None:
        path = self.session_path()
        self.session_label.set_path(str(path) if path is not None else "none yet")
        self.file_label.set_path(str(self.calibration_file) if self.calibration.currentData() == FILE
                                 and self.calibration_file else "")
        why = self._why_not()
        self.start_button.setEnabled(not why)
        self.start_button.setToolTip(why or "Deliver every original of the session again with these choices.")
        self.cancel_button.setEnabled(self.handle is not None)

    def start(self) -> None:
        why = self._why_not()
        try:
            if why:
                raise ValueError(why)
            request = self.request()
        except ValueError as exc:
            self.ctx.errors.report("Re-deliver", exc)
            return
        current, result = self.ws.calibration, RedeliveryResult()
        self.outcome, self.result, self.request_running = "", result, request
        self.table.setRowCount(0)
        self.progress.setValue(0)
        self.message.setText(f"re-delivering {request.session.name} …")
        self.handle = self.ctx.runner.submit(
            lambda progress, cancel: run_redelivery(request, current, progress, cancel, result), pool="compute",
            name="re-deliver", pass_progress=True, pass_cancel=True, on_result=self._done, on_error=self._failed,
            on_progress=self._progress, on_finished=self._finished)
        self.ws.set_running(RUN_NAME)            # the session's deliverables are being written: sequences wait
        self._update()

    def _progress(self, fraction: float, message: str) -> None:
        self.progress.setValue(int(round(1000 * fraction)))
        self.message.setText(message)

    def _done(self, result: RedeliveryResult) -> None:
        self.outcome = "done"
        self._show(result)
        self.ctx.errors.clear("Re-deliver")

    def _failed(self, exc: BaseException) -> None:
        if isinstance(exc, Cancelled) and self.result is not None:
            self.outcome, self.result.cancelled = "cancelled", True
            self._show(self.result)              # the originals delivered before Cancel keep their new files
            return
        self.outcome = "failed"
        self.message.setText(f"failed: {exc}")
        self.ctx.errors.report("Re-deliver", exc)

    def _show(self, result: RedeliveryResult) -> None:
        """The table (one row per original: delivered, not delivered, refused, not done) and the summary; the
        Originals queue takes the new QA lines of the current session's originals delivered again."""
        self.table.setRowCount(0)
        for row in result.rows():
            r = self.table.rowCount()
            self.table.insertRow(r)
            for c, text in enumerate(row):
                self.table.setItem(r, c, QTableWidgetItem(text))
        self.message.setText(result.summary())
        log.info("re-delivered: %s", result.summary())
        session, request = self.lab.session, self.request_running
        if session is None or request is None or Path(session.path).resolve() != request.session.resolve():
            return                               # another session's originals: not the queue's
        for delivery in result.done.delivered:
            try:
                self.ws.queue.row(delivery.original.identifier).redelivered(delivery)
            except KeyError:
                continue
        self.ws.queue_changed()

    def _finished(self) -> None:
        self.handle = None
        if self.ws.running == RUN_NAME:
            self.ws.set_running("")
        self._update()
        self.ctx.bus.sessionUpdated.emit()

    def cancel_running(self) -> None:
        if self.handle is not None:
            self.handle.cancel()
            self.message.setText("cancelling …")

    def shutdown(self) -> None:
        self.cancel_running()
