"""What every panel gets: the task runner, the devices (Lab), settings, error reporting and a signal bus."""
from __future__ import annotations

import logging
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Optional

from PySide6.QtCore import QObject, QSettings, QStandardPaths, Signal

from app.gui.device_hub import Lab
from app.gui.widgets import ErrorReporter
from app.gui.workers import TaskRunner

log = logging.getLogger(__name__)

ORGANISATION = "dualrgb"
APPLICATION = "dualrgb"


class Bus(QObject):
    """Signals between panels (results flow from capture to target to results; presets from simulate)."""

    presetsChanged = Signal()
    sequenceStarted = Signal(str)          # sequence name
    sequenceFinished = Signal(str, str)    # name, 'done' | 'cancelled' | 'failed'
    targetImageReady = Signal(object)      # dict: image (H, W, C) float, meta
    resultsReady = Signal(object)          # dict: processing report
    crfReady = Signal(object)              # CrfSweep result
    sessionUpdated = Signal()              # frames were added to the session
    gridChanged = Signal(object)           # app.processing.patches.PatchGrid placed in Target (superpixel coords)


def default_settings() -> QSettings:
    return QSettings(QSettings.IniFormat, QSettings.UserScope, ORGANISATION, APPLICATION)


@dataclass
class AppContext:
    runner: TaskRunner
    lab: Lab
    settings: QSettings
    errors: ErrorReporter
    bus: Bus
    shared: dict = field(default_factory=dict)     # latest grid, capture lights, ... for panels that need them

    # ---- typed settings, saved as soon as they change ----
    def get(self, key: str, default: Any = None, type_: Optional[type] = None) -> Any:
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

    @property
    def presets_dir(self) -> Path:
        return self.path_setting("paths/presets", self.data_dir() / "presets")

    @property
    def captures_dir(self) -> Path:
        return self.path_setting("paths/captures", self.data_dir() / "captures")
