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
from dualrgb.app.gui.focus_aid import tenengrad
from dualrgb.app.gui.framing_light import MAX_FRAMING_LEVEL
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
        previous = [p for p in (folder / "previous").rglob(f"{ident}.json")]
        assert previous and json.loads(previous[0].read_text())["calibration"]["id"] == "cal-test"
    # the options are remembered in the window's settings (the same keys as the Originals panel's)
    assert w.ctx.get("options/render_illuminant", "", str) == "A"
    assert w.ctx.get("originals/resolution", "", str) == "half"


def test_redeliver_applies_the_mode_rule_and_force(qtbot, make_window, captured_session, tmp_path):
    session, first, _other = captured_session
    from dualrgb.app.workflow.profile import load_profile

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
    click(qtbot, view.start_button)
    assert view.cancel_button.isEnabled()
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
    assert view.start_button.isEnabled() and not view.cancel_button.isEnabled()
