"""Devices panel: failures show what to do, in the panel and as a (non-blocking) dialog."""
from __future__ import annotations

from PySide6.QtCore import Qt

from tests.gui.conftest import HANG_GUARD_MS, wait_idle


def test_sphere_on_a_missing_port_says_what_to_check(qtbot, make_window):
    w = make_window()
    dev = w.devices
    wait_idle(qtbot, w)
    dev.port_combo.setCurrentText("/dev/ttyDOES_NOT_EXIST")
    qtbot.mouseClick(dev.sphere_button, Qt.LeftButton)
    wait_idle(qtbot, w)
    assert w.lab.sphere is None
    assert dev.sphere_light.state == "error"
    assert "check the cable" in dev.sphere_message.text()
    assert w.errors.history and w.errors.history[-1][0] == "Connect the LED sphere"
    assert dev.sphere_button.isEnabled()


def test_no_camera_detected_gives_the_fix(qtbot, make_window):
    w = make_window()
    dev = w.devices
    qtbot.mouseClick(dev.detect_button, Qt.LeftButton)
    wait_idle(qtbot, w)
    names = [dev.camera_combo.itemText(i) for i in range(dev.camera_combo.count())]
    assert "virtual camera (virtual lab)" in names
    if len(names) == 1:                                    # the usual case on a machine without a camera
        assert "connect the camera by USB" in dev.camera_message.text()


def test_camera_errors_show_their_advice(qtbot, make_window):
    from dualrgb.drivers.camera.gphoto import GP_ERROR_CAMERA_BUSY, GP_ERROR_IO_USB_CLAIM, camera_error

    class FakeGphotoError(Exception):
        def __init__(self, code):
            super().__init__(f"[{code}]")
            self.code = code

    w = make_window()
    dev = w.devices
    for code, words in ((GP_ERROR_IO_USB_CLAIM, "gvfs"), (GP_ERROR_CAMERA_BUSY, "busy")):
        def fail(code=code):
            raise camera_error(FakeGphotoError(code), "open camera")
        w.lab.device_call(fail, "Connect the camera")
        wait_idle(qtbot, w)
        assert words in dev.camera_message.text()
        assert dev.camera_light.state == "error"


def test_unplugged_camera_port(qtbot, make_window):
    w = make_window()
    dev = w.devices
    dev.camera_combo.addItem("Nikon DSC D610 @ usb:001,099")
    dev.camera_combo.setCurrentText("Nikon DSC D610 @ usb:001,099")
    qtbot.mouseClick(dev.camera_button, Qt.LeftButton)
    wait_idle(qtbot, w)
    assert w.lab.camera is None
    assert "unplugged" in dev.camera_message.text()
    assert w.ctx.settings.value("devices/camera") == "Nikon DSC D610 @ usb:001,099"


def test_virtual_lab_start_and_keyboard_capture(qtbot, make_window):
    w = make_window()
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    assert w.devices.virtual_label.text().startswith("running")
    w.tabs.setCurrentWidget(w.camera)
    w.capture_action.trigger()                              # Ctrl+Enter / F5
    qtbot.waitUntil(lambda: w.camera.last_view is not None, timeout=HANG_GUARD_MS)
    assert list((w.ctx.captures_dir / "test-shots").glob("*.DNG"))


def test_live_view_updates_picture_and_histogram(qtbot, make_window):
    w = make_window()
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    w.lab.place("open-gate")
    cam = w.camera
    qtbot.mouseClick(cam.live_button, Qt.LeftButton)
    qtbot.waitUntil(lambda: cam.view_title.text().startswith("live view"), timeout=HANG_GUARD_MS)
    qtbot.waitUntil(lambda: cam.hist_label.text().startswith("live view"), timeout=HANG_GUARD_MS)
    assert set(cam.hist_curves) == {"R", "G", "B"}
    qtbot.mouseClick(cam.live_button, Qt.LeftButton)
    assert not cam._live_timer.isActive()
    wait_idle(qtbot, w)
