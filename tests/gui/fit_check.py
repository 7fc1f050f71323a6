"""What a technician cannot read: widgets whose text does not fit their width (issue 42).

:func:`clipped_texts` walks the visible widgets of a window and returns one line per label, button, line edit
or combo box whose text is wider than the room it has. An elided text is allowed when the tooltip holds the
whole text. Word-wrapped labels wrap and are not checked.
"""
from __future__ import annotations

from PySide6.QtGui import QTextDocument
from PySide6.QtWidgets import QAbstractButton, QComboBox, QLabel, QLineEdit, QPushButton, QTabBar, QTabWidget, QWidget

SLACK = 2          # px: rounding between a font's advance and a style's metrics


def _plain(text: str) -> str:
    if "<" in text and ">" in text:
        doc = QTextDocument()
        doc.setHtml(text)
        return doc.toPlainText()
    return text


def _widest(widget: QWidget, text: str) -> int:
    fm = widget.fontMetrics()
    return max((fm.horizontalAdvance(line) for line in text.replace("&&", "&").splitlines()), default=0)


def _tip_holds(widget: QWidget, text: str) -> bool:
    tip = _plain(widget.toolTip())
    return bool(text.strip()) and text.strip() in tip


def _label_problem(w: QLabel) -> str | None:
    if w.wordWrap() or w.pixmap() is not None and not w.pixmap().isNull():
        return None
    text = _plain(w.text())
    room = w.contentsRect().width() - 2 * w.margin() - 2 * max(w.indent(), 0)
    need = _widest(w, text)
    if need > room + SLACK and not _tip_holds(w, text):
        return f"label {text[:60]!r}: needs {need} px, has {room}"
    return None


def _button_problem(w: QAbstractButton) -> str | None:
    text = w.text()
    if not text:
        return None
    need = w.sizeHint().width() if isinstance(w, QPushButton) else w.minimumSizeHint().width()
    if need > w.width() + SLACK and not _tip_holds(w, text.replace("&", "")):
        return f"{type(w).__name__} {text[:60]!r}: needs {need} px, has {w.width()}"
    return None


def _line_edit_problem(w: QLineEdit) -> str | None:
    room = w.contentsRect().width() - 8
    for what, text in (("placeholder", w.placeholderText() if not w.text() else ""), ("text", w.text())):
        if text and _widest(w, text) > room + SLACK and not _tip_holds(w, text):
            return f"line edit {what} {text[:60]!r}: needs {_widest(w, text)} px, has {room}"
    return None


def _combo_problem(w: QComboBox) -> str | None:
    text = w.currentText()
    room = w.width() - 28                  # the arrow and the frame
    if text and _widest(w, text) > room + SLACK and not _tip_holds(w, text):
        return f"combo {text[:60]!r}: needs {_widest(w, text)} px, has {room}"
    return None


def problem_of(w: QWidget) -> str | None:
    """The one line saying why ``w``'s text does not fit, or None."""
    if isinstance(w, QLabel):
        return _label_problem(w)
    if isinstance(w, QAbstractButton) and not isinstance(w.parent(), QTabBar):
        return _button_problem(w)
    if isinstance(w, QLineEdit) and not isinstance(w.parent(), QComboBox):
        return _line_edit_problem(w)
    if isinstance(w, QComboBox):
        return _combo_problem(w)
    return None


def clipped_texts(root: QWidget) -> list[str]:
    """Every visible widget under ``root`` whose text does not fit, one line each (its object path first)."""
    out = []
    for w in root.findChildren(QWidget):
        if not w.isVisible() or w.width() <= 0:
            continue
        problem = problem_of(w)
        if problem is not None:
            out.append(f"{_path(w)}: {problem}")
    return out


def _path(w: QWidget) -> str:
    names = []
    while w is not None and len(names) < 4:
        names.append(w.objectName() or type(w).__name__)
        w = w.parentWidget()
    return "/".join(reversed(names))


def tab_bars_scroll(root: QWidget) -> list[str]:
    """Tab bars that need their scroll arrows: the tabs are wider than the bar."""
    out = []
    for tabs in root.findChildren(QTabWidget):
        if not tabs.isVisible():
            continue
        bar = tabs.tabBar()
        need = sum(bar.tabSizeHint(i).width() for i in range(bar.count()))
        if need > bar.width() + SLACK or bar.tabRect(bar.count() - 1).right() > bar.width():
            out.append(f"{tabs.objectName() or type(tabs).__name__}: tabs need {need} px, bar has {bar.width()}")
    return out
