"""Devices: connect the LED sphere (serial port or the emulator) and the camera (gphoto2 or virtual); the mode; the
folders (captures with their free space, your presets), and captures left in the old default folder offered."""
from __future__ import annotations

import logging

from PySide6.QtWidgets import (
    QComboBox,
    QFileDialog,
    QGridLayout,
    QGroupBox,
    QHBoxLayout,
    QLabel,
    QPushButton,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.context import AppContext
from dualrgb.app.gui.device_hub import VIRTUAL_CAMERA, VIRTUAL_SPHERE, serial_ports
from dualrgb.app.gui.units import temperature
from dualrgb.app.gui.widgets import PathLabel, StatusLight
from dualrgb.app.gui.wording import in_window_words
from dualrgb.app.workflow.stand.defaults import DEFAULT_MODE, MODES
from dualrgb.app.workflow.stand.folders import LegacyCaptures, folder_summary, legacy_captures, move_sessions
from dualrgb.app.workflow.stand.stand_devices import NO_CAMERA_ADVICE

log = logging.getLogger(__name__)

USE, MOVE, LEAVE = "Use it", "Move them", "Leave them"
LEGACY_CHOICES = (USE, MOVE, LEAVE)
PLACES = (("test target (CC24)", "test", False), ("training target", "train", False),
          ("test target + ND 2.0 over half", "test", True), ("open gate (flat field)", "open-gate", False),
          ("lens cap (dark)", "lens-cap", False))


class DevicesPanel(QWidget):
    title = "Devices"

    def __init__(self, ctx: AppContext, parent: QWidget | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.lab = ctx.lab
        lay = QVBoxLayout(self)
        for box in (self._sphere_box(), self._camera_box(), self._virtual_box(), self._folders_box()):
            lay.addWidget(box)
        lay.addStretch(1)
        self.lab.sphereChanged.connect(self._sphere_changed)
        self.lab.cameraChanged.connect(self._camera_changed)
        self.lab.virtualLabChanged.connect(self._virtual_changed)
        self.lab.sphereStatus.connect(self._sphere_status)
        self.lab.failed.connect(self._failed)
        ctx.workspace.runningChanged.connect(lambda name: self._set_sequence_running(bool(name)))
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

    # ------------------------------------------------------------------ builders
    def _sphere_box(self) -> QGroupBox:
        box = QGroupBox("LED sphere")
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
        _device_grid(box, "Port", self.port_combo, self.sphere_button, self.refresh_ports, self.sphere_light,
                     self.sphere_message)
        return box

    def _camera_box(self) -> QGroupBox:
        box = QGroupBox("Camera")
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
        _device_grid(box, "Camera", self.camera_combo, self.camera_button, self.detect_button, self.camera_light,
                     self.camera_message)
        return box

    def _virtual_box(self) -> QGroupBox:
        box = QGroupBox("Virtual lab (no hardware needed)")
        vg = QGridLayout(box)
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
        self.virtual_label.setWordWrap(True)
        self.mode_combo = QComboBox()
        self.mode_combo.addItems(list(MODES))
        self.mode_combo.setToolTip("Reflective: prints and paintings on the stand; transmissive: film on the light "
                                   "box (chooses the virtual lab's targets and the reference data).")
        self.mode_combo.setCurrentText(self.ctx.get("virtual/mode", DEFAULT_MODE, str))
        self.lab.set_mode(self.mode_combo.currentText())
        self.mode_combo.currentTextChanged.connect(self._mode_changed)
        for col, w in enumerate((self.virtual_button, self.place_combo, self.place_button, self.mode_combo)):
            vg.addWidget(w, 0, col)
        vg.addWidget(self.virtual_label, 1, 0, 1, 4)
        return box

    def _folders_box(self) -> QGroupBox:
        box = QGroupBox("Folders")
        fg = QGridLayout(box)
        self.folder_labels: dict[str, PathLabel] = {}
        for r, (key, title, tip) in enumerate((
                ("paths/captures", "Captures", "Where sessions (raw frames, calibrations, deliverables) and test "
                                               "shots are saved, with the free space there; default: the per-user "
                                               "data folder (app.workflow.stand.defaults)."),
                ("paths/presets", "Your presets", "Where your own light presets are saved (the packaged ones "
                                                  "are always listed too)."))):
            label = PathLabel()
            label.setToolTip(tip)
            button = QPushButton("Change…")
            button.setToolTip(tip)
            button.clicked.connect(lambda _=False, k=key, t=title: self._choose_folder(k, t))
            fg.addWidget(QLabel(title), r, 0)
            fg.addWidget(label, r, 1)
            fg.addWidget(button, r, 2)
            self.folder_labels[key] = label
        self.legacy: LegacyCaptures | None = None
        self.legacy_label = QLabel("")
        self.legacy_label.setWordWrap(True)
        self.legacy_use = QPushButton("Use it")
        self.legacy_use.setToolTip("Make the old folder the captures folder again (its sessions open as before).")
        self.legacy_use.clicked.connect(self.use_legacy)
        self.legacy_move = QPushButton("Move them here")
        self.legacy_move.setToolTip("Move its sessions and test shots, as they are, into the captures folder above.")
        self.legacy_move.clicked.connect(self.move_legacy)
        buttons = QHBoxLayout()
        buttons.addWidget(self.legacy_use)
        buttons.addWidget(self.legacy_move)
        fg.addWidget(self.legacy_label, 2, 0, 1, 2)
        fg.addLayout(buttons, 2, 2)
        fg.setColumnStretch(1, 1)
        for w in (self.legacy_label, self.legacy_use, self.legacy_move):
            w.hide()
        self._show_folders()
        self.find_legacy()
        return box

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
                                              f"{temperature(status.get('temperature_c'))}")

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
        captures, label = self.ctx.captures_dir, self.folder_labels["paths/captures"]
        label.set_path(str(captures))
        self.folder_labels["paths/presets"].set_path(str(self.ctx.presets_dir))
        self.ctx.runner.submit(lambda: folder_summary(captures), pool="compute", name="free space",
                               on_result=lambda text: label.set_path(text) if captures == self.ctx.captures_dir
                               else None, on_error=lambda exc: log.warning("free space: %s", exc))

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
        else:
            self.find_legacy()

    # ------------------------------------------------------------------ the old default captures folder
    def find_legacy(self) -> None:
        """Look for sessions in the old default captures folder (beside the settings file) and offer them."""
        settings_dir, captures = self.ctx.data_dir(), self.ctx.captures_dir
        self.ctx.runner.submit(lambda: legacy_captures(settings_dir, captures), pool="compute",
                               name="old captures folder", on_result=self._legacy_found,
                               on_error=lambda exc: log.warning("old captures folder: %s", exc))

    def _legacy_found(self, legacy: LegacyCaptures | None) -> None:
        self.legacy = legacy
        for w in (self.legacy_label, self.legacy_use, self.legacy_move):
            w.setVisible(legacy is not None)
        if legacy is None:
            return
        self.legacy_label.setText(f"{legacy.text()} (the default before this version); they stay openable "
                                  "there (Calibrate & capture: Open…)")
        if self.ctx.get("paths/legacy_offered", "", str) == str(legacy.folder):
            return                                   # asked once; the notice above stays
        self.ctx.set("paths/legacy_offered", str(legacy.folder))
        text = (f"{legacy.text()}, where captures went before this version (beside the settings file). New "
                f"sessions now go to {self.ctx.captures_dir}. Use the old folder, move its sessions into the new "
                "one, or leave them where they are (Devices keeps this offer; Open… still opens them)?")
        self.ctx.asker.ask("Earlier captures", text, LEGACY_CHOICES, self._legacy_answer, default=LEAVE)

    def _legacy_answer(self, choice: str) -> None:
        if choice == USE:
            self.use_legacy()
        elif choice == MOVE:
            self.move_legacy()

    def use_legacy(self) -> None:
        if self.legacy is not None:
            self.set_folder("paths/captures", str(self.legacy.folder))

    def move_legacy(self) -> None:
        legacy, target = self.legacy, self.ctx.captures_dir
        if legacy is None:
            return
        busy = [self.lab.session.path] if self.lab.session is not None else []
        self.lab.message.emit(f"moving the sessions of {legacy.folder} to {target} …")

        def moved(report) -> None:
            self.lab.message.emit(f"{legacy.folder} -> {target}: {report.text()}")
            self._show_folders()
            self.find_legacy()
        self.ctx.runner.submit(lambda: move_sessions(legacy.folder, target, busy), pool="devices",
                               name="move the old captures", on_result=moved,
                               on_error=lambda exc: self.ctx.errors.report("Move the old captures", exc))

    # ------------------------------------------------------------------ virtual lab / errors
    def _place(self) -> None:
        _label, what, nd = PLACES[self.place_combo.currentIndex()]
        self.lab.place(what, nd, on_done=self._virtual_changed)

    def _mode_changed(self, mode: str) -> None:
        self.ctx.set("virtual/mode", mode)
        self.lab.set_mode(mode)

    def _virtual_changed(self) -> None:
        vl = self.lab.virtual_lab
        running = vl is not None
        self.place_button.setEnabled(running)
        self.virtual_button.setEnabled(not running)
        self.mode_combo.setEnabled(not running)         # the lab's targets are chosen when it starts
        if vl is not None:
            self.virtual_label.setText(f"running: sphere emulator on {vl.port}, {vl.width}x{vl.height} frames, "
                                       f"on the stand: {vl.placed or 'nothing'}")
        else:
            self.virtual_label.setText("not started: Start virtual lab, or connect the virtual sphere or camera")

    def _failed(self, title: str, exc: object) -> None:
        text = in_window_words(str(exc))            # what the error box and status bar say: the port once, no shell
        if "sphere" in title.lower():
            self.sphere_light.set_state("error", "problem (see below)")
            self.sphere_message.setText(text)
            self._sphere_changed()
        elif "camera" in title.lower():
            self.camera_light.set_state("error", "problem (see below)")
            self.camera_message.setText(text)
            self._camera_changed()


def _device_grid(box: QGroupBox, label: str, combo: QComboBox, connect: QPushButton, find: QPushButton,
                 light: StatusLight, message: QLabel) -> None:
    """One device's row: its choice, the connect button (the primary action first) and the find one, then its
    status light and message."""
    grid = QGridLayout(box)
    for col, w in enumerate((QLabel(label), combo, connect, find)):
        grid.addWidget(w, 0, col)
    grid.addWidget(light, 1, 0, 1, 4)
    grid.addWidget(message, 2, 0, 1, 4)
