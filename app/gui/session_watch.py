"""The session folder watched (issue 42): deleted, renamed or on a drive unplugged, it is said at once - one line
in the status bar and the log, one question - not at the next capture. The day's queue is kept (it lives in the
workspace; app.gui.day_keeper writes it into the next session), and a new session is offered: *New session* makes a
dated one in the captures folder, *Later* leaves the window without one (the next run makes one, as at the start of
a day).

QFileSystemWatcher watches the session folder and the folder holding it (a folder removed with its parent, or a
drive unmounted, tells only the parent); the check itself is a plain ``is_dir`` on the GUI thread (one stat).
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from pathlib import Path

from PySide6.QtCore import QFileSystemWatcher, QObject

from dualrgb.app.gui.context import AppContext

log = logging.getLogger(__name__)

TITLE = "Session folder"
NEW, LATER = "New session", "Later"


class SessionWatch(QObject):
    """Watches the lab's current session folder; ``new_session`` makes a new one when the technician asks."""

    def __init__(self, ctx: AppContext, new_session: Callable[[], None], parent: QObject | None = None):
        super().__init__(parent)
        self.ctx = ctx
        self.new_session = new_session
        self.folder: Path | None = None
        self.gone: Path | None = None                 # the folder said gone (said once)
        self.watcher = QFileSystemWatcher(self)
        self.watcher.directoryChanged.connect(lambda _p: self.check())
        ctx.lab.sessionChanged.connect(self.follow)
        self.follow()

    def follow(self) -> None:
        """Watch the lab's session now (none: nothing)."""
        if self.watcher.directories():
            self.watcher.removePaths(self.watcher.directories())
        session = self.ctx.lab.session
        self.folder = Path(session.path) if session is not None else None
        if self.folder is not None and self.folder.is_dir():
            self.watcher.addPaths([str(self.folder), str(self.folder.parent)])

    def check(self) -> None:
        folder = self.folder
        if folder is None or folder.is_dir() or self.gone == folder:
            return
        self.gone = folder
        message = (f"{folder}: the session folder is gone (deleted, moved or its drive unplugged); its frames "
                   "cannot be written. The queue is kept.")
        self.ctx.errors.report(TITLE, message)        # the status bar and the log, once
        self.ctx.asker.ask(TITLE, message + "\n\nMake a new session in the captures folder now?", [NEW, LATER],
                           self._answer, LATER)

    def _answer(self, choice: str) -> None:
        if choice == NEW:
            self.new_session()
