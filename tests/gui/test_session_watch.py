"""Issue 42: a deleted session folder is said at once - one error, one question - the queue is kept and *New
session* makes a new one."""
from __future__ import annotations

import shutil

from tests.gui.conftest import HANG_GUARD_MS, connect_devices, wait_idle


def test_a_deleted_session_folder_is_said_at_once_and_a_new_one_offered(qtbot, make_window):
    from dualrgb.app.gui.session_watch import NEW, TITLE

    w = make_window()
    connect_devices(qtbot, w)
    w.capture.new_session()
    qtbot.waitUntil(lambda: w.lab.session is not None, timeout=HANG_GUARD_MS)
    wait_idle(qtbot, w)
    org = w.originals
    org.identifier.setText("ACC-7")
    org.add_original()
    assert [r.identifier for r in w.ctx.workspace.queue.rows] == ["ACC-7"]
    old = w.lab.session
    first = old.path
    w.asker.scripted = [NEW]
    w.day.flush()                  # the queue's write into <session>/day/ is done before the folder goes
    shutil.rmtree(first)
    qtbot.waitUntil(lambda: any(t == TITLE for t, _ in w.errors.history), timeout=60_000)   # no capture needed
    said = [m for t, m in w.errors.history if t == TITLE]
    assert len(said) == 1 and "gone" in said[0] and "queue is kept" in said[0]
    assert [t for t, _ in w.asker.history].count(TITLE) == 1
    qtbot.waitUntil(lambda: w.lab.session is not None and w.lab.session is not old, timeout=60_000)
    wait_idle(qtbot, w)
    assert w.lab.session.path.is_dir()
    assert [r.identifier for r in w.ctx.workspace.queue.rows] == ["ACC-7"]          # the queue kept
