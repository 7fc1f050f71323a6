"""The CLI's copy-stand abilities in the window and the focus aids (issue 30 items 6, 7), clicked on the virtual
lab: re-deliver a session with another calibration (dualrgb process), the rendering light / ppi / resolution and
the calibration's sampling as remembered options, measuring the camera and the LEDs from the Tools panel (prompts
as dialogs), the live view's zoom box and focus measure, and the framing light within its cap."""
from __future__ import annotations

import dataclasses
import json
import time

import numpy as np
import pytest
from PySide6.QtCore import Qt
from scipy import ndimage
from spectral_profiles import SPECTRAL, estimator
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.gui.focus_aid import brightened, tenengrad
from dualrgb.app.gui.framing_light import MAX_FRAMING_LEVEL
from dualrgb.core.vocabulary import EventKind
from dualrgb.simulation.matrix_fit import CharacterisationMatrix
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, wait_idle

LONG = HANG_GUARD_MS


# ---------------------------------------------------------------- re-deliver (dualrgb process in the window)
@pytest.fixture
def captured_session(tmp_path, capsys):
    """A session with two originals delivered with calibration cal-test, and a second calibration cal-other."""
    first = make_profile(tmp_path / "cal", shape=(64, 96), estimator=estimator(), spectral=SPECTRAL)
    other = dataclasses.replace(first, id="cal-other", matrix=CharacterisationMatrix(np.eye(3) * 45,
                                                                                       ["R1", "G1", "B1"]))
    other.save(tmp_path / "cal2")
    session = tmp_path / "session"
    for identifier in ("ACC-1", "ACC-2"):
        assert main(["capture", "--virtual-lab", "--calibration", str(first.path), "--id", identifier, "--session",
                     str(session), "--force", "--settle", "0", "--frame-size", "96x64"]) == 0
    capsys.readouterr()
    return session, first.path, other.path


def sidecar(session, identifier):
    return json.loads((session / "deliverables" / identifier / f"{identifier}.json").read_text())


def test_redeliver_with_another_calibration(qtbot, make_window, captured_session):
    session, _first, other = captured_session
    before = {i: sidecar(session, i) for i in ("ACC-1", "ACC-2")}
    w = make_window()
    view = w.tools.redeliver
    w.show_panel("tools")
    assert not view.start_button.isEnabled()                  # no session yet: the tooltip says why
    assert "no session" in view.start_button.toolTip()
    view.choose_session(session)                              # what "Other session..." does after its dialog
    view.choose_calibration_file(other)                       # what "a calibration file..." does after its dialog
    view.render_light.setCurrentIndex(view.render_light.findData("A"))
    view.resolution.setCurrentIndex(view.resolution.findData("half"))
    view.ppi.setValue(600.0)
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    assert view.outcome == "done", (view.message.text(), w.errors.history)
    rows = [(view.table.item(r, 0).text(), view.table.item(r, 1).text()) for r in range(view.table.rowCount())]
    assert rows == [("ACC-1", "delivered"), ("ACC-2", "delivered")]
    assert view.message.text() == "2 delivered, 0 not delivered, 0 refused by the mode rule"
    for ident in ("ACC-1", "ACC-2"):
        side = sidecar(session, ident)
        assert side["calibration"]["id"] == "cal-other" != before[ident]["calibration"]["id"]
        assert side["reprocessed"] is True and side["resolution"]["mode"] == "half"
        assert side["ppi"] == 600.0
        folder = session / "deliverables" / ident
        assert (folder / f"{ident}_under_A_prophoto_16bit.tif").exists()            # the rendering light chosen
        previous = list((folder / "previous").rglob(f"{ident}.json"))
        assert previous and json.loads(previous[0].read_text())["calibration"]["id"] == "cal-test"
    # the options are remembered in the window's settings (the same keys as the Originals panel's)
    assert w.ctx.get("options/render_illuminant", "", str) == "A"
    assert w.ctx.get("originals/resolution", "", str) == "half"


def test_redeliver_applies_the_mode_rule_and_force(qtbot, make_window, captured_session, tmp_path):
    session, first, _other = captured_session
    from dualrgb.app.workflow.calibration.profile import load_profile

    film = dataclasses.replace(load_profile(first), id="cal-film", mode="transmissive")
    film.save(tmp_path / "film")
    w = make_window()
    view = w.tools.redeliver
    view.choose_session(session)
    view.choose_calibration_file(tmp_path / "film" / "cal-film.json")
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    refused = [view.table.item(r, 1).text() for r in range(view.table.rowCount())]
    assert refused == ["refused (mode)"] * 2 and sidecar(session, "ACC-1")["calibration"]["id"] == "cal-test"
    assert "transmissive" in view.table.item(0, 2).text()
    qtbot.mouseClick(view.force, Qt.LeftButton)                   # --force: said in the sidecar
    assert view.force.isChecked()
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.outcome == "done" and view.table.rowCount() == 2
                    and view.table.item(0, 1).text() == "delivered", timeout=LONG)
    wait_idle(qtbot, w)
    side = sidecar(session, "ACC-1")
    assert side["calibration"]["id"] == "cal-film" and side["overrides"], side.get("overrides")


def test_redeliver_cancels_and_keeps_every_original_whole(qtbot, make_window, captured_session):
    session, _first, other = captured_session
    w = make_window()
    view = w.tools.redeliver
    view.choose_session(session)
    view.choose_calibration_file(other)
    assert w.capture.calibration.load_button.isEnabled()
    click(qtbot, view.start_button)
    assert view.cancel_button.isEnabled()
    assert w.ctx.workspace.running == "re-delivery"           # no sequence writes to the session meanwhile
    assert not w.capture.calibration.load_button.isEnabled()     # the calibration box is locked meanwhile
    click(qtbot, view.cancel_button)
    t0 = time.monotonic()
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    print(f"re-delivery: cancelled {time.monotonic() - t0:.2f} s after Cancel")     # reported, not asserted
    wait_idle(qtbot, w)
    assert view.outcome == "cancelled" and "cancelled" in view.message.text()
    for ident in ("ACC-1", "ACC-2"):                          # each original: its old set or its new one, whole
        side = sidecar(session, ident)
        assert side["calibration"]["id"] in ("cal-test", "cal-other")
        assert all((session / "deliverables" / ident / name).exists() for name in side["files"].values())
    assert view.start_button.isEnabled() and not view.cancel_button.isEnabled() and w.ctx.workspace.running == ""


# ---------------------------------------------------------------- focus and framing
def texture(h: int = 120, w: int = 160, seed: int = 1) -> np.ndarray:
    """A painting-like test picture: random brush marks at several scales (uint8 RGB)."""
    rng = np.random.default_rng(seed)
    base = sum(ndimage.zoom(rng.uniform(0, 1, (h // s, w // s)), s, order=0)[:h, :w] for s in (1, 2, 4, 8))
    grey = 40 + 180 * (base - base.min()) / np.ptp(base)
    return np.repeat(grey[:, :, None], 3, axis=2).astype(np.uint8)


def test_the_focus_measure_rises_as_the_view_gets_sharper():
    sharp = texture().astype(float)
    values = [tenengrad(ndimage.gaussian_filter(sharp, (s, s, 0))) for s in (4.0, 2.0, 1.0, 0.5)] + [tenengrad(sharp)]
    assert all(a < b for a, b in zip(values, values[1:], strict=False)), values
    assert tenengrad(sharp * 0.5) == pytest.approx(tenengrad(sharp))     # a dimmer light is not a focus change
    assert tenengrad(np.full((20, 20, 3), 128.0)) == 0.0 and tenengrad(np.zeros((20, 20))) == 0.0
    dim = (texture() // 10).astype(np.uint8)                  # a framing light's live view
    shown, gain = brightened(dim)
    bright = np.full((20, 20, 3), 255, np.uint8)
    assert gain > 5 and np.percentile(shown, 99.5) >= 250 and brightened(bright)[1] == 1.0
    assert tenengrad(shown) == pytest.approx(tenengrad(dim), rel=0.05)        # the measure does not see it


def test_live_view_zoom_box_and_focus_plot(qtbot, make_window):
    w = make_window()
    connect_devices(qtbot, w)
    cam = w.camera
    w.show_panel("camera")
    click(qtbot, cam.live_button)
    qtbot.waitUntil(lambda: len(cam.focus.values) >= 2, timeout=LONG)
    assert cam.focus.roi.isVisible()                          # the box is drawn where it measures
    x, y, bw, bh = cam.focus.region(cam.image.image.shape)
    assert cam.focus.zoom.pixmap().width() == bw and cam.focus.zoom.pixmap().height() == bh     # 100 %
    click(qtbot, cam.live_button)                             # stop: frames from here on are ours
    wait_idle(qtbot, w)
    cam.focus.roi.setPos((0, 0))                              # as a drag ends: a new region, the plot starts over
    assert len(cam.focus.values) == 0 and cam.focus.box[:2] == (0, 0)
    sharp = texture(cam.image.image.shape[0], cam.image.image.shape[1])
    blurred = ndimage.gaussian_filter(sharp, (2, 2, 0))
    cam.live_button.setChecked(True)
    wait_idle(qtbot, w)
    for frame in (blurred, sharp):                            # the focus ring turned towards focus
        cam._show_preview((frame, None))
    assert cam.focus.values[-1] > cam.focus.values[-2] and cam.focus.best == cam.focus.values[-1]
    assert "focus" in cam.focus.label.text()
    cam.live_button.setChecked(False)


def test_the_framing_light_stays_within_its_cap_and_is_renewed(qtbot, make_window):
    w = make_window()
    connect_devices(qtbot, w)
    emulator = w.lab.virtual_lab.emulator
    cap = 1.5
    w.light.max_on.setValue(cap)                              # the manual light's cap: the framing light's too
    cam = w.camera
    w.show_panel("camera")
    click(qtbot, cam.live_button)
    qtbot.waitUntil(lambda: len(cam.focus.values) >= 1, timeout=LONG)
    dark_view = float(np.mean(cam.image.image))               # the light off: what "black" is here
    start = emulator.clock()
    qtbot.mouseClick(cam.framing_box.check, Qt.LeftButton)
    assert cam.framing.active and cam.framing_box.check.isChecked(), cam.framing_box.state.text()
    qtbot.waitUntil(lambda: len(cam.framing.periods) >= 4, timeout=LONG)      # renewed three times
    qtbot.waitUntil(lambda: emulator.snapshot().light_on, timeout=LONG)
    qtbot.waitUntil(lambda: float(np.mean(cam.image.image)) > dark_view + 2.0, timeout=LONG)   # not black
    qtbot.waitUntil(lambda: "brightened" in cam.view_title.text(), timeout=LONG)   # shown brightened, said so
    # the host can no longer switch it off (its switch-offs unanswered, as if it hung or died): the light goes
    # off at the cap by itself (the sphere's own ON <ms>), and the framing light stops, saying so
    emulator.inject("ignore", keywords=["ALLOFF", "LIGHT"])
    qtbot.waitUntil(lambda: not cam.framing.active, timeout=LONG)
    qtbot.waitUntil(lambda: not emulator.snapshot().light_on, timeout=LONG)
    emulator.inject(None)
    record = [i for i in emulator.light_record() if i.t_on >= start]
    assert len(record) >= 4
    for interval in record:
        assert interval.t_off is not None and interval.duration_s <= cap + 0.05, interval
        assert max(interval.levels) <= MAX_FRAMING_LEVEL + 1e-4, interval
    assert sum(i.ended_by == "LIGHT 0" for i in record) >= 3          # renewed: switched off, then on again
    assert record[-1].ended_by == "on-time limit"                      # the last one: by the sphere itself
    gaps = [b.t_on - a.t_off for a, b in zip(record, record[1:], strict=False) if a.ended_by == "LIGHT 0"]
    print(f"framing light: dark between renewed periods {1000 * min(gaps):.0f}-{1000 * max(gaps):.0f} ms")
    assert all(p.max_on_s == cap for p in cam.framing.periods)
    assert not cam.framing.active and not cam.framing_box.check.isChecked()
    assert "framing light off" in cam.framing_box.state.text() and "lit periods" in cam.framing_box.state.text()
    click(qtbot, cam.live_button)                             # live view off
    wait_idle(qtbot, w)
    assert not emulator.snapshot().light_on and np.allclose(emulator.snapshot().levels, 0)
    dose = w.lab.last_status.get("dose")
    assert dose is not None and dose.on_s > 0                 # counted in the light dose (the status polls)


# ---------------------------------------------------------------- measuring the camera and the LEDs
def test_measure_the_camera_on_the_virtual_lab(qtbot, make_window, tmp_path):
    w = make_window()
    view = w.tools.measure_camera
    w.show_panel("tools")
    w.tools.tabs.setCurrentWidget(view)
    view.start_nm.setValue(500.0)
    view.end_nm.setValue(600.0)
    view.step_nm.setValue(50.0)
    view.frames.setValue(1)
    click(qtbot, view.start_button)                           # written under the captures folder by default
    assert "3 wavelengths" in view.view.summary.text() and "sphere stays off" in view.view.summary.text()
    qtbot.waitUntil(lambda: view.view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    assert view.view.outcome == "done", (view.view.message.text(), w.errors.history)
    csv = tmp_path / "captures" / "measurements" / "camera_csrf.csv"
    assert csv.exists() and view.files_label.full_text() == str(csv)
    assert (csv.parent / "camera_csrf-session" / "radiance-virtual.csv").exists()
    text = csv.read_text()
    assert "500" in text and "600" in text
    assert "RMS % of peak" in view.result_label.text()
    assert len(view.plot.getPlotItem().listDataItems()) == 3                 # R, G, B
    click(qtbot, view.use_button)                             # calibrate --camera-csv in the window
    assert w.ctx.get("options/camera_csv", "", str) == str(csv)


def test_a_bad_measured_curve_is_refused_before_the_light(qtbot, make_window, tmp_path):
    w = make_window()
    connect_devices(qtbot, w)
    cap = w.capture
    qtbot.waitUntil(lambda: len(cap.presets) > 0, timeout=LONG)
    cap.choose_preset("dual-RGB reflective")
    w.show_panel("capture")
    cap.calibration.sampling.stand_dir.setText(str(tmp_path / "no-such-stand"))
    lit_before = len(w.lab.virtual_lab.emulator.light_record())
    click(qtbot, cap.calibration.calibrate_button)
    wait_idle(qtbot, w)
    title, message = w.errors.history[-1]
    assert title == "Calibrate" and "no-such-stand" in message and "\n" not in message
    assert len(w.lab.virtual_lab.emulator.light_record()) == lit_before and not cap.view.running


def test_a_prompt_of_a_hand_set_monochromator_is_a_dialog(qtbot, make_window, tmp_path):
    w = make_window()
    connect_devices(qtbot, w)
    radiance = tmp_path / "radiance.csv"
    radiance.write_text("wavelength_nm,radiance\n500,1.0\n550,1.0\n600,1.0\n")
    view = w.tools.measure_camera
    view.bench.setCurrentIndex(view.bench.findData("manual"))
    view.start_nm.setValue(500.0)
    view.end_nm.setValue(600.0)
    view.step_nm.setValue(50.0)
    view.radiance.setText(str(radiance))
    view.out.setText(str(tmp_path / "hand" / "camera.csv"))
    w.asker.scripted = ["Cancel the measurement"]
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    assert w.asker.history and w.asker.history[0][1].startswith("Set the monochromator to 500 nm")
    assert view.view.outcome == "cancelled" and not (tmp_path / "hand" / "camera.csv").exists()
    assert "nothing written" in view.result_label.text()


def test_measure_the_leds_on_the_virtual_lab(qtbot, make_window, tmp_path, caplog):
    w = make_window()
    view = w.tools.measure_leds
    view.warmup_min.setValue(0.5)
    view.out.setText(str(tmp_path / "stand"))
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    assert view.view.outcome == "done", (view.view.message.text(), w.errors.history)
    names = {p.name for p in view.written}
    assert {"leds.csv", "stand.json"} <= names and all(p.exists() for p in view.written)
    assert len(view.plot.getPlotItem().listDataItems()) == 10                # a spectrum per LED
    assert "10 LEDs measured" in view.result_label.text()
    assert not [r.message for r in caplog.records if "warm-up" in r.message and "expected at least" in r.message]
    # the stand folder becomes the next calibration's starting curves (calibrate --stand-dir)
    click(qtbot, view.use_button)
    w.show_panel("capture")
    sampling = w.capture.calibration.sampling
    assert sampling.stand_dir.text() == str(tmp_path / "stand")
    start = sampling.measured()
    assert start is not None and start.led_table() is not None


def test_measuring_the_leds_cancels(qtbot, make_window, tmp_path):
    w = make_window()
    view = w.tools.measure_leds
    view.out.setText(str(tmp_path / "stand"))
    click(qtbot, view.start_button)
    assert view.view.cancel_button.isEnabled()
    w.cancel_action.trigger()                                 # Esc, as everywhere
    t0 = time.monotonic()
    qtbot.waitUntil(lambda: view.view.outcome != "", timeout=LONG)
    print(f"LED measurement: cancelled {time.monotonic() - t0:.2f} s after Esc")     # reported, not asserted
    wait_idle(qtbot, w)
    assert view.view.outcome == "cancelled" and "nothing written" in view.result_label.text()
    assert not (tmp_path / "stand" / "stand.json").exists()


def test_measuring_the_camera_cancels_mid_sweep(qtbot, make_window, tmp_path):
    w = make_window()
    view = w.tools.measure_camera
    view.out.setText(str(tmp_path / "c" / "camera.csv"))
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: any(e.kind is EventKind.FRAME for e in view.view.events), timeout=LONG)
    click(qtbot, view.view.cancel_button)
    t0 = time.monotonic()
    qtbot.waitUntil(lambda: view.view.outcome != "", timeout=LONG)
    print(f"camera measurement: cancelled {time.monotonic() - t0:.2f} s after Cancel")   # reported, not asserted
    wait_idle(qtbot, w)
    assert view.view.outcome == "cancelled" and not (tmp_path / "c" / "camera.csv").exists()


# ---------------------------------------------------------------- the capture options reach the workflow
def test_capture_options_reach_the_sidecar(qtbot, make_window, tmp_path):
    """Originals' rendering light and ppi, remembered, go to the original's delivery through StandSettings."""
    profile = make_profile(tmp_path / "cal", shape=(80, 120), estimator=estimator(), spectral=SPECTRAL)
    w = make_window()
    connect_devices(qtbot, w)
    w.capture.calibration.load(profile.path)
    qtbot.waitUntil(lambda: w.ctx.workspace.calibration_check is not None, timeout=LONG)
    org = w.originals
    w.show_panel("originals")
    org.delivery_options.render_light.setCurrentIndex(org.delivery_options.render_light.findData("FL11"))
    org.delivery_options.ppi.setValue(450.0)
    org.resolution.setCurrentIndex(org.resolution.findData("half"))
    org.identifier.setText("OPT-1")
    click(qtbot, org.add_button)
    org.force.setChecked(True)                                # the test calibration is another camera's
    org.select("OPT-1")
    click(qtbot, org.capture_button)
    row = w.ctx.workspace.queue.row("OPT-1")
    qtbot.waitUntil(lambda: row.state.value in ("delivered", "failed"), timeout=LONG)
    wait_idle(qtbot, w)
    assert row.state.value == "delivered", (row.qa, w.errors.history)
    side = json.loads(row.sidecar.read_text())
    assert side["ppi"] == 450.0 and side["resolution"]["mode"] == "half"
    assert (row.sidecar.parent / "OPT-1_under_FL11_prophoto_16bit.tif").exists()
    again = make_window()                                     # remembered in the window's settings
    assert again.originals.delivery_options.stand_fields() == {"render_illuminant": "FL11", "ppi": 450.0}


def test_the_framing_light_yields_to_the_light_panel(qtbot, make_window):
    """Light OFF in the Light source panel ends the framing light (it is not lit again at the next renewal);
    a light applied by hand ends it too (its levels are not carried on in framing periods)."""
    w = make_window()
    connect_devices(qtbot, w)
    emulator = w.lab.virtual_lab.emulator
    w.light.max_on.setValue(2.0)
    cam = w.camera
    w.show_panel("camera")
    click(qtbot, cam.live_button)
    qtbot.mouseClick(cam.framing_box.check, Qt.LeftButton)
    qtbot.waitUntil(lambda: emulator.snapshot().light_on, timeout=LONG)
    w.show_panel("light")
    click(qtbot, w.light.off_button)
    qtbot.waitUntil(lambda: not cam.framing.active, timeout=LONG)
    assert "the light was switched off" in cam.framing_box.state.text()
    renewals = len(cam.framing.periods)
    qtbot.wait(2500)                                          # past the cap: nothing lights it again
    assert len(cam.framing.periods) == renewals and not emulator.snapshot().light_on
    w.show_panel("camera")
    qtbot.mouseClick(cam.framing_box.check, Qt.LeftButton)
    assert cam.framing.active
    w.show_panel("light")
    click(qtbot, w.light.apply_button)                        # the panel's levels, set by hand
    qtbot.waitUntil(lambda: not cam.framing.active, timeout=LONG)
    assert "set by hand" in cam.framing_box.state.text()
    wait_idle(qtbot, w)
