"""PtyLineServer: a line-oriented serial device served on a real pseudo-terminal (the virtual lab's instruments).

``start()`` opens a pty (os.openpty) in raw mode and serves it from a background thread; any serial client
(pyserial, a driver, ``screen``) opens the returned slave path as if it were /dev/ttyUSB0. Each received line
(terminator ``\\n`` stripped, and a ``\\r`` before it) goes to the ``on_line`` callback, which answers with
:meth:`PtyLineServer.respond` (at once, or after a delay on the real clock: a slow instrument). A line longer than
``max_line`` bytes is passed once with ``too_long=True`` and the rest of it up to the next ``\\n`` is discarded.
``on_tick`` is called on every wake-up of the serving thread (at least every 50 ms), for physics that runs on by
itself. :meth:`PtyLineServer.close` ends the thread and closes the pty (an unplugged cable, for the client).
"""
from __future__ import annotations

import logging
import os
import select
import threading
import time
import tty
from collections.abc import Callable

log = logging.getLogger(__name__)

OnLine = Callable[[bytes, bool], None]


class PtyLineServer:
    """Serve ``on_line(line, too_long)`` on a pty; see the module docstring."""

    def __init__(self, name: str, on_line: OnLine, *, max_line: int = 96,
                 on_tick: Callable[[], None] | None = None):
        self.name = name
        self._on_line = on_line
        self._on_tick = on_tick
        self.max_line = max_line
        self._master: int | None = None
        self._slave: int | None = None
        self._wake: tuple[int, int] | None = None
        self._port = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._pending: list[tuple[float, bytes]] = []
        self._pending_lock = threading.Lock()

    @property
    def port(self) -> str:
        return self._port

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> str:
        """Open the pty and serve it; returns the path a serial client opens."""
        if self.running:
            return self._port
        master, slave = os.openpty()
        tty.setraw(slave)                   # no echo, no CR/LF translation: bytes pass verbatim
        os.set_blocking(master, False)
        self._master, self._slave = master, slave   # holding the slave open keeps the master readable
        self._port = os.ttyname(slave)
        self._wake = wake = os.pipe()
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, args=(master, wake[0]), name=f"{self.name} {self._port}",
                                        daemon=True)
        self._thread.start()
        return self._port

    def close(self) -> None:
        """Stop serving and close the pty."""
        self._stop.set()
        if self._wake is not None:
            try:
                os.write(self._wake[1], b"x")
            except OSError:
                pass
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        self._thread = None
        for fd in (self._master, self._slave, *(self._wake or ())):
            if fd is not None:
                try:
                    os.close(fd)
                except OSError:
                    pass
        self._master = self._slave = self._wake = None
        with self._pending_lock:
            self._pending.clear()

    def respond(self, data: bytes, delay_s: float = 0.0) -> None:
        """Send ``data`` to the client now, or ``delay_s`` seconds (real time) from now."""
        if delay_s <= 0:
            self._write(data)
            return
        with self._pending_lock:
            self._pending.append((time.monotonic() + delay_s, data))
            self._pending.sort(key=lambda p: p[0])

    def _write(self, data: bytes) -> None:
        if self._master is None:
            return
        try:
            os.write(self._master, data)
        except OSError as exc:              # client not reading and the pty buffer full: the reply is lost
            log.warning("%s: reply %r dropped (%s)", self.name, data, exc)

    def _flush_pending(self) -> None:
        now = time.monotonic()
        while True:
            with self._pending_lock:
                if not self._pending or self._pending[0][0] > now:
                    return
                data = self._pending.pop(0)[1]
            self._write(data)

    def _wait_s(self) -> float:
        with self._pending_lock:
            if self._pending:
                return max(0.0, min(0.05, self._pending[0][0] - time.monotonic()))
        return 0.05

    def _serve(self, master: int, wake: int) -> None:
        buf = bytearray()
        discarding = False
        while not self._stop.is_set():
            try:
                ready, _, _ = select.select([master, wake], [], [], self._wait_s())
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
            self._flush_pending()
            if self._on_tick is not None:
                self._on_tick()

    def _split_lines(self, buf: bytearray, discarding: bool) -> bool:
        """Hand every complete line in ``buf`` to ``on_line`` (consuming it); returns the new discarding state."""
        while True:
            nl = buf.find(b"\n")
            if nl < 0:
                if len(buf) >= self.max_line:
                    if not discarding:
                        self._on_line(bytes(buf), True)
                    buf.clear()
                    return True
                return discarding
            line = bytes(buf[:nl])
            del buf[:nl + 1]
            if discarding:
                discarding = False
                continue
            self._on_line(line.rstrip(b"\r"), len(line) + 1 > self.max_line)
