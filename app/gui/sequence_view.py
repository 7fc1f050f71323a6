"""Running one capture sequence (app.sequences contract) from the GUI: its plan (frames and estimated time),
a progress bar with time left, pause / resume, cancel, and 'continue' for steps that need a person.

The sequence's ``run()`` generator is iterated in the runner's ``sequences`` thread; every ProgressEvent comes
back as a queued signal. A 'prompt' event pauses the sequence in the worker before it is shown, so the next
step waits for the technician's Continue.
"""
from __future__ import annotations

import logging
import time
from typing import Any, Callable, Optional

from PySide6.QtCore import Qt, Signal
from PySide6.QtWidgets import (QHBoxLayout, QLabel, QProgressBar, QPushButton, QTableWidget, QTableWidgetItem,
                               QVBoxLayout, QWidget)

from app.gui.context import AppContext
from app.gui.viewmodel import format_duration
from app.gui.workers import TaskHandle
from app.sequences.base import PlannedFrame, ProgressEvent, Sequence
from app.workflow.vocabulary import EventKind, format_exposure as format_shutter

log = logging.getLogger(__name__)

DEFAULT_OVERHEAD_S = 1.5          # per frame beyond the exposure (download, write) until one has been measured


def estimate_s(plan: list[PlannedFrame], settle_s: float, overhead_s: float) -> float:
    """Rough time for a plan: every exposure, the light settling before lit frames, and a per-frame overhead."""
    return sum(f.exposure_s + (settle_s if f.light else 0.0) + overhead_s for f in plan)


def drive(seq: Sequence, emit: Callable[[ProgressEvent], None]) -> None:
    """Worker side: iterate the sequence; pause it on a prompt before telling the GUI."""
    for event in seq.run():
        if event.kind == "prompt":
            seq.pause()
        emit(event)


class SequenceView(QWidget):
    """Plan table + summary + progress + controls for one sequence at a time."""

    started = Signal(object)           # the Sequence
    finished = Signal(object, str)     # the Sequence, 'done' | 'cancelled' | 'failed'
    event = Signal(object)             # every ProgressEvent

    def __init__(self, ctx: AppContext, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.ctx = ctx
        self.seq: Optional[Sequence] = None
        self.handle: Optional[TaskHandle] = None
        self.events: list[ProgressEvent] = []
        self.outcome = ""
        self.overhead_s = DEFAULT_OVERHEAD_S
        self.settle_s = 0.2
        self._t_start = 0.0

        self.table = QTableWidget(0, 4)
        self.table.setHorizontalHeaderLabels(["frame", "exposure", "light", "note"])
        self.table.setToolTip("Every frame the sequence will take, in order, before anything moves.")
        self.table.verticalHeader().setDefaultSectionSize(20)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.summary = QLabel("")
        self.summary.setWordWrap(True)
        self.progress = QProgressBar()
        self.progress.setRange(0, 1000)
        self.progress.setToolTip("Frames done of frames planned.")
        self.time_left = QLabel("")
        self.message = QLabel("")
        self.message.setWordWrap(True)
        self.start_button = QPushButton("Start")
        self.start_button.setToolTip("Run the planned frames (Ctrl+Enter). The lights are switched off at the end, "
                                     "on cancel and on any error.")
        self.pause_button = QPushButton("Pause")
        self.pause_button.setCheckable(True)
        self.pause_button.setToolTip("Stop after the current frame; press again to go on.")
        self.pause_button.toggled.connect(self._pause_toggled)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop after the current frame and switch the lights off (Esc). Frames taken "
                                      "so far stay in the session.")
        self.cancel_button.clicked.connect(self.cancel)
        self.continue_button = QPushButton("Continue")
        self.continue_button.setToolTip("Press when you have done what the message asks.")
        self.continue_button.clicked.connect(self._continue)
        self.continue_button.hide()
        buttons = QHBoxLayout()
        for w in (self.start_button, self.pause_button, self.cancel_button, self.continue_button):
            buttons.addWidget(w)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.table, 1)
        lay.addWidget(self.summary)
        lay.addLayout(buttons)
        lay.addWidget(self.progress)
        row = QHBoxLayout()
        row.addWidget(self.message, 1)
        row.addWidget(self.time_left)
        lay.addLayout(row)
        self._set_running(False)

    # ------------------------------------------------------------------ plan
    def show_plan(self, plan: list[PlannedFrame], title: str = "") -> None:
        self.table.setRowCount(len(plan))
        for r, f in enumerate(plan):
            for c, text in enumerate((f.role, format_shutter(f.exposure_s), f.light or "off", f.note)):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                self.table.setItem(r, c, item)
        self.table.resizeColumnsToContents()
        total = estimate_s(plan, self.settle_s, self.overhead_s)
        lit = sum(f.exposure_s + self.settle_s for f in plan if f.light)
        self.summary.setText(f"{title + ': ' if title else ''}{len(plan)} frames, about {format_duration(total)} "
                             f"(light on about {format_duration(lit)} in all)")
        self.planned = plan

    def clear_plan(self, why: str = "") -> None:
        self.table.setRowCount(0)
        self.summary.setText(why)

    # ------------------------------------------------------------------ run
    @property
    def running(self) -> bool:
        return self.handle is not None and self.handle.running

    def start(self, seq: Sequence) -> None:
        if self.running:
            self.ctx.errors.report("Start a sequence", "a sequence is already running: wait for it or cancel it")
            return
        self.seq = seq
        self.events = []
        self.outcome = ""
        self.show_plan(seq.plan(), seq.name)
        self.progress.setValue(0)
        self.time_left.setText("")
        self.message.setText(f"{seq.name}: starting …")
        self._t_start = time.monotonic()
        self._set_running(True)
        self.started.emit(seq)
        self.ctx.bus.sequenceStarted.emit(seq.name)
        self.handle = self.ctx.runner.submit(lambda emit: drive(seq, emit), pool="sequences", name=seq.name,
                                             pass_emit=True, on_event=self._on_event, on_error=self._on_error,
                                             on_finished=self._on_finished, on_cancel=seq.cancel)

    def _on_event(self, ev: ProgressEvent) -> None:
        self.events.append(ev)
        if ev.kind == "cancelled":
            self.outcome = "cancelled"
            self.message.setText(ev.message)
        elif ev.kind == "prompt":
            self.message.setText(f"<b>{ev.message}</b>")
            self.continue_button.show()
            self.pause_button.setEnabled(False)
        else:
            if ev.total:
                self.progress.setValue(int(round(1000 * ev.fraction)))
            self.message.setText(ev.message)
            self.time_left.setText(f"time left {format_duration(ev.time_left_s)}"
                                   if ev.time_left_s is not None else "")
        self.event.emit(ev)

    def _on_error(self, exc: BaseException) -> None:
        self.outcome = "failed"
        name = self.seq.name if self.seq else "sequence"
        self.message.setText(f"{name} stopped: {exc} (lights off)")
        self.ctx.errors.report(f"{name[:1].upper()}{name[1:]} stopped", exc)

    def _on_finished(self) -> None:
        seq = self.seq
        if not self.outcome:
            self.outcome = "done"
            self.progress.setValue(1000)
            self.time_left.setText("")
            frames = [e for e in self.events if e.kind == "frame"]
            if frames and seq is not None:
                spent = time.monotonic() - self._t_start
                exposure = sum(float(e.data.get("exposure_s") or 0.0) for e in frames)
                self.overhead_s = max(0.05, (spent - exposure) / len(frames) - self.settle_s)
            kept = sum(e.kind == EventKind.KEPT.value for e in self.events)
            self.message.setText(f"{seq.name if seq else 'sequence'} done: {len(frames)} new, {kept} kept "
                                 "(already in the session)" if kept else
                                 f"{seq.name if seq else 'sequence'} done: {len(frames)} frames saved")
        self._set_running(False)
        self.continue_button.hide()
        self.pause_button.setChecked(False)
        self.finished.emit(seq, self.outcome)
        self.ctx.bus.sequenceFinished.emit(seq.name if seq else "", self.outcome)

    # ------------------------------------------------------------------ controls
    def cancel(self) -> None:
        if self.running and self.seq is not None:
            self.message.setText(f"cancelling {self.seq.name} after this frame …")
            self.seq.cancel()
            self.continue_button.hide()

    def _pause_toggled(self, paused: bool) -> None:
        if self.seq is None or not self.running:
            return
        if paused:
            self.seq.pause()
            self.pause_button.setText("Resume")
            self.message.setText(f"{self.seq.name}: paused after the current frame")
        else:
            self.seq.resume()
            self.pause_button.setText("Pause")

    def _continue(self) -> None:
        self.continue_button.hide()
        self.pause_button.setEnabled(True)
        if self.seq is not None:
            self.seq.resume()

    def _set_running(self, running: bool) -> None:
        self.start_button.setEnabled(not running)
        self.pause_button.setEnabled(running)
        self.cancel_button.setEnabled(running)
        if not running:
            self.pause_button.setText("Pause")

    def results(self) -> Any:
        return self.seq
