"""The technician's whole day in the window with a restart in the middle (issue 30 "must show"): calibrate, import
a queue, capture two, quit (asked first: originals are waiting), start again on the same settings - the session,
the calibration and the queue come back, said in one line - re-import the CSV (the delivered rows count as
delivered), capture the rest, calibrate again keeping the frames and re-deliver the day with that other
calibration from Tools → Re-deliver."""
from __future__ import annotations

import json
from pathlib import Path

from dualrgb.app.gui.day_keeper import QUIT, STAY
from dualrgb.app.workflow.day.day import OriginalState
from dualrgb.app.workflow.day.day_file import day_path
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, quick_calibrate, wait_idle

LONG = HANG_GUARD_MS
IDS = ("DAY-1", "DAY-2", "DAY-3", "DAY-4")


def write_queue(tmp_path: Path) -> Path:
    path = tmp_path / "queue.csv"
    path.write_text("identifier,title,mode\n" + "".join(f"{i},{i} title,reflective\n" for i in IDS), encoding="utf-8")
    return path


def calibrate(qtbot, w):
    asked = quick_calibrate(qtbot, w)
    assert w.capture.view.outcome == "done", (w.capture.view.message.text(), w.errors.history)
    return asked


def delivered(w, idents):
    rows = w.ctx.workspace.queue.rows
    return all(r.state is OriginalState.DELIVERED for r in rows if r.identifier in idents)


def capture(qtbot, w, idents):
    org = w.originals
    org.capture(list(idents))
    qtbot.waitUntil(lambda: all(w.ctx.workspace.queue.row(i).state in (OriginalState.DELIVERED, OriginalState.FAILED)
                                for i in idents), timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert delivered(w, idents), [(r.identifier, r.qa) for r in w.ctx.workspace.queue.rows]


def first_half(qtbot, w, csv):
    connect_devices(qtbot, w)
    assert calibrate(qtbot, w) == []                       # a fresh session: nothing to re-shoot, nothing asked
    profile = w.ctx.workspace.calibration
    org = w.originals
    org.stand_in.setCurrentText("painting")
    org.import_csv(csv)                                     # no bad row: added at once
    assert [r.identifier for r in w.ctx.workspace.queue.waiting()] == list(IDS)
    capture(qtbot, w, IDS[:2])
    w.day.flush()
    saved = json.loads(day_path(w.lab.session.path).read_text())
    assert saved["format"].startswith("dualrgb-day/")
    assert saved["calibration"] == f"calibration/{profile.path.name}"        # relative to the session (issue 38)
    assert [r["original"]["identifier"] for r in saved["rows"]] == list(IDS[2:])       # saved as it changed
    return profile, w.lab.session.path


def quit_asks(w):
    w.asker.scripted = [STAY]
    w.close()                                               # the technician stays: nothing closes
    title, text = w.asker.history[-1]
    assert title == "Quit" and "2 originals waiting" in text and w.isVisible() and w.lab.sphere is not None
    w.asker.scripted = [QUIT]
    w.close()
    assert not w.isVisible()


def test_the_day_survives_a_restart(qtbot, make_window, tmp_path):
    csv = write_queue(tmp_path)
    w = make_window()
    profile, session_path = first_half(qtbot, w, csv)
    quit_asks(w)

    w2 = make_window()                                      # the same settings: a restart
    qtbot.waitUntil(lambda: w2.day.restored != "", timeout=LONG)
    wait_idle(qtbot, w2)
    ws = w2.ctx.workspace
    line = w2.day.restored
    assert line == (f"restored session {session_path.name}, calibration {profile.id}, queue: 2 waiting, "
                    "2 delivered"), line
    assert w2.lab.session.path == session_path and ws.calibration.id == profile.id
    assert [(r.identifier, r.state) for r in ws.queue.rows] == [
        (IDS[0], OriginalState.DELIVERED), (IDS[1], OriginalState.DELIVERED),
        (IDS[2], OriginalState.WAITING), (IDS[3], OriginalState.WAITING)]
    assert ws.queue.row(IDS[2]).original.title == f"{IDS[2]} title" and ws.queue.row(IDS[2]).stand_in == "painting"

    connect_devices(qtbot, w2)
    org = w2.originals
    org.import_csv(csv)                                     # the same CSV again: the delivered rows are delivered
    report = org.import_report.text()
    assert "0 added, 2 delivered already" in report and f"{IDS[0]} is already in the queue" not in report, report
    assert len(ws.queue.rows) == 4
    qtbot.waitUntil(lambda: ws.calibration_check is not None, timeout=LONG)
    click(qtbot, org.capture_all_button)                    # resume: the rest of the day
    qtbot.waitUntil(lambda: delivered(w2, IDS) and not org.view.running, timeout=LONG)
    wait_idle(qtbot, w2, LONG)
    assert all(json.loads(r.sidecar.read_text())["original"]["identifier"] == r.identifier for r in ws.queue.rows)
    redeliver_with_another_calibration(qtbot, w2, profile)


def redeliver_with_another_calibration(qtbot, w, first):
    """Calibrate again in the same session: asked re-shoot / keep / cancel; Keep computes another calibration from
    the frames the session holds (nothing lit), and Tools → Re-deliver delivers the day again with it (the window's
    `dualrgb process`)."""
    from dualrgb.app.gui.redeliver_view import CURRENT

    w.asker.scripted = ["Keep"]
    asked = calibrate(qtbot, w)
    assert [t for t, _ in asked] == ["Calibrate again?"] and "Re-shoot" in asked[0][1]
    second = w.ctx.workspace.calibration
    assert second.id != first.id and second.path.parent == first.path.parent
    view = w.tools.redeliver
    w.show_panel("tools")
    view.calibration.setCurrentIndex(view.calibration.findData(CURRENT))     # the calibration just made
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert view.outcome == "done", (view.message.text(), w.errors.history)
    rows = sorted((view.table.item(r, 0).text(), view.table.item(r, 1).text()) for r in range(view.table.rowCount()))
    assert rows == [(i, "delivered") for i in IDS]
    session = w.lab.session.path
    for ident in IDS:
        side = json.loads((session / "deliverables" / ident / f"{ident}.json").read_text())
        assert side["calibration"]["id"] == second.id and side["reprocessed"] is True
