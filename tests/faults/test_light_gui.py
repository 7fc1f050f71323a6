"""The GUI's error path (issue 9 item 1): replies lost while 'Light ON' switches the sphere on. Before, the dialog
said "no reply" while the sphere stayed lit as long as the window was open (its 1 Hz status poll fed the
watchdog). Now the light is off within its limit + 0.5 s on the emulator's own clock, while the GUI keeps
polling, and the dialog says truthfully what state the light was left in. 'Light ON' is a plan of the run engine
(app.workflow.light_plans.HeldLight): a sphere whose switch-off is not confirmed is never switched on."""
from __future__ import annotations

import pytest

pytest.importorskip("PySide6")
pytest.importorskip("pytestqt")

from light_record import LS1, assert_dark_within, lit_spans
from PySide6.QtCore import QSettings, Qt

MANUAL_LIMIT_S = 1.0
HANG_GUARD_MS = 600_000        # waits are hang guards, far above a step's time at load 8 (tests/gui/conftest.py)

CASES = {
    "ON replies lost": ([("no_reply", {"keywords": ["ON"]})],
                        ("no reply to 'ON 1000'", "all LEDs and the light were switched off")),
    # the run engine starts every run from dark, read back: a switch-off that cannot be confirmed refuses the run
    # before anything is switched on (the same fault after ON: tests/faults/test_light_limits.py)
    "switch-off ignored too": ([("no_reply", {"keywords": ["ON"]}), ("ignore", {"keywords": ["ALLOFF", "LIGHT"]})],
                               ("manual light not started", "no reply to 'ALLOFF'", "the light's state is unknown")),
}


@pytest.fixture
def window(qtbot, tmp_path):
    from dualrgb.app.gui.main_window import MainWindow

    settings = QSettings(str(tmp_path / "dualrgb.ini"), QSettings.IniFormat)
    settings.setValue("paths/captures", str(tmp_path / "captures"))
    w = MainWindow(settings, frame_size=(96, 64), show_dialogs=False)
    w.lab.lab_in_process = True               # its emulator in reach, to inject the faults
    qtbot.addWidget(w)
    w.show()
    yield w
    w.close()


def idle(qtbot, w, timeout=HANG_GUARD_MS):
    qtbot.waitUntil(lambda: not w.runner.busy("devices"), timeout=timeout)


@pytest.mark.fault("light safety")
@pytest.mark.parametrize("case", list(CASES))
def test_light_on_with_lost_replies_ends_dark_and_says_so(qtbot, window, case):
    faults, says = CASES[case]
    w = window
    w.lab.start_virtual_lab()
    idle(qtbot, w)
    emulator = w.lab.virtual_lab.emulator
    w.lab.sphere.timeout = 0.3
    w.lab.manual_max_on_s = MANUAL_LIMIT_S
    w.lab.apply_light(LS1.light)
    idle(qtbot, w)
    for fault, params in faults:
        emulator.inject(fault, **params)
    t0 = emulator.clock()
    qtbot.mouseClick(w.light.on_button, Qt.LeftButton)
    qtbot.waitUntil(lambda: any(t == "Switch the light" for t, _ in w.errors.history), timeout=HANG_GUARD_MS)
    qtbot.wait(int((MANUAL_LIMIT_S + 1.0) * 1000))     # the GUI keeps polling STATUS? at 1 Hz meanwhile
    idle(qtbot, w)
    title, message = next((t, m) for t, m in w.errors.history if t == "Switch the light")
    assert all(part in message for part in says), message
    assert "\n" not in message
    if "not started" in message:                        # refused from dark: never lit
        assert lit_spans(emulator, t0) == []
    else:
        assert_dark_within(emulator, t0, MANUAL_LIMIT_S, f"GUI Light ON, {case}")
    assert not emulator.snapshot().light_on
