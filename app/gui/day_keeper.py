"""The day survives a restart: the originals queue and the calibration in use are written into the session folder
as they change (app.workflow.day.day_file, atomically, on a writer thread of its own so a busy pool never delays a
save), and on start the last session (dualrgb.ini's ``capture/last_session``) is opened again with its queue and
calibration, said in one line. Quitting with originals waiting or a run going on asks first."""
from __future__ import annotations

import logging
from concurrent.futures import Future, ThreadPoolExecutor
from pathlib import Path

from PySide6.QtCore import QObject, QTimer
from PySide6.QtWidgets import QMessageBox, QWidget

from dualrgb.app.gui.context import AppContext
from dualrgb.app.workflow.calibration.profile import CalibrationProfile, load_profile
from dualrgb.app.workflow.day.day import OriginalsQueue
from dualrgb.app.workflow.day.day_file import day_path, day_rows, read_day, restore_day, restored_line, write_day
from dualrgb.app.workflow.stand.folders import open_session
from dualrgb.core.session.capture_session import CaptureSession

log = logging.getLogger(__name__)

QUIT, STAY = "Quit", "Keep working"
Restored = tuple[CaptureSession, OriginalsQueue, CalibrationProfile | None, list[str]]


class DayKeeper(QObject):
    def __init__(self, ctx: AppContext, parent: QObject | None = None):
        super().__init__(parent)
        self.ctx, self.ws, self.lab = ctx, ctx.workspace, ctx.lab
        self.restored = ""                   # the line said on start ('' when nothing was restored)
        self._restoring = False
        self._writer = ThreadPoolExecutor(max_workers=1, thread_name_prefix="day-writer")
        self._pending: Future | None = None
        self._timer = QTimer(self)
        self._timer.setSingleShot(True)
        self._timer.setInterval(0)           # coalesce a burst of changes into one write, at once
        self._timer.timeout.connect(self.save)
        for sig in (self.ws.queueChanged, self.ws.calibrationChanged, self.lab.sessionChanged):
            sig.connect(self._changed)
        self._unchecked: CaptureSession | None = None      # restored before a camera said what the stand is
        for sig in (self.lab.cameraChanged, self.lab.virtualLabChanged):
            sig.connect(self._check_restored)

    # ------------------------------------------------------------------ saving
    def _changed(self) -> None:
        if not self._restoring:
            self._timer.start()

    def save(self) -> None:
        """Write the queue and the calibration's path into the current session; before there is one, into the
        settings folder (``<data>/day/queue.json``: originals queued before the first session are kept too)."""
        session = self.lab.session
        if session is not None and session.readonly:
            return
        order, rows = day_rows(self.ws.queue)
        profile = self.ws.calibration
        calibration = Path(profile.path) if profile is not None and profile.path else None
        unsessioned = self.ctx.data_dir()
        if session is None:
            self._pending = self._writer.submit(write_day, unsessioned, order, rows, calibration)
        else:                                   # in the session now: the rows queued before it moved along
            self._pending = self._writer.submit(_write_in_session, Path(session.path), order, rows, calibration,
                                                unsessioned)
        self._pending.add_done_callback(_log_failure)

    def flush(self) -> None:
        """Wait for the last write (tests; shutdown)."""
        if self._timer.isActive():
            self._timer.stop()
            self.save()
        if self._pending is not None:
            self._pending.exception()

    # ------------------------------------------------------------------ restoring
    def restore(self) -> None:
        """Open the last session again with its queue and calibration (on the devices thread), unless one is open."""
        folder = self.ctx.get("capture/last_session", "", str)
        if self.lab.session is not None:
            return
        if not folder or not (Path(folder) / "session.json").is_file():
            self._restore_unsessioned()
            return
        definition = self.lab.session_definition()
        self._restoring = True

        def work() -> Restored:
            session = open_session(Path(folder), definition, existing=True,
                                   hint="connect the same camera and mode, or start a new session")
            notes = [f"{len(aside)} missing or damaged frame(s) set aside"] if (aside := session.set_aside_damaged()) \
                else []
            queue, calibration, more = restore_day(session)
            profile = None
            if calibration is not None:
                try:
                    profile = load_profile(calibration)
                except (OSError, ValueError) as exc:
                    more.append(f"calibration not restored: {exc}")
            return session, queue, profile, notes + more
        self.ctx.runner.submit(work, pool="devices", name="restore the day", on_result=self._restored,
                               on_error=self._not_restored)

    def _restored(self, result: Restored) -> None:
        session, queue, profile, notes = result
        self.ws.queue = queue
        self.lab.set_session(session, note="restored")
        self.ws.queue_changed()
        if profile is not None:
            self.ws.set_calibration(profile)
        self._restoring = False
        self._unchecked = session
        self._check_restored()
        self.restored = restored_line(session.path.name, queue, profile.id if profile is not None else "")
        for note in notes:
            log.warning("restoring the day: %s", note)
        log.info("%s", self.restored)
        self.lab.message.emit(self.restored)
        self.save()

    def _restore_unsessioned(self) -> None:
        """The originals queued before any session (none was made yet when the window closed)."""
        saved = read_day(self.ctx.data_dir())
        for note in saved.notes:
            log.warning("restoring the queue: %s", note)
        calibration = saved.calibration if saved.calibration is not None and saved.calibration.is_file() else None
        if not saved.rows and calibration is None:
            return
        self.ws.queue = OriginalsQueue()
        self.ws.queue.rows = list(saved.rows)
        self.ws.queue_changed()

        def said(profile: CalibrationProfile | None) -> None:
            if profile is not None:
                self.ws.set_calibration(profile)
            self.restored = restored_line("", self.ws.queue, profile.id if profile is not None else "")
            log.info("%s", self.restored)
            self.lab.message.emit(self.restored)
        if calibration is None:
            said(None)
            return
        self.ctx.runner.submit(lambda: load_profile(calibration), pool="compute", name="restore the calibration",
                               on_result=said, on_error=self._not_restored)

    def _check_restored(self) -> None:
        """Once the camera is connected, the restored session's definition (camera, frame size) is checked like a
        session opened by hand; another stand's session is let go, said in one line."""
        session = self._unchecked
        if session is None or self.lab.camera is None:
            return
        self._unchecked = None
        if self.lab.session is not session:
            return
        definition = self.lab.session_definition()

        def refused(exc: BaseException) -> None:
            if self.lab.session is session:
                self.lab.set_session(None)
                session.close()
            self.ctx.errors.report("Restore the last session", exc)
        self.ctx.runner.submit(lambda: session.check_definition(
            definition, hint="this stand is not the one of the session restored; open another or start a new one"),
            pool="devices", name="check the restored session", on_error=refused)

    def _not_restored(self, exc: BaseException) -> None:
        self._restoring = False
        self.ctx.errors.report("Restore the last session", exc, level=logging.WARNING)

    # ------------------------------------------------------------------ quitting
    def quit_question(self) -> str:
        """What quitting now would leave (waiting originals, a run going on); '' when nothing."""
        parts = []
        if self.ws.running:
            parts.append(f"{self.ws.running} is running: quitting cancels it (the lights go off; its frames so far "
                         "stay in the session)")
        waiting = len(self.ws.queue.waiting())
        if waiting:
            parts.append(f"{waiting} original{'s' if waiting > 1 else ''} waiting in the queue (kept: "
                         f"{'they come' if waiting > 1 else 'it comes'} back when the window opens again)")
        return "; ".join(parts)

    def may_quit(self, parent: QWidget, show_dialogs: bool) -> bool:
        """Ask before quitting with work left (a modal question: the window waits for it). Without dialogs a
        scripted answer is taken, else Quit (nobody is there to ask)."""
        text = self.quit_question()
        if not text:
            return True
        asker = self.ctx.asker
        asker.history.append(("Quit", text))
        if asker.scripted or not show_dialogs:
            return (asker.scripted.pop(0) if asker.scripted else QUIT) == QUIT
        box = QMessageBox(QMessageBox.Icon.Question, "Quit dualrgb?", text[0].upper() + text[1:] + ".",
                          QMessageBox.StandardButton.NoButton, parent)
        quit_button = box.addButton(QUIT, QMessageBox.ButtonRole.AcceptRole)
        box.setDefaultButton(box.addButton(STAY, QMessageBox.ButtonRole.RejectRole))
        box.exec()
        return box.clickedButton() is quit_button

    def shutdown(self) -> None:
        """The last write, then the session's writer lock is given back (the next window opens it again)."""
        self.flush()
        self._writer.shutdown(wait=True)
        if self.lab.session is not None:
            self.lab.session.close()


def _write_in_session(session: Path, order: list[str], rows: list[dict], calibration: Path | None,
                      unsessioned: Path) -> Path:
    path = write_day(session, order, rows, calibration)
    day_path(unsessioned).unlink(missing_ok=True)
    return path


def _log_failure(future: Future) -> None:
    exc = future.exception()
    if exc is not None:
        log.error("saving the day's queue: %s", exc)
