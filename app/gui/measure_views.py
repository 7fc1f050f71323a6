"""Measuring the camera and the LEDs in the window (issue 30): ``dualrgb measure csrf`` and ``dualrgb measure leds``
/ ``import-leds`` as tabs of the Tools panel.

*Measure the camera* runs app.workflow.csrf_bench (the code the command runs) as a Run in a SequenceView:
progress, pause, Cancel (the shutter closed), and every prompt of a monochromator set by hand as a dialog
("Continue" / "Cancel"; the run waits in its worker until it is answered). On the virtual lab the bench is the
virtual monochromator bench and the result is compared with the curves the virtual camera renders with; on a real
stand it is the camera connected in Devices with a Cornerstone on a serial port, or a monochromator set by hand,
and a radiance file. The result: the camera CSV's path, the session, and a plot of R, G, B.

*Measure the LEDs* runs app.lab.led_bench.measure_virtual (the virtual lab's sphere and spectroradiometer, on
a skippable clock: the hour of warm-up takes moments; Cancel is checked at every reading) or, for a real
instrument's files, import_readings; the result: the stand folder's files and a plot of each LED's spectrum.
"""
from __future__ import annotations

import logging
from pathlib import Path
from typing import Any

import numpy as np
from PySide6.QtWidgets import (
    QComboBox,
    QDoubleSpinBox,
    QFileDialog,
    QFormLayout,
    QHBoxLayout,
    QLabel,
    QLineEdit,
    QPushButton,
    QSpinBox,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.sequence_view import SequenceView
from dualrgb.app.gui.stand_options import CAMERA_CSV_KEY, STAND_DIR_KEY
from dualrgb.app.gui.widgets import PathLabel, plot_widget
from dualrgb.app.lab.csrf_bench import VIRTUAL
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.csrf import CsrfSettings
from dualrgb.app.workflow.csrf_bench import CORNERSTONE, MANUAL, CsrfBench, CsrfOutcome
from dualrgb.core.engine import Run, RunHooks
from dualrgb.core.vocabulary import EventKind, Role

log = logging.getLogger(__name__)

WARMUP_READINGS = 10      # at least this many warm-up spectra per LED (the command: one a minute, --interval-s)
CONTINUE, STOP = "Continue", "Cancel the measurement"
CHANNEL_PENS = ("#c62828", "#2e7d32", "#1565c0")
BENCHES = {VIRTUAL: "virtual lab (monochromator bench)", CORNERSTONE: "Cornerstone on a serial port",
           MANUAL: "set by hand (a dialog at each wavelength)"}


def world_combo(ctx: AppContext) -> QComboBox:
    """The virtual lab's worlds (resources/worlds), the window's own first."""
    from dualrgb.drivers.virtual.world import packaged_worlds

    combo = QComboBox()
    combo.addItems(packaged_worlds())
    own = ctx.lab.world if isinstance(ctx.lab.world, str) else "nominal"
    combo.setCurrentText(own)
    combo.setToolTip("The world the virtual lab renders.")
    return combo


def path_row(edit: QLineEdit, button: QPushButton) -> QHBoxLayout:
    row = QHBoxLayout()
    row.addWidget(edit, 1)
    row.addWidget(button)
    return row


class MeasureView(QWidget):
    """What both measurements share: a form, a SequenceView for the run, a result line and a plot."""

    title = "measurement"
    use_key = ""                       # the calibration's setting this measurement's result can be (stand_options)

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.view = SequenceView(ctx, preview=False)       # frames live in the measurement's own session
        self.view.start_button.hide()
        self.view.run_event.connect(self._run_event)
        self.view.finished.connect(self._finished)
        self.start_button = QPushButton(f"Measure {self.title}")
        self.start_button.clicked.connect(self.start)
        self.result_label = QLabel("")
        self.result_label.setWordWrap(True)
        self.files_label = PathLabel("")
        self.use_button = QPushButton("Use in the next calibration")
        self.use_button.setToolTip("The calibration box's measured curves (Measured camera / "
                                   "Measured LEDs): the stand model fitted to the captures starts from them.")
        self.use_button.setEnabled(False)
        self.use_button.clicked.connect(self.use_result)
        self.plot = plot_widget(bottom="wavelength (nm)", left="relative")
        self.run: Run | None = None
        self.out = QLineEdit()                             # the file or folder written; '': default_out
        self.form = QFormLayout()
        ctx.workspace.runningChanged.connect(lambda name: self.start_button.setEnabled(not name))

    def lay_out(self) -> None:
        left = QVBoxLayout()
        left.addLayout(self.form)
        left.addWidget(self.start_button)
        left.addWidget(self.result_label)
        left.addWidget(self.files_label)
        left.addWidget(self.use_button)
        left.addWidget(self.plot, 1)
        layout = QHBoxLayout(self)
        layout.addLayout(left, 2)
        layout.addWidget(self.view, 3)

    def start(self) -> None:
        if self.ctx.workspace.running:
            self.ctx.errors.report(f"Measure {self.title}", f"{self.ctx.workspace.running} is running")
            return
        try:
            plan, work = self.prepare()
        except ValueError as exc:
            self.ctx.errors.report(f"Measure {self.title}", exc)
            return
        self.result_label.setText("")
        self.files_label.set_path("")
        self.use_button.setEnabled(False)
        self.run = Run(f"{self.title} measurement", plan, work)
        self.view.start(self.run)
        self.view.summary.setText(self.plan_line())

    default_out = ""                   # under the captures folder (as it is when the run starts)

    def out_path(self) -> Path:
        text = self.out.text().strip()
        return Path(text).expanduser() if text else self.ctx.captures_dir / "measurements" / self.default_out

    def prepare(self) -> tuple[list[PlannedFrame], Any]:
        raise NotImplementedError

    def plan_line(self) -> str:
        """What the run does, for the plan's summary (the frame estimate of a capture does not fit it)."""
        return ""

    def _run_event(self, ev: ProgressEvent) -> None:
        if ev.kind is EventKind.PROMPT and self.view.seq is self.run:
            self.ctx.asker.ask(f"Measure {self.title}", ev.message, (CONTINUE, STOP), self._answered,
                               default=CONTINUE)

    def _answered(self, choice: str) -> None:
        if choice == CONTINUE:
            self.view.continue_button.click()
        else:
            self.view.cancel()

    def _finished(self, run: Run, outcome: str) -> None:
        if run is self.run and outcome == "done" and run.result is not None:
            self.show_result(run.result)
            self.view.message.setText(f"{self.title} measurement done")
        elif run is self.run:
            self.result_label.setText(f"{self.title} measurement {outcome}: nothing written")

    def show_result(self, result: Any) -> None:
        raise NotImplementedError

    def use_result(self) -> None:
        """The result's file (camera CSV) or folder (stand) becomes the calibration's measured curves."""
        path = self.files_label.full_text()
        if path and self.use_key:
            self.ctx.set(self.use_key, path)
            self.ctx.lab.message.emit(f"the next calibration starts its stand model from {path}")

    def cancel_running(self) -> None:
        if self.view.running and self.view.seq is self.run:
            self.view.cancel()

    def shutdown(self) -> None:
        self.cancel_running()


class CameraMeasureView(MeasureView):
    """``dualrgb measure csrf``: the camera's spectral sensitivity -> a camera CSV."""

    title = "the camera"
    use_key = CAMERA_CSV_KEY
    default_out = "camera_csrf.csv"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(ctx, parent)
        self.bench = QComboBox()
        for key, label in BENCHES.items():
            self.bench.addItem(label, key)
        self.port = QLineEdit(ctx.get("measure/monochromator_port", "", str))
        self.port.setPlaceholderText("/dev/ttyUSB0")
        self.port.textChanged.connect(lambda t: ctx.set("measure/monochromator_port", t))
        self.world = world_combo(ctx)
        self.start_nm, self.end_nm, self.step_nm = (self._nm(v) for v in (380.0, 780.0, 10.0))
        self.frames = QSpinBox()
        self.frames.setRange(1, 50)
        self.frames.setValue(2)
        self.radiance = QLineEdit()
        self.radiance.setPlaceholderText("radiance CSV or CGATS")
        self.radiance.setToolTip("The spectroradiometer's readings (CSV or CGATS); empty with the virtual lab: it "
                                 "measures its own.")
        browse = QPushButton("…")
        browse.clicked.connect(lambda: self._browse(self.radiance, "Radiance readings"))
        self.out.setPlaceholderText("measurements/camera_csrf.csv")
        self.out.setToolTip("Where the camera CSV is written; empty: <captures folder>/measurements/camera_csrf.csv.")
        self.form.addRow("Monochromator", self.bench)
        self.form.addRow("Serial port", self.port)
        self.form.addRow("World (virtual lab)", self.world)
        for label, w in (("From", self.start_nm), ("To", self.end_nm), ("Step", self.step_nm),
                         ("Frames per wavelength", self.frames)):
            self.form.addRow(label, w)
        self.form.addRow("Radiance", path_row(self.radiance, browse))
        self.form.addRow("Camera CSV", self.out)
        self.plot.setLabel("left", "relative sensitivity (green max = 1)")
        self.lay_out()

    @staticmethod
    def _nm(value: float) -> QDoubleSpinBox:
        spin = QDoubleSpinBox()
        spin.setRange(1.0 if value < 20 else 100.0, 100.0 if value < 20 else 2500.0)
        spin.setSuffix("\u00a0nm")
        spin.setValue(value)
        return spin

    def _browse(self, edit: QLineEdit, title: str) -> None:
        path, _ = QFileDialog.getOpenFileName(self, title, str(self.ctx.captures_dir))
        if path:
            edit.setText(path)

    def settings(self) -> CsrfSettings:
        return CsrfSettings(self.start_nm.value(), self.end_nm.value(), self.step_nm.value(),
                            frames=self.frames.value())

    def prepare(self) -> tuple[list[PlannedFrame], Any]:
        from dualrgb.app.lab.csrf_bench import VirtualBench, measure_on_virtual_bench, virtual_bench
        from dualrgb.app.workflow.csrf_bench import bench_devices, measure_on_bench
        from dualrgb.simulation.radiance_reference import read_radiance_reference

        kind = str(self.bench.currentData())
        bench = None if kind == VIRTUAL else CsrfBench(kind, port=self.port.text().strip())
        virtual = VirtualBench(self.world.currentText(), self.ctx.lab.frame_size)
        settings = self.settings()
        camera = None if kind == VIRTUAL else self.ctx.lab.camera
        if kind != VIRTUAL and camera is None:
            raise ValueError("a real monochromator needs the camera: connect it in Devices first")
        radiance = self.radiance.text().strip()
        reference = read_radiance_reference(radiance) if radiance else None   # a bad file: said before any device
        if reference is None and kind != VIRTUAL:
            raise ValueError("a real measurement needs the monochromator's radiance: choose the spectroradiometer's "
                             "readings file")
        out = self.out_path()
        out.parent.mkdir(parents=True, exist_ok=True)

        def work(hooks: RunHooks) -> CsrfOutcome:
            def on_event(ev: ProgressEvent) -> None:
                hooks.on_event(ev)
                hooks.progress(ev.fraction, ev.message)
            if bench is None:
                with virtual_bench(virtual) as started:
                    return measure_on_virtual_bench(started, settings, out, None, reference=reference,
                                                    read_radiance=read_radiance_reference, prompt=hooks.prompt,
                                                    on_event=on_event, cancel=hooks.cancel)
            with bench_devices(bench, camera) as (cam, mono):
                return measure_on_bench(cam, mono, settings, out, None, radiance=reference, prompt=hooks.prompt,
                                        on_event=on_event, cancel=hooks.cancel)
        plan = [PlannedFrame(Role.CSRF.value, 0.0, f"{nm:g} nm", "metered, shutter open")
                for nm in settings.wavelengths()]
        return plan, work

    def plan_line(self) -> str:
        s = self.settings()
        return (f"{len(s.wavelengths())} wavelengths, {s.frames} frame(s) each at a metered exposure, then darks at "
                "every exposure used; the sphere stays off (the monochromator lights the camera)")

    def show_result(self, result: CsrfOutcome) -> None:
        m = result.measurement
        if m is None:
            self.result_label.setText("camera measurement cancelled: the shutter is closed, nothing written")
            return
        r = m.result
        self.plot.clear()
        for i, pen in enumerate(CHANNEL_PENS):
            self.plot.plot(np.asarray(r.wavelengths), np.asarray(r.values[:, i]), pen=pen, name="RGB"[i])
        line = f"camera CSV written: {len(r.wavelengths)} wavelengths, session {m.session}"
        if result.rms_percent is not None:
            line += ("; against the virtual camera's curves, RMS % of peak: "
                     + ", ".join(f"{c} {v:.2f}" for c, v in result.rms_percent.items()))
        self.result_label.setText(line)
        self.files_label.set_path(str(m.path))
        self.use_button.setEnabled(True)
        log.info("%s: %s", m.path, line)


class LedMeasureView(MeasureView):
    """``dualrgb measure leds --virtual-lab`` and ``dualrgb measure import-leds``: a stand folder."""

    title = "the LEDs"
    use_key = STAND_DIR_KEY
    default_out = "leds"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(ctx, parent)
        self.written: list[Path] = []
        self._plan_line = ""
        self.world = world_combo(ctx)
        self.warmup_min = QDoubleSpinBox()
        self.warmup_min.setRange(0.1, 59.5)
        self.warmup_min.setValue(59.0)
        self.warmup_min.setSuffix("\u00a0min")
        self.warmup_min.setToolTip("Warm-up per LED at full level (the virtual lab's clock skips the waiting).")
        self.out.setPlaceholderText("<captures folder>/measurements/leds")
        self.import_button = QPushButton("Import a real instrument's readings…")
        self.import_button.setToolTip("Spectroradiometer files (CGATS .ti3, .sp or "
                                      "CSV) named LED<n>_level<x> / LED<n>_t<seconds>, analysed into the folder.")
        self.import_button.clicked.connect(self._ask_import)
        self.form.addRow("World (virtual lab)", self.world)
        self.form.addRow("Warm-up", self.warmup_min)
        self.form.addRow("Stand folder", self.out)
        self.form.addRow(self.import_button)
        self.plot.setLabel("left", "spectrum at full level (relative)")
        self.start_button.setToolTip("The virtual lab's sphere and spectroradiometer (a real sphere's readings come "
                                     "from its instrument's software: Import). No original on the stand.")
        self.lay_out()

    def prepare(self) -> tuple[list[PlannedFrame], Any]:
        from dualrgb.app.lab.led_bench import measure_virtual
        from dualrgb.app.sequences.led_measurement import LedMeasurementPlan

        warmup_s = 60.0 * self.warmup_min.value()
        plan = LedMeasurementPlan(warmup_s=warmup_s, interval_s=min(60.0, warmup_s / WARMUP_READINGS))
        out, world = self.out_path(), self.world.currentText()
        self._plan_line = f"{plan.steps} readings; {plan.light_mode()}"

        def work(hooks: RunHooks) -> tuple[Any, list[Path]]:
            def progress(fraction: float, message: str) -> None:
                hooks.cancel.check()                       # Cancel: the virtual lab closes, its light off
                hooks.progress(fraction, message)
            return measure_virtual(out, world, plan, None, 0, progress)
        rows = [PlannedFrame("led", 0.0, f"LED {led}", "levels and warm-up") for led in plan.leds]
        return rows, work

    def plan_line(self) -> str:
        return self._plan_line

    def _ask_import(self) -> None:
        paths, _ = QFileDialog.getOpenFileNames(self, "Spectroradiometer readings", str(self.ctx.captures_dir))
        if paths:
            self.import_readings([Path(p) for p in paths])

    def import_readings(self, paths: list[Path]) -> None:
        from dualrgb.app.workflow.calibration.led_stand import import_readings

        out = self.out_path()
        self.ctx.runner.submit(lambda: import_readings(list(paths), out), name="import LED readings",
                               on_result=self.show_result,
                               on_error=lambda exc: self.ctx.errors.report("Import LED readings", exc))

    def show_result(self, result: tuple[Any, list[Path]]) -> None:
        measurement, files = result
        self.plot.clear()
        for led, r in sorted(measurement.leds.items()):
            if r.spectrum is not None:
                peak = float(np.max(r.spectrum)) or 1.0
                self.plot.plot(np.asarray(measurement.wavelengths), np.asarray(r.spectrum) / peak,
                               pen=(led - 1, 10), name=f"LED {led}")
        level = measurement.min_stable_level
        stable = f"minimum stable level {level:.4g}" if level is not None else "minimum stable level not measured"
        self.result_label.setText(f"{len(measurement.leds)} LEDs measured, {stable}; {len(files)} files written "
                                  "(Simulate & optimise on the measured stand takes the folder)")
        self.files_label.set_path(str(self.out_path()))
        self.use_button.setEnabled(bool(files))
        self.written = files
