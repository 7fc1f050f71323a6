"""Calibrate & capture: the session folder, the lights (a preset) and their exposures, the calibration (made in one
run, saved, loaded, checked), and the single sequences for experts: auto-exposure, dark series, open-gate flats,
dual-RGB capture of a target, HDR metering and capture - every one planned, paused between frames, cancelled with
the LEDs off, its frames ticked in the plan. While anything runs, what it depends on is locked."""
from __future__ import annotations

import logging
from pathlib import Path

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QGroupBox,
    QHBoxLayout,
    QHeaderView,
    QLabel,
    QPushButton,
    QScrollArea,
    QSpinBox,
    QTableWidget,
    QTableWidgetItem,
    QTabWidget,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.calibration_box import CalibrationBox
from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.image_viewer import ImageViewer
from dualrgb.app.gui.preset_chooser import PresetChooser
from dualrgb.app.gui.sequence_view import SequenceView
from dualrgb.app.gui.uniformity_view import UniformityView
from dualrgb.app.gui.units import light_pct, parse_exposure, shutter
from dualrgb.app.gui.widgets import PathLabel, side_by_side
from dualrgb.app.sequences.base import Sequence
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.workflow.stand.copystand import StandSettings, plans_only
from dualrgb.app.workflow.stand.defaults import workflow_defaults
from dualrgb.app.workflow.stand.folders import open_session
from dualrgb.app.workflow.stand.metering import AutoExposure, HdrMetering
from dualrgb.app.workflow.stand.plans import StandPlanner, next_take, planned_steps, steps_done
from dualrgb.core.engine import Run
from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import NamedLight, SequenceKind, Subject, lights_of
from dualrgb.simulation.presets import Preset

log = logging.getLogger(__name__)

SEQUENCE_KINDS = {"Dark series": SequenceKind.DARKS, "Open-gate flats": SequenceKind.FLATS,
                  "Dual-RGB capture": SequenceKind.TARGET, "HDR capture": SequenceKind.HDR_TARGET}
KINDS = tuple(SEQUENCE_KINDS)
TARGETS = (("training target", "train"), ("test target (CC24)", "test"))
RESHOOT, KEEP, CANCEL = "Re-shoot", "Keep", "Cancel"


EXACT = Qt.ItemDataRole.UserRole      # an exposure cell's exact seconds (its text has 4 significant digits)


def exposure_item(seconds: float) -> QTableWidgetItem:
    item = QTableWidgetItem(shutter(seconds))
    item.setData(EXACT, float(seconds))
    return item


def item_exposure(item: QTableWidgetItem | None) -> float:
    """The cell's exact exposure while its text is the one written for it, else what was typed (a calibration's
    0.76923 s shown as 0.7692 s stays 0.76923 s: its darks and flats cover it)."""
    text = item.text() if item is not None else ""
    exact = item.data(EXACT) if item is not None else None
    if isinstance(exact, float) and shutter(exact) == text:
        return exact
    return parse_exposure(text)


class CapturePanel(QWidget):
    title = "Calibrate & capture"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx, self.lab, self.ws = ctx, ctx.lab, ctx.workspace
        self.lights: list[NamedLight] = []
        self.hdr_plans: dict = {}
        self.hdr_key: tuple[str, bool] = ("", False)
        self._last_session: CaptureSession | None = None
        self.view = SequenceView(ctx)
        self.view.start_button.clicked.connect(self.start)
        self.view.finished.connect(self._finished)
        self.calibration = CalibrationBox(ctx, self.view, self.stand_settings, self.plans)
        self.view.start_button.setText("Run single step")    # secondary: Calibrate is the primary action (issue 42)
        self._layout((self.calibration, self._session_box(), self._lights_box(), self._sequence_box()))
        self._connect()
        self._kind_changed()
        self.chooser.load()
        self._session_changed()
        self._update_enabled()

    # ------------------------------------------------------------------ builders
    def _session_box(self) -> QGroupBox:
        box = QGroupBox("Session (every frame is saved here before the next one)")
        lay = QHBoxLayout(box)
        self.session_label = PathLabel("no session")
        self.new_button = QPushButton("New session")
        self.new_button.setToolTip("Make a new dated session folder (e.g. 2026-11-24_1) in the captures folder now; "
                                   "Calibrate, a run or an original makes one when there is none.")
        self.new_button.clicked.connect(lambda: self.new_session())
        self.open_button = QPushButton("Open…")
        self.open_button.setToolTip("Continue an earlier session: frames already taken are not taken again; "
                                    "missing or damaged frames are set aside (damaged/) and shot again.")
        self.open_button.clicked.connect(self._ask_open)
        lay.addWidget(self.session_label, 1)
        lay.addWidget(self.new_button)
        lay.addWidget(self.open_button)
        return box

    def _lights_box(self) -> QGroupBox:
        box = QGroupBox("Lights")
        lay = QVBoxLayout(box)
        self.chooser = PresetChooser(self.ctx)
        self.chooser.chosen.connect(self._preset_chosen)
        self.preset_combo = self.chooser.combo
        self.light_table = QTableWidget(0, 3)
        self.light_table.setHorizontalHeaderLabels(["light", "LED levels", "exposure"])
        self.light_table.setToolTip("Exposure per light (e.g. 1/80 or 0.5): set by auto-exposure on the open gate, "
                                    "or type one.")
        self.light_table.verticalHeader().hide()
        header = self.light_table.horizontalHeader()
        header.setSectionResizeMode(0, QHeaderView.ResizeMode.ResizeToContents)
        header.setSectionResizeMode(1, QHeaderView.ResizeMode.Stretch)      # the levels wrap; the exposure shows whole
        header.setSectionResizeMode(2, QHeaderView.ResizeMode.ResizeToContents)
        self.light_table.setMaximumHeight(130)
        self.light_table.setWordWrap(True)
        self.light_table.itemChanged.connect(lambda _item: self._exposures_edited())
        self.auto_button = QPushButton("Auto-exposure")
        self.auto_button.setToolTip("Meter the open gate under each light and set the exposure that puts the "
                                    "brightest channel at 80 % of the linear limit (a sequence: pause, cancel).")
        self.auto_button.clicked.connect(self.auto_expose)
        lay.addWidget(self.chooser)
        lay.addWidget(self.light_table)
        lay.addWidget(self.auto_button)
        lay.addLayout(self._safety_form())
        return box

    def _safety_form(self) -> QFormLayout:
        form = QFormLayout()
        self.settle = QDoubleSpinBox()
        self.settle.setRange(0.0, 5.0)
        self.settle.setDecimals(2)
        self.settle.setSingleStep(0.05)
        self.settle.setSuffix(" s")
        self.settle.setValue(self.ctx.get("capture/settle_s", SafetySettings().settle_s, float))
        self.settle.setToolTip("Wait after switching the light on before the shutter opens.")
        self.settle.valueChanged.connect(lambda v: self._setting("capture/settle_s", v))
        self.latency = QDoubleSpinBox()
        self.latency.setRange(0.0, 5.0)
        self.latency.setDecimals(2)
        self.latency.setSingleStep(0.05)
        self.latency.setSuffix(" s")
        self.latency.setSpecialValueText("the camera's")
        self.latency.setValue(self.ctx.get("capture/latency_s", 0.0, float))
        self.latency.setToolTip("Time the camera needs beyond the exposure (trigger, shutter lag, reporting the "
                                "shutter closed), kept lit. 'the camera's': what the camera reports (measure a "
                                "real body: python -m dualrgb.drivers.camera.gphoto_latency).")
        self.latency.valueChanged.connect(lambda v: self._setting("capture/latency_s", v))
        self.limit_label = QLabel(f"the light is on at most {SafetySettings().max_on_s:g}\u00a0s per frame "
                                  "(settle + exposure + camera latency; LEDs drift after 10\u00a0s, thesis 4.3.2)")
        self.limit_label.setWordWrap(True)
        form.addRow("Settle", self.settle)
        form.addRow("Camera latency allowance", self.latency)
        form.addRow(self.limit_label)
        return form

    def _sequence_box(self) -> QGroupBox:
        box = QGroupBox("Single steps (the Calibrate run does them all)")
        form = QFormLayout(box)
        self.kind = QComboBox()
        self.kind.addItems(KINDS)
        self.kind.setToolTip("Darks (lens cap) and flats (open gate) at every exposure the captures use, then "
                             "the target under each light; HDR adds longer exposures for dark regions.")
        self.frames = QSpinBox()
        self.frames.setRange(1, 100)
        d = workflow_defaults()
        self.frames.setToolTip(f"Frames per exposure (darks: {d.dark_frames}, thesis 8.2.1; flats: {d.flat_frames}).")
        self.target = QComboBox()
        for label, _ in TARGETS:
            self.target.addItem(label)
        self.target.setToolTip("Which colour target is on the stand (the virtual lab places it for you).")
        self.nd = QCheckBox("ND 2.0 filter over half the target")
        self.nd.setToolTip("Virtual lab: a neutral-density filter darkens half the patches 100x (an HDR test).")
        self.hdr_button = QPushButton("Meter and plan HDR")
        self.hdr_button.setToolTip("Take one frame per light and plan the fewest exposures that bring every "
                                   "patch into the linear range (a sequence: pause, cancel).")
        self.hdr_button.clicked.connect(self.plan_hdr)
        self.hdr_label = QLabel("")
        self.hdr_label.setWordWrap(True)
        form.addRow("Run", self.kind)
        form.addRow("Frames per exposure", self.frames)
        form.addRow("Target", self.target)
        form.addRow("", self.nd)
        form.addRow(self.hdr_button, self.hdr_label)
        for w in (self.kind, self.target):
            w.currentIndexChanged.connect(self._kind_changed)
        self.nd.toggled.connect(self._kind_changed)
        self.frames.valueChanged.connect(self._frames_changed)
        return box

    def _layout(self, boxes) -> None:
        left = QWidget()
        lv = QVBoxLayout(left)
        for b in boxes:
            lv.addWidget(b)
        lv.addStretch(1)
        scroll = QScrollArea()
        scroll.setWidget(left)
        scroll.setWidgetResizable(True)
        scroll.setMinimumWidth(380)
        self.uniformity = UniformityView(self.ctx)
        self.right = QTabWidget()
        self.right.addTab(self.view, "Run")
        self.right.addTab(self.uniformity, "Flat-field uniformity")
        self.viewer = ImageViewer(self.ctx, follow_frames=True)     # the last frame, full size (issue 42)
        self.right.addTab(self.viewer, "Viewer")
        side_by_side(self, scroll, self.right, sizes=[470, 800])

    def _connect(self) -> None:
        self.lab.sessionChanged.connect(self._session_changed)
        self.lab.sphereChanged.connect(self._update_enabled)
        self.lab.cameraChanged.connect(self._update_enabled)
        self.ws.runningChanged.connect(lambda _name: self._update_enabled())
        self.ctx.bus.presetsChanged.connect(self.chooser.load)
        self.ctx.bus.frameSaved.connect(self._show_frames)
        self.ws.calibrationChanged.connect(self._calibration_changed)

    # ------------------------------------------------------------------ session
    def new_session(self, folder: Path | None = None, meta: dict | None = None) -> None:
        """A new session in ``folder``, or under a dated name in the captures folder (app.workflow.stand.folders)."""
        root = self.ctx.captures_dir
        info = {"operator": self.ctx.get("originals/operator", "", str), "virtual_lab": self.lab.is_virtual,
                **(meta or {})}
        lab = self.lab

        def work() -> CaptureSession:            # app.workflow.stand.folders.open_session: the one way
            return open_session(folder, lab.session_definition(), meta=info, root=root)
        self.ctx.runner.submit(work, pool="devices", name="new session", on_result=self.lab.set_session,
                               on_error=lambda exc: self.ctx.errors.report("New session", exc))

    def open_session(self, folder: Path) -> None:
        """Resume a session: its definition (mode, camera, frame size) must match the stand's; missing or damaged
        frames are set aside so their steps are shot again (core.session)."""
        lab = self.lab

        def work() -> tuple[CaptureSession, int]:
            session = open_session(folder, lab.session_definition(), existing=True,
                                   hint="connect the same camera and mode, or start a new session")
            return session, len(session.set_aside_damaged())

        def done(result: tuple[CaptureSession, int]) -> None:
            session, aside = result
            self.lab.set_session(session)
            self.ctx.errors.clear("Open the session")
            if aside:
                self.ctx.errors.report("Open the session", f"{aside} missing or damaged frame(s) set aside in "
                                       f"{session.path / 'damaged'}; their steps will be shot again",
                                       level=logging.WARNING)
        self.ctx.runner.submit(work, pool="devices", name="open session", on_result=done,
                               on_error=lambda exc: self.ctx.errors.report("Open the session", exc))

    def _ask_open(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open a session folder", str(self.ctx.captures_dir))
        if folder:
            self.open_session(Path(folder))

    def _session_changed(self) -> None:
        s = self.lab.session
        if s is not self._last_session:
            self._last_session = s
            self.ws.reset_session_plan()
            self.hdr_plans = {}
        self._show_frames()
        if s is not None:
            self.ctx.set("capture/last_session", str(s.path))
        self._update_enabled()
        self.update_plan()

    def _show_frames(self) -> None:
        s = self.lab.session
        self.session_label.set_path(f"{s.path}  ({len(s.entries())} frames)" if s is not None else
                                    f"no session yet: one is made in {self.ctx.captures_dir} when a run starts")

    # ------------------------------------------------------------------ lights
    @property
    def presets(self) -> list[tuple[Path, Preset]]:
        return self.chooser.presets

    def choose_preset(self, name: str) -> None:
        self.chooser.choose(name)

    def _preset_chosen(self, preset: Preset) -> None:
        cal = self.ws.calibration           # the calibration's exposures for its own lights, else those typed
        old = {**self.ws.base_exposures, **(cal.base_exposures if cal is not None and cal.preset == preset.name
                                            else {})}
        self.lights = lights_of(preset)
        self.hdr_plans = {}
        self.light_table.blockSignals(True)
        self.light_table.setRowCount(len(self.lights))
        for r, nl in enumerate(self.lights):
            for c, text in enumerate((f"light {r + 1}", light_pct(nl.light))):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemFlag.ItemIsEditable)
                self.light_table.setItem(r, c, item)
            self.light_table.setItem(r, 2, exposure_item(old.get(nl.name) or 1 / 60))
        self.light_table.resizeRowsToContents()
        self.light_table.blockSignals(False)
        self.ws.set_lights(preset, self.lights, self._table_exposures())
        self.update_plan()

    def _calibration_changed(self) -> None:
        """A calibration made or loaded: the lights table shows its preset and its open-gate exposures (the plan
        is then the calibration's: no false "incomplete for the new HDR plan")."""
        profile = self.ws.calibration
        if profile is None or self.view.running or self.ws.running:
            return
        current = self.ws.preset.name if self.ws.preset is not None else ""
        if profile.preset != current and profile.preset in [p.name for _, p in self.presets]:
            self.choose_preset(profile.preset)
        names = {nl.name for nl in self.lights}
        if not names or not names <= set(profile.base_exposures):
            return
        self.light_table.blockSignals(True)              # one change, and a calibration run's ticked plan stays
        for name in names:
            self.set_exposure(name, profile.base_exposures[name])
        self.light_table.blockSignals(False)
        self.ws.set_base_exposures(self._table_exposures())
        self.hdr_plans = {}
        if self.view.seq is None or self.view.seq.source is not None:
            self.update_plan()

    def _table_exposures(self) -> dict[str, float]:
        out = {}
        for r, nl in enumerate(self.lights):
            item = self.light_table.item(r, 2)
            try:
                out[nl.name] = item_exposure(item)
            except ValueError:
                continue
        return out

    def _exposures_edited(self) -> None:
        self.ws.set_base_exposures(self._table_exposures())
        self.hdr_plans = {}
        self.update_plan()

    def exposure_of(self, name: str) -> float | None:
        return self._table_exposures().get(name)

    def set_exposure(self, name: str, t: float) -> None:
        for r, nl in enumerate(self.lights):
            if nl.name == name and (cell := self.light_table.item(r, 2)) is not None:
                cell.setData(EXACT, float(t))
                cell.setText(shutter(t))

    def exposures(self) -> dict[str, list[float]]:
        have = self._table_exposures()
        missing = [nl.name for nl in self.lights if nl.name not in have]
        if missing:
            raise ValueError(f"light {missing[0]}: the exposure must be a time such as 1/80 or 0.5 (seconds)")
        return {n: [t] for n, t in have.items()}

    def all_exposures(self) -> dict[str, list[float]]:
        """Per light: every exposure the captures use (app.workflow.stand.plans.calibration_exposures)."""
        self.exposures()
        return self.ws.planned_exposures(self.lab.session)

    # ------------------------------------------------------------------ building sequences
    def stand_settings(self) -> StandSettings:
        latency = self.latency.value()
        return StandSettings(settle_s=self.settle.value(), latency_s=latency if latency > 0 else None)

    def plans(self) -> StandPlanner:
        """The single steps' plans only (nothing is touched): the camera's latency allowance, as the real one."""
        return plans_only(self.lab.camera, self.stand_settings())

    def planner(self) -> StandPlanner:
        """The single steps on the copy stand (app.workflow.stand.copystand.CopyStand.planner), to run."""
        self._require_devices()
        if self.lab.session is None:
            raise ValueError("no session yet (one is made when a run starts)")
        return self.lab.copy_stand(self.stand_settings()).planner()

    def target_key(self) -> str:
        return TARGETS[self.target.currentIndex()][1]

    def subject(self) -> Subject:
        return Subject.target(self.target_key(), self.nd.isChecked())

    def build(self, stand: StandPlanner | None, take: int = 1) -> Sequence:
        """The selected sequence (with ``stand=None`` only for its plan), built by the workflow
        (app.workflow.stand.plans.StandPlanner)."""
        kind = SEQUENCE_KINDS[self.kind.currentText()]
        st = stand or self.plans()
        if kind in (SequenceKind.DARKS, SequenceKind.FLATS):
            return st.sequence(kind, self.lights, exposures=self.all_exposures(), frames=self.frames.value())
        if kind is SequenceKind.TARGET:
            return st.sequence(kind, self.lights, exposures=self.exposures(), subject=self.subject(), take=take)
        if self.hdr_key != (self.target_key(), self.nd.isChecked()) or not self.hdr_plans:
            raise ValueError("press 'Meter and plan HDR' for this target first")
        return st.sequence(kind, self.lights, exposures={n: p.exposures for n, p in self.hdr_plans.items()},
                           subject=self.subject(), take=take)

    def _done(self, seq: Sequence) -> list[bool]:
        session = self.lab.session
        return steps_done(session, planned_steps(seq)) if session is not None else []

    def _setting(self, key: str, value: object) -> None:
        """Remember a setting and show the plan it makes."""
        self.ctx.set(key, value)
        self.update_plan()

    def update_plan(self) -> None:
        self.view.settle_s = self.settle.value()
        if self.view.running:
            return
        try:
            seq = self.build(None)
        except (ValueError, KeyError) as exc:
            self.view.clear_plan(str(exc))
            return
        self.view.show_plan(seq.plan(), self.kind.currentText(), self._done(seq))

    def _kind_changed(self, *_args) -> None:
        kind = self.kind.currentText()
        self.frames.blockSignals(True)
        d = workflow_defaults(self.lab.mode)
        default = d.dark_frames if kind == "Dark series" else d.flat_frames
        self.frames.setValue(self.ctx.get(f"capture/frames/{kind}", default, int))
        self.frames.blockSignals(False)
        self._update_enabled()
        self.update_plan()

    def _frames_changed(self, value: int) -> None:
        self.ctx.set(f"capture/frames/{self.kind.currentText()}", value)
        self.update_plan()

    def _ready(self) -> bool:
        """The devices are connected (a session is made when the run starts, if there is none)."""
        return self.lab.camera is not None and self.lab.sphere is not None

    def _update_enabled(self) -> None:
        """Lock what a running sequence depends on (session, lights, exposures, settings); devices and a session
        are needed to start anything."""
        running = bool(self.ws.running) or self.view.running
        ready = self._ready() and not running
        kind = self.kind.currentText()
        calib = kind in ("Dark series", "Open-gate flats")
        for w in (self.new_button, self.open_button, self.preset_combo, self.light_table, self.settle, self.latency,
                  self.kind):
            w.setEnabled(not running)
        self.frames.setEnabled(calib and not running)
        self.target.setEnabled(not calib and not running)
        self.nd.setEnabled(not calib and not running)
        self.view.start_button.setEnabled(ready)
        self.auto_button.setEnabled(ready)
        self.hdr_button.setEnabled(ready and kind == "HDR capture")
        self.calibration.set_locked(running)
        self.calibration.calibrate_button.setEnabled(ready)
        if not self._ready() and not running:
            missing = [w for w, ok in (("the sphere", self.lab.sphere), ("the camera", self.lab.camera)) if ok is None]
            self.view.message.setText("needs " + " and ".join(missing) + " (Devices) before it can start")
        elif self.view.message.text().startswith("needs "):      # connected now: the old advice goes
            self.view.message.setText("")

    # ------------------------------------------------------------------ running
    def capture_shortcut(self) -> None:
        if self.view.start_button.isEnabled():
            self.start()

    def start(self) -> None:
        """Start the chosen step; without a session one is made first (AppContext.with_session)."""
        what = self.kind.currentText().lower()
        try:
            self.build(None)                      # refuses (nothing made) what cannot run
            self._require_devices()
        except ValueError as exc:
            self.ctx.errors.report(f"Start {what}", exc)
            return
        self.ctx.with_session(self._start_now, f"the {what}")

    def _require_devices(self) -> None:
        if self.lab.camera is None or self.lab.sphere is None:
            raise ValueError("connect the LED sphere and the camera in Devices first")

    def _start_now(self) -> None:
        try:
            seq = self.build(self.planner())
        except ValueError as exc:
            self.ctx.errors.report(f"Start {self.kind.currentText().lower()}", exc)
            return
        done = self._done(seq)
        if isinstance(seq, SubjectCapture) and any(done):
            self._ask_reshoot(seq, done)
            return
        self._run(seq, done)

    def _run(self, seq: Sequence, done: list[bool] | None = None) -> None:
        """Run one plan on the copy stand's run engine (app.gui.device_hub.Lab.plan_run)."""
        self.view.start(self.lab.plan_run(seq, self.stand_settings()), done or [])

    def _ask_reshoot(self, seq: SubjectCapture, done: list[bool]) -> None:
        text = (f"The {seq.subject.label} is already in the session ({sum(done)} of {len(done)} frames). "
                "Re-shoot it (a new take; the old frames stay in the session), keep the frames it has, or cancel?")

        def answer(choice: str) -> None:
            if choice == RESHOOT:
                session = self.lab.session
                take = next_take(session, planned_steps(seq)) if session is not None else 1
                self._run(self.build(self.planner(), take=take))
            elif choice == KEEP:
                self._run(seq, done)
        self.ctx.asker.ask("Already in the session", text, (RESHOOT, KEEP, CANCEL), answer, default=CANCEL)

    def cancel_running(self) -> None:
        self.view.cancel()

    def _finished(self, run: Run, outcome: str) -> None:
        seq = run.source if run is not None else None         # the plan of a one-plan run; None: a calibration
        if isinstance(seq, AutoExposure) and seq.exposures:
            for name, t in seq.exposures.items():
                self.set_exposure(name, t)
            self.hdr_plans = {}
        if isinstance(seq, HdrMetering) and outcome == "done":
            self.hdr_plans = dict(seq.plans)
            self.hdr_key = (seq.subject.name, seq.subject.nd)
            self.ws.add_hdr_brackets({n: p.exposures for n, p in seq.plans.items()})
            self.hdr_label.setText(seq.summary())
        self._show_frames()
        self._update_enabled()
        if seq is not None:                # a calibration run's ticked plan stays in view
            self.update_plan()
        self.ctx.bus.sessionUpdated.emit()
        if outcome == "done" and getattr(seq, "name", "") == "open-gate flats":
            self.uniformity.refresh()

    def auto_expose(self) -> None:
        try:
            self._require_devices()
        except ValueError as exc:
            self.ctx.errors.report("Auto-exposure", exc)
            return

        def now() -> None:
            try:
                seq = self.planner().auto_exposure(self.lights)
            except ValueError as exc:
                self.ctx.errors.report("Auto-exposure", exc)
                return
            self._run(seq)
        self.ctx.with_session(now, "the auto-exposure")

    def patch_boxes(self, target: str, nd: bool) -> list[tuple[int, int, int, int]]:
        """Patch boxes (full-frame rows/cols) for HDR metering: the virtual lab's scene, or the grid placed in
        Target (superpixel coordinates, doubled)."""
        if self.lab.virtual_lab is not None:
            return self.lab.virtual_lab.scene_for(target, nd=nd).patch_boxes()
        grid = self.ws.grids.get(Subject.target(target, nd).key) or self.ws.last_grid
        if grid is None:
            raise ValueError("place the patch grid on a frame of this target in Target first (HDR metering "
                             "measures every patch)")
        boxes = []
        for poly in grid.sample_polygons():
            x0, y0 = poly.min(axis=0) * 2
            x1, y1 = poly.max(axis=0) * 2
            boxes.append((int(y0), int(y1) + 1, int(x0), int(x1) + 1))
        return boxes

    def plan_hdr(self) -> None:
        try:
            base = {n: ts[0] for n, ts in self.exposures().items()}
            subject = self.subject()
            boxes = self.patch_boxes(subject.name, subject.nd)
            self._require_devices()
        except ValueError as exc:
            self.ctx.errors.report("Plan HDR", exc)
            return

        def now() -> None:
            try:
                seq = self.planner().hdr_metering(self.lights, base, subject, boxes)
            except ValueError as exc:
                self.ctx.errors.report("Plan HDR", exc)
                return
            self._run(seq)
        self.ctx.with_session(now, "the HDR metering")

    def shutdown(self) -> None:
        self.view.cancel()

