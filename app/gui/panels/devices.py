"""Devices: connect the LED sphere (serial port or the emulator) and the camera (gphoto2 or virtual)."""
from __future__ import annotations

import logging
from typing import Optional

from PySide6.QtWidgets import (QComboBox, QFileDialog, QGridLayout, QGroupBox, QLabel, QPushButton,
                               QVBoxLayout, QWidget)

from app.gui.context import AppContext
from app.gui.device_hub import NO_CAMERA_ADVICE, VIRTUAL_CAMERA, VIRTUAL_SPHERE, serial_ports
from app.gui.widgets import StatusLight

log = logging.getLogger(__name__)

PLACES = (("test target (CC24)", "test", False), ("training target", "train", False),
          ("test target + ND 2.0 over half", "test", True), ("open gate (flat field)", "open-gate", False),
          ("lens cap (dark)", "lens-cap", False))


class DevicesPanel(QWidget):
    title = "Devices"

    def __init__(self, ctx: AppContext, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab

        # ---- sphere ----
        sbox = QGroupBox("LED sphere")
        sg = QGridLayout(sbox)
        self.port_combo = QComboBox()
        self.port_combo.setEditable(True)
        self.port_combo.setToolTip("The sphere's serial port (/dev/ttyACM0 on Linux), or the built-in emulator "
                                   "to try everything without hardware.")
        self.refresh_ports = QPushButton("Refresh")
        self.refresh_ports.setToolTip("List the serial ports again (after plugging the sphere in).")
        self.refresh_ports.clicked.connect(self.list_ports)
        self.sphere_button = QPushButton("Connect")
        self.sphere_button.setToolTip("Open the port, check the sphere answers, and switch every LED off.")
        self.sphere_button.clicked.connect(self._toggle_sphere)
        self.sphere_light = StatusLight("not connected")
        self.sphere_message = QLabel("")
        self.sphere_message.setWordWrap(True)
        sg.addWidget(QLabel("Port"), 0, 0)
        sg.addWidget(self.port_combo, 0, 1)
        sg.addWidget(self.refresh_ports, 0, 2)
        sg.addWidget(self.sphere_button, 0, 3)
        sg.addWidget(self.sphere_light, 1, 0, 1, 4)
        sg.addWidget(self.sphere_message, 2, 0, 1, 4)

        # ---- camera ----
        cbox = QGroupBox("Camera")
        cg = QGridLayout(cbox)
        self.camera_combo = QComboBox()
        self.camera_combo.setToolTip("Cameras found on USB (gphoto2), and the virtual camera of the virtual lab.")
        self.detect_button = QPushButton("Detect")
        self.detect_button.setToolTip("Look for cameras on USB again.")
        self.detect_button.clicked.connect(self.detect)
        self.camera_button = QPushButton("Connect")
        self.camera_button.setToolTip("Open the camera and read its settings.")
        self.camera_button.clicked.connect(self._toggle_camera)
        self.camera_light = StatusLight("not connected")
        self.camera_message = QLabel("")
        self.camera_message.setWordWrap(True)
        cg.addWidget(QLabel("Camera"), 0, 0)
        cg.addWidget(self.camera_combo, 0, 1)
        cg.addWidget(self.detect_button, 0, 2)
        cg.addWidget(self.camera_button, 0, 3)
        cg.addWidget(self.camera_light, 1, 0, 1, 4)
        cg.addWidget(self.camera_message, 2, 0, 1, 4)

        # ---- virtual lab ----
        vbox = QGroupBox("Virtual lab (no hardware needed)")
        vg = QGridLayout(vbox)
        self.virtual_button = QPushButton("Start virtual lab")
        self.virtual_button.setToolTip("Start the sphere emulator and the virtual camera and connect both.")
        self.virtual_button.clicked.connect(lambda: self.lab.start_virtual_lab())
        self.place_combo = QComboBox()
        for label, _what, _nd in PLACES:
            self.place_combo.addItem(label)
        self.place_combo.setToolTip("What lies on the virtual copy stand (the sequences place what they need).")
        self.place_button = QPushButton("Place")
        self.place_button.setToolTip("Put the chosen object on the virtual copy stand.")
        self.place_button.clicked.connect(self._place)
        self.virtual_label = QLabel("not started")
        self.mode_combo = QComboBox()
        self.mode_combo.addItems(["reflective", "transmissive"])
        self.mode_combo.setToolTip("Reflective: prints and paintings on the stand; transmissive: film on the light "
                                   "box (chooses the virtual lab's targets and the reference data).")
        self.mode_combo.setCurrentText(ctx.get("virtual/mode", "reflective", str))
        self.lab.mode = self.mode_combo.currentText()
        self.mode_combo.currentTextChanged.connect(self._mode_changed)
        vg.addWidget(self.mode_combo, 0, 3)
        vg.addWidget(self.virtual_button, 0, 0)
        vg.addWidget(self.place_combo, 0, 1)
        vg.addWidget(self.place_button, 0, 2)
        vg.addWidget(self.virtual_label, 1, 0, 1, 4)

        # ---- folders ----
        fbox = QGroupBox("Folders")
        fg = QGridLayout(fbox)
        self.folder_labels: dict[str, QLabel] = {}
        for r, (key, title, tip) in enumerate((
                ("paths/captures", "Captures", "Where sessions and test shots are saved."),
                ("paths/presets", "Your presets", "Where your own light presets are saved (the packaged ones "
                                                  "are always listed too)."))):
            label = QLabel()
            label.setToolTip(tip)
            button = QPushButton("Change…")
            button.setToolTip(tip)
            button.clicked.connect(lambda _=False, k=key, t=title: self._choose_folder(k, t))
            fg.addWidget(QLabel(title), r, 0)
            fg.addWidget(label, r, 1)
            fg.addWidget(button, r, 2)
            self.folder_labels[key] = label
        fg.setColumnStretch(1, 1)
        self._show_folders()

        lay = QVBoxLayout(self)
        lay.addWidget(sbox)
        lay.addWidget(cbox)
        lay.addWidget(vbox)
        lay.addWidget(fbox)
        lay.addStretch(1)

        self.lab.sphereChanged.connect(self._sphere_changed)
        self.lab.cameraChanged.connect(self._camera_changed)
        self.lab.virtualLabChanged.connect(self._virtual_changed)
        self.lab.sphereStatus.connect(self._sphere_status)
        self.lab.failed.connect(self._failed)
        ctx.bus.sequenceStarted.connect(lambda _n: self._set_sequence_running(True))
        ctx.bus.sequenceFinished.connect(lambda _n, _how: self._set_sequence_running(False))
        self.list_ports()
        self.camera_combo.addItem(VIRTUAL_CAMERA)
        last = ctx.get("devices/camera", "", str)
        if last and self.camera_combo.findText(last) < 0:
            self.camera_combo.addItem(last)
        if last:
            self.camera_combo.setCurrentText(last)
        self._sphere_changed()
        self._camera_changed()
        self._virtual_changed()

    # ------------------------------------------------------------------ sphere
    def list_ports(self) -> None:
        def done(ports: list[str]) -> None:
            current = self.port_combo.currentText() or self.ctx.get("devices/sphere_port", VIRTUAL_SPHERE, str)
            self.port_combo.clear()
            self.port_combo.addItems(ports)
            if current and self.port_combo.findText(current) < 0:
                self.port_combo.addItem(current)
            self.port_combo.setCurrentText(current or VIRTUAL_SPHERE)
        self.ctx.runner.submit(serial_ports, pool="devices", name="list serial ports", on_result=done,
                               on_error=lambda exc: self.ctx.errors.report("List serial ports", exc))

    def _toggle_sphere(self) -> None:
        if self.lab.sphere is not None:
            self.lab.disconnect_sphere()
            return
        port = self.port_combo.currentText().strip()
        if not port:
            self.ctx.errors.report("Connect the LED sphere", "choose a port first (e.g. /dev/ttyACM0), or the "
                                   "virtual sphere (emulator)")
            return
        self.ctx.set("devices/sphere_port", port)
        self.sphere_light.set_state("busy", f"connecting to {port} …")
        self.sphere_message.setText("")
        self.sphere_button.setEnabled(False)
        self.lab.connect_sphere(port, on_done=lambda ok: self.sphere_button.setEnabled(True))

    def _sphere_changed(self) -> None:
        if self.lab.sphere is not None:
            self.sphere_light.set_state("ok", f"connected on {self.lab.sphere.port}")
            self.sphere_button.setText("Disconnect")
            self.sphere_button.setToolTip("Switch every LED off and close the port.")
            self.sphere_message.setText("")
            if self.lab.sphere_port:
                self.port_combo.setCurrentText(self.lab.sphere_port)
        else:
            if self.sphere_light.state != "error":
                self.sphere_light.set_state("off", "not connected")
            self.sphere_button.setText("Connect")
            self.sphere_button.setToolTip("Open the port, check the sphere answers, and switch every LED off.")
        self.sphere_button.setEnabled(True)

    def _sphere_status(self, status: dict) -> None:
        if status.get("light_on"):
            self.sphere_light.set_state("on", f"connected on {status.get('port')}: light ON")
        else:
            self.sphere_light.set_state("ok", f"connected on {status.get('port')}: light off, "
                                              f"{status.get('temperature_c', 0):.1f} °C")

    # ------------------------------------------------------------------ camera
    def detect(self) -> None:
        self.detect_button.setEnabled(False)
        self.camera_message.setText("looking for cameras …")

        def done(found: tuple[list[str], list[str]]) -> None:
            names, hints = found
            current = self.camera_combo.currentText()
            self.camera_combo.clear()
            self.camera_combo.addItems(names)
            if current in names:
                self.camera_combo.setCurrentText(current)
            real = [n for n in names if n != VIRTUAL_CAMERA]
            lines = [f"found {len(real)} camera(s) on USB" if real else NO_CAMERA_ADVICE] + hints
            self.camera_message.setText("\n".join(lines))
            if hints:
                self.camera_light.set_state("error", "a camera is on USB but cannot be used (see below)")
        self.lab.detect_cameras(done, on_finished=lambda: self.detect_button.setEnabled(True))

    def _toggle_camera(self) -> None:
        if self.lab.camera is not None:
            self.lab.disconnect_camera()
            return
        choice = self.camera_combo.currentText()
        if not choice:
            self.ctx.errors.report("Connect the camera", NO_CAMERA_ADVICE)
            return
        self.ctx.set("devices/camera", choice)
        self.camera_light.set_state("busy", f"opening {choice} …")
        self.camera_message.setText("")
        self.camera_button.setEnabled(False)
        self.lab.connect_camera(choice, on_done=lambda ok: self.camera_button.setEnabled(True))

    def _camera_changed(self) -> None:
        if self.lab.camera is not None:
            self.camera_light.set_state("ok", f"connected: {self.lab.camera_name}")
            self.camera_button.setText("Disconnect")
            self.camera_message.setText("")
            if self.camera_combo.findText(self.lab.camera_name) < 0:
                self.camera_combo.addItem(self.lab.camera_name)
            self.camera_combo.setCurrentText(self.lab.camera_name)
        else:
            if self.camera_light.state != "error":
                self.camera_light.set_state("off", "not connected")
            self.camera_button.setText("Connect")
        self.camera_button.setEnabled(True)

    def _set_sequence_running(self, running: bool) -> None:
        """No connecting, disconnecting or placing while a sequence uses the devices."""
        for w in (self.sphere_button, self.camera_button, self.place_button, self.virtual_button):
            w.setEnabled(not running)
        if not running:
            self._sphere_changed()
            self._camera_changed()
            self._virtual_changed()

    # ------------------------------------------------------------------ folders
    def _show_folders(self) -> None:
        self.folder_labels["paths/captures"].setText(str(self.ctx.captures_dir))
        self.folder_labels["paths/presets"].setText(str(self.ctx.presets_dir))

    def _choose_folder(self, key: str, title: str) -> None:
        current = self.ctx.captures_dir if key == "paths/captures" else self.ctx.presets_dir
        folder = QFileDialog.getExistingDirectory(self, f"{title} folder", str(current))
        if folder:
            self.set_folder(key, folder)

    def set_folder(self, key: str, folder: str) -> None:
        self.ctx.set(key, str(folder))
        self._show_folders()
        if key == "paths/presets":
            self.ctx.bus.presetsChanged.emit()

    # ------------------------------------------------------------------ virtual lab / errors
    def _place(self) -> None:
        _label, what, nd = PLACES[self.place_combo.currentIndex()]
        self.lab.place(what, nd, on_done=self._virtual_changed)

    def _mode_changed(self, mode: str) -> None:
        self.ctx.set("virtual/mode", mode)
        self.lab.mode = mode

    def _virtual_changed(self) -> None:
        vl = self.lab.virtual_lab
        running = vl is not None
        self.place_button.setEnabled(running)
        self.virtual_button.setEnabled(not running)
        self.mode_combo.setEnabled(not running)         # the lab's targets are chosen when it starts
        if running:
            self.virtual_label.setText(f"running: sphere emulator on {vl.port}, {vl.width}x{vl.height} frames, "
                                       f"on the stand: {vl.placed or 'nothing'}")

    def _failed(self, title: str, exc: object) -> None:
        text = str(exc)
        if "sphere" in title.lower():
            self.sphere_light.set_state("error", "problem (see below)")
            self.sphere_message.setText(text)
            self._sphere_changed()
        elif "camera" in title.lower():
            self.camera_light.set_state("error", "problem (see below)")
            self.camera_message.setText(text)
            self._camera_changed()
