"""The workflow guide, always visible beside the panels: Connect -> Calibrate -> Originals -> Deliver, each step
with what is done (coverage such as "darks 2/4 exposures", the calibration's age and errors, the queue) and a
warning when something needs attention (a new HDR plan the calibration does not cover, a calibration that does
not match the stand, a failed original). Clicking a step brings its panel forward.

The state comes from dualrgb.app.workflow.day.day.day_checklist (Qt-free); this widget only draws it, refreshed
(coalesced)
whenever the devices, the session, the workspace or a running sequence change.
"""
from __future__ import annotations

import logging

from PySide6.QtCore import Qt, QTimer, Signal
from PySide6.QtWidgets import QFrame, QLabel, QPushButton, QVBoxLayout, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.workflow.day.day import DayState, DayStep, GuideStep, StepState, day_checklist

log = logging.getLogger(__name__)

STATE_LOOK = {StepState.DONE: ("✓", "#2e7d32", "#e8f5e9"), StepState.ACTIVE: ("▶", "#1565c0", "#e3f2fd"),
              StepState.TODO: ("○", "#757575", "#fafafa"), StepState.WARNING: ("⚠", "#b26a00", "#fff8e1")}
STEP_PANEL = {DayStep.CONNECT: "devices", DayStep.CALIBRATE: "capture", DayStep.ORIGINALS: "originals",
              DayStep.DELIVER: "originals"}
STEP_TIPS = {DayStep.CONNECT: "Connect the LED sphere and the camera (Devices). A session folder is made in the "
                              "captures folder when you first calibrate, run or capture (or press New session in "
                              "Calibrate & capture).",
             DayStep.CALIBRATE: "Once a day or when something changes: darks, flats, the training and test targets "
                                "and the matrix (Calibrate & capture: Calibrate; it makes a session if there is "
                                "none). Save it to reuse it.",
             DayStep.ORIGINALS: "Add each original with its identifier and capture it with the calibration (HDR "
                                "when metering asks for it).",
             DayStep.DELIVER: "Each captured original's archival TIFFs and sidecar are written at once to "
                              "<session>/deliverables/<identifier>/."}


class StepCard(QFrame):
    def __init__(self, step: DayStep, on_click, parent: QWidget | None = None):
        super().__init__(parent)
        self.step = step
        self.setFrameShape(QFrame.Shape.StyledPanel)
        self.setCursor(Qt.CursorShape.PointingHandCursor)
        self.setToolTip(STEP_TIPS[step] + "\nClick to open the panel.")
        self._on_click = on_click
        self.title = QLabel()
        self.detail = QLabel()
        self.detail.setWordWrap(True)
        self.detail.setTextFormat(Qt.TextFormat.PlainText)
        lay = QVBoxLayout(self)
        lay.setContentsMargins(6, 4, 6, 4)
        lay.addWidget(self.title)
        lay.addWidget(self.detail)
        self.state = StepState.TODO

    def show_step(self, step: GuideStep, number: int) -> None:
        self.state = step.state
        mark, colour, background = STATE_LOOK[step.state]
        self.title.setText(f"<span style='color:{colour}; font-weight:bold'>{mark} {number}. {step.title}</span>")
        self.detail.setText("\n".join(step.lines))
        self.setStyleSheet(f"StepCard {{ background:{background}; border:1px solid {colour}; border-radius:6px }}")

    def mousePressEvent(self, event) -> None:
        self._on_click(self.step)
        super().mousePressEvent(event)


class WorkflowGuide(QWidget):
    refreshed = Signal()                       # the steps were drawn again (app.gui.next_action follows them)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.steps: list[GuideStep] = []
        self.cards = {s: StepCard(s, self._clicked) for s in DayStep}
        lay = QVBoxLayout(self)
        lay.setContentsMargins(4, 4, 4, 4)
        for card in self.cards.values():
            lay.addWidget(card)
        self.open_button = QPushButton("Open the deliverables folder")
        self.open_button.setToolTip("Show <session>/deliverables in the file manager.")
        self.open_button.clicked.connect(self._open_deliverables)
        lay.addWidget(self.open_button)
        lay.addStretch(1)
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(60)
        self._timer.timeout.connect(self.refresh)
        self._connect_signals()
        self.refresh()

    def _connect_signals(self) -> None:
        lab, ws, bus = self.ctx.lab, self.ctx.workspace, self.ctx.bus
        for sig in (lab.sphereChanged, lab.cameraChanged, lab.sessionChanged, ws.planChanged, ws.lightsChanged,
                    ws.calibrationChanged, ws.queueChanged, bus.sessionUpdated, bus.frameSaved):
            sig.connect(self.schedule)
        bus.sequenceFinished.connect(lambda *_: self.schedule())

    def schedule(self, *_args) -> None:
        """Refresh soon (many changes in a row make one refresh)."""
        if not self._timer.isActive():
            self._timer.start()

    def state(self) -> DayState:
        lab, ws = self.ctx.lab, self.ctx.workspace
        session = lab.session
        return DayState(sphere=lab.sphere_port if lab.sphere is not None else "",
                        camera=lab.camera_name if lab.camera is not None else "", session=session,
                        plan=ws.planned_exposures(session) if ws.lights or ws.run_plan else {},
                        profile=ws.calibration, check=ws.calibration_check, queue=ws.queue,
                        deliverables=(session.path / "deliverables") if session is not None else None,
                        session_note=lab.session_note)

    def refresh(self) -> None:
        self.steps = day_checklist(self.state())
        for i, step in enumerate(self.steps, start=1):
            self.cards[step.step].show_step(step, i)
        self.open_button.setEnabled(self.ctx.lab.session is not None)
        self.refreshed.emit()

    def step(self, which: DayStep) -> GuideStep:
        return next(s for s in self.steps if s.step is which)

    def _clicked(self, step: DayStep) -> None:
        self.ctx.bus.showPanel.emit(STEP_PANEL[step])

    def _open_deliverables(self) -> None:
        session = self.ctx.lab.session
        if session is not None:
            folder = session.path / "deliverables"
            folder.mkdir(parents=True, exist_ok=True)
            self.ctx.open_path(folder)
