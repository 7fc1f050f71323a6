"""What every panel gets: the task runner, the devices (Lab), the shared workspace, settings, error reporting,
questions to the technician, and a signal bus for events."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from PySide6.QtCore import QObject, QSettings, QStandardPaths, QUrl, Signal
from PySide6.QtGui import QDesktopServices

from app.gui.device_hub import Lab
from app.gui.widgets import Asker, ErrorReporter
from app.gui.workers import TaskRunner
from app.gui.workspace import Workspace

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
    return QSettings(QSettings.IniFormat, QSettings.UserScope, ORGANISATION, APPLICATION)


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
        """Next to the settings file (~/.config/dualrgb/ by default; a test's temp dir in tests)."""
        name = self.settings.fileName()
        if name and self.settings.format() == QSettings.IniFormat:
            return Path(name).parent
        base = QStandardPaths.writableLocation(QStandardPaths.AppDataLocation) or str(Path.home() / ".dualrgb")
        return Path(base)

    def path_setting(self, key: str, default: Path) -> Path:
        text = self.get(key, "", str)
        return Path(text) if text else default

    def open_path(self, path: Path) -> None:
        """Show a file or folder in the desktop's viewer (a TIFF in the image viewer, a folder in the file
        manager)."""
        self.opened.append(Path(path))
        log.info("opening %s", path)
        if self.open_externally:
            QDesktopServices.openUrl(QUrl.fromLocalFile(str(path)))

    @property
    def presets_dir(self) -> Path:
        return self.path_setting("paths/presets", self.data_dir() / "presets")

    @property
    def captures_dir(self) -> Path:
        return self.path_setting("paths/captures", self.data_dir() / "captures")
