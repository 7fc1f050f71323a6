"""Small widgets shared by the panels: status lights, the log view and its logging handler, error dialogs."""
from __future__ import annotations

import logging
from collections import deque
from typing import Optional

from PySide6.QtCore import QObject, Qt, Signal, Slot
from PySide6.QtGui import QColor, QFont
from PySide6.QtWidgets import (QHBoxLayout, QLabel, QMessageBox, QPlainTextEdit, QVBoxLayout, QWidget)

log = logging.getLogger(__name__)

LIGHT_COLOURS = {"off": "#9e9e9e", "ok": "#2e7d32", "busy": "#f9a825", "error": "#c62828", "on": "#fdd835"}


class StatusLight(QWidget):
    """A coloured dot and a short text: grey = not connected, green = ready, amber = busy, red = problem."""

    def __init__(self, text: str = "", parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.dot = QLabel()
        self.dot.setFixedSize(14, 14)
        self.label = QLabel(text)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(self.dot)
        lay.addWidget(self.label, 1)
        self.state = "off"
        self.set_state("off", text)

    def set_state(self, state: str, text: Optional[str] = None) -> None:
        self.state = state
        colour = LIGHT_COLOURS.get(state, LIGHT_COLOURS["off"])
        self.dot.setStyleSheet(f"background:{colour}; border-radius:7px; border:1px solid #555;")
        if text is not None:
            self.label.setText(text)


class _LogBridge(QObject):
    record = Signal(str, int)


class QtLogHandler(logging.Handler):
    """A logging.Handler that forwards formatted records to the GUI thread through a queued signal."""

    def __init__(self, level: int = logging.INFO):
        super().__init__(level)
        self.bridge = _LogBridge()
        self.setFormatter(logging.Formatter("%(asctime)s %(levelname)-7s %(name)s: %(message)s", "%H:%M:%S"))

    def emit(self, record: logging.LogRecord) -> None:
        try:
            self.bridge.record.emit(self.format(record), record.levelno)
        except RuntimeError:      # the bridge was deleted at shutdown
            pass


class LogView(QWidget):
    """The log panel: what the drivers, sequences and simulation report, newest at the bottom."""

    MAX_LINES = 5000

    def __init__(self, parent: Optional[QWidget] = None):
        super().__init__(parent)
        self.text = QPlainTextEdit()
        self.text.setReadOnly(True)
        self.text.setMaximumBlockCount(self.MAX_LINES)
        self.text.setFont(QFont("monospace", 9))
        self.text.setToolTip("What the program and the devices did, newest at the bottom.")
        lay = QVBoxLayout(self)
        lay.setContentsMargins(2, 2, 2, 2)
        lay.addWidget(self.text)
        self.handler = QtLogHandler()
        self.handler.bridge.record.connect(self.append, Qt.QueuedConnection)
        self.lines: deque[str] = deque(maxlen=200)

    @Slot(str, int)
    def append(self, line: str, level: int = logging.INFO) -> None:
        self.lines.append(line)
        if level >= logging.ERROR:
            line = f"<span style='color:#c62828'>{_html(line)}</span>"
        elif level >= logging.WARNING:
            line = f"<span style='color:#b26a00'>{_html(line)}</span>"
        else:
            line = _html(line)
        self.text.appendHtml(line)

    def install(self, logger: Optional[logging.Logger] = None) -> None:
        """Attach to ``logger`` (root) and let INFO through to this view; handlers already there (the
        console) keep the level they showed before."""
        logger = logger or logging.getLogger()
        self._previous_level = logger.level
        if logger.getEffectiveLevel() > logging.INFO:
            for h in logger.handlers:
                if h.level == logging.NOTSET:
                    h.setLevel(logger.getEffectiveLevel())
            logger.setLevel(logging.INFO)
        logger.addHandler(self.handler)

    def uninstall(self, logger: Optional[logging.Logger] = None) -> None:
        logger = logger or logging.getLogger()
        logger.removeHandler(self.handler)
        if getattr(self, "_previous_level", None) is not None:
            logger.setLevel(self._previous_level)


def _html(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


class ErrorReporter(QObject):
    """Shows errors as non-modal dialogs (the window keeps running); remembers them for tests."""

    shown = Signal(str, str)

    def __init__(self, parent_widget: QWidget):
        super().__init__(parent_widget)
        self._parent = parent_widget
        self.history: list[tuple[str, str]] = []
        self.dialogs: list[QMessageBox] = []
        self.show_dialogs = True

    def report(self, title: str, error: object, level: int = logging.ERROR) -> None:
        message = str(error) or type(error).__name__
        log.log(level, "%s: %s", title, message)
        self.history.append((title, message))
        self.shown.emit(title, message)
        if not self.show_dialogs:
            return
        box = QMessageBox(QMessageBox.Warning if level < logging.ERROR else QMessageBox.Critical,
                          title, message, QMessageBox.Ok, self._parent)
        box.setWindowModality(Qt.NonModal)
        box.setAttribute(Qt.WA_DeleteOnClose)
        box.finished.connect(lambda _=0, b=box: self.dialogs.remove(b) if b in self.dialogs else None)
        self.dialogs.append(box)
        box.show()

    def close_all(self) -> None:
        for box in list(self.dialogs):
            box.close()
        self.dialogs.clear()


def plot_widget(title: str = "", bottom: str = "", left: str = "", tooltip: str = ""):
    """A white pyqtgraph plot with plain axis labels (no automatic SI prefixes like '(x0.001)')."""
    import pyqtgraph as pg

    w = pg.PlotWidget(background="w", title=title or None)
    for side, text in (("bottom", bottom), ("left", left)):
        w.getAxis(side).enableAutoSIPrefix(False)
        if text:
            w.setLabel(side, text)
    w.showGrid(x=True, y=True, alpha=0.2)
    if tooltip:
        w.setToolTip(tooltip)
    return w


def colour_for_de(value: float) -> QColor:
    """Green below 1, amber to 3, red above (display only; the thresholds come from the results panel)."""
    if value < 1.0:
        return QColor("#2e7d32")
    if value < 3.0:
        return QColor("#f9a825")
    return QColor("#c62828")


def image_widget(tooltip: str):
    """A picture view (row-major image, y down, aspect locked): (GraphicsLayoutWidget, ImageItem, ViewBox)."""
    import pyqtgraph as pg

    w = pg.GraphicsLayoutWidget()
    w.setBackground("#202020")
    vb = w.addViewBox(lockAspect=True, invertY=True)
    item = pg.ImageItem(axisOrder="row-major")
    vb.addItem(item)
    w.setToolTip(tooltip)
    return w, item, vb
