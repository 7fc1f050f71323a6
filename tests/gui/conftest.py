"""GUI tests: offscreen Qt, settings and data in a temp dir, dialogs recorded instead of shown."""
from __future__ import annotations

import os

os.environ.setdefault("QT_QPA_PLATFORM", "offscreen")

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")


# every wait in the GUI tests is a hang guard, far above what a step takes on a machine at load 8 (issue 26): a
# wait that runs out means something hangs, never that the machine was busy
HANG_GUARD_MS = 600_000

@pytest.fixture
def settings(tmp_path):
    from PySide6.QtCore import QSettings

    s = QSettings(str(tmp_path / "config" / "dualrgb.ini"), QSettings.IniFormat)
    s.setValue("paths/captures", str(tmp_path / "captures"))
    s.sync()
    return s


@pytest.fixture
def make_window(qtbot, settings):
    """Factory: a MainWindow on the temp settings (small virtual-lab frames); closed after the test."""
    from dualrgb.app.gui.main_window import MainWindow

    made = []

    def make(**kw):
        in_process = kw.pop("lab_in_process", True)       # the lab's emulator in reach (its own process: test_lab)
        w = MainWindow(kw.pop("settings", settings), frame_size=kw.pop("frame_size", (120, 80)),
                       show_dialogs=False, **kw)
        w.lab.lab_in_process = in_process
        qtbot.addWidget(w)
        w.show()
        made.append(w)
        return w

    yield make
    for w in made:
        w.close()


def wait_idle(qtbot, window, timeout=HANG_GUARD_MS):
    """Until no task runs in any pool (device calls, computations, sequences)."""
    qtbot.waitUntil(lambda: not window.runner.busy(), timeout=timeout or HANG_GUARD_MS)


DEVICE_TIMEOUT_MS = HANG_GUARD_MS


def click(qtbot, button):
    """A real mouse click on ``button``, which must be enabled (its tooltip says why when it is not)."""
    from PySide6.QtCore import Qt

    assert button.isEnabled(), f"{button.text()!r} is disabled: {button.toolTip()}"
    qtbot.mouseClick(button, Qt.LeftButton)


def connect_devices(qtbot, w):
    """Connect the virtual sphere and the virtual camera from the Devices panel, as a technician does."""
    dev = w.devices
    wait_idle(qtbot, w)
    dev.port_combo.setCurrentText("virtual sphere (emulator)")
    click(qtbot, dev.sphere_button)
    qtbot.waitUntil(lambda: w.lab.sphere is not None, timeout=DEVICE_TIMEOUT_MS)
    dev.camera_combo.setCurrentText("virtual camera (virtual lab)")
    click(qtbot, dev.camera_button)
    qtbot.waitUntil(lambda: w.lab.camera is not None, timeout=DEVICE_TIMEOUT_MS)
    wait_idle(qtbot, w)


def quick_calibrate(qtbot, w, *, de_fit=False):
    """Calibrate from the calibration box with the fewest frames (1 dark, 1 flat, no HDR exposures, settle 0);
    returns the questions asked meanwhile (title, text)."""
    cap = w.capture
    qtbot.waitUntil(lambda: len(cap.presets) > 0, timeout=HANG_GUARD_MS)
    cap.settle.setValue(0.0)
    box = cap.calibration
    box.dark_frames.setValue(1)
    box.flat_frames.setValue(1)
    box.de_fit.setChecked(de_fit)
    box.hdr_auto.setChecked(False)
    asked = len(w.asker.history)
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: not cap.view.running and cap.view.outcome != "", timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w, HANG_GUARD_MS)
    return w.asker.history[asked:]
