"""PtyLineServer: the virtual lab's line server (drivers/virtual/line_server.py) on a real pseudo-terminal (POSIX).

``start()`` opens a pty (os.openpty) in raw mode and serves it from a background thread; any serial client
(pyserial, a driver, ``screen``) opens the returned slave path as if it were /dev/ttyUSB0. The POSIX modules
(``tty``) are imported when a pty is opened, never at import: on Windows the socket transport serves instead.
"""
from __future__ import annotations

import logging
import os
import select
from collections.abc import Callable

from dualrgb.drivers.virtual.line_server import LineServer, OnLine

log = logging.getLogger(__name__)


class PtyLineServer(LineServer):
    """Serve ``on_line(line, too_long)`` on a pty; see drivers/virtual/line_server.py."""

    transport = "pty"

    def __init__(self, name: str, on_line: OnLine, *, max_line: int = 96,
                 on_tick: Callable[[], None] | None = None):
        super().__init__(name, on_line, max_line=max_line, on_tick=on_tick)
        self._master: int | None = None
        self._slave: int | None = None
        self._wake_pipe: tuple[int, int] | None = None

    def _open(self) -> str:
        import tty  # POSIX only: imported when a pty is made

        master, slave = os.openpty()
        tty.setraw(slave)                   # no echo, no CR/LF translation: bytes pass verbatim
        os.set_blocking(master, False)
        self._master, self._slave = master, slave   # holding the slave open keeps the master readable
        self._wake_pipe = os.pipe()
        return os.ttyname(slave)

    def _wake(self) -> None:
        if self._wake_pipe is not None:
            try:
                os.write(self._wake_pipe[1], b"x")
            except OSError:
                pass

    def _serve(self) -> None:
        master, wake = self._master, self._wake_pipe
        if master is None or wake is None:
            return
        buf = bytearray()
        discarding = False
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([master, wake[0]], [], [], self._wait_s())
            except (OSError, ValueError):
                break
            if self._stop.is_set():
                break
            if master in ready:
                try:
                    buf += os.read(master, 4096)
                except (BlockingIOError, OSError) as exc:    # EIO: no slave open (cannot happen while we hold it)
                    log.debug("%s: pty read: %s", self.name, exc)
                discarding = self._split_lines(buf, discarding)
            self._after_wake()

    def _send(self, data: bytes, to: object) -> None:
        if self._master is None:
            return
        try:
            os.write(self._master, data)
        except OSError as exc:              # client not reading and the pty buffer full: the reply is lost
            log.warning("%s: reply %r dropped (%s)", self.name, data, exc)

    def _close_transport(self) -> None:
        for fd in (self._master, self._slave, *(self._wake_pipe or ())):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = self._wake_pipe = None
