"""What a first-day technician trips on (issue 11), each on the virtual lab: a calibration that no longer matches
the stand is shown before anything is captured; a dark test shot says so; an earlier error leaves the status bar
when the action succeeds; a session reopened with other settings is refused, and its damaged frames are set
aside."""
from __future__ import annotations

from PySide6.QtCore import Qt

from dualrgb.app.workflow.day import OriginalState
from dualrgb.simulation.lightsource import LightSource
from tests.gui.conftest import HANG_GUARD_MS, wait_idle

LONG = HANG_GUARD_MS


def click(qtbot, button):
    assert button.isEnabled(), f"{button.text()!r} is disabled: {button.toolTip()}"
    qtbot.mouseClick(button, Qt.LeftButton)


def start(qtbot, w):
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    cap = w.capture
    cap.new_session()
    qtbot.waitUntil(lambda: w.lab.session is not None and len(cap.presets) > 0, timeout=LONG)
    cap.choose_preset("dual-RGB reflective")
    cap.settle.setValue(0.0)
    return cap


def test_a_mismatching_calibration_is_shown_before_capture(qtbot, make_window):
    w = make_window(frame_size=(96, 64))
    cap = start(qtbot, w)
    box = cap.calibration
    box.dark_frames.setValue(1)
    box.flat_frames.setValue(1)
    box.de_fit.setChecked(False)
    box.hdr_auto.setChecked(False)
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: w.ctx.workspace.calibration_check is not None, timeout=LONG)
    org = w.originals
    org.identifier.setText("ACC-9")
    click(qtbot, org.add_button)
    org.select("ACC-9")
    assert org.capture_button.isEnabled() and "matches the stand" in org.calibration_label.text()
    # the technician turns the camera to ISO 100 (the D610's base ISO): the calibration was made at 50
    w.camera.iso.setCurrentText("100")
    click(qtbot, w.camera.apply_button)
    qtbot.waitUntil(lambda: w.ctx.workspace.calibration_refused, timeout=LONG)
    wait_idle(qtbot, w)
    assert "ISO 100 differs from the calibration's 50" in org.calibration_label.text()
    assert not org.capture_button.isEnabled() and "does not match" in org.capture_button.toolTip()
    assert org.force.isVisible() or not org.isVisible()
    guide = w.guide
    guide.refresh()
    assert any("does not match the stand" in line for line in guide.step(guide.steps[1].step).lines)
    assert "does not match the stand" in box.summary.text()
    org.force.setChecked(True)                        # use it anyway: allowed, and said in the deliverables
    assert org.capture_button.isEnabled()
    assert [r.state for r in w.ctx.workspace.queue.rows] == [OriginalState.WAITING]        # nothing was shot


def test_a_dark_test_shot_says_so(qtbot, make_window):
    w = make_window()
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    w.lab.place("lens-cap")
    wait_idle(qtbot, w)
    click(qtbot, w.camera.capture_button)
    qtbot.waitUntil(lambda: w.camera.last_view is not None, timeout=LONG)
    assert w.camera.warning_label.text().startswith("frame is dark"), w.camera.warning_label.text()
    assert "the light was off" in w.camera.warning_label.text()
    w.lab.place("test")
    w.lab.apply_light(LightSource((1, 6, 8)), switch_on=True)
    wait_idle(qtbot, w)
    qtbot.waitUntil(lambda: w.lab.last_status.get("light_on") is True, timeout=LONG)
    w.camera.last_view = None
    click(qtbot, w.camera.capture_button)
    qtbot.waitUntil(lambda: w.camera.last_view is not None, timeout=LONG)
    assert not w.camera.warning_label.text().startswith("frame is dark")
    w.lab.set_light_on(False)
    wait_idle(qtbot, w)


def test_a_stale_error_leaves_the_status_bar_on_success(qtbot, make_window):
    w = make_window()
    dev = w.devices
    wait_idle(qtbot, w)
    dev.port_combo.setCurrentText("/dev/ttyDOES_NOT_EXIST")
    click(qtbot, dev.sphere_button)
    wait_idle(qtbot, w)
    assert w.error_state.text().startswith("Connect the LED sphere:")
    dev.port_combo.setCurrentText("virtual sphere (emulator)")
    click(qtbot, dev.sphere_button)
    qtbot.waitUntil(lambda: w.lab.sphere is not None, timeout=LONG)
    wait_idle(qtbot, w)
    assert w.error_state.text() == "" and w.errors.current is None
    assert dev.sphere_light.state in ("ok", "on") and dev.sphere_message.text() == ""


def test_reopened_session_checks_its_definition_and_sets_damaged_frames_aside(qtbot, make_window, tmp_path):
    w = make_window(frame_size=(96, 64))
    cap = start(qtbot, w)
    cap.kind.setCurrentText("Dark series")
    cap.frames.setValue(2)
    click(qtbot, cap.view.start_button)
    qtbot.waitUntil(lambda: cap.view.outcome == "done", timeout=LONG)
    wait_idle(qtbot, w)
    session = w.lab.session
    darks = session.entries("dark")
    (session.path / darks[0].file).write_bytes(b"not a raw file any more")       # damaged on disk
    folder = session.path
    w.capture.new_session(tmp_path / "other")                                     # let go of the first one
    qtbot.waitUntil(lambda: w.lab.session is not None and w.lab.session.path != folder, timeout=LONG)
    w.lab.session.close()
    w.capture.open_session(folder)
    qtbot.waitUntil(lambda: w.lab.session is not None and w.lab.session.path == folder, timeout=LONG)
    wait_idle(qtbot, w)
    assert (folder / "damaged" / darks[0].file).exists()
    title, message = w.errors.history[-1]
    assert title == "Open the session" and "1 missing or damaged frame(s) set aside" in message
    assert w.lab.session.has_step(darks[1].step_id) and not w.lab.session.has_step(darks[0].step_id)
    # the same folder with another frame size (another virtual lab: its camera's image area) is refused, naming it
    w2 = make_window(frame_size=(120, 80))
    w2.lab.start_virtual_lab()
    wait_idle(qtbot, w2)
    w.lab.session.close()
    w2.capture.open_session(folder)
    wait_idle(qtbot, w2)
    assert w2.lab.session is None
    title, message = w2.errors.history[-1]
    assert title == "Open the session" and "image_area" in message and "\n" not in message
