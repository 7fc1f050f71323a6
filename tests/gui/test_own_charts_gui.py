"""The first real day in the window (issue 27): the calibration box takes the stand's own charts (the SG-layout
training reference with its layout, the CC24 test reference) and the profile names them; *Import CSV…* shows the
plan `capture --check` prints; a film under the reflective calibration is marked and not shot, and captured only
when the technician overrides it, which its QA line says."""
from __future__ import annotations

from pathlib import Path

import pytest

from dualrgb.app.gui.panels.originals import ADD_VALID, LEAVE, OVERRIDE
from dualrgb.app.workflow.charts import ChartChoice
from dualrgb.app.workflow.day import OriginalState
from dualrgb.app.workflow.vocabulary import Role, role_of
from tests.gui.conftest import wait_idle
from tests.gui.test_copystand_gui import click, start

LONG = 180000
ROOT = Path(__file__).resolve().parents[2]
CHARTS = ROOT / "tests" / "data" / "charts"


@pytest.mark.timeout(600)
def test_own_charts_plan_and_the_mode_rule_in_the_window(qtbot, make_window):
    w = make_window(frame_size=(240, 160))
    box = start(qtbot, w).calibration
    box.dark_frames.setValue(1)
    box.flat_frames.setValue(2)
    box.de_fit.setChecked(False)
    box.hdr_auto.setChecked(False)
    box.charts.set_choice("train", ChartChoice(str(CHARTS / "sg140_layout.txt"), "10x14", "A2,A3"))
    box.charts.set_choice("test", ChartChoice(str(CHARTS / "cc24_test.cie")))
    click(qtbot, box.calibrate_button)
    ws = w.ctx.workspace
    qtbot.waitUntil(lambda: ws.calibration is not None, timeout=LONG)
    charts = ws.calibration.charts
    assert (charts["train"]["file"], charts["train"]["used"]) == ("sg140_layout.txt", 138)
    assert charts["test"]["file"] == "cc24_test.cie" and "sg140_layout.txt" in box.summary.text()
    wait_idle(qtbot, w)

    org = w.originals
    w.asker.scripted = [ADD_VALID]
    org.import_csv(ROOT / "docs" / "queue-example.csv")
    qtbot.waitUntil(lambda: len(ws.queue.rows) == 6, timeout=LONG)
    report = org.import_report.text()
    assert "5 to shoot, 0 kept, 1 refused" in report and "row 7: 東博-F-7: refused (transmissive original" in report
    film = ws.queue.row("東博-F-7")
    w.asker.scripted = [LEAVE]                          # the film under the reflective calibration: marked, not shot
    org.capture([film.identifier])
    qtbot.waitUntil(lambda: film.state is OriginalState.FAILED and not w.asker.scripted, timeout=LONG)
    assert film.qa.startswith("not shot: transmissive original, reflective calibration")
    assert not [e for e in w.lab.session.entries() if role_of(e) is Role.ORIGINAL]
    w.asker.scripted = [OVERRIDE]                       # the technician overrides it: shot, and said so
    org.capture([film.identifier])
    qtbot.waitUntil(lambda: film.state is OriginalState.DELIVERED, timeout=LONG)
    assert "OVERRIDE: mode overridden" in film.qa
