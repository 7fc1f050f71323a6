"""`dualrgb demo` and the GUI give the same report numbers from the same session: both process it through
app.workflow.calibration.session_processing.process_session (the demo holds no processing code of its own)."""
from __future__ import annotations

from PySide6.QtCore import Qt

from dualrgb.app.demo import DemoSettings, run_demo
from tests.gui.conftest import HANG_GUARD_MS, wait_idle

LONG = HANG_GUARD_MS


def test_demo_and_gui_report_the_same_numbers(qtbot, make_window, tmp_path):
    data = run_demo(DemoSettings(out=tmp_path / "demo", frame_size=(240, 160), dark_frames=3, flat_frames=2,
                                 optimise_matrix=False, settle_s=0.0, conditions=("dual_rgb", "dual_rgb_pso")))
    w = make_window(frame_size=(240, 160))
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    w.capture.open_session(tmp_path / "demo" / "session")
    qtbot.waitUntil(lambda: w.lab.session is not None, timeout=LONG)
    res = w.results
    for cond, preset in (("dual_rgb", "dual-RGB reflective"), ("dual_rgb_pso", "dual-RGB-PSO reflective")):
        qtbot.waitUntil(lambda p=preset: res.lights.findText(p) >= 0
                        and res.train_subject.findData("target:train") >= 0, timeout=LONG)
        res.optimise.setChecked(False)
        res.lights.setCurrentText(preset)
        res.select(res.train_subject, "target:train")
        res.select(res.test_subject, "target:test")
        res.result = None
        qtbot.mouseClick(res.process_button, Qt.LeftButton)
        qtbot.waitUntil(lambda: res.result is not None or "failed" in res.status.text(), timeout=LONG)
        wait_idle(qtbot, w)
        assert res.result is not None, (res.status.text(), w.errors.history)
        rep = res.result.report
        for split in ("train", "test"):
            for stat in ("mean", "median", "p90", "max"):
                assert rep[split][stat] == data[cond][split][stat], (cond, split, stat)
        assert rep["lights"] == [light["name"] for light in data[cond]["lights"]]
