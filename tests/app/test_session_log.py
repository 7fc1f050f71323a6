"""dualrgb.core.session.log: each session folder gets session.log with the app's records while it was open."""
from __future__ import annotations

import logging

import pytest

from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.session.log import LOG_NAME, SessionLog

log = logging.getLogger("dualrgb.app.test_session_log")


@pytest.fixture
def quiet_console():
    """A console handler at the CLI's default (root WARNING, handler NOTSET), as logging.basicConfig sets up."""
    root = logging.getLogger()
    old = root.level
    console = logging.StreamHandler()
    root.addHandler(console)
    root.setLevel(logging.WARNING)
    yield console
    root.removeHandler(console)
    root.setLevel(old)


def test_records_while_open_go_to_the_session_log(tmp_path, quiet_console):
    session = CaptureSession.create(tmp_path / "s", {"operator": "t"})
    log.info("before: not in the log")
    with SessionLog(session.path):
        log.info("exposure %s s", "1/60")
        logging.getLogger("dualrgb.drivers.led_sphere.x").warning("sphere warm")
        logging.getLogger("someone.else").warning("not ours")
        assert quiet_console.level == logging.WARNING          # the console does not get chattier
    log.info("after: not in the log")
    text = (session.path / LOG_NAME).read_text()
    assert "exposure 1/60 s" in text and "sphere warm" in text
    assert "not ours" not in text and "before" not in text and "after" not in text
    assert quiet_console.level == logging.NOTSET and logging.getLogger().level == logging.WARNING


def test_records_before_the_session_exists_wait_for_it(tmp_path, quiet_console):
    folder = tmp_path / "new"
    folder.mkdir()                                              # an empty folder chosen for the new session
    with SessionLog(folder):
        log.info("optimiser done")                              # before CaptureSession.create: held
        CaptureSession.create(folder)                            # the folder must still be empty here
        log.info("first dark")
    lines = (folder / LOG_NAME).read_text().splitlines()
    assert [line.split(": ", 1)[1] for line in lines if "test_session_log" in line] == ["optimiser done", "first dark"]


def test_error_ending_the_session_is_logged_and_resume_appends(tmp_path, quiet_console):
    session = CaptureSession.create(tmp_path / "s")
    with pytest.raises(RuntimeError):
        with SessionLog(session.path):
            raise RuntimeError("camera unplugged")
    with SessionLog(session.path):
        log.info("resumed")
    text = (session.path / LOG_NAME).read_text()
    assert "session ended by RuntimeError: camera unplugged" in text and text.index("unplugged") < text.index("resumed")


def test_gui_lab_switches_the_log_with_the_session(tmp_path, qapp):
    from dualrgb.app.gui.device_hub import Lab
    from dualrgb.app.gui.workers import TaskRunner

    lab = Lab(TaskRunner())
    a, b = CaptureSession.create(tmp_path / "a"), CaptureSession.create(tmp_path / "b")
    lab.set_session(a)
    log.warning("while a")
    lab.set_session(b)
    log.warning("while b")
    lab.set_session(None)
    log.warning("no session")
    assert "while a" in (a.path / LOG_NAME).read_text() and "while b" not in (a.path / LOG_NAME).read_text()
    assert "while b" in (b.path / LOG_NAME).read_text() and "no session" not in (b.path / LOG_NAME).read_text()
    lab.stop_polling()


def test_progress_bar_and_session_log_keep_the_console_quiet(tmp_path, quiet_console, capsys):
    import io

    from dualrgb.app.terminal_progress import TerminalProgress

    session = CaptureSession.create(tmp_path / "s")
    with TerminalProgress("demo", stream=io.StringIO(), terminal=True) as bar, SessionLog(session.path):
        bar(0.5, "captures")
        log.info("info for the file only")
        log.warning("warning for both")
    err = capsys.readouterr().err
    assert "warning for both" in err and "info for the file only" not in err
    assert "info for the file only" in (session.path / LOG_NAME).read_text()
    assert logging.getLogger().handlers.count(quiet_console) == 1           # tqdm gave the console back
