"""What every panel gets: the task runner, the devices (Lab), the shared workspace, settings, error reporting,
questions to the technician, and a signal bus for events."""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QSettings, QStandardPaths, QUrl, Signal
from PySide6.QtGui import QDesktopServices

from dualrgb.app.gui.device_hub import Lab
from dualrgb.app.gui.widgets import Asker, ErrorReporter
from dualrgb.app.gui.workers import TaskRunner
from dualrgb.app.gui.workspace import Workspace
from dualrgb.app.workflow.stand.defaults import captures_dir
from dualrgb.app.workflow.stand.folders import open_session
from dualrgb.core.session.capture_session import CaptureSession

log = logging.getLogger(__name__)

ORGANISATION = "dualrgb"
APPLICATION = "dualrgb"


class Bus(QObject):
    """Events between panels (what is shared as state lives in the Workspace)."""

    presetsChanged = Signal()
    sequenceStarted = Signal(str)          # sequence name
    sequenceFinished = Signal(str, str)    # name, 'done' | 'cancelled' | 'failed'
    resultsReady = Signal(object)          # dict: processing report
    crfReady = Signal(object)              # CrfSweep summary
    sessionUpdated = Signal()              # a sequence finished: frames were added to the session
    frameSaved = Signal()                  # one frame saved (or kept) while a sequence runs
    cameraSettingsChanged = Signal()       # ISO / aperture applied: the calibration is checked again
    showPanel = Signal(str)                # ask the window to bring a panel forward ('capture', 'originals', ...)


def default_settings() -> QSettings:
    return QSettings(QSettings.Format.IniFormat, QSettings.Scope.UserScope, ORGANISATION, APPLICATION)


@dataclass
class AppContext:
    runner: TaskRunner
    lab: Lab
    settings: QSettings
    errors: ErrorReporter
    bus: Bus
    workspace: Workspace
    asker: Asker
    opened: list[Path] = field(default_factory=list)     # files and folders opened for the user (tests read it)
    open_externally: bool = True
    _waiting_for_session: list[Callable[[], None]] = field(default_factory=list)

    # ---- typed settings, saved as soon as they change ----
    def get(self, key: str, default: Any = None, type_: type | None = None) -> Any:
        if type_ is None and default is not None:
            type_ = type(default)
        value = self.settings.value(key, default)
        if value is None or type_ is None:
            return value
        try:
            if type_ is bool:
                return value if isinstance(value, bool) else str(value).lower() in ("1", "true", "yes")
            return type_(value)
        except (TypeError, ValueError):
            return default

    def set(self, key: str, value: Any) -> None:
        self.settings.setValue(key, value)
        self.settings.sync()

    def data_dir(self) -> Path:
        """The settings file's folder (~/.config/dualrgb/ by default; a test's temp dir in tests): the window's
        own small files, never captures (:attr:`captures_dir`)."""
        name = self.settings.fileName()
        if name and self.settings.format() == QSettings.Format.IniFormat:
            return Path(name).parent
        where = QStandardPaths.StandardLocation.AppDataLocation
        base = QStandardPaths.writableLocation(where) or str(Path.home() / ".dualrgb")
        return Path(base)

    def path_setting(self, key: str, default: Path) -> Path:
        text = self.get(key, "", str)
        return Path(text) if text else default

    def open_path(self, path: Path) -> bool:
        """Show a file or folder in the desktop's viewer (a TIFF in the image viewer, a folder in the file
        manager); a path that is gone or a desktop without a launcher is said in the window."""
        self.opened.append(Path(path))
        log.info("opening %s", path)
        if not Path(path).exists():
            self.errors.report("Open", f"{path} does not exist (moved or deleted?)")
            return False
        return self.open_url(QUrl.fromLocalFile(str(path)), Path(path).name)

    def open_url(self, url: QUrl, what: str) -> bool:
        """Hand ``url`` to the desktop; when nothing opens it (no launcher such as xdg-open), say so visibly with
        where it is."""
        if not self.open_externally:
            return True
        if QDesktopServices.openUrl(url):
            self.errors.clear("Open")
            return True
        where = url.toLocalFile() or url.toString()
        self.errors.report("Open", f"no launcher on this desktop (such as xdg-open) opens {what}; open it "
                           f"yourself: {where}")
        return False

    @property
    def presets_dir(self) -> Path:
        return self.path_setting("paths/presets", self.data_dir() / "presets")

    @property
    def captures_dir(self) -> Path:
        """The folder chosen in Devices, else the day's default (app.workflow.stand.defaults.captures_dir: the per-user
        data folder, not the settings folder)."""
        return self.path_setting("paths/captures", captures_dir())

    # ---- the session rule: starting without one makes one ----
    def with_session(self, then: Callable[[], None], reason: str) -> None:
        """Call ``then`` once there is a session: the current one, or a new dated one made in the captures folder
        first (app.workflow.stand.folders.open_session, on the devices thread; the status bar and the guide say so).
        Calls arriving while it is being made wait for it."""
        lab = self.lab
        if lab.session is not None:
            then()
            return
        self._waiting_for_session.append(then)
        if len(self._waiting_for_session) > 1:
            return
        root, meta = self.captures_dir, {"operator": self.get("originals/operator", "", str),
                                         "virtual_lab": lab.is_virtual}

        def made(session: CaptureSession) -> None:
            lab.set_session(session, note=f"made for {reason}")
            waiting, self._waiting_for_session[:] = list(self._waiting_for_session), []
            for call in waiting:
                call()

        def failed(exc: BaseException) -> None:
            self._waiting_for_session.clear()
            self.errors.report("New session", exc)
        self.runner.submit(lambda: open_session(None, lab.session_definition(), meta=meta, root=root), pool="devices",
                           name="new session", on_result=made, on_error=failed)
