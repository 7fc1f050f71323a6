"""Issue 22 from fresh settings: the window starts from the defaults `dualrgb calibrate` uses (the mode's
recommended lights, marked, every preset with its expected captured error; darks, flats, HDR plan, matrix),
Calibrate with no session makes a dated one in the captures folder under the per-user data folder (never the
settings folder) and says so; the old default captures folder is found and offered, never silently left."""
from __future__ import annotations

import re
from pathlib import Path

import pytest
from PySide6.QtCore import QSettings

from dualrgb.app.cli import build_parser
from dualrgb.app.commands import calibrate
from dualrgb.app.workflow.calibration.preset_figures import preset_figures
from dualrgb.app.workflow.stand import defaults
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import lights_of
from dualrgb.simulation.presets import load_preset
from tests.gui.conftest import DEVICE_TIMEOUT_MS, HANG_GUARD_MS, click, connect_devices, wait_idle

LONG = HANG_GUARD_MS


@pytest.fixture
def fresh(tmp_path):
    """A settings file nobody has written to (no captures folder chosen)."""
    return QSettings(str(tmp_path / "config" / "dualrgb" / "dualrgb.ini"), QSettings.IniFormat)


def cli_default_lights(mode: str = "reflective"):
    preset, *_ = calibrate.resolve(build_parser().parse_args(["calibrate", "--virtual-lab", "--mode", mode]))
    return [nl.light for nl in lights_of(preset)]


def default_lights(mode: str = "reflective"):
    return [nl.light for nl in lights_of(load_preset(defaults.default_preset_path(mode)))]


def lights(nls):
    return [nl.light for nl in nls]


def test_calibrate_from_fresh_settings_makes_a_session_with_the_cli_default_lights(qtbot, make_window, fresh,
                                                                                    user_data_dir):
    w = make_window(settings=fresh, frame_size=(96, 64))
    cap, box, ws = w.capture, w.capture.calibration, w.ctx.workspace
    connect_devices(qtbot, w)
    qtbot.waitUntil(lambda: len(cap.presets) > 0 and all(f is not None for f in cap.chooser.figures), timeout=LONG)
    assert w.lab.session is None and box.calibrate_button.isEnabled(), box.calibrate_button.toolTip()
    d = defaults.workflow_defaults("reflective")
    assert (box.dark_frames.value(), box.flat_frames.value()) == (d.dark_frames, d.flat_frames)
    assert box.hdr_auto.isChecked() is d.hdr_auto and box.de_fit.isChecked() is d.optimise_matrix
    assert lights(ws.lights) == default_lights() == cli_default_lights()
    texts = [cap.preset_combo.itemText(i) for i in range(cap.preset_combo.count())]
    fig = preset_figures(ws.preset)
    assert cap.preset_combo.currentText() == f"{ws.preset.name} · {fig.text()} · recommended"
    assert sum("recommended" in t for t in texts) == 1 and fig.text() in cap.chooser.note.text()
    assert any(t.startswith("dual-RGB reflective · expected ΔE00 0.67 / 0.49, per pixel 1.") for t in texts)
    assert fig.text().startswith("expected ΔE00 0.42 / 0.30, per pixel 0.")
    box.dark_frames.setValue(1)                      # a short run; the lights stay the default ones
    box.flat_frames.setValue(1)
    box.hdr_auto.setChecked(False)
    box.de_fit.setChecked(False)
    cap.settle.setValue(0.0)
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: w.lab.session is not None, timeout=DEVICE_TIMEOUT_MS)
    folder = w.lab.session.path
    assert folder.parent == defaults.captures_dir() == user_data_dir / "captures"
    assert re.fullmatch(r"\d{4}-\d{2}-\d{2}_1", folder.name), folder
    assert fresh.fileName().startswith(str(user_data_dir.parent / "config"))     # the settings folder ...
    assert not str(folder).startswith(str(user_data_dir.parent / "config"))       # ... holds no captures
    w.guide.refresh()
    assert f"session: {folder.name} (" in w.guide.step(w.guide.steps[0].step).lines[2]
    assert "made for the calibration" in w.guide.step(w.guide.steps[0].step).lines[2]
    qtbot.waitUntil(lambda: ws.calibration is not None, timeout=LONG)
    wait_idle(qtbot, w)
    assert lights(ws.calibration.lights) == default_lights() == cli_default_lights()
    assert ws.calibration.path.is_relative_to(folder) and w.errors.history == []


def test_changing_the_one_place_changes_the_window_and_the_cli(qtbot, make_window, fresh, monkeypatch):
    monkeypatch.setitem(defaults.PRESETS, "reflective", "reflective_exhaustive")
    monkeypatch.setitem(defaults.PRESETS, "transmissive", "transmissive_exhaustive")
    monkeypatch.setattr(defaults, "DARK_FRAMES", 4)
    w = make_window(settings=fresh)
    cap = w.capture
    qtbot.waitUntil(lambda: len(cap.presets) > 0, timeout=LONG)
    assert cap.calibration.dark_frames.value() == 4
    assert lights(w.ctx.workspace.lights) == default_lights() == cli_default_lights()
    assert w.ctx.workspace.preset.name == "dual-RGB reflective"
    w.devices.mode_combo.setCurrentText("transmissive")          # the lights follow the mode, as in the CLI
    assert lights(w.ctx.workspace.lights) == cli_default_lights("transmissive") == default_lights("transmissive")
    cap.choose_preset("dual-RGB-PSO transmissive")                  # the technician's own choice stays chosen
    w.devices.mode_combo.setCurrentText("reflective")
    w.devices.mode_combo.setCurrentText("transmissive")
    assert w.ctx.workspace.preset.name == "dual-RGB-PSO transmissive"
    assert "Not the recommended lights for transmissive" in cap.chooser.note.text()


def _old_captures(fresh):
    from dualrgb.app.workflow.stand.folders import legacy_captures_dir

    old = legacy_captures_dir(Path(fresh.fileName()).parent)
    CaptureSession.create(old / "session-20260101-090000", {}, definition={"mode": "reflective"}).close()
    return old


def test_the_old_default_captures_folder_is_found_and_offered(qtbot, make_window, fresh, user_data_dir):
    old = _old_captures(fresh)
    w = make_window(settings=fresh)
    dev = w.devices
    qtbot.waitUntil(lambda: dev.legacy is not None, timeout=LONG)
    title, text = w.asker.history[-1]
    assert title == "Earlier captures" and str(old) in text and "1 session" in text
    assert not dev.legacy_label.isHidden() and str(old) in dev.legacy_label.text()   # left there: still offered
    assert w.ctx.captures_dir == user_data_dir / "captures"
    second = make_window(settings=fresh)                                # asked once; the notice stays
    qtbot.waitUntil(lambda: second.devices.legacy is not None, timeout=LONG)
    assert all(t != "Earlier captures" for t, _ in second.asker.history)
    second.close()
    click(qtbot, dev.legacy_move)
    qtbot.waitUntil(lambda: dev.legacy is None, timeout=LONG)
    wait_idle(qtbot, w)
    moved = user_data_dir / "captures" / "session-20260101-090000"
    CaptureSession.open(moved).close()                                  # still a session where it went
    assert not old.exists() and dev.legacy_label.isHidden()


def test_the_old_captures_folder_can_be_used_as_it_is(qtbot, make_window, fresh):
    old = _old_captures(fresh)
    w = make_window(settings=fresh)
    qtbot.waitUntil(lambda: w.devices.legacy is not None, timeout=LONG)
    click(qtbot, w.devices.legacy_use)
    qtbot.waitUntil(lambda: w.devices.legacy is None, timeout=LONG)
    assert w.ctx.captures_dir == old and (old / "session-20260101-090000" / "session.json").is_file()
