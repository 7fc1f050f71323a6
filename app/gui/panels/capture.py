"""Calibrate & capture: the session folder, the lights (a preset) and their exposures, then the sequences:
dark series, open-gate flats, dual-RGB capture of a target, HDR capture (metering frame -> bracket plan)."""
from __future__ import annotations

import datetime as _dt
import logging
from pathlib import Path
from typing import Optional

from PySide6.QtCore import Qt
from PySide6.QtWidgets import (QCheckBox, QComboBox, QDoubleSpinBox, QFileDialog, QFormLayout, QGroupBox,
                               QHBoxLayout, QLabel, QPushButton, QSpinBox, QSplitter, QTableWidget,
                               QTableWidgetItem, QVBoxLayout, QWidget)

from app.gui.context import AppContext
from app.gui.sequence_view import SequenceView
from app.sequences.base import Sequence
from app.sequences.calibration import auto_exposure
from app.sequences.hdr import HdrPlan, meter_and_plan
from app.sequences.shooter import SafetySettings, Shooter
from app.session import CaptureSession
from app.workflow.plans import build_sequence, calibration_exposures
from app.workflow.vocabulary import NamedLight, SequenceKind, Subject, format_exposure as format_shutter, lights_of
from simulation.presets import Preset, PresetError, load_preset, packaged_presets

log = logging.getLogger(__name__)

SEQUENCE_KINDS = {"Dark series": SequenceKind.DARKS, "Open-gate flats": SequenceKind.FLATS,
                  "Dual-RGB capture": SequenceKind.TARGET, "HDR capture": SequenceKind.HDR_TARGET}
KINDS = tuple(SEQUENCE_KINDS)
TARGETS = (("training target", "train"), ("test target (CC24)", "test"))


class CapturePanel(QWidget):
    title = "Calibrate & capture"

    def __init__(self, ctx: AppContext, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.presets: list[tuple[Path, Preset]] = []
        self.lights: list[NamedLight] = []
        self.hdr_plans: dict[str, HdrPlan] = {}
        self.hdr_key: tuple[str, bool] = ("", False)
        self.hdr_brackets: dict[str, set[float]] = {}     # every HDR exposure planned in this session, per light

        # ---- session ----
        sbox = QGroupBox("Session (every frame is saved here before the next one)")
        sl = QHBoxLayout(sbox)
        self.session_label = QLabel("no session")
        self.session_label.setWordWrap(True)
        self.new_button = QPushButton("New session")
        self.new_button.setToolTip("Make a new session folder in the captures folder.")
        self.new_button.clicked.connect(lambda: self.new_session())
        self.open_button = QPushButton("Open…")
        self.open_button.setToolTip("Continue an earlier session: frames already taken are not taken again.")
        self.open_button.clicked.connect(self._ask_open)
        sl.addWidget(self.session_label, 1)
        sl.addWidget(self.new_button)
        sl.addWidget(self.open_button)

        # ---- lights ----
        lbox = QGroupBox("Lights")
        ll = QVBoxLayout(lbox)
        self.preset_combo = QComboBox()
        self.preset_combo.setToolTip("The preset whose lights this session uses (one preset per session).")
        self.preset_combo.currentIndexChanged.connect(self._preset_chosen)
        self.light_table = QTableWidget(0, 3)
        self.light_table.setHorizontalHeaderLabels(["light", "LEDs @ levels", "exposure (s)"])
        self.light_table.setToolTip("Exposure per light: set by auto-exposure on the open gate, or type one.")
        self.light_table.verticalHeader().hide()
        self.light_table.horizontalHeader().setStretchLastSection(True)
        self.light_table.setMaximumHeight(120)
        self.auto_button = QPushButton("Auto-exposure")
        self.auto_button.setToolTip("Meter the open gate under each light and set the exposure that puts the "
                                    "brightest channel at 80 % of the linear limit.")
        self.auto_button.clicked.connect(self.auto_expose)
        self.settle = QDoubleSpinBox()
        self.settle.setRange(0.0, 5.0)
        self.settle.setDecimals(2)
        self.settle.setSingleStep(0.05)
        self.settle.setSuffix(" s")
        self.settle.setValue(ctx.get("capture/settle_s", SafetySettings().settle_s, float))
        self.settle.setToolTip("Wait after switching the light on before the shutter opens.")
        self.settle.valueChanged.connect(lambda v: (ctx.set("capture/settle_s", v), self.update_plan()))
        row = QHBoxLayout()
        row.addWidget(self.auto_button)
        row.addWidget(QLabel("settle"))
        row.addWidget(self.settle)
        ll.addWidget(self.preset_combo)
        ll.addWidget(self.light_table)
        ll.addLayout(row)

        # ---- sequence choice ----
        qbox = QGroupBox("Sequence")
        qf = QFormLayout(qbox)
        self.kind = QComboBox()
        self.kind.addItems(KINDS)
        self.kind.setToolTip("Darks (lens cap) and flats (open gate) at every exposure the captures use, then "
                             "the target under each light; HDR adds longer exposures for dark regions.")
        self.frames = QSpinBox()
        self.frames.setRange(1, 100)
        self.frames.setToolTip("Frames per exposure (darks: 10 in the thesis; flats: 3).")
        self.target = QComboBox()
        for label, _ in TARGETS:
            self.target.addItem(label)
        self.target.setToolTip("Which colour target is on the stand (the virtual lab places it for you).")
        self.nd = QCheckBox("ND 2.0 filter over half the target")
        self.nd.setToolTip("Virtual lab: a neutral-density filter darkens half the patches 100x (an HDR test).")
        self.hdr_button = QPushButton("Meter and plan HDR")
        self.hdr_button.setToolTip("Take one frame per light and plan the fewest exposures that bring every "
                                   "patch into the linear range.")
        self.hdr_button.clicked.connect(self.plan_hdr)
        self.hdr_label = QLabel("")
        self.hdr_label.setWordWrap(True)
        qf.addRow("Run", self.kind)
        qf.addRow("Frames per exposure", self.frames)
        qf.addRow("Target", self.target)
        qf.addRow("", self.nd)
        qf.addRow(self.hdr_button, self.hdr_label)
        for w in (self.kind, self.target):
            w.currentIndexChanged.connect(self._kind_changed)
        self.nd.toggled.connect(self._kind_changed)
        self.frames.valueChanged.connect(self._frames_changed)
        self.light_table.itemChanged.connect(lambda _item: self.update_plan())

        self.view = SequenceView(ctx)
        self.view.settle_s = self.settle.value()
        self.view.start_button.clicked.connect(self.start)
        self.view.finished.connect(self._finished)

        left = QWidget()
        lv = QVBoxLayout(left)
        lv.addWidget(sbox)
        lv.addWidget(lbox)
        lv.addWidget(qbox)
        split = QSplitter(Qt.Horizontal)
        split.addWidget(left)
        split.addWidget(self.view)
        split.setStretchFactor(1, 1)
        QVBoxLayout(self).addWidget(split)

        self.lab.sessionChanged.connect(self._session_changed)
        self.lab.sphereChanged.connect(self._devices_changed)
        self.lab.cameraChanged.connect(self._devices_changed)
        ctx.bus.presetsChanged.connect(self.load_presets)
        self._kind_changed()
        self.load_presets()
        self._session_changed()
        self._devices_changed()

    # ------------------------------------------------------------------ session
    def new_session(self, folder: Optional[Path] = None, meta: Optional[dict] = None) -> None:
        folder = folder or self.ctx.captures_dir / _dt.datetime.now().strftime("session-%Y%m%d-%H%M%S")
        info = {"operator": "", "virtual_lab": self.lab.is_virtual, **(meta or {})}
        self.ctx.runner.submit(lambda: CaptureSession.create(folder, info), pool="compute", name="new session",
                               on_result=self.lab.set_session,
                               on_error=lambda exc: self.ctx.errors.report("New session", exc))

    def open_session(self, folder: Path) -> None:
        self.ctx.runner.submit(lambda: CaptureSession.open(folder), pool="compute", name="open session",
                               on_result=self.lab.set_session,
                               on_error=lambda exc: self.ctx.errors.report("Open the session", exc))

    def _ask_open(self) -> None:
        folder = QFileDialog.getExistingDirectory(self, "Open a session folder", str(self.ctx.captures_dir))
        if folder:
            self.open_session(Path(folder))

    def _session_changed(self) -> None:
        s = self.lab.session
        if s is not getattr(self, "_last_session", None):
            self._last_session = s
            self.hdr_brackets = {}
        self.session_label.setText(f"{s.path}  ({len(s.entries())} frames)" if s is not None else
                                   "no session: press New session")
        if s is not None:
            self.ctx.set("capture/last_session", str(s.path))
        self._devices_changed()

    # ------------------------------------------------------------------ lights
    def load_presets(self) -> None:
        folder = self.ctx.presets_dir

        def work() -> list[tuple[Path, Preset]]:
            out = []
            for p in packaged_presets() + (sorted(folder.glob("*.json")) if folder.is_dir() else []):
                try:
                    out.append((p, load_preset(p)))
                except PresetError as exc:
                    log.warning("preset skipped: %s", exc)
            return out

        self.ctx.runner.submit(work, pool="compute", name="load presets", on_result=self._fill_presets,
                               on_error=lambda exc: self.ctx.errors.report("Presets", exc))

    def _fill_presets(self, presets: list[tuple[Path, Preset]]) -> None:
        wanted = self.ctx.get("capture/preset", "", str)
        current = str(self.presets[self.preset_combo.currentIndex()][0]) if self.presets and \
            self.preset_combo.currentIndex() >= 0 else wanted
        self.presets = presets
        self.preset_combo.blockSignals(True)
        self.preset_combo.clear()
        for path, p in presets:
            self.preset_combo.addItem(f"{p.name}  ({len(p.sources)} light{'s' if len(p.sources) > 1 else ''})")
        paths = [str(p) for p, _ in presets]
        self.preset_combo.setCurrentIndex(paths.index(current) if current in paths else 0)
        self.preset_combo.blockSignals(False)
        self._preset_chosen(self.preset_combo.currentIndex())

    def choose_preset(self, name: str) -> None:
        for i, (_path, p) in enumerate(self.presets):
            if p.name == name:
                self.preset_combo.setCurrentIndex(i)
                return
        raise ValueError(f"no preset named {name!r}")

    def _preset_chosen(self, index: int) -> None:
        if not 0 <= index < len(self.presets):
            return
        path, preset = self.presets[index]
        self.ctx.set("capture/preset", str(path))
        old = {nl.name: self.exposure_of(nl.name) for nl in self.lights}
        self.lights = lights_of(preset)
        self.hdr_plans = {}
        self.light_table.blockSignals(True)
        self.light_table.setRowCount(len(self.lights))
        for r, nl in enumerate(self.lights):
            for c, text in enumerate((nl.name, nl.light.label())):
                item = QTableWidgetItem(text)
                item.setFlags(item.flags() & ~Qt.ItemIsEditable)
                self.light_table.setItem(r, c, item)
            self.light_table.setItem(r, 2, QTableWidgetItem(f"{old.get(nl.name) or 1 / 60:.6g}"))
        self.light_table.resizeColumnsToContents()
        self.light_table.blockSignals(False)
        self.update_plan()

    def exposure_of(self, name: str) -> Optional[float]:
        for r in range(self.light_table.rowCount()):
            if self.light_table.item(r, 0) and self.light_table.item(r, 0).text() == name:
                try:
                    t = float(self.light_table.item(r, 2).text().replace(",", "."))
                except (AttributeError, ValueError):
                    return None
                return t if t > 0 else None
        return None

    def set_exposure(self, name: str, t: float) -> None:
        for r in range(self.light_table.rowCount()):
            if self.light_table.item(r, 0).text() == name:
                self.light_table.item(r, 2).setText(f"{t:.6g}")

    def exposures(self) -> dict[str, list[float]]:
        out = {}
        for nl in self.lights:
            t = self.exposure_of(nl.name)
            if t is None:
                raise ValueError(f"light {nl.name}: the exposure must be a positive number of seconds")
            out[nl.name] = [t]
        return out

    def all_exposures(self) -> dict[str, list[float]]:
        """Per light: every exposure the captures use (app.workflow.plans.calibration_exposures)."""
        return calibration_exposures(self.lab.session, self.exposures(), self.hdr_brackets)

    # ------------------------------------------------------------------ building sequences
    def shooter(self) -> Shooter:
        if self.lab.camera is None or self.lab.sphere is None:
            raise ValueError("connect the LED sphere and the camera in Devices first")
        if self.lab.session is None:
            raise ValueError("start a session first (New session)")
        stand = self.lab.virtual_lab.place if self.lab.virtual_lab is not None else None
        return Shooter(self.lab.camera, self.lab.sphere, self.lab.session, stand=stand,
                       safety=SafetySettings(settle_s=self.settle.value()))

    def target_key(self) -> str:
        return TARGETS[self.target.currentIndex()][1]

    def build(self, shooter: Optional[Shooter]) -> Sequence:
        """The selected sequence (with ``shooter=None`` only for its plan), built by app.workflow.plans."""
        kind = SEQUENCE_KINDS[self.kind.currentText()]
        sh = shooter or _PlanOnlyShooter(self.settle.value())
        if kind in (SequenceKind.DARKS, SequenceKind.FLATS):
            return build_sequence(kind, sh, self.lights, exposures=self.all_exposures(), frames=self.frames.value())
        subject = Subject.target(self.target_key(), self.nd.isChecked())
        if kind is SequenceKind.TARGET:
            return build_sequence(kind, sh, self.lights, exposures=self.exposures(), subject=subject)
        if self.hdr_key != (self.target_key(), self.nd.isChecked()) or not self.hdr_plans:
            raise ValueError("press 'Meter and plan HDR' for this target first")
        return build_sequence(kind, sh, self.lights, exposures={n: p.exposures for n, p in self.hdr_plans.items()},
                              subject=subject)

    def update_plan(self) -> None:
        self.view.settle_s = self.settle.value()
        if self.view.running:
            return
        try:
            seq = self.build(None)
        except (ValueError, KeyError) as exc:
            self.view.clear_plan(str(exc))
            return
        self.view.show_plan(seq.plan(), self.kind.currentText())

    def _kind_changed(self, *_args) -> None:
        kind = self.kind.currentText()
        calib = kind in ("Dark series", "Open-gate flats")
        self.frames.setEnabled(calib)
        self.target.setEnabled(not calib)
        self.nd.setEnabled(not calib)
        self.hdr_button.setEnabled(kind == "HDR capture" and self._ready())
        self.frames.blockSignals(True)
        self.frames.setValue(self.ctx.get(f"capture/frames/{kind}", 10 if kind == "Dark series" else 3, int))
        self.frames.blockSignals(False)
        self.update_plan()

    def _frames_changed(self, value: int) -> None:
        self.ctx.set(f"capture/frames/{self.kind.currentText()}", value)
        self.update_plan()

    def _ready(self) -> bool:
        return self.lab.camera is not None and self.lab.sphere is not None and self.lab.session is not None

    def _devices_changed(self) -> None:
        ready = self._ready() and not self.view.running
        self.view.start_button.setEnabled(ready)
        self.auto_button.setEnabled(ready)
        self.hdr_button.setEnabled(ready and self.kind.currentText() == "HDR capture")
        if not self._ready():
            missing = [w for w, ok in (("the sphere", self.lab.sphere), ("the camera", self.lab.camera),
                                       ("a session", self.lab.session)) if ok is None]
            self.view.message.setText("needs " + ", ".join(missing) + " before it can start")

    # ------------------------------------------------------------------ running
    def capture_shortcut(self) -> None:
        if self.view.start_button.isEnabled():
            self.start()

    def start(self) -> None:
        try:
            seq = self.build(self.shooter())
        except ValueError as exc:
            self.ctx.errors.report(f"Start {self.kind.currentText().lower()}", exc)
            return
        self.view.start(seq)
        self._devices_changed()

    def cancel_running(self) -> None:
        self.view.cancel()

    def _finished(self, seq, outcome: str) -> None:
        self._session_changed()
        self.ctx.bus.sessionUpdated.emit()
        self.update_plan()

    def auto_expose(self) -> None:
        try:
            shooter = self.shooter()
        except ValueError as exc:
            self.ctx.errors.report("Auto-exposure", exc)
            return
        lights = list(self.lights)

        def work(progress, cancel) -> dict[str, float]:
            out = {}
            try:
                for i, nl in enumerate(lights):
                    cancel.check()
                    progress(i / len(lights), f"metering {nl.name} on the open gate")
                    out[nl.name], _ = auto_exposure(shooter, nl)
            finally:
                shooter.lights_off()
            return out

        def done(result: dict[str, float]) -> None:
            for name, t in result.items():
                self.set_exposure(name, t)
            self.view.message.setText("auto-exposure: " + ", ".join(f"{n} {format_shutter(t)}"
                                                                   for n, t in result.items()))
            self.hdr_plans = {}
            self.update_plan()

        self.view.message.setText("auto-exposure: metering the open gate …")
        self.auto_button.setEnabled(False)
        self.ctx.bus.sequenceStarted.emit("auto-exposure")
        self.ctx.runner.submit(work, pool="sequences", name="auto-exposure", pass_progress=True, pass_cancel=True,
                               on_progress=lambda f, m: self.view.message.setText(m), on_result=done,
                               on_error=lambda exc: self.ctx.errors.report("Auto-exposure", exc),
                               on_finished=self._metering_finished)

    def _metering_finished(self) -> None:
        self.ctx.bus.sequenceFinished.emit("metering", "done")
        self._session_changed()
        self._devices_changed()

    def patch_boxes(self, target: str, nd: bool) -> list[tuple[int, int, int, int]]:
        """Patch boxes (full-frame rows/cols) for HDR metering: the virtual lab's scene, or the grid placed in
        Target (superpixel coordinates, doubled)."""
        if self.lab.virtual_lab is not None:
            return self.lab.virtual_lab.scene_for(target, nd=nd).patch_boxes()
        grid = self.ctx.shared.get("grid")
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
            shooter = self.shooter()
            base = self.exposures()
            target, nd = self.target_key(), self.nd.isChecked()
            boxes = self.patch_boxes(target, nd)
        except ValueError as exc:
            self.ctx.errors.report("Plan HDR", exc)
            return
        lights = list(self.lights)

        def work(progress, cancel) -> dict[str, HdrPlan]:
            return meter_and_plan(shooter, lights, {n: ts[0] for n, ts in base.items()}, Subject.target(target, nd),
                                  boxes, progress=progress, cancel=cancel)

        def done(plans: dict[str, HdrPlan]) -> None:
            self.hdr_plans = plans
            self.hdr_key = (target, nd)
            for name, plan in plans.items():
                self.hdr_brackets.setdefault(name, set()).update(plan.exposures)
            self.hdr_label.setText("; ".join(
                f"{n}: {', '.join(format_shutter(t) for t in p.exposures)} (range {p.dynamic_range:.0f}:1"
                + (", limited by the light-on time" if p.limited_by_light_time else "") + ")"
                for n, p in plans.items()))
            self.update_plan()

        self.ctx.bus.sequenceStarted.emit("HDR metering")
        self.ctx.runner.submit(work, pool="sequences", name="HDR metering", pass_progress=True, pass_cancel=True,
                               on_progress=lambda f, m: self.view.message.setText(m), on_result=done,
                               on_error=lambda exc: self.ctx.errors.report("Plan HDR", exc),
                               on_finished=self._metering_finished)

    def shutdown(self) -> None:
        self.view.cancel()


class _PlanOnlyShooter:
    """Stands in for a Shooter while only ``plan()`` is asked for (nothing is touched)."""

    def __init__(self, settle_s: float):
        self.safety = SafetySettings(settle_s=settle_s)

    def check_light_time(self, exposure_s: float) -> None:
        Shooter.check_light_time(self, exposure_s)  # type: ignore[arg-type]

