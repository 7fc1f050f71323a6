"""Small widgets shared by the panels: status lights, the log view and its logging handler, error dialogs, the
panels' controls-beside-view layout."""
from __future__ import annotations

import logging
from collections import deque
from collections.abc import Callable, Sequence

from PySide6.QtCore import QObject, Qt, QTimer, Signal, Slot
from PySide6.QtGui import QFont
from PySide6.QtWidgets import (
    QAbstractButton,
    QHBoxLayout,
    QLabel,
    QMessageBox,
    QPlainTextEdit,
    QSizePolicy,
    QSplitter,
    QVBoxLayout,
    QWidget,
)

from dualrgb.app.gui.de_scale import DeBand, de_bands
from dualrgb.app.gui.wording import in_window_words

log = logging.getLogger(__name__)

LIGHT_COLOURS = {"off": "#9e9e9e", "ok": "#2e7d32", "busy": "#f9a825", "error": "#c62828", "on": "#fdd835"}


class StatusLight(QWidget):
    """A coloured dot and a short text: grey = not connected, green = ready, amber = busy, red = problem."""

    def __init__(self, text: str = "", parent: QWidget | None = None):
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

    def set_state(self, state: str, text: str | None = None) -> None:
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

    def __init__(self, parent: QWidget | None = None):
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
        self.handler.bridge.record.connect(self.append, Qt.ConnectionType.QueuedConnection)
        self.lines: deque[str] = deque(maxlen=200)

    @Slot(str, int)
    def append(self, line: str, level: int = logging.INFO) -> None:
        line = in_window_words(line)                # the workflow's lines in the window's words (issue 42)
        self.lines.append(line)
        if level >= logging.ERROR:
            line = f"<span style='color:#c62828'>{_html(line)}</span>"
        elif level >= logging.WARNING:
            line = f"<span style='color:#b26a00'>{_html(line)}</span>"
        else:
            line = _html(line)
        self.text.appendHtml(line)

    def install(self, logger: logging.Logger | None = None) -> None:
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

    def uninstall(self, logger: logging.Logger | None = None) -> None:
        logger = logger or logging.getLogger()
        logger.removeHandler(self.handler)
        if getattr(self, "_previous_level", None) is not None:
            logger.setLevel(self._previous_level)


def _html(text: str) -> str:
    return text.replace("&", "&amp;").replace("<", "&lt;").replace(">", "&gt;")


class ErrorReporter(QObject):
    """Shows errors as non-modal dialogs (the window keeps running); remembers them for tests. The last error
    stays in the status bar until the same action succeeds (``clear``) or another error replaces it."""

    shown = Signal(str, str)
    cleared = Signal()

    def __init__(self, parent_widget: QWidget):
        super().__init__(parent_widget)
        self._parent = parent_widget
        self.history: list[tuple[str, str]] = []
        self.dialogs: list[QMessageBox] = []
        self.show_dialogs = True
        self.current: tuple[str, str] | None = None

    def report(self, title: str, error: object, level: int = logging.ERROR) -> None:
        message = in_window_words(str(error) or type(error).__name__)
        log.log(level, "%s: %s", title, message)
        self.history.append((title, message))
        self.current = (title, message)
        self.shown.emit(title, message)
        if not self.show_dialogs:
            return
        same = next((b for b in self.dialogs if b.windowTitle() == title), None)
        if same is not None:                       # one message per error: the open box says the latest
            same.setText(message)
            same.raise_()
            return
        box = QMessageBox(QMessageBox.Icon.Warning if level < logging.ERROR else QMessageBox.Icon.Critical,
                          title, message, QMessageBox.StandardButton.Ok, self._parent)
        box.setWindowModality(Qt.WindowModality.NonModal)
        box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)
        box.finished.connect(lambda _=0, b=box: self.dialogs.remove(b) if b in self.dialogs else None)
        self.dialogs.append(box)
        box.show()

    def clear(self, title: str | None = None) -> None:
        """The action ``title`` succeeded (None: any): its error is no longer current."""
        if self.current is not None and (title is None or self.current[0] == title):
            self.current = None
            self.cleared.emit()

    def close_all(self) -> None:
        for box in list(self.dialogs):
            box.close()
        self.dialogs.clear()


class Asker(QObject):
    """Questions to the technician (re-shoot or keep, use a calibration that does not match) as non-modal message
    boxes: ``ask`` returns at once and ``on_answer(choice)`` is called when a button is pressed (closing the box
    answers ``default``). Tests script the answers (``scripted``); without dialogs the default is taken."""

    asked = Signal(str, str)

    def __init__(self, parent_widget: QWidget):
        super().__init__(parent_widget)
        self._parent = parent_widget
        self.history: list[tuple[str, str]] = []
        self.scripted: list[str] = []
        self.show_dialogs = True
        self.boxes: list[QMessageBox] = []

    def ask(self, title: str, text: str, choices: Sequence[str], on_answer: Callable[[str], None],
            default: str) -> None:
        if default not in choices:
            raise ValueError(f"default answer {default!r} is not one of {list(choices)}")
        text = in_window_words(text)
        self.history.append((title, text))
        self.asked.emit(title, text)
        log.info("asked: %s: %s", title, text)
        if self.scripted or not self.show_dialogs:
            answer = self.scripted.pop(0) if self.scripted else default
            QTimer.singleShot(0, lambda: on_answer(answer))
            return
        box = QMessageBox(QMessageBox.Icon.Question, title, text, QMessageBox.StandardButton.NoButton, self._parent)
        made = [(box.addButton(c, QMessageBox.ButtonRole.AcceptRole), c) for c in choices]
        buttons: dict[QAbstractButton, str] = dict(made)
        box.setDefaultButton(next(b for b, c in made if c == default))      # Enter answers the default
        box.setWindowModality(Qt.WindowModality.NonModal)
        box.setAttribute(Qt.WidgetAttribute.WA_DeleteOnClose)

        def finished(_result: int = 0) -> None:
            if box in self.boxes:
                self.boxes.remove(box)
            on_answer(buttons.get(box.clickedButton(), default))
        box.finished.connect(finished)
        self.boxes.append(box)
        box.show()


class PathLabel(QLabel):
    """A file path on one line, shortened in the middle of its folders when the panel is narrow (never wrapped
    mid-name): the last name - the session's, the file's - stays whole; the whole path is the tooltip."""

    def __init__(self, text: str = "", parent: QWidget | None = None):
        super().__init__(parent)
        self._full = ""
        self.setSizePolicy(QSizePolicy.Policy.Ignored, QSizePolicy.Policy.Preferred)
        self.setTextInteractionFlags(Qt.TextInteractionFlag.TextSelectableByMouse)
        self.set_path(text)

    def set_path(self, text: str) -> None:
        self._full = str(text)
        self.setToolTip(self._full)
        self._elide()

    def full_text(self) -> str:
        return self._full

    def resizeEvent(self, event) -> None:
        super().resizeEvent(event)
        self._elide()

    def _elide(self) -> None:
        width = max(self.width(), 80)
        fm, full = self.fontMetrics(), self._full
        cut = max(full.rfind("/"), full.rfind("\\")) + 1           # the last name (session, file) is kept whole
        head, tail = full[:cut], full[cut:]
        room = width - fm.horizontalAdvance(tail)
        if fm.horizontalAdvance(full) <= width:
            text = full
        elif room <= fm.horizontalAdvance("…/"):                  # too narrow even for the name: its start
            text = fm.elidedText(tail, Qt.TextElideMode.ElideRight, width)
        else:
            text = fm.elidedText(head, Qt.TextElideMode.ElideMiddle, room) + tail
        super().setText(text)


class DeLegend(QWidget):
    """The fixed ΔE00 colour bands (viewmodel.de_bands: traffic lights at the grading thresholds) as a legend."""

    def __init__(self, parent: QWidget | None = None):
        super().__init__(parent)
        lay = QHBoxLayout(self)
        lay.setContentsMargins(0, 0, 0, 0)
        lay.addWidget(QLabel("ΔE00:"))
        for band in de_bands():
            lay.addWidget(_band_chip(band))
        lay.addStretch(1)


def _band_chip(band: DeBand) -> QLabel:
    chip = QLabel(band.label)
    chip.setStyleSheet(f"background:{band.colour}; color:{band.text_colour}; border-radius:4px; padding:1px 6px")
    chip.setToolTip(band.meaning)
    return chip


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


def side_by_side(panel: QWidget, left: QWidget, right: QWidget, *, stretch: tuple[int, int] = (0, 1),
                 sizes: Sequence[int] | None = None) -> QSplitter:
    """Fill ``panel`` with ``left`` (its controls) beside ``right`` (what they show) in a splitter the user can
    drag; ``stretch``: how extra width is shared; ``sizes``: the starting widths in pixels."""
    split = QSplitter(Qt.Orientation.Horizontal)
    split.addWidget(left)
    split.addWidget(right)
    split.setStretchFactor(0, stretch[0])
    split.setStretchFactor(1, stretch[1])
    if sizes:
        split.setSizes(list(sizes))
    QVBoxLayout(panel).addWidget(split)
    return split
