"""The small things that make a technician's day harder (issue 30 point 5), one test each where a test can see it:
the wheel, stale advice, the calibration's exposures in the lights table (and no false "incomplete"), Calibrate
again asks re-shoot / keep / cancel, Results grades the delivered matrix, the menus, visible open errors, the queue
at 1366 px, paths that keep the session's name, the Target tab on a target, measured time estimates."""
from __future__ import annotations

from pathlib import Path

import pytest
from PySide6.QtCore import QPoint, QPointF, Qt
from PySide6.QtGui import QWheelEvent
from PySide6.QtWidgets import QApplication

from dualrgb.app.gui.panels.results import METHOD_NAMES
from dualrgb.app.gui.widgets import PathLabel
from dualrgb.app.workflow.day.day import DayStep, StepState
from dualrgb.app.workflow.delivery.delivery import Original
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, quick_calibrate, wait_idle

LONG = HANG_GUARD_MS


def wheel(widget, steps: int = -1) -> None:
    """A real wheel turn over ``widget`` (through the application, as the mouse sends it)."""
    pos = QPointF(widget.width() / 2, widget.height() / 2)
    event = QWheelEvent(pos, widget.mapToGlobal(pos), QPoint(0, 0), QPoint(0, 120 * steps), Qt.MouseButton.NoButton,
                        Qt.KeyboardModifier.NoModifier, Qt.ScrollPhase.NoScrollPhase, False)
    QApplication.sendEvent(widget, event)


def test_the_wheel_changes_a_choice_only_when_it_has_the_focus(qtbot, make_window):
    w = make_window()
    w.show_panel("capture")
    kind = w.capture.kind
    kind.setCurrentIndex(0)
    w.capture.settle.setFocus()
    wheel(kind)
    assert kind.currentIndex() == 0                      # scrolling over the left panel changes nothing
    kind.setFocus()
    qtbot.waitUntil(kind.hasFocus)
    wheel(kind)
    assert kind.currentIndex() == 1                      # chosen on purpose: it changes


def test_menus_file_and_help(qtbot, make_window, tmp_path):
    w = make_window()
    titles = [a.text() for a in w.menuBar().actions()]
    assert titles == ["&File", "&Capture", "&Help"]
    acts = w.menu_actions
    acts["open_deliverables"].trigger()                  # no session: said, nothing opened
    assert w.errors.current[0] == "Open deliverables" and w.ctx.opened == []
    acts["about"].trigger()
    assert w.asker.history[-1][0] == "About dualrgb" and "dual-RGB" in w.asker.history[-1][1]
    assert {"open_session", "documentation", "quit"} <= set(acts)


def test_originals_queued_before_any_session_survive_a_restart(qtbot, make_window):
    w = make_window()
    org = w.originals
    org.identifier.setText("EARLY-1")
    org.title_edit.setText("Queued before the first session")
    click(qtbot, org.add_button)
    w.close()                                                # asked (1 waiting); unattended: Quit
    assert w.asker.history[-1][0] == "Quit" and not w.isVisible()
    w2 = make_window()
    qtbot.waitUntil(lambda: w2.day.restored != "", timeout=LONG)
    assert w2.day.restored == "restored (no session yet), calibration none, queue: 1 waiting"
    assert w2.ctx.workspace.queue.row("EARLY-1").original.title == "Queued before the first session"


def test_quitting_while_a_run_goes_on_asks_first(qtbot, make_window):
    w = make_window()
    assert w.day.quit_question() == ""                       # nothing left: quits without a question
    w.ctx.workspace.set_running("calibration")
    w.asker.scripted = ["Keep working"]
    w.close()
    assert w.isVisible() and "calibration is running: quitting cancels it" in w.asker.history[-1][1]
    w.ctx.workspace.set_running("")


def test_a_file_that_cannot_be_opened_is_said_in_the_window(qtbot, make_window, tmp_path, monkeypatch):
    from PySide6.QtGui import QDesktopServices

    w = make_window()
    w.ctx.open_externally = True
    monkeypatch.setattr(QDesktopServices, "openUrl", staticmethod(lambda _url: False))     # no launcher
    tiff = tmp_path / "ACC-1_srgb_16bit.tif"
    tiff.write_bytes(b"II*\x00")
    assert not w.ctx.open_path(tiff)
    title, message = w.errors.current
    assert title == "Open" and "no launcher" in message and str(tiff) in message
    assert "no launcher" in w.error_state.text()
    assert not w.ctx.open_path(tmp_path / "gone.tif") and "does not exist" in w.errors.current[1]


def test_paths_keep_the_session_name_visible(qtbot):
    label = PathLabel("/home/technician/.local/share/dualrgb/captures/2026-11-27_3  (56 frames)")
    qtbot.addWidget(label)
    label.resize(label.fontMetrics().horizontalAdvance("/home/…/captures/2026-11-27_3  (56 frames)") + 4, 20)
    label.show()
    assert label.text().endswith("2026-11-27_3  (56 frames)") and label.text() != label.full_text()
    assert label.text().startswith("/")                      # the start stays too: shortened in the middle


def test_the_queue_is_readable_at_1366_px(qtbot, make_window):
    w = make_window()
    w.resize(1366, 768)
    w.show_panel("originals")
    org, ws = w.originals, w.ctx.workspace
    ws.queue.add(Original("ACC-1", title="A very long title of a painting " * 6))
    ws.queue_changed()
    qtbot.wait(50)
    table, header = org.table, org.table.horizontalHeader()
    visible = table.viewport().width()
    for name in ("identifier", "state", "QA"):
        c = [header.model().headerData(i, Qt.Orientation.Horizontal) for i in range(table.columnCount())].index(name)
        assert header.sectionViewportPosition(c) + 20 < visible, (name, header.sectionViewportPosition(c), visible)


def test_measured_frame_times_make_the_estimate():
    from dualrgb.app.gui.sequence_view import frame_overhead_s

    times = [(0.0, 0.0), (3.0, 0.5), (3.7, 0.5), (4.4, 0.5), (5.1, 0.5)]     # the first waits for the session
    assert frame_overhead_s(times, 0.1) == pytest.approx(0.1)
    assert frame_overhead_s(times[:3], 0.1) is None


def test_calibration_loaded_shows_its_exposures_and_calibrate_again_asks(qtbot, make_window, tmp_path):
    w = make_window()
    cap, ws, guide = w.capture, w.ctx.workspace, w.guide
    assert cap.view.message.text().startswith("needs ")
    connect_devices(qtbot, w)
    assert not cap.view.message.text().startswith("needs "), cap.view.message.text()   # connected: advice gone
    quick_calibrate(qtbot, w)
    profile = ws.calibration
    assert cap.view.outcome == "done" and profile is not None
    overhead = w.ctx.get("runs/frame_overhead_s", 0.0, float)
    assert overhead > 0 and cap.view.overhead_s == overhead            # measured on the run, kept for the next
    # another exposure typed, then the calibration loaded: the table shows the calibration's, nothing "incomplete"
    for nl in cap.lights:
        cap.set_exposure(nl.name, 1 / 4000)
    ws.set_calibration(None)
    cap.calibration.load(Path(profile.path))
    qtbot.waitUntil(lambda: ws.calibration_check is not None, timeout=LONG)
    assert cap.exposures() == {n: [t] for n, t in profile.base_exposures.items()}
    guide.refresh()
    step = guide.step(DayStep.CALIBRATE)
    assert step.state is StepState.DONE and not any("incomplete" in line for line in step.lines), step.lines
    # Calibrate again: asked; Cancel lights nothing
    frames = len(w.lab.session.entries())
    w.asker.scripted = ["Cancel"]
    click(qtbot, cap.calibration.calibrate_button)
    qtbot.waitUntil(lambda: w.asker.history and w.asker.history[-1][0] == "Calibrate again?", timeout=LONG)
    qtbot.wait(50)
    wait_idle(qtbot, w)
    assert not cap.view.running and len(w.lab.session.entries()) == frames and ws.calibration.id == profile.id
    # Re-shoot: a new session for the new frames (the old one keeps its own), then cancelled at once
    old = w.lab.session.path
    w.asker.scripted = ["Re-shoot"]
    click(qtbot, cap.calibration.calibrate_button)
    qtbot.waitUntil(lambda: cap.view.running, timeout=LONG)
    assert w.lab.session.path != old and w.lab.session.entries() == []
    w.cancel_action.trigger()
    qtbot.waitUntil(lambda: not cap.view.running, timeout=LONG)
    wait_idle(qtbot, w)
    assert ws.calibration.id == profile.id                    # a cancelled calibration never replaces the current


def test_results_grade_the_delivered_matrix(qtbot, make_window):
    w = make_window()
    connect_devices(qtbot, w)
    quick_calibrate(qtbot, w)                # no ΔE00 fit: least squares or a root-polynomial is what is delivered
    res = w.results
    delivered = res.delivered_method()
    assert delivered in ("least-squares", "root-polynomial-2", "root-polynomial-3") and not res.optimise.isChecked()
    assert res.comparison_note(delivered) == ""
    assert "comparison" in res.comparison_note("de2000") and METHOD_NAMES[delivered] in res.comparison_note("de2000")
    qtbot.waitUntil(lambda: res.train_subject.count() > 0, timeout=LONG)
    click(qtbot, res.process_button)
    qtbot.waitUntil(lambda: res.result is not None, timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert delivered in res.summary.text() and "comparison" not in res.summary.text()
    assert "per pixel, test: mean" in res.summary.text()           # issue 40: beside the patch means
    assert all("comparison" not in b.text() for b in res.badge_labels.values())


def test_the_target_tab_opens_on_a_target_not_an_original(qtbot, make_window):
    from dualrgb.app.gui.panels.target import target_first
    from dualrgb.core.vocabulary import Subject

    keys = [Subject.original("AAA-1").key, Subject.target("train").key, Subject.target("test").key]
    assert sorted(keys, key=target_first) == [keys[2], keys[1], keys[0]]


def test_every_copy_stand_option_has_its_row_in_docs_gui():
    """docs/gui.md's table names every option of `dualrgb calibrate`, `capture` and `process` (issue 30)."""
    import argparse

    from dualrgb.app.cli import build_parser

    text = (Path(__file__).resolve().parents[2] / "docs" / "gui.md").read_text(encoding="utf-8")
    section = text.split("## Every copy-stand option of the command line", 1)[1].split("\n## ", 1)[0]
    rows = [line for line in section.splitlines() if line.startswith("| ") and "`--" in line]
    sub = next(a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction))
    missing = []
    for command in ("calibrate", "capture", "process"):
        for action in sub.choices[command]._actions:
            for option in (o for o in action.option_strings if o.startswith("--") and o != "--help"):
                if not any(f"`{option}`" in row.split("|")[2] and command in row.split("|")[1] for row in rows):
                    missing.append(f"{command} {option}")
    assert not missing, missing
