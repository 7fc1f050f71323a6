"""Issue 42: the window fits a 1366x768 laptop and the default 1280x860 window - every tab rendered at both sizes,
no clipped text, every tab reachable without the tab bar's arrows, the primary button of each step above the fold
and first in its column, the workflow dock at a fixed width, and the guide's step and the highlighted button
agree."""
from __future__ import annotations

import pytest
from PySide6.QtCore import QPoint, QRect
from PySide6.QtWidgets import QApplication, QPushButton, QScrollArea, QTabWidget, QWidget

from tests.gui.conftest import connect_devices
from tests.gui.fit_check import clipped_texts, tab_bars_scroll

SIZES = ((1280, 860), (1366, 768))


def _settle(w) -> None:
    for _ in range(4):
        QApplication.processEvents()


def _every_page(w):
    """Each main tab, and inside it each page of its first nested tab widget(s), shown in turn."""
    for i in range(w.tabs.count()):
        w.tabs.setCurrentIndex(i)
        _settle(w)
        inner = [t for t in w.tabs.widget(i).findChildren(QTabWidget) if t.isVisible()]
        if not inner:
            yield w.tabs.tabText(i)
            continue
        for t in inner:
            for j in range(t.count()):
                t.setCurrentIndex(j)
                _settle(w)
                yield f"{w.tabs.tabText(i)} / {t.tabText(j)}"


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_every_tab_fits(make_window, size):
    w = make_window()
    w.resize(*size)
    _settle(w)
    seen, problems = [], []
    for page in _every_page(w):
        seen.append(page)
        problems += [f"{page}: {p}" for p in clipped_texts(w) + tab_bars_scroll(w)]
    assert len(seen) >= 10
    assert problems == []


def test_the_checker_finds_clipped_text(make_window):
    """The check itself can fail: a label squeezed narrower than its text is found, then allowed once its tooltip
    holds the whole text (an elided label)."""
    w = make_window()
    w.resize(*SIZES[0])
    label = w.devices.sphere_message
    label.setWordWrap(False)
    label.setText("a long message that cannot fit in forty pixels")
    label.setFixedWidth(40)
    _settle(w)
    assert any("a long message" in p for p in clipped_texts(w))
    label.setToolTip("a long message that cannot fit in forty pixels")
    assert not any("a long message" in p for p in clipped_texts(w))


def test_the_tab_bar_needs_no_arrows_even_with_a_larger_font(make_window, qapp):
    """A desktop with a 10 pt font (the issue's X server) still shows every tab."""
    font = qapp.font()
    old = font.pointSizeF()
    font.setPointSizeF(10.0)
    qapp.setFont(font)
    try:
        w = make_window()
        for size in SIZES:
            w.resize(*size)
            _settle(w)
            assert tab_bars_scroll(w) == []
    finally:
        font.setPointSizeF(old)
        qapp.setFont(font)


def test_the_dock_keeps_its_width(make_window):
    from dualrgb.app.gui.main_window import GUIDE_WIDTH

    w = make_window()
    for size in SIZES:
        w.resize(*size)
        _settle(w)
        assert w.guide_dock.width() == GUIDE_WIDTH
    card = next(iter(w.guide.cards.values()))
    card.detail.setText("a_long_unbreakable_line_from_a_delivery_" * 4)        # what widened it in the issue
    _settle(w)
    assert w.guide_dock.width() == GUIDE_WIDTH


def _in_view(button: QPushButton) -> bool:
    """The button is wholly shown: inside its window and, in a scroll area, inside the viewport (no scrolling)."""
    top = button.window()
    rect = QRect(button.mapTo(top, QPoint(0, 0)), button.size())
    parent = button.parentWidget()
    while parent is not None:
        if isinstance(parent, QScrollArea):
            view = parent.viewport()
            if not QRect(view.mapTo(top, QPoint(0, 0)), view.size()).contains(rect):
                return False
        parent = parent.parentWidget()
    return top.rect().contains(rect)


def _first_in_column(button: QPushButton, panel: QWidget) -> bool:
    """No other push button of the panel's column (the scroll area holding ``button``) comes before it."""
    column: QWidget = panel
    parent = button.parentWidget()
    while parent is not None and parent is not panel:
        if isinstance(parent, QScrollArea):
            column = parent
        parent = parent.parentWidget()
    top = button.window()
    at = button.mapTo(top, QPoint(0, 0))
    for other in column.findChildren(QPushButton):
        if other is button or not other.isVisible():
            continue
        p = other.mapTo(top, QPoint(0, 0))
        if p.y() + other.height() <= at.y() or (abs(p.y() - at.y()) < 4 and p.x() < at.x()):
            return False
    return True


@pytest.mark.parametrize("size", SIZES, ids=lambda s: f"{s[0]}x{s[1]}")
def test_primary_buttons_first_and_above_the_fold(make_window, size):
    from dualrgb.app.gui.next_action import step_button
    from dualrgb.app.workflow.day.day import DayStep

    w = make_window()
    w.resize(*size)
    for step, panel in ((DayStep.CONNECT, "devices"), (DayStep.CALIBRATE, "capture"),
                        (DayStep.ORIGINALS, "originals"), (DayStep.DELIVER, "originals")):
        w.show_panel(panel)
        _settle(w)
        button = step_button(w.panels, step, False)
        assert button is not None and button.isVisible(), step
        assert _in_view(button), f"{step}: {button.text()!r} is below the fold"
        if step is not DayStep.DELIVER:          # Capture all waiting sits in the queue's row, after Add
            assert _first_in_column(button, w.panels[panel]), f"{step}: {button.text()!r} is not first"


def test_the_guide_step_and_the_highlighted_button_agree(qtbot, make_window):
    from dualrgb.app.gui.next_action import PRIMARY

    w = make_window()
    highlighted = lambda: [b for b in w.findChildren(QPushButton) if b.property(PRIMARY)]   # noqa: E731
    assert highlighted() == [w.devices.sphere_button]
    assert w.guide.cards[w.guide.steps[0].step].state.value == "active"
    connect_devices(qtbot, w)
    qtbot.waitUntil(lambda: highlighted() == [w.capture.calibration.calibrate_button], timeout=60_000)
    assert w.capture.view.start_button not in highlighted()
