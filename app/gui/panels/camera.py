"""Camera: ISO / shutter / aperture / RAW, single capture with a DN histogram, live view with a zoom box at 100 %,
a focus measure over time (app.gui.focus_aid) and a framing light (app.gui.framing_light)."""
from __future__ import annotations

import datetime as _dt
import logging
from pathlib import Path

import numpy as np
import pyqtgraph as pg
from PySide6.QtCore import Qt, QTimer
from PySide6.QtWidgets import (
    QCheckBox,
    QComboBox,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.focus_aid import FocusAid, brightened
from dualrgb.app.gui.frame_preview import WARNING_STYLE, HistogramPlot
from dualrgb.app.gui.framing_light import FramingBox, FramingLight
from dualrgb.app.gui.live_aids import live_overlay
from dualrgb.app.gui.viewmodel import RawView, preview_histogram, raw_view
from dualrgb.app.gui.widgets import PathLabel, image_widget, side_by_side
from dualrgb.core.session.capture_session import atomic_write
from dualrgb.core.vocabulary import format_exposure as format_shutter
from dualrgb.drivers.camera.base import CameraSettings

log = logging.getLogger(__name__)
CameraReading = tuple[CameraSettings, list[float], list[int]]     # settings, shutter speeds, ISO values

COMMON_ISO = (50, 64, 80, 100, 125, 160, 200, 250, 320, 400, 500, 640, 800, 1000, 1250, 1600, 3200, 6400)
COMMON_APERTURES = (2.8, 4.0, 5.6, 8.0, 11.0, 16.0, 22.0)
RAW_QUALITY = "NEF (Raw)"
ISO_NOTE = ("ISO 50 is the thesis' choice; on a D610 it is the extended 'Lo 1' setting, which gives up highlight "
            "headroom. Base ISO 100 keeps the full raw range. Calibrate and capture at the same ISO.")


class CameraPanel(QWidget):
    title = "Camera"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        self.last_view: RawView | None = None
        self._preview_pending = False
        self._capturing = False
        self._sequence_running = False
        left = QWidget()
        ll = QVBoxLayout(left)
        ll.addWidget(self._settings_box())
        ll.addWidget(self._capture_box())
        self.framing = FramingLight(self.lab, ctx.workspace, self)
        self.framing_box = FramingBox(self.framing, ctx.get, ctx.set)
        ll.addWidget(self.framing_box)
        ll.addStretch(1)
        side_by_side(self, left, self._picture())
        self._live_timer = QTimer(self)
        self._live_timer.setInterval(250)
        self._live_timer.timeout.connect(self._request_preview)
        self.lab.cameraChanged.connect(self._camera_changed)
        ctx.workspace.runningChanged.connect(lambda name: self._set_sequence_running(bool(name)))
        self._camera_changed()

    # ------------------------------------------------------------------ builders
    def _settings_box(self) -> QGroupBox:
        box = QGroupBox("Settings")
        sg = QGridLayout(box)
        self.iso = QComboBox()
        self.iso.setEditable(True)
        self.iso.setToolTip(ISO_NOTE)
        self.iso_note = QLabel(ISO_NOTE)
        self.iso_note.setWordWrap(True)
        self.iso_note.setStyleSheet("color:#555")
        self.shutter = QComboBox()
        self.shutter.setToolTip("Exposure time. Above 30 s the camera uses bulb (timed by this program).")
        self.aperture = QComboBox()
        self.aperture.setEditable(True)
        self.aperture.setToolTip("Lens f-number. f/8 is sharp and keeps the whole object in focus.")
        self.raw = QCheckBox("RAW (NEF)")
        self.raw.setChecked(True)
        self.raw.setToolTip("Record raw files (needed for measurement; JPEG is for looking only).")
        self.read_button = QPushButton("Read from camera")
        self.read_button.setToolTip("Show what the camera is set to now.")
        self.read_button.clicked.connect(self.read_settings)
        self.apply_button = QPushButton("Apply to camera")
        self.apply_button.setToolTip("Send ISO, shutter, aperture and RAW to the camera (it picks the nearest "
                                     "values it offers); the calibration is checked against them again.")
        self.apply_button.clicked.connect(self.apply_settings)
        sg.addWidget(QLabel("ISO"), 0, 0)
        sg.addWidget(self.iso, 0, 1)
        sg.addWidget(self.iso_note, 1, 0, 1, 2)
        for r, (label, w) in enumerate((("Shutter", self.shutter), ("Aperture f/", self.aperture)), start=2):
            sg.addWidget(QLabel(label), r, 0)
            sg.addWidget(w, r, 1)
        sg.addWidget(self.raw, 4, 0, 1, 2)
        sg.addWidget(self.read_button, 5, 0)
        sg.addWidget(self.apply_button, 5, 1)
        self.settings_label = QLabel("camera not connected")
        self.settings_label.setWordWrap(True)
        sg.addWidget(self.settings_label, 6, 0, 1, 2)
        for c in COMMON_ISO:
            self.iso.addItem(str(c))
        for a in COMMON_APERTURES:
            self.aperture.addItem(f"{a:g}")
        return box

    def _capture_box(self) -> QGroupBox:
        box = QGroupBox("Capture")
        cl = QVBoxLayout(box)
        self.capture_button = QPushButton("Take a picture  (Ctrl+Enter)")
        self.capture_button.setToolTip("One raw exposure with these settings, saved in the test-shots folder; "
                                       "its histogram shows clipping and the linear limit. A dark frame says so.")
        self.capture_button.clicked.connect(self.capture)
        self.live_button = QPushButton("Live view")
        self.live_button.setCheckable(True)
        self.live_button.setToolTip("Show the camera's live picture (a few frames a second); with the virtual camera "
                                    "the histogram follows it (estimated from the preview).")
        self.live_button.toggled.connect(self.set_live_view)
        self.capture_label = PathLabel("")
        self.warning_label = QLabel("")
        self.warning_label.setWordWrap(True)
        self.warning_label.setStyleSheet(WARNING_STYLE)
        self.peaking = QCheckBox("Focus peaking")
        self.peaking.setToolTip("Mark the sharpest edges of the live picture in green (app.gui.live_aids): turn the "
                                "focus ring until the marks crowd on the subject's edges.")
        self.grid = QCheckBox("Grid")
        self.grid.setToolTip("Thirds over the live picture, to square the original on the stand.")
        aids = QHBoxLayout()
        aids.addWidget(self.peaking)
        aids.addWidget(self.grid)
        aids.addStretch(1)
        cl.addWidget(self.capture_button)
        cl.addWidget(self.live_button)
        cl.addLayout(aids)
        cl.addWidget(self.capture_label)
        cl.addWidget(self.warning_label)
        return box

    def _picture(self) -> QSplitter:
        self.view_widget, self.image, self.viewbox = image_widget(
            "Live view, or the last picture taken (raw, shown brightened for the screen).")
        self.view_title = QLabel("no picture yet")
        self.histogram = HistogramPlot()
        self.hist = self.histogram.widget
        self.hist_curves = self.histogram.curves
        self.hist_label = QLabel("")
        self.hist_label.setWordWrap(True)
        right = QSplitter(Qt.Orientation.Vertical)
        top = QWidget()
        tl = QVBoxLayout(top)
        tl.setContentsMargins(0, 0, 0, 0)
        tl.addWidget(self.view_title)
        tl.addWidget(self.view_widget, 1)
        bottom = QWidget()
        bl = QVBoxLayout(bottom)
        bl.setContentsMargins(0, 0, 0, 0)
        bl.addWidget(self.hist, 1)
        bl.addWidget(self.hist_label)
        self.focus = FocusAid()
        self.focus.attach(self.viewbox)
        right.addWidget(top)
        right.addWidget(self.focus)
        right.addWidget(bottom)
        right.setStretchFactor(0, 3)
        right.setStretchFactor(1, 2)
        right.setStretchFactor(2, 2)
        return right

    # ------------------------------------------------------------------ state
    def _enable(self) -> None:
        ok = self.lab.camera is not None and not self._sequence_running
        for w in (self.read_button, self.apply_button, self.live_button, self.iso, self.shutter, self.aperture,
                  self.raw):
            w.setEnabled(ok)
        self.capture_button.setEnabled(ok and not self._capturing)

    def _set_sequence_running(self, running: bool) -> None:
        self._sequence_running = running
        if running:
            self.live_button.setChecked(False)     # the sequence owns the camera now
        self._enable()

    def _camera_changed(self) -> None:
        if self.lab.camera is None:
            self.live_button.setChecked(False)
            self.settings_label.setText("camera not connected: connect it in Devices")
        else:
            self.read_settings()
        self._enable()

    # ------------------------------------------------------------------ settings
    def read_settings(self) -> None:
        cam = self.lab.camera
        if cam is None:
            return

        def work() -> CameraReading:
            iso_values = getattr(cam, "iso_values", None)
            return cam.settings(), cam.shutter_speeds(), list(iso_values()) if iso_values else []

        self.lab.device_call(work, "Read the camera settings", on_result=self._show_settings)

    def _show_settings(self, result: CameraReading) -> None:
        s, speeds, isos = result
        self.shutter.blockSignals(True)
        self.shutter.clear()
        for t in speeds:
            self.shutter.addItem(format_shutter(t), t)
        if s.shutter_s is not None:
            idx = int(np.argmin([abs(np.log(t / s.shutter_s)) for t in speeds])) if speeds else -1
            if idx >= 0:
                self.shutter.setCurrentIndex(idx)
        self.shutter.blockSignals(False)
        if isos:
            self.iso.clear()
            self.iso.addItems([str(i) for i in isos])
        if s.iso is not None:
            self.iso.setCurrentText(str(s.iso))
        if s.aperture is not None:
            self.aperture.setCurrentText(f"{s.aperture:g}")
        if s.image_quality:
            self.raw.setChecked("raw" in s.image_quality.lower() or "nef" in s.image_quality.lower())
        self.settings_label.setText(
            f"camera: ISO {s.iso}, {format_shutter(s.shutter_s)}, f/{s.aperture:g}, {s.image_quality or '?'}, "
            f"to {s.capture_target or '?'}" if s.aperture else f"camera: {s}")

    def wanted_settings(self) -> CameraSettings:
        def num(text: str) -> float | None:
            try:
                return float(text.strip().replace(",", "."))
            except ValueError:
                return None
        iso = num(self.iso.currentText())
        return CameraSettings(iso=int(iso) if iso else None, shutter_s=self.shutter.currentData(),
                              aperture=num(self.aperture.currentText()),
                              image_quality=RAW_QUALITY if self.raw.isChecked() else None)

    def apply_settings(self) -> None:
        cam = self.lab.camera
        if cam is None:
            return
        wanted = self.wanted_settings()
        def work() -> CameraReading:
            cam.apply(wanted)
            return cam.settings(), cam.shutter_speeds(), []

        def applied(r: CameraReading) -> None:
            self._show_settings(r)
            self.ctx.bus.cameraSettingsChanged.emit()
        self.lab.device_call(work, "Apply the camera settings", on_result=applied)

    # ------------------------------------------------------------------ capture
    def capture_shortcut(self) -> None:
        if self.capture_button.isEnabled():
            self.capture()

    def capture(self) -> None:
        cam = self.lab.camera
        if cam is None:
            self.ctx.errors.report("Take a picture", "the camera is not connected: connect it in Devices first")
            return
        wanted = self.wanted_settings()
        folder = self.ctx.captures_dir / "test-shots"
        self._capturing = True
        self._enable()
        self.capture_label.set_path("capturing …")
        self.warning_label.setText("")

        def work() -> RawView:
            cam.apply(wanted)
            raw = cam.capture(wanted.shutter_s)
            folder.mkdir(parents=True, exist_ok=True)
            stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
            path = folder / f"{stamp}_{raw.filename}"
            atomic_write(path, raw.data)
            log.info("test shot saved: %s (%.1f MB)", path, len(raw.data) / 1e6)
            view = raw_view(path)
            if view.iso is None:
                view.iso = raw.iso
            return view

        def finished() -> None:
            self._capturing = False
            self._enable()

        self.lab.device_call(work, "Take a picture", on_result=self.show_raw, on_finished=finished,
                             on_error=lambda exc: self.capture_label.set_path(f"failed: {exc}"))

    def show_raw(self, view: RawView) -> None:
        self.last_view = view
        self.image.setImage(view.image, autoLevels=False, levels=(0, 255))
        self.viewbox.autoRange()
        exp = format_shutter(view.exposure_s) if view.exposure_s else "?"
        self.view_title.setText(f"{Path(view.path).name}: {view.camera}, {exp}, ISO {view.iso or '?'}")
        self.capture_label.set_path(f"saved {view.path}")
        self.show_histogram(view.histogram, f"{Path(view.path).name} (raw)")
        light_on = self.lab.last_status.get("light_on") if self.lab.last_status else None
        self.warning_label.setText(view.check.warning(light_on) if view.check is not None else "")

    def show_histogram(self, h, source: str) -> None:
        self.histogram.show(h)
        self.hist_label.setText(f"{source}: {h.summary()}")
        self.hist_label.setStyleSheet("color:#c62828" if h.fraction_clipped > 0 else
                                      "color:#b26a00" if h.fraction_nonlinear > 0 else "")

    # ------------------------------------------------------------------ live view
    def set_live_view(self, on: bool) -> None:
        if on and self.lab.camera is not None:
            self._live_timer.start()
            self._request_preview()
        else:
            self._live_timer.stop()
            self.framing.stop("live view stopped")
            if self.live_button.isChecked():
                self.live_button.setChecked(False)

    def _request_preview(self) -> None:
        cam = self.lab.camera
        if cam is None or self._preview_pending:
            return
        self._preview_pending = True

        def failed(exc: BaseException) -> None:
            self.live_button.setChecked(False)

        def work():
            frame = cam.preview()
            sensor = getattr(cam, "sensor", None)        # the virtual camera: preview encoded like its raw data
            hist = preview_histogram(frame, sensor.black_level, sensor.white_level) \
                if sensor is not None and frame.ndim == 3 else None
            return frame, hist

        self.lab.device_call(work, "Live view", on_result=self._show_preview, on_error=failed,
                             on_finished=lambda: setattr(self, "_preview_pending", False))

    def _show_preview(self, result) -> None:
        frame, hist = result
        if not self.live_button.isChecked():
            return
        shown, gain = brightened(frame) if self.framing.active else (frame, 1.0)     # the low framing light
        self.image.setImage(shown, autoLevels=False, levels=(0, 255))
        self.view_title.setText(f"live view {frame.shape[1]}x{frame.shape[0]}"
                                + (f", brightened x{gain:.2g} for the framing light" if gain > 1 else ""))
        self.focus.feed(frame, shown)
        self._show_aids(frame)
        if hist is not None:
            self.show_histogram(hist, "live view (estimated from the preview)")

    def _show_aids(self, frame) -> None:
        """Focus peaking and the grid over the live picture (app.gui.live_aids)."""
        if not hasattr(self, "aid_overlay"):
            self.aid_overlay = pg.ImageItem(axisOrder="row-major")
            self.viewbox.addItem(self.aid_overlay)
        on = self.peaking.isChecked() or self.grid.isChecked()
        self.aid_overlay.setVisible(on)
        if on:
            overlay = live_overlay(frame, peaking=self.peaking.isChecked(), grid=3 if self.grid.isChecked() else 0)
            self.aid_overlay.setImage(overlay, autoLevels=False, levels=(0, 255))

    def shutdown(self) -> None:
        self._live_timer.stop()
        self.framing.stop("the window closes")
