"""``session.log`` in each session folder: the app's log records while that session was open.

Front ends (the demo, the CLI commands, the GUI) call it when they open a session::

    with SessionLog(session.path):          # a block
        ...
    log_file = SessionLog(session.path).start()   # or start/stop, e.g. for the GUI's current session
    log_file.stop()

Records of dualrgb's own loggers (``dualrgb.app``, ``dualrgb.drivers``, ``dualrgb.simulation``, ...) at INFO
and above (DEBUG with ``level``) are appended to ``<session>/session.log``, one line each with a UTC timestamp,
whatever the console shows; a resumed session appends. The handler sits on the root logger, so records from worker
threads are kept too. The file is written only once the folder is a session (``session.json`` exists), so opening
the log before ``CaptureSession.create`` cannot make the folder "not empty".
"""
from __future__ import annotations

import logging
import sys
import threading
import time
from pathlib import Path
from types import TracebackType

log = logging.getLogger(__name__)


def _shown(path: Path) -> str:
    """A path as a log line can carry: a folder named in another encoding (lone surrogates) escaped as \\udcfc."""
    return str(path).encode("utf-8", "backslashreplace").decode("utf-8")

LOG_NAME = "session.log"
SESSION_MARKER = "session.json"          # core.session.capture_session.SETTINGS
NAMESPACE = "dualrgb"
FORMAT = "%(asctime)s.%(msecs)03dZ %(levelname)-7s %(threadName)s %(name)s: %(message)s"
MAX_EARLY_RECORDS = 10000                # held until the folder becomes a session
SESSION_ONLY = "session_only"            # a record's attribute: for the session's file, not the terminal (the front
                                         # end says the error itself)


class _PackageFilter(logging.Filter):
    def filter(self, record: logging.LogRecord) -> bool:
        return record.name.split(".", 1)[0] == NAMESPACE


class _SessionLogHandler(logging.Handler):
    """Appends to ``folder/session.log``; holds records until ``folder/session.json`` exists."""

    def __init__(self, folder: Path, level: int) -> None:
        super().__init__(level)
        self.folder = folder
        self._file: logging.FileHandler | None = None
        self._early: list[logging.LogRecord] = []
        formatter = logging.Formatter(FORMAT, datefmt="%Y-%m-%dT%H:%M:%S")
        formatter.converter = time.gmtime
        self.setFormatter(formatter)
        self.addFilter(_PackageFilter())

    def _target(self) -> logging.FileHandler | None:
        if self._file is None and (self.folder / SESSION_MARKER).is_file():
            self._file = logging.FileHandler(self.folder / LOG_NAME, encoding="utf-8",
                                             errors="backslashreplace")   # a path in another encoding: \xfc
            self._file.setFormatter(self.formatter)
            for early in self._early:
                self._file.emit(early)
            self._early.clear()
        return self._file

    def emit(self, record: logging.LogRecord) -> None:
        try:
            target = self._target()
        except OSError:
            self.handleError(record)
            return
        if target is not None:
            target.emit(record)
        elif len(self._early) < MAX_EARLY_RECORDS:
            self._early.append(record)

    def close(self) -> None:
        self.acquire()
        try:
            try:
                self._target()                 # the session may have been created by the last step
            except OSError as exc:
                log.debug("session log of %s not written: %s", self.folder, exc)
            if self._file is not None:
                self._file.close()
                self._file = None
            self._early.clear()
        finally:
            self.release()
            super().close()


def _is_console(handler: logging.Handler) -> bool:
    """A handler printing to the terminal (basicConfig's, or tqdm's stand-in while a progress bar shows)."""
    return (isinstance(handler, logging.StreamHandler) and not isinstance(handler, logging.FileHandler)
            and getattr(handler, "stream", None) in (sys.stderr, sys.stdout))


class _RootLevel:
    """Lowers the root logger to the session logs' level while any is open, without making the console
    chattier: a console handler with no level of its own gets the old level while it is lowered."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._users = 0
        self._saved: tuple[int, list[logging.Handler]] | None = None

    def lower(self, level: int) -> None:
        with self._lock:
            self._users += 1
            root = logging.getLogger()
            old = root.getEffectiveLevel()
            if self._users == 1 and old > level:
                console = [h for h in root.handlers if _is_console(h) and h.level == logging.NOTSET]
                for h in console:
                    h.setLevel(old)
                self._saved = (root.level, console)
                root.setLevel(level)

    def restore(self) -> None:
        with self._lock:
            self._users -= 1
            if self._users == 0 and self._saved is not None:
                level, console = self._saved
                logging.getLogger().setLevel(level)
                for h in console:
                    h.setLevel(logging.NOTSET)
                self._saved = None


_ROOT = _RootLevel()


class SessionLog:
    """Attach a session's log file to the app's logging (see the module docstring)."""

    def __init__(self, folder: str | Path, level: int = logging.INFO) -> None:
        self.folder = Path(folder)
        self.level = level
        self._handler: _SessionLogHandler | None = None

    @property
    def path(self) -> Path:
        return self.folder / LOG_NAME

    @property
    def active(self) -> bool:
        return self._handler is not None

    def start(self) -> SessionLog:
        if self._handler is not None:
            return self
        self._handler = _SessionLogHandler(self.folder, self.level)
        _ROOT.lower(self.level)
        logging.getLogger().addHandler(self._handler)
        log.info("session log %s opened", _shown(self.path))
        return self

    def stop(self) -> None:
        if self._handler is None:
            return
        log.info("session log %s closed", _shown(self.path))
        logging.getLogger().removeHandler(self._handler)
        self._handler.close()
        self._handler = None
        _ROOT.restore()

    def __enter__(self) -> SessionLog:
        return self.start()

    def __exit__(self, exc_type: type[BaseException] | None, exc: BaseException | None,
                 tb: TracebackType | None) -> None:
        if exc is not None and self._handler is not None:
            log.error("session ended by %s: %s", type(exc).__name__, exc, extra={SESSION_ONLY: True})
        self.stop()
