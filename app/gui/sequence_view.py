"""Running one capture sequence (app.sequences contract) or a whole CopyStand call (core.engine.Run) from
the GUI: its plan (frames and estimated time; frames already in the session ticked), a progress bar with time
left, pause / resume, cancel, 'continue' for steps that need a person, and the last frame saved.

The run is executed by the run engine (core.engine.Run.execute) in the runner's ``sequences`` thread; every
ProgressEvent comes back as a queued signal. A 'prompt' event pauses the run in the worker before it is shown, so
the next step waits for Continue. Starting a run ends the light held by hand (the manual and the framing light);
the engine starts the run from dark and ends it with the light off (read back).
"""
from __future__ import annotations

import logging
import time
from collections.abc import Sequence as Seq
from typing import Any

from PySide6.QtCore import Qt, Signal
from PySide6.QtGui import QColor
from PySide6.QtWidgets import (
    QHBoxLayout,
    QLabel,
    QProgressBar,
    QPushButton,
    QSplitter,
    QTableWidget,
    QTableWidgetItem,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.frame_preview import FramePreview
from dualrgb.app.gui.units import shutter, time_left_s
from dualrgb.app.gui.viewmodel import format_duration
from dualrgb.app.gui.wording import in_window_words
from dualrgb.app.gui.workers import TaskHandle
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.workflow.day.queue_clock import QueueClock
from dualrgb.app.workflow.phase_costs import PhaseClock
from dualrgb.app.workflow.stand.run_phases import DEFAULT_OVERHEAD_S, plan_seconds
from dualrgb.core.engine import RUN_PROGRESS
from dualrgb.core.engine import Run as EngineRun
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

OVERHEAD_KEY = "runs/frame_overhead_s"     # the last measured one, for every view and the next start
Run = EngineRun
DONE_MARK = "✓"
DONE_COLOUR = QColor("#e8f5e9")


def frame_overhead_s(times: list[tuple[float, float]], settle_s: float) -> float | None:
    """A frame's time beyond its exposure and settle, measured: the median over consecutive new frames of a run
    (``times``: the start, then each frame's (monotonic time, exposure)); None under 3 frames. The median leaves
    out the pauses between a run's parts (processing, a prompt)."""
    if len(times) < 4:
        return None
    steps = sorted(t1 - t0 - exp - settle_s for (t0, _), (t1, exp) in zip(times, times[1:], strict=False))
    return max(0.05, steps[len(steps) // 2])


class SequenceView(QWidget):
    """Plan table + summary + progress + controls + last frame, for one run at a time."""

    started = Signal(object)           # the run
    finished = Signal(object, str)     # the run, 'done' | 'cancelled' | 'failed'
    run_event = Signal(object)         # every ProgressEvent (not "event": QWidget.event() is a virtual)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None, *, preview: bool = True):
        super().__init__(parent)
        self.ctx = ctx
        self.seq: Run | None = None
        self.handle: TaskHandle | None = None
        self.events: list[ProgressEvent] = []
        self.outcome = ""
        self.overhead_s = ctx.get(OVERHEAD_KEY, DEFAULT_OVERHEAD_S, float)     # measured on the last run (any view)
        self.settle_s = 0.2
        self._frame_times: list[tuple[float, float]] = []          # (monotonic time, exposure) of each new frame
        self.planned: list[PlannedFrame] = []
        self._t_start = 0.0
        self._ticked = 0
        self._build_table()
        self._build_controls()
        self.preview = FramePreview(ctx) if preview else None
        self._layout()
        self._set_running(False)

    # ------------------------------------------------------------------ builders
    def _build_table(self) -> None:
        self.table = QTableWidget(0, 5)
        self.table.setHorizontalHeaderLabels(["", "frame", "exposure", "light", "note"])
        self.table.setToolTip("Every frame the run will take, in order, before anything moves; ✓: in the session "
                              "(saved now, or already there and kept).")
        self.table.verticalHeader().setDefaultSectionSize(20)
        self.table.horizontalHeader().setStretchLastSection(True)
        self.summary = QLabel("")
        self.summary.setWordWrap(True)

    def _build_controls(self) -> None:
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
        self.pause_button.setToolTip("Stop after the current frame (the light is already off then); press again "
                                     "to go on.")
        self.pause_button.toggled.connect(self._pause_toggled)
        self.cancel_button = QPushButton("Cancel")
        self.cancel_button.setToolTip("Stop after the current frame and switch the lights off (Esc). Frames taken "
                                      "so far stay in the session.")
        self.cancel_button.clicked.connect(self.cancel)
        self.continue_button = QPushButton("Continue")
        self.continue_button.setToolTip("Press when you have done what the message asks.")
        self.continue_button.clicked.connect(self._continue)
        self.continue_button.hide()

    def _layout(self) -> None:
        buttons = QHBoxLayout()
        for w in (self.start_button, self.pause_button, self.cancel_button, self.continue_button):
            buttons.addWidget(w)
        top = QWidget()
        tl = QVBoxLayout(top)
        tl.setContentsMargins(0, 0, 0, 0)
        tl.addWidget(self.table, 1)
        tl.addWidget(self.summary)
        tl.addLayout(buttons)
        tl.addWidget(self.progress)
        row = QHBoxLayout()
        row.addWidget(self.message, 1)
        row.addWidget(self.time_left)
        tl.addLayout(row)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        if self.preview is None:
            lay.addWidget(top)
            return
        split = QSplitter(Qt.Orientation.Vertical)
        split.addWidget(top)
        split.addWidget(self.preview)
        split.setStretchFactor(0, 3)
        split.setStretchFactor(1, 2)
        lay.addWidget(split)

    # ------------------------------------------------------------------ plan
    def show_plan(self, plan: list[PlannedFrame], title: str = "", done: Seq[bool] = ()) -> None:
        """The planned frames; ``done[i]`` ticks row i (already in the session)."""
        self.table.setRowCount(len(plan))
        for r, f in enumerate(plan):
            texts = ("", f.role, shutter(f.exposure_s), self.ctx.workspace.light_text(f.light) or "off", f.note)
            for c, text in enumerate(texts):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                self.table.setItem(r, c, item)
            if r < len(done) and done[r]:
                self.tick(r, "in the session")
        self.table.resizeColumnsToContents()
        total, measured = self._expected_total(plan)
        lit = sum(f.exposure_s + self.settle_s for f in plan if f.light)
        n_done = sum(bool(d) for d in done)
        already = f"; {n_done} already in the session" if n_done else ""
        self.summary.setText(f"{title + ': ' if title else ''}{len(plan)} frames{already}, about "
                             f"{format_duration(total)}{' as measured on earlier runs' if measured else ''} (light on "
                             f"about {format_duration(lit)} in all)")
        self.planned = plan

    def _expected_total(self, plan: list[PlannedFrame]) -> tuple[float, bool]:
        """The run's time and whether it is measured: its phases' costs when its clock has them all
        (app.workflow.phase_costs: processing included; a queue's: app.workflow.day.queue_clock), else the plan's
        frames' rough time."""
        clock = getattr(self.seq, "clock", None)
        measured = clock.expected_total_s() if isinstance(clock, (PhaseClock, QueueClock)) else None
        if measured is not None:
            return measured, True
        return plan_seconds(plan, self.settle_s, self.overhead_s), False

    def replan(self, plan: list[PlannedFrame]) -> None:
        """The plan changed while running (an HDR bracket metered): rows already done stay ticked."""
        done = self._ticked
        self.show_plan(plan, self.seq.name if self.seq else "")
        for r in range(done):
            self.tick(r, "saved now")

    def clear_plan(self, why: str = "") -> None:
        self.table.setRowCount(0)
        self.summary.setText(why)
        self.planned = []

    def tick(self, row: int, how: str) -> None:
        if not 0 <= row < self.table.rowCount():
            return
        mark = self.table.item(row, 0)
        if mark is None:
            return
        mark.setText(DONE_MARK)
        mark.setToolTip(how)
        for c in range(self.table.columnCount()):
            item = self.table.item(row, c)
            if item is not None:
                item.setBackground(DONE_COLOUR)

    def ticked_rows(self) -> list[int]:
        return [r for r in range(self.table.rowCount())
                if (item := self.table.item(r, 0)) is not None and item.text() == DONE_MARK]

    # ------------------------------------------------------------------ run
    @property
    def running(self) -> bool:
        return self.handle is not None and self.handle.running

    def start(self, seq: Run, done: Seq[bool] = ()) -> None:
        if self.running:
            self.ctx.errors.report("Start a sequence", "a sequence is already running: wait for it or cancel it")
            return
        self.seq = seq
        self.events = []
        self.outcome = ""
        self._ticked = 0
        self.show_plan(seq.plan(), seq.name, done)
        self.progress.setValue(0)
        self.time_left.setText("")
        self.ctx.errors.clear()                     # an earlier run's error is not this one's (issue 42)
        self.message.setText(f"{seq.name}: starting …")
        self._t_start = time.monotonic()
        self._frame_times = [(self._t_start, 0.0)]
        self.overhead_s = self.ctx.get(OVERHEAD_KEY, self.overhead_s, float)
        self._set_running(True)
        self.started.emit(seq)
        self.ctx.workspace.set_running(seq.name)
        self.ctx.bus.sequenceStarted.emit(seq.name)
        self.ctx.lab.stop_light()               # the light held by hand ends (dark, read back) before the run
        self.handle = self.ctx.runner.submit(seq.execute, pool="sequences", name=seq.name,
                                             pass_emit=True, on_event=self._on_event, on_error=self._on_error,
                                             on_finished=self._on_finished, on_cancel=seq.cancel)

    def _on_event(self, ev: ProgressEvent) -> None:
        self.events.append(ev)
        if ev.kind is EventKind.FRAME:
            self._frame_times.append((time.monotonic(), float(ev.data.get("exposure_s") or 0.0)))
        if ev.kind is EventKind.CANCELLED:
            self.outcome = "cancelled"
            self.message.setText(ev.message)
        elif ev.kind is EventKind.PROMPT:
            self.message.setText(f"<b>{ev.message}</b>")
            self.continue_button.show()
            self.pause_button.setEnabled(False)
        else:
            self._show_progress(ev)
        if "plan" in ev.data:
            self.show_plan(ev.data["plan"], self.seq.name if self.seq else "")
            self._ticked = 0
        if ev.kind in (EventKind.FRAME, EventKind.KEPT) or ev.data.get("role") == "metering":
            self.tick(self._ticked, "already in the session" if ev.kind is EventKind.KEPT else "saved now")
            self._ticked += 1
            self.ctx.bus.frameSaved.emit()
        self._preview(ev)
        self.run_event.emit(ev)

    def _show_progress(self, ev: ProgressEvent) -> None:
        stand = getattr(self.seq, "progress_events", False)
        if stand and not ev.data.get(RUN_PROGRESS):
            return                                  # a CopyStand run's inner events count their own sequence
        if ev.total:
            self.progress.setValue(int(round(1000 * ev.fraction)))
        self.message.setText(ev.message)
        left = ev.time_left_s if ev.time_left_s is not None else \
            time_left_s(time.monotonic() - self._t_start, ev.fraction)
        self.time_left.setText(f"time left {format_duration(left)}" if left is not None else "")

    def _preview(self, ev: ProgressEvent) -> None:
        entry = ev.data.get("entry")
        session = self.ctx.lab.session
        if self.preview is None or entry is None or session is None:
            return
        found = next((e for e in reversed(session.entries()) if e.seq == entry), None)
        if found is not None:
            t = found.exposure_s or 0.0
            label = LightSource.from_dict(found.light).label() if found.light else ""
            longer = any(f.role == found.role and f.light == label and f.exposure_s < 0.99 * t for f in self.planned)
            self.preview.show_file(session.file_path(found), found.role, bracket_long=longer)

    def _on_error(self, exc: BaseException) -> None:
        self.outcome = "failed"
        name = self.seq.name if self.seq else "sequence"
        self.message.setText(f"{name} stopped: {in_window_words(str(exc))} (lights off)")
        self.ctx.errors.report(f"{name[:1].upper()}{name[1:]} stopped", exc)

    def _on_finished(self) -> None:
        seq = self.seq
        if not self.outcome:
            self.outcome = "done"
            self._done_message(seq)
        self._set_running(False)
        self.time_left.setText("")                 # never a stale time left after a run ends or is cancelled
        self.continue_button.hide()
        self.pause_button.setChecked(False)
        self.ctx.workspace.set_running("")
        self.finished.emit(seq, self.outcome)
        self.ctx.bus.sequenceFinished.emit(seq.name if seq else "", self.outcome)

    def _done_message(self, seq: Any) -> None:
        self.progress.setValue(1000)
        self.time_left.setText("")
        frames = [e for e in self.events if e.kind is EventKind.FRAME]
        kept = sum(e.kind is EventKind.KEPT for e in self.events)
        measured = frame_overhead_s(self._frame_times, self.settle_s)
        if measured is not None:                    # the next plans are estimated from this run's frames
            self.overhead_s = measured
            self.ctx.set(OVERHEAD_KEY, measured)
        name = seq.name if seq else "sequence"
        extra = seq.summary() if seq else ""                        # a one-plan run's own one-line summary
        self.message.setText(f"{name} done: {len(frames)} new, {kept} kept" + (f"; {extra}" if extra else ""))
        self.ctx.errors.clear(f"{name[:1].upper()}{name[1:]} stopped")

    # ------------------------------------------------------------------ controls
    def cancel(self) -> None:
        if self.running and self.seq is not None:
            self.message.setText(f"cancelling {self.seq.name} …")
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
