"""Issue 42 point 4, stale and foreign words: the Originals queue shows the QA line and calibration of a re-delivery
(no restart needed), a cancelled re-delivery keeps the rows it delivered and lists the rest as not done, a CSV's
refused row is never queued and the import's counts are the same in the log and the panel ("Add the valid row",
"Add the 6 valid rows"), the re-shoot question says "deliver it again" only for a delivered original and counts its
frames right, the Operator stays after *Add*, and a wrong port is said once in a technician's words."""
from __future__ import annotations

import dataclasses
import json
import logging
import re

import pytest
from workflow_profiles import make_profile

from dualrgb.app.cli import main
from dualrgb.app.gui.wording import add_valid, reshoot_question
from dualrgb.app.workflow.day.day import OriginalState
from dualrgb.common.formatting import counted
from tests.gui.conftest import HANG_GUARD_MS, click, connect_devices, wait_idle

LONG = HANG_GUARD_MS
IDS = ("ACC-1", "ACC-2")


def other_statistics(train: float, test: float) -> dict:
    return {"best": "least-squares", "methods": {"least-squares": {"train": {"mean": train}, "test": {"mean": test}}}}


@pytest.fixture
def delivered_session(tmp_path, capsys):
    """A session with two originals delivered with calibration cal-test (`dualrgb capture`), and cal-other: another
    calibration whose figures differ (so its QA lines do)."""
    first = make_profile(tmp_path / "cal", shape=(64, 96))
    other = dataclasses.replace(first, id="cal-other", statistics=other_statistics(1.4, 1.3))
    other.save(tmp_path / "cal2")
    session = tmp_path / "session"
    for identifier in IDS:
        assert main(["capture", "--virtual-lab", "--calibration", str(first.path), "--id", identifier, "--session",
                     str(session), "--force", "--settle", "0", "--frame-size", "96x64"]) == 0
    capsys.readouterr()
    return session, other.path


def sidecar(session, identifier):
    return json.loads((session / "deliverables" / identifier / f"{identifier}.json").read_text())


def restored(qtbot, make_window, settings, session):
    """The window opened on ``session`` as after a restart (its delivered originals in the queue)."""
    settings.setValue("capture/last_session", str(session))
    settings.sync()
    w = make_window()
    qtbot.waitUntil(lambda: w.day.restored != "", timeout=LONG)
    wait_idle(qtbot, w)
    queue = w.ctx.workspace.queue
    assert [(r.identifier, r.state) for r in queue.rows] == [(i, OriginalState.DELIVERED) for i in IDS]
    return w


def redeliver(qtbot, w, calibration):
    view = w.tools.redeliver
    view.choose_calibration_file(calibration)                 # the current session, another calibration
    click(qtbot, view.start_button)
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w)
    return view


def table(view):
    return [tuple(view.table.item(r, c).text() for c in range(2)) for r in range(view.table.rowCount())]


def test_the_originals_show_the_qa_of_a_redelivery(qtbot, make_window, settings, delivered_session):
    session, other = delivered_session
    w = restored(qtbot, make_window, settings, session)
    org, ws = w.originals, w.ctx.workspace
    before = {r.identifier: r.qa for r in ws.queue.rows}
    assert all("train 0.40 / test 0.30" in qa for qa in before.values()), before
    view = redeliver(qtbot, w, other)
    assert view.outcome == "done" and table(view) == [(i, "delivered") for i in IDS]
    for ident in IDS:                                         # no restart: the queue says what the files say
        row, side = ws.queue.row(ident), sidecar(session, ident)
        assert side["calibration"]["id"] == "cal-other"
        assert row.qa == side["qa"]["text"] != before[ident] and "train 1.40 / test 1.30" in row.qa
        org.select(ident)
        assert "calibration cal-other" in org.qa_label.text() and "train 1.40" in org.qa_label.text()


def test_a_cancelled_redelivery_keeps_its_rows(qtbot, make_window, settings, delivered_session, monkeypatch):
    """Cancel after the first original: it keeps its new set and its row; the other is listed as not done and
    keeps its previous set; the Originals queue shows the first one's new QA line."""
    from dualrgb.app.workflow.delivery import redelivery

    session, other = delivered_session
    w = restored(qtbot, make_window, settings, session)
    ws = w.ctx.workspace
    one = redelivery._redeliver_one

    def then_cancel(*args, **kw):                             # Cancel pressed while the first one is delivered
        delivered = one(*args, **kw)
        args[8].cancel()                                      # the run's cancel token
        return delivered
    monkeypatch.setattr(redelivery, "_redeliver_one", then_cancel)
    before = ws.queue.row("ACC-2").qa
    view = redeliver(qtbot, w, other)
    assert view.outcome == "cancelled"
    assert table(view) == [("ACC-1", "delivered"), ("ACC-2", "not done")]
    assert "keeps its previous deliverables" in view.table.item(1, 2).text()
    assert view.message.text().startswith("cancelled: 1 delivered") and "1 not done" in view.message.text()
    assert sidecar(session, "ACC-1")["calibration"]["id"] == "cal-other"
    assert sidecar(session, "ACC-2")["calibration"]["id"] == "cal-test"
    assert "train 1.40" in ws.queue.row("ACC-1").qa and ws.queue.row("ACC-2").qa == before


def write_csv(path, reflective, transmissive=()):
    rows = [f"{i},{i} title,reflective" for i in reflective] + [f"{i},{i} film,transmissive" for i in transmissive]
    path.write_text("identifier,title,mode\n" + "\n".join(rows) + "\n", encoding="utf-8")
    return path


def test_a_refused_row_is_never_queued_and_the_log_counts_as_the_panel(qtbot, make_window, tmp_path, caplog):
    caplog.set_level(logging.INFO)
    w = make_window()
    ws, org = w.ctx.workspace, w.originals
    ws.set_calibration(make_profile(tmp_path / "cal"))         # reflective: a film is refused by the mode rule
    paintings = [f"P-{n}" for n in range(1, 7)]
    w.asker.scripted = [add_valid(6)]
    org.import_csv(write_csv(tmp_path / "day.csv", paintings, ["F-7"]))
    qtbot.waitUntil(lambda: not w.asker.scripted and len(ws.queue.rows) > 0, timeout=LONG)
    title, text = w.asker.history[-1]
    assert title == "Refused rows in the CSV" and "row 8: F-7: transmissive original" in text
    assert "Add the 6 valid rows and leave the refused one out" in text
    assert [r.identifier for r in ws.queue.rows] == paintings            # the film is not queued
    report = org.import_report.text()
    assert report.startswith("day.csv: 7 rows with calibration cal-test: 6 to shoot, 0 kept, 1 refused; 6 added")
    said = [r.getMessage() for r in caplog.records if "to shoot" in r.getMessage()]
    assert said and all("6 to shoot" in m for m in said), said          # the log counts what the panel counts

    w.asker.scripted = ["Add the valid row"]                   # one valid row: said in the singular
    org.import_csv(write_csv(tmp_path / "two.csv", ["P-9"], ["F-8", "F-9"]))
    qtbot.waitUntil(lambda: not w.asker.scripted and len(ws.queue.rows) == 7, timeout=LONG)
    text = w.asker.history[-1][1]
    assert "Add the valid row and leave the 2 refused ones out" in text and "1 rows" not in text
    assert ws.queue.rows[-1].identifier == "P-9" and "F-8" not in [r.identifier for r in ws.queue.rows]


def test_add_valid_and_the_plural_rule():
    assert (add_valid(1), add_valid(6)) == ("Add the valid row", "Add the 6 valid rows")
    assert [counted(n, "frame") for n in (0, 1, 2)] == ["0 frames", "1 frame", "2 frames"]
    assert counted(1, "delivery", "deliveries") == "1 delivery" and counted(3, "delivery", "deliveries") == \
        "3 deliveries"


@pytest.mark.parametrize("takes, delivered, said, unsaid", [
    ([1], False, "1 frame already captured (take 1), never delivered", "deliver"),
    ([1, 1, 1, 2, 2], False, "2 frames already captured (take 2), never delivered", "deliver"),
    ([1, 1], True, "already delivered in this session (2 frames, take 1)", "1 frames"),
    ([1], True, "(1 frame, take 1)", "frames,"),
])
def test_the_reshoot_question_says_the_truth(takes, delivered, said, unsaid):
    text = reshoot_question("X-1", takes, delivered)
    assert said in text and unsaid not in text.replace("never delivered", "")
    assert ("deliver it again" in text) == delivered and ("shoot only what is missing" in text) != delivered


def test_the_resume_question_for_a_take_never_delivered(qtbot, make_window, tmp_path, monkeypatch):
    """A take whose delivery failed (as after a crash mid-delivery): its frames are in the session, it was never
    delivered; the question counts its frames and offers to keep them and shoot what is missing, not to deliver
    them 'again'. Once delivered, the question says so."""
    from dualrgb.app.workflow.stand import copystand

    w = make_window(frame_size=(96, 64))
    connect_devices(qtbot, w)
    ws, org = w.ctx.workspace, w.originals
    w.capture.settle.setValue(0.0)
    ws.set_calibration(make_profile(tmp_path / "cal", shape=(64, 96)))
    org.force.setChecked(True)                                 # the made calibration is not this stand's
    org.identifier.setText("RES-1")
    click(qtbot, org.add_button)
    row = ws.queue.row("RES-1")

    def disk_full(*_args, **_kw):
        raise OSError("the disk is full")
    monkeypatch.setattr(copystand, "deliver", disk_full)
    capture_until(qtbot, w, row, OriginalState.FAILED)
    monkeypatch.undo()
    n = len([t for t in copystand.original_takes(w.lab.session, row.original) if t == 1])
    assert n >= 1
    text = ask(qtbot, w, row, "Cancel")
    assert f"RES-1: {counted(n, 'frame')} already captured (take 1), never delivered" in text, text
    assert "deliver" not in text.replace("never delivered", "") and not re.search(r"\b1 frames\b", text)
    w.asker.scripted = ["Keep"]                                # kept, the rest shot, delivered
    capture_until(qtbot, w, row, OriginalState.DELIVERED)
    text = ask(qtbot, w, row, "Cancel")
    assert "RES-1 is already delivered in this session" in text and "deliver it again" in text, text


def capture_until(qtbot, w, row, state):
    w.originals.capture([row.identifier])
    qtbot.waitUntil(lambda: row.state is state and not w.originals.view.running, timeout=LONG)
    wait_idle(qtbot, w)


def ask(qtbot, w, row, answer):
    """Capture ``row`` and answer the question with ``answer``; the question's text."""
    asked = len(w.asker.history)
    w.asker.scripted = [answer]
    w.originals.capture([row.identifier])
    qtbot.waitUntil(lambda: len(w.asker.history) > asked and not w.asker.scripted, timeout=LONG)
    wait_idle(qtbot, w)
    title, text = w.asker.history[asked]
    assert title == "Already in the session"
    return text


def test_the_operator_stays_after_add_and_across_windows(qtbot, make_window, settings):
    w = make_window()
    org = w.originals
    org.operator.setText("J. Doe")
    for ident in ("OP-1", "OP-2"):
        org.identifier.setText(ident)
        click(qtbot, org.add_button)
        assert org.identifier.text() == "" and org.operator.text() == "J. Doe"
    assert [r.original.operator for r in w.ctx.workspace.queue.rows] == ["J. Doe"] * 2
    assert make_window().originals.operator.text() == "J. Doe"           # remembered for the next start


def test_a_wrong_port_is_said_once_in_a_technician_s_words(qtbot, make_window):
    w = make_window()
    dev = w.devices
    wait_idle(qtbot, w)
    port = "/dev/ttyACM_NOT_THERE"
    dev.port_combo.setCurrentText(port)
    click(qtbot, dev.sphere_button)
    qtbot.waitUntil(lambda: bool(w.errors.history), timeout=LONG)
    wait_idle(qtbot, w)
    assert len(w.errors.history) == 1, w.errors.history                 # one message
    title, message = w.errors.history[0]
    assert title == "Connect the LED sphere" and message.count(port) == 1, message      # the port tried, once
    assert "check the cable and the port name" in message and "Refresh lists the ports" in message
    assert "ls " not in message and "/dev/ttyACM*" not in message and "--" not in message and "Errno" not in message
    assert dev.sphere_message.text() == message
