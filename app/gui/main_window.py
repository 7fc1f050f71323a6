"""The copy-stand window: the workflow guide on the left (always visible), a tab per panel, the log at the bottom,
a status bar (devices, what runs, the last error until the action succeeds), shortcuts, saved layout."""
from __future__ import annotations

import importlib
import logging
from collections.abc import Callable

from PySide6.QtCore import QByteArray, QSettings, Qt, QTimer
from PySide6.QtGui import QAction, QCloseEvent, QKeySequence
from PySide6.QtWidgets import QDockWidget, QLabel, QMainWindow, QMenu, QScrollArea, QTabWidget, QWidget

from dualrgb.app.gui import gc_thread
from dualrgb.app.gui.context import AppContext, Bus, default_settings
from dualrgb.app.gui.day_keeper import DayKeeper
from dualrgb.app.gui.device_hub import Lab
from dualrgb.app.gui.guide import WorkflowGuide
from dualrgb.app.gui.next_action import NextAction
from dualrgb.app.gui.panels.placeholder import NotAvailablePanel
from dualrgb.app.gui.session_watch import SessionWatch
from dualrgb.app.gui.units import temperature
from dualrgb.app.gui.widgets import Asker, ErrorReporter, LogView
from dualrgb.app.gui.window_menus import WheelGuard, build_menus
from dualrgb.app.gui.workers import TaskRunner
from dualrgb.app.gui.workspace import Workspace
from dualrgb.app.workflow.stand.defaults import VIRTUAL_FRAME_SIZE

log = logging.getLogger(__name__)

# (attribute, module, class, what is missing when the module cannot be imported)
PANELS = (
    ("devices", "dualrgb.app.gui.panels.devices", "DevicesPanel", "device drivers"),
    ("light", "dualrgb.app.gui.panels.light", "LightPanel", "LED sphere driver"),
    ("camera", "dualrgb.app.gui.panels.camera", "CameraPanel", "camera drivers"),
    ("capture", "dualrgb.app.gui.panels.capture", "CapturePanel", "capture sequences (app.sequences)"),
    ("originals", "dualrgb.app.gui.panels.originals", "OriginalsPanel", "the copy-stand workflow (app.workflow)"),
    ("target", "dualrgb.app.gui.panels.target", "TargetPanel", "patch grid (app.processing.patches)"),
    ("results", "dualrgb.app.gui.panels.results", "ResultsPanel", "characterisation report (app.processing)"),
    ("simulate", "dualrgb.app.gui.panels.simulate", "SimulatePanel", "simulation runner"),
    ("characterise", "dualrgb.app.gui.panels.characterise", "CharacterisePanel", "CRF sweep sequence"),
    ("tools", "dualrgb.app.gui.panels.tools", "ToolsPanel", "the copy-stand tools (app.workflow)"),
)
GUIDE_WIDTH = 270           # px: the workflow dock's fixed width; the panels get the rest of a 1280 px window
PANEL_TITLES = {"devices": "Devices", "light": "Light source", "camera": "Camera", "capture": "Calibrate && capture",
                "originals": "Originals", "target": "Target", "results": "Results",
                "simulate": "Simulate && optimise", "characterise": "Characterise", "tools": "Tools"}


class MainWindow(QMainWindow):
    def __init__(self, settings: QSettings | None = None, *, frame_size: tuple[int, int] = VIRTUAL_FRAME_SIZE,
                 show_dialogs: bool = True, shutter_bumps: bool = False):
        super().__init__()
        self.setWindowTitle("dualrgb — dual-RGB copy stand")
        gc_thread.start()                      # Qt objects are freed on the GUI thread only (app.gui.gc_thread)
        self.runner = TaskRunner(self)
        self.errors = ErrorReporter(self)
        self.errors.show_dialogs = show_dialogs
        self.asker = Asker(self)
        self.asker.show_dialogs = show_dialogs
        self.lab = Lab(self.runner, self, frame_size=frame_size, shutter_bumps=shutter_bumps)
        self.ctx = AppContext(self.runner, self.lab, settings or default_settings(), self.errors, Bus(self),
                              Workspace(self), self.asker, open_externally=show_dialogs)
        self.lab.failed.connect(lambda title, exc: self.errors.report(title, exc))
        self.lab.succeeded.connect(self.errors.clear)
        self._closing = False
        self._build_log_dock()
        self._build_panels()
        self._build_guide_dock()
        self._build_status_bar()
        self._build_actions()
        self._build_persistence()
        self.day = DayKeeper(self.ctx, self)       # the queue and calibration kept in the session; restored now
        self.day.restore()
        self.session_watch = SessionWatch(self.ctx, self.capture_new_session, self)   # a gone folder said at once

    def _build_log_dock(self) -> None:
        self.log_view = LogView()
        self.log_view.install()
        dock = QDockWidget("Log", self)
        dock.setObjectName("log_dock")
        dock.setWidget(self.log_view)
        self.addDockWidget(Qt.DockWidgetArea.BottomDockWidgetArea, dock)
        self.resizeDocks([dock], [140], Qt.Orientation.Vertical)
        self.log_dock = dock

    def _build_panels(self) -> None:
        self.tabs = QTabWidget()
        self.tabs.setObjectName("panels")
        self.panels: dict[str, QWidget] = {}
        for attr, module, cls, missing in PANELS:
            panel = self._make_panel(attr, module, cls, missing)
            self.panels[attr] = panel
            setattr(self, attr, panel)
            self.tabs.addTab(panel, PANEL_TITLES[attr])
            if isinstance(panel, NotAvailablePanel):
                self.tabs.setTabToolTip(self.tabs.count() - 1, panel.message)
        self.setCentralWidget(self.tabs)
        self.ctx.bus.showPanel.connect(self.show_panel)

    def _build_guide_dock(self) -> None:
        """The workflow guide: docked on the left, always visible (it can move, not close)."""
        self.guide = WorkflowGuide(self.ctx)
        scroll = QScrollArea()
        scroll.setWidget(self.guide)
        scroll.setWidgetResizable(True)
        dock = QDockWidget("Workflow", self)
        dock.setObjectName("guide_dock")
        dock.setWidget(scroll)
        dock.setFeatures(QDockWidget.DockWidgetFeature.DockWidgetMovable)
        dock.setFixedWidth(GUIDE_WIDTH)          # never moves the panels' buttons under the pointer (issue 42)
        self.addDockWidget(Qt.DockWidgetArea.LeftDockWidgetArea, dock)
        self.guide_dock = dock
        self.next_action = NextAction(self.panels, lambda: self.lab.sphere is not None)
        self.guide.refreshed.connect(lambda: self.next_action.show(self.guide.steps))
        self.next_action.show(self.guide.steps)

    def _build_status_bar(self) -> None:
        self.sphere_state = QLabel("sphere: —")
        self.camera_state = QLabel("camera: —")
        self.task_state = QLabel("")
        self.error_state = QLabel("")
        self.error_state.setStyleSheet("color:#c62828")
        self.error_state.setToolTip("The last error; it goes away when the same action succeeds.")
        for w in (self.error_state, self.task_state, self.sphere_state, self.camera_state):
            self.statusBar().addPermanentWidget(w)
        self.lab.message.connect(lambda m: self.statusBar().showMessage(m, 8000))
        self.lab.sphereChanged.connect(self._devices_changed)
        self.lab.cameraChanged.connect(self._devices_changed)
        self.lab.sphereStatus.connect(self._sphere_status)
        self.runner.busyChanged.connect(self._busy_changed)
        self.ctx.bus.sequenceFinished.connect(lambda *_: self.lab.poll_status())   # show the lights off at once
        self.errors.shown.connect(self._error_shown)
        self.errors.cleared.connect(lambda: self.error_state.setText(""))
        self._devices_changed()

    def _error_shown(self, title: str, message: str) -> None:
        short = message if len(message) <= 90 else message[:87] + "…"
        self.error_state.setText(f"{title}: {short}")
        self.error_state.setToolTip(f"{title}: {message}")

    def _build_actions(self) -> None:
        self.capture_action = QAction("Capture", self)
        self.capture_action.setShortcuts([QKeySequence("Ctrl+Return"), QKeySequence("F5")])
        self.capture_action.setToolTip("Take a picture (Camera), start the chosen sequence (Calibrate & capture) "
                                       "or capture the selected originals (Originals).")
        self.capture_action.triggered.connect(self.capture_shortcut)
        self.cancel_action = QAction("Cancel", self)
        self.cancel_action.setShortcuts([QKeySequence(Qt.Key.Key_Escape), QKeySequence("Ctrl+.")])
        self.cancel_action.setToolTip("Stop the running sequence or simulation (the lights go off).")
        self.cancel_action.triggered.connect(self.cancel_running)
        self.menu_actions = build_menus(self, self.ctx, self._open_session)     # File, then Capture, then Help
        menu = QMenu("&Capture", self)
        self.menuBar().insertMenu(self.menuBar().actions()[1], menu)
        menu.addAction(self.capture_action)
        menu.addAction(self.cancel_action)
        self.wheel_guard = WheelGuard(self)
        self.wheel_guard.guard(self)
        for a in (self.capture_action, self.cancel_action):
            a.setShortcutContext(Qt.ShortcutContext.ApplicationShortcut)
            self.addAction(a)

    def _build_persistence(self) -> None:
        self._save_timer = QTimer(self)
        self._save_timer.setSingleShot(True)
        self._save_timer.setInterval(500)
        self._save_timer.timeout.connect(self.save_layout)
        self.restore_layout()
        self.tabs.currentChanged.connect(lambda i: self.ctx.set("window/tab", i))
        for dock in (self.log_dock, self.guide_dock):
            dock.dockLocationChanged.connect(lambda *_: self._save_timer.start())
            dock.visibilityChanged.connect(lambda *_: self._save_timer.start())

    def capture_new_session(self) -> None:
        new_session = getattr(self.panels.get("capture"), "new_session", None)
        if new_session is not None:
            new_session()

    def _open_session(self, folder) -> None:
        open_session = getattr(self.panels.get("capture"), "open_session", None)
        if open_session is not None:
            open_session(folder)

    def show_panel(self, name: str) -> None:
        panel = self.panels.get(name)
        if panel is not None:
            self.tabs.setCurrentWidget(panel)

    def _make_panel(self, attr: str, module: str, cls: str, missing: str) -> QWidget:
        try:
            panel_cls = getattr(importlib.import_module(module), cls)
        except ImportError as exc:
            log.info("panel %s not available: %s", attr, exc)
            return NotAvailablePanel(PANEL_TITLES[attr], missing)
        return panel_cls(self.ctx)

    # ------------------------------------------------------------------ state display
    def _devices_changed(self) -> None:
        s = self.lab.sphere
        self.sphere_state.setText(f"sphere: {s.port}" if s is not None else "sphere: not connected")
        self.camera_state.setText(f"camera: {self.lab.camera_name}" if self.lab.camera else "camera: not connected")

    def _sphere_status(self, status: dict) -> None:
        on = "ON" if status.get("light_on") else "off"
        self.sphere_state.setText(f"sphere: light {on}, {temperature(status.get('temperature_c'))}")

    def _busy_changed(self, pool: str, busy: bool) -> None:
        running = [h.name for h in self.runner.running() if h.pool != "devices"]
        self.task_state.setText(("running: " + ", ".join(running)) if running else "")

    # ------------------------------------------------------------------ shortcuts
    def capture_shortcut(self) -> None:
        action: Callable[[], None] | None = getattr(self.tabs.currentWidget(), "capture_shortcut", None)
        if action is None:
            action = getattr(self.panels.get("camera"), "capture_shortcut", None)
        if action is not None:
            action()

    def cancel_running(self) -> None:
        for panel in self.panels.values():
            cancel = getattr(panel, "cancel_running", None)
            if cancel is not None:
                cancel()

    # ------------------------------------------------------------------ settings
    def restore_layout(self) -> None:
        geometry = self.ctx.settings.value("window/geometry")
        if isinstance(geometry, QByteArray):
            self.restoreGeometry(geometry)
        else:                                      # never taller or wider than the screen (a 1366x768 laptop)
            room = self.screen().availableGeometry() if self.screen() is not None else None
            self.resize(min(1280, room.width()) if room else 1280, min(860, room.height()) if room else 860)
        state = self.ctx.settings.value("window/state")
        if isinstance(state, QByteArray):
            self.restoreState(state)
        tab = self.ctx.get("window/tab", 0, int)
        if 0 <= tab < self.tabs.count():
            self.tabs.setCurrentIndex(tab)

    def save_layout(self) -> None:
        self.ctx.settings.setValue("window/geometry", self.saveGeometry())
        self.ctx.settings.setValue("window/state", self.saveState())
        self.ctx.settings.sync()

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        if hasattr(self, "_save_timer"):
            self._save_timer.start()

    def moveEvent(self, event) -> None:
        super().moveEvent(event)
        if hasattr(self, "_save_timer"):
            self._save_timer.start()

    def closeEvent(self, event: QCloseEvent) -> None:
        if not self._closing and not self.day.may_quit(self, self.errors.show_dialogs):
            event.ignore()                         # work left: the technician chose to keep working
            return
        if not self._closing:
            self._closing = True
            self.save_layout()
            self.shutdown()
        super().closeEvent(event)

    def shutdown(self) -> None:
        """Cancel what runs, switch the LEDs off, close the devices, stop the virtual lab."""
        for panel in self.panels.values():
            stop = getattr(panel, "shutdown", None)
            if stop is not None:
                stop()
        self.lab.stop_polling()
        self.runner.cancel_all()
        self.runner.submit(self.lab.shutdown, pool="devices", name="switch off and close devices",
                           on_error=lambda exc: log.error("closing the devices: %s", exc))
        if not self.runner.wait(20000):
            log.error("some work did not stop within 20 s")
        self.day.shutdown()
        self.errors.close_all()
        for box in list(self.asker.boxes):
            box.close()
        self.log_view.uninstall()
        gc_thread.stop()
