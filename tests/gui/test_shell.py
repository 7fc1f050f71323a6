"""The window shell: panels, no-display message, settings persistence, light source, simulate."""
from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

from tests.gui.conftest import HANG_GUARD_MS, wait_idle

ROOT = Path(__file__).resolve().parents[2]


def test_no_display_prints_one_line_and_exits_1(tmp_path):
    env = {k: v for k, v in os.environ.items() if k not in ("DISPLAY", "WAYLAND_DISPLAY", "QT_QPA_PLATFORM")}
    env["HOME"] = str(tmp_path)
    proc = subprocess.run([sys.executable, "-m", "dualrgb", "gui"], cwd=ROOT, env=env, capture_output=True,
                          text=True, timeout=120)
    assert proc.returncode == 1
    lines = [ln for ln in proc.stderr.splitlines() if ln.strip()]
    assert lines == ["dualrgb: error: no display found; set QT_QPA_PLATFORM=offscreen for headless use or run "
                     "on a desktop"]


def test_display_problem_rules():
    from dualrgb.app.gui.app import display_problem

    assert display_problem({}) is not None
    assert display_problem({"QT_QPA_PLATFORM": "offscreen"}) is None
    assert display_problem({"QT_QPA_PLATFORM": "minimal"}) is None
    assert display_problem({"DISPLAY": ":0"}) is None
    assert display_problem({"WAYLAND_DISPLAY": "wayland-0"}) is None
    assert display_problem({"QT_QPA_PLATFORM": "xcb"}) is not None
    assert display_problem({"QT_QPA_PLATFORM": ""}) is not None       # what `make run` clears it to


def test_pyside_has_no_none_refcount_bug(qapp):
    from dualrgb.app.gui.app import pyside_drops_none_references

    assert not pyside_drops_none_references()


def test_every_panel_is_there(make_window):
    w = make_window()
    titles = [w.tabs.tabText(i).replace("&&", "&") for i in range(w.tabs.count())]
    assert titles == ["Devices", "Light source", "Camera", "Calibrate & capture", "Originals", "Target", "Results",
                      "Simulate & optimise", "Characterise", "Tools"]
    for name in ("devices", "light", "camera", "originals", "simulate"):
        assert w.panels[name].isEnabled()


def test_settings_persist_between_windows(qtbot, make_window, settings):
    w = make_window()
    w.resize(760, 590)
    w.tabs.setCurrentIndex(6)
    w.light.set_levels([0.5] + [0.0] * 8 + [0.25])
    w.simulate.seed.setValue(42)
    w.simulate.method.setCurrentText("ga")
    w.close()
    assert settings.value("window/tab") in (6, "6")
    w2 = make_window()
    assert w2.tabs.currentIndex() == 6
    assert (w2.size().width(), w2.size().height()) == (w.size().width(), w.size().height())
    assert np.allclose(w2.light.levels(), [0.5] + [0.0] * 8 + [0.25])
    assert w2.simulate.seed.value() == 42
    assert w2.simulate.method.currentText() == "ga"


def test_light_spectrum_follows_sliders(make_window):
    from dualrgb.simulation.lightsource import LightSource

    w = make_window()
    panel = w.light
    panel.sliders[0].setValue(1000)
    panel.sliders[5].setValue(500)
    x, y = panel.mix_curve.getData()
    expected = LightSource((1, 6), (1.0, 0.5)).spectrum(panel.led_spectra)
    assert np.allclose(y, expected)
    assert panel.spins[5].value() == pytest.approx(50.0)                # levels shown in %
    assert panel.spins[5].suffix().strip() == "%"


def test_presets_listed_and_applied_to_the_emulated_sphere(qtbot, make_window):
    w = make_window()
    w.lab.start_virtual_lab()
    wait_idle(qtbot, w)
    assert w.lab.sphere is not None
    items = w.light.preset_items()
    assert items, "packaged presets should be listed"
    item = next(i for i in items if len(i.preset.sources) == 2)
    w.light.presets.setCurrentItem(item)
    qtbot.mouseClick(w.light.apply2, __import__("PySide6.QtCore", fromlist=["Qt"]).Qt.LeftButton)
    wait_idle(qtbot, w)
    want = item.preset.sources[1].weights(10)
    assert np.allclose(w.lab.manual_light.weights(10), want, atol=1e-4)       # the manual light's levels
    qtbot.mouseClick(w.light.on_button, __import__("PySide6.QtCore", fromlist=["Qt"]).Qt.LeftButton)
    wait_idle(qtbot, w)
    qtbot.waitUntil(lambda: w.lab.last_status.get("light_on") is True, timeout=HANG_GUARD_MS)
    assert np.allclose(w.lab.virtual_lab.emulator.commanded_levels(), want, atol=1e-4)   # lit with them
    qtbot.mouseClick(w.light.off_button, __import__("PySide6.QtCore", fromlist=["Qt"]).Qt.LeftButton)
    wait_idle(qtbot, w)
    qtbot.waitUntil(lambda: not w.runner.busy("light"), timeout=HANG_GUARD_MS)     # the light held by hand ends
    assert not w.lab.virtual_lab.emulator.snapshot().light_on
    assert w.errors.history == []


def test_rename_packaged_preset_saves_a_copy(qtbot, make_window, tmp_path):
    w = make_window()
    wait_idle(qtbot, w)
    item = w.light.preset_items()[0]
    item.setText("my renamed preset")
    wait_idle(qtbot, w)
    saved = w.ctx.presets_dir / "my_renamed_preset.json"
    assert saved.is_file()
    qtbot.waitUntil(lambda: any(i.preset.name == "my renamed preset" and not i.packaged
                                for i in w.light.preset_items()), timeout=HANG_GUARD_MS)


def test_simulate_defaults_are_the_default_optimiser_on_the_expected_captured_error(make_window):
    sim = make_window().simulate
    assert sim.method.currentText() == "halving" and sim.objective.currentText() == "expected-captured"
    assert sim.objective.isEnabled() and sim.seed.isEnabled()
    sim.method.setCurrentText("three-channel")
    assert not sim.objective.isEnabled()


def test_simulate_tiny_pso_and_save_preset(qtbot, make_window):
    from dualrgb.simulation.presets import load_preset

    w = make_window()
    sim = w.simulate
    sim.mode.setCurrentText("reflective")
    sim.method.setCurrentText("pso")
    sim.iterations.setValue(2)
    sim.population.setValue(6)
    sim.start()
    qtbot.waitUntil(lambda: sim.result is not None, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    assert len(sim.live) > 10                              # live convergence points arrived during the run
    bests = [b for _, b in sim.live]
    assert all(b2 <= b1 for b1, b2 in zip(bests, bests[1:], strict=False))
    _, hist = sim.iter_curve.getData()
    assert len(hist) == 3 and hist[-1] <= hist[0]
    assert sim.sens_plot.listDataItems() and len(sim.sens_plot.listDataItems()) == 6
    path = sim.save_preset("gui tiny pso")
    wait_idle(qtbot, w)
    preset = load_preset(path)
    assert preset.method == "pso" and len(preset.sources) == 2
    qtbot.waitUntil(lambda: any(i.preset.name == "gui tiny pso" for i in w.light.preset_items()), timeout=HANG_GUARD_MS)


def test_simulation_cancel(qtbot, make_window):
    w = make_window()
    sim = w.simulate
    sim.method.setCurrentText("pso")
    sim.iterations.setValue(10)
    sim.population.setValue(200)
    sim.start()
    qtbot.waitUntil(lambda: len(sim.live) > 0, timeout=HANG_GUARD_MS)
    w.cancel_action.trigger()
    wait_idle(qtbot, w)
    # the best light pair found so far is kept, labelled partial (issue 11 item 8)
    assert sim.result is not None and sim.result.extra.get("partial")
    assert sim.status.text().startswith("PARTIAL (cancelled)")
    assert sim.table.rowCount() == 1 and "(partial)" in sim.table.item(0, 2).text()
    cand = sim.result.outcome.candidates[0]
    # its float64 re-evaluation agrees with the search's cost, in the objective the search ran (expected captured)
    assert sim.result.objective == "expected-captured" and cand.expected_train is not None
    assert cand.objective_mean(sim.result.objective) == pytest.approx(cand.train_cost, abs=1e-3)
    assert cand.train.mean < cand.expected_train.mean               # noise-free is the lower bound
    assert sim.result.evaluations > 0
    assert sim.run_button.isEnabled()


@pytest.mark.parametrize("method", ["ga", "three-channel", "exhaustive"])
def test_simulate_other_methods(qtbot, make_window, method):
    w = make_window()
    sim = w.simulate
    sim.method.setCurrentText(method)
    sim.iterations.setValue(2)
    sim.population.setValue(10)
    sim.start()
    qtbot.waitUntil(lambda: sim.result is not None, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    assert sim.result.method == method
    assert "baseline" in sim.status.text()
    if method == "ga":
        assert sim.live and sim.table.rowCount() > 0 and sim.save_button.isEnabled()
    elif method == "exhaustive":                     # no iterations: said so, not an empty +-500 000 axis
        assert "none (exhaustive" in sim.iter_plot.getPlotItem().titleLabel.text
        (x0, x1), (y0, y1) = sim.iter_plot.getPlotItem().viewRange()
        assert x1 - x0 < 10 and y1 - y0 < 10
    else:
        assert sim.table.rowCount() == 0 and not sim.save_button.isEnabled()
    from PySide6.QtWidgets import QHeaderView
    header = sim.table.horizontalHeader()                   # the light columns wrap, the numbers show whole
    modes = [header.sectionResizeMode(c) for c in range(4)]
    assert modes == [QHeaderView.Stretch] * 2 + [QHeaderView.ResizeToContents] * 2


def test_study_charts_listed(qtbot, make_window, user_data_dir):
    import shutil

    from dualrgb import resources
    packaged = sorted(resources.path("figures").glob("*.png"))
    assert packaged, "the reference study charts are packaged (resources/figures)"
    mine = user_data_dir / "studies" / "parsimony"            # where 'dualrgb study parsimony' writes
    mine.mkdir(parents=True)
    shutil.copy(packaged[0], mine / "parsimony.png")
    w = make_window()
    sim = w.simulate
    sim.right_tabs.setCurrentIndex(1)
    wait_idle(qtbot, w)
    labels = [sim.figure_combo.itemText(i) for i in range(sim.figure_combo.count())]
    assert labels[0] == "parsimony/parsimony.png" and len(labels) == len(packaged) + 1
    assert sim.figure_label.pixmap() is not None and not sim.figure_label.pixmap().isNull()
    assert str(user_data_dir / "studies") in sim.figures_info.text()
