"""The whole production day clicked through the GUI on the virtual lab (issue 11 "must show"): connect, calibrate
with the guide showing coverage, save the calibration, queue two originals with identifiers (the virtual painting
and the shadow, which needs an HDR bracket), capture and deliver them; the TIFFs exist named by identifier, a
re-shoot asks and reports "0 new, 2 kept", controls are locked while a sequence runs, metering can be cancelled;
the GUI thread's longest stall (a PSO run included) is recorded as a benchmark figure (bench/gui_stall.py)."""
from __future__ import annotations

import json

import numpy as np
import tifffile
from xmp_check import read_xmp

from dualrgb.app.workflow.day.day import DayStep, OriginalState, StepState
from dualrgb.core.vocabulary import EventKind
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, wait_idle
from tests.gui.watchdog import StallWatchdog

LONG = HANG_GUARD_MS


def finish(qtbot, w, view):
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w, LONG)
    return view.outcome


def connect_both(qtbot, w):
    connect_devices(qtbot, w)
    dev = w.devices
    assert dev.virtual_label.text().startswith("running"), dev.virtual_label.text()     # not "not started"


def cancel_metering(qtbot, w):
    """Auto-exposure runs like any sequence: it can be cancelled, and the LEDs end off."""
    cap = w.capture
    cap.settle.setValue(0.2)
    click(qtbot, cap.auto_button)
    assert cap.view.running and cap.view.cancel_button.isEnabled()
    w.cancel_action.trigger()                                  # Esc
    assert finish(qtbot, w, cap.view) == "cancelled"
    assert not w.lab.virtual_lab.emulator.snapshot().light_on
    assert np.allclose(w.lab.virtual_lab.emulator.snapshot().levels, 0)
    cap.settle.setValue(0.0)


def assert_locked(w):
    cap, org = w.capture, w.originals
    locked = (cap.new_button, cap.open_button, cap.preset_combo, cap.light_table, cap.auto_button, cap.kind,
              cap.calibration.calibrate_button, cap.calibration.load_button, cap.view.start_button,
              org.capture_button, org.capture_all_button, w.devices.sphere_button, w.devices.camera_button,
              w.light.on_button, w.camera.capture_button, w.characterise.view.start_button)
    enabled = [x.text() if hasattr(x, "text") else type(x).__name__ for x in locked if x.isEnabled()]
    assert not enabled, f"enabled while a sequence runs: {enabled}"


def calibrate(qtbot, w, tmp_path):
    cap, guide = w.capture, w.guide
    box = cap.calibration
    box.dark_frames.setValue(2)
    box.flat_frames.setValue(2)
    box.de_fit.setChecked(False)
    box.hdr_auto.setChecked(True)
    guide.refresh()
    assert "darks 0/" in "\n".join(guide.step(DayStep.CALIBRATE).lines)          # coverage before
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: any("plan" in e.data for e in cap.view.events), timeout=LONG)
    assert_locked(w)
    qtbot.waitUntil(lambda: sum(e.kind is EventKind.FRAME for e in cap.view.events) >= 3, timeout=LONG)
    guide.refresh()
    during = "\n".join(guide.step(DayStep.CALIBRATE).lines)
    assert "darks" in during and "exposures" in during, during
    assert finish(qtbot, w, cap.view) == "done", (cap.view.message.text(), w.errors.history)
    profile = w.ctx.workspace.calibration
    assert profile is not None and all(len(ts) == 2 for ts in profile.exposures.values())    # HDR auto
    planned = next(len(e.data["plan"]) for e in cap.view.events if "plan" in e.data)
    assert sum(e.kind is EventKind.FRAME for e in cap.view.events) == planned       # every planned frame taken
    assert cap.view.ticked_rows() == list(range(planned))                   # and ticked in the plan
    # a single step's plan ticks what the session already has: a 10-frame dark series, 2 darks per exposure done
    cap.kind.setCurrentText("Open-gate flats")
    cap.kind.setCurrentText("Dark series")
    assert cap.view.ticked_rows() == [0, 1, 10, 11, 20, 21, 30, 31]
    qtbot.waitUntil(lambda: w.ctx.workspace.calibration_check is not None, timeout=LONG)
    guide.refresh()
    step = guide.step(DayStep.CALIBRATE)
    n = len({t for ts in profile.exposures.values() for t in ts})
    assert step.state is StepState.DONE and f"darks {n}/{n} exposures" in "\n".join(step.lines), step.lines
    # save it elsewhere and load it back: the same calibration, checked against the stand
    box.save_to(tmp_path / "saved")
    wait_idle(qtbot, w)
    saved = tmp_path / "saved" / f"{profile.id}.json"
    assert saved.exists() and saved.with_suffix(".npz").exists()
    w.ctx.workspace.set_calibration(None)
    box.load(saved)
    qtbot.waitUntil(lambda: w.ctx.workspace.calibration_check is not None, timeout=LONG)
    assert w.ctx.workspace.calibration.id == profile.id and w.ctx.workspace.calibration_check.ok
    assert "matches the stand" in box.summary.text()
    return profile


def add_original(qtbot, w, ident, stand_in):
    org = w.originals
    org.identifier.setText(ident)
    org.title_edit.setText(f"{ident} title")
    org.operator.setText("GUI test")
    org.stand_in.setCurrentText(stand_in)
    click(qtbot, org.add_button)
    return w.ctx.workspace.queue.row(ident)


def capture_originals(qtbot, w):
    org, ws = w.originals, w.ctx.workspace
    org.identifier.setText("")
    assert not org.add_button.isEnabled()                      # the identifier is required
    paint, shadow = add_original(qtbot, w, "PAINT-1", "painting"), add_original(qtbot, w, "SHADOW-1", "shadow")
    assert [r.state for r in ws.queue.rows] == [OriginalState.WAITING] * 2
    click(qtbot, org.capture_all_button)
    qtbot.waitUntil(lambda: org.view.running, timeout=LONG)
    assert_locked(w)
    qtbot.waitUntil(lambda: all(r.state in (OriginalState.DELIVERED, OriginalState.FAILED) for r in ws.queue.rows),
                    timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert [r.state for r in ws.queue.rows] == [OriginalState.DELIVERED] * 2, [r.qa for r in ws.queue.rows]
    for row in (paint, shadow):
        assert row.files and all(p.exists() and p.name.startswith(row.identifier) for p in row.files.values())
        # full resolution by default: the sensor's pixels; the cube and its rendering are made on demand
        assert set(row.files) == {"prophoto", "srgb", "xyz", "channels_1", "channels_2"}
        lab = w.lab.virtual_lab
        assert tifffile.imread(row.files["xyz"]).shape == (lab.height, lab.width, 3)
        for path in (p for p in row.files.values() if p.suffix == ".tif"):
            xmp = read_xmp(path)
            assert (xmp.identifier, xmp.title, xmp.dualrgb["Operator"]) == (row.identifier, f"{row.identifier} title",
                                                                            "GUI test")
        side = json.loads(row.sidecar.read_text())
        assert side["original"]["identifier"] == row.identifier and side["original"]["operator"] == "GUI test"
    shadow_exposures = json.loads(shadow.sidecar.read_text())["exposures"]
    assert all(len(ts) == 2 for ts in shadow_exposures.values()) and "HDR" in shadow.qa      # metering asked
    assert all(len(ts) == 1 for ts in json.loads(paint.sidecar.read_text())["exposures"].values())
    org.select("PAINT-1")
    qtbot.waitUntil(lambda: org.delivered.view is not None and org.delivered.view.identifier == "PAINT-1",
                    timeout=LONG)                          # the Delivered tab: its cube, a pixel's spectrum
    assert org.delivered.spectrum.curves and org.delivered.image.image.shape[2] == 3
    click(qtbot, org.open_tiff_button)
    click(qtbot, org.open_folder_button)
    assert w.ctx.opened[-2:] == [paint.files["srgb"], paint.folder]
    return paint


def reshoot_asks(qtbot, w, paint):
    """Keep: the frames delivered again, here at half resolution (the panel's "Deliver at"): the 2x2 cells, the cube
    and its rendering as files."""
    org = w.originals
    org.resolution.setCurrentIndex(org.resolution.findData("half"))
    w.asker.scripted = ["Keep"]
    org.select("PAINT-1")
    before = paint.qa
    click(qtbot, org.capture_button)
    qtbot.waitUntil(lambda: paint.qa != before and paint.state is OriginalState.DELIVERED and not org.view.running,
                    timeout=LONG)
    wait_idle(qtbot, w, LONG)
    title, text = w.asker.history[-1]
    assert title == "Already in the session" and "PAINT-1" in text
    assert "PAINT-1: 0 new, 2 kept" in paint.qa, paint.qa
    assert "0 new, 2 kept" in org.view.message.text()
    lab = w.lab.virtual_lab
    assert {"spectral", "spectral_header", "render"} <= set(paint.files)
    assert tifffile.imread(paint.files["xyz"]).shape == (lab.height // 2, lab.width // 2, 3)
    org.resolution.setCurrentIndex(org.resolution.findData("full"))


def run_pso(qtbot, w):
    sim = w.simulate
    sim.mode.setCurrentText("reflective")
    sim.method.setCurrentText("pso")
    sim.iterations.setValue(3)
    sim.population.setValue(40)
    click(qtbot, sim.run_button)
    qtbot.waitUntil(lambda: sim.result is not None, timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert sim.iter_curve.getData()[0] is not None and len(sim.iter_curve.getData()[0]) == 4


def test_production_day_through_the_gui(qtbot, make_window, tmp_path):
    w = make_window(frame_size=(160, 108))
    dog = StallWatchdog()
    dog.start()
    dog.phase = "connect"
    connect_both(qtbot, w)
    w.guide.refresh()
    connect = w.guide.step(DayStep.CONNECT)                 # the devices: a session is made when one is needed
    assert connect.state is StepState.DONE and connect.lines[2].startswith("session: none yet"), connect.lines
    cap = w.capture
    click(qtbot, cap.new_button)
    qtbot.waitUntil(lambda: w.lab.session is not None and len(cap.presets) > 0, timeout=LONG)
    cap.choose_preset("dual-RGB reflective")
    w.guide.refresh()
    assert w.guide.step(DayStep.CONNECT).state is StepState.DONE
    dog.phase = "metering cancelled"
    cancel_metering(qtbot, w)
    dog.phase = "calibration"
    calibrate(qtbot, w, tmp_path)
    dog.phase = "originals"
    paint = capture_originals(qtbot, w)
    dog.phase = "re-shoot"
    reshoot_asks(qtbot, w, paint)
    w.guide.refresh()
    assert w.guide.step(DayStep.DELIVER).state is StepState.DONE
    assert "2 of 2 delivered" in w.guide.step(DayStep.DELIVER).lines[0]
    dog.phase = "PSO"
    run_pso(qtbot, w)
    dog.stop()
    dog.record("production_day")          # a benchmark figure (bench/gui_stall.py), never a timed assertion
    assert dog.ticks > 100
    assert [t for t, _ in w.errors.history] == [], w.errors.history
    assert not w.lab.virtual_lab.emulator.snapshot().light_on
