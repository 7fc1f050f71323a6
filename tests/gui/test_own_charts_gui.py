"""The first real day in the window (issue 27): the calibration box takes the stand's own charts (the SG-layout
training reference with its layout, the CC24 test reference) and the profile names them; *Import CSV…* shows the
plan `capture --check` prints (the film it refuses is not queued); a film queued by hand under the reflective
calibration is marked and not shot, and captured only when the technician overrides it, which its QA line says."""
from __future__ import annotations

from pathlib import Path

import pytest

from dualrgb.app.gui.panels.originals import LEAVE, OVERRIDE
from dualrgb.app.gui.wording import add_valid
from dualrgb.app.workflow.calibration.charts import ChartChoice
from dualrgb.app.workflow.day.day import OriginalState
from dualrgb.core.vocabulary import Role, role_of
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
    w.asker.scripted = [add_valid(5)]
    org.import_csv(ROOT / "docs" / "queue-example.csv")
    qtbot.waitUntil(lambda: len(ws.queue.rows) == 5, timeout=LONG)
    report = org.import_report.text()
    assert "5 to shoot, 0 kept, 1 refused; 5 added" in report
    assert "row 7: 東博-F-7: refused (transmissive original" in report
    assert "東博-F-7" not in [r.identifier for r in ws.queue.rows]            # a refused row is not queued (issue 42)
    org.identifier.setText("東博-F-7")                  # the technician queues the film by hand
    org.mode.setCurrentText("transmissive")
    org.add_original()
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


@pytest.mark.timeout(900)
def test_results_and_calibrate_again_use_the_calibration_s_own_charts(qtbot, make_window):
    """Issue 36: calibrated with a 10x14 SG and a CC24 reference file, Results grades with those charts (read again
    from the calibration, whatever the box shows now: not the packaged CC24, not a 12x17 grid over the SG) and gets
    the calibration's figures; *Calibrate again* offers Keep only where the session allows it (other charts: not
    offered, and why), and Keep computes the calibration again with nothing lit."""
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
    wait_idle(qtbot, w)
    profile = ws.calibration
    ws.set_charts({})                                   # as after a restart: the box's choice is not what counts

    res = w.results
    res.optimise.setChecked(False)
    qtbot.waitUntil(lambda: res.train_subject.count() > 0 and res.test_subject.count() > 1, timeout=LONG)
    click(qtbot, res.process_button)
    qtbot.waitUntil(lambda: res.result is not None or "failed" in res.status.text(), timeout=LONG)
    wait_idle(qtbot, w)
    assert res.result is not None, (res.status.text(), w.errors.history)
    train, test = res.views["train"], res.views["test"]
    assert train.layout == (10, 14) and len(train.names) == 138 and "A2" not in train.names
    assert test.layout == (4, 6) and len(test.names) == 24 and "cc24" in test.label.lower()
    rep, cal = res.result.report, profile.statistics["methods"][profile.statistics["best"]]
    print(f"Results: train {rep['train']['mean']:.3f} / test {rep['test']['mean']:.3f}; calibration "
          f"{cal['train']['mean']:.3f} / {cal['test']['mean']:.3f}")
    assert rep["train"]["mean"] == pytest.approx(cal["train"]["mean"], abs=0.05)
    assert rep["test"]["mean"] == pytest.approx(cal["test"]["mean"], abs=0.05) and rep["test"]["mean"] < 1.5

    emulator = w.lab.virtual_lab.emulator
    lit = len(emulator.light_record())
    box.charts.set_choice("train", ChartChoice())      # the packaged targets: the session's frames are the SG's
    box.charts.set_choice("test", ChartChoice())
    w.asker.scripted = ["Cancel"]
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: not w.asker.scripted, timeout=LONG)
    title, text = w.asker.history[-1]
    assert title == "Calibrate again?" and "cannot be kept: its frames were taken with other settings: charts" in text
    box.charts.set_choice("train", ChartChoice(str(CHARTS / "sg140_layout.txt"), "10x14", "A2,A3"))
    box.charts.set_choice("test", ChartChoice(str(CHARTS / "cc24_test.cie")))
    w.asker.scripted = ["Keep"]
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(lambda: ws.calibration is not None and ws.calibration.id != profile.id, timeout=LONG)
    wait_idle(qtbot, w)
    assert "keep them and compute the calibration again" in w.asker.history[-1][1]
    assert len(emulator.light_record()) == lit                 # Keep lit nothing
    assert ws.calibration.charts["train"]["sha256"] == profile.charts["train"]["sha256"]
