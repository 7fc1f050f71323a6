"""A line-oriented serial device served from a background thread: the transport of the virtual lab's instruments.

The emulators (drivers/virtual/sphere_emulator.py, monochromator_emulator.py) speak their protocol through a
:class:`LineServer`: each received line (terminator ``\\n`` stripped, and a ``\\r`` before it) goes to the
``on_line`` callback, which answers with :meth:`LineServer.respond` (at once, or after a delay on the real clock: a
slow instrument). A line longer than ``max_line`` bytes is passed once with ``too_long=True`` and the rest of it up
to the next ``\\n`` is discarded. ``on_tick`` is called on every wake-up of the serving thread (at least every
50 ms), for physics that runs on by itself. :meth:`LineServer.close` ends the thread and the transport (an
unplugged cable, for the client).

Two transports, one protocol:

* ``pty``: a real pseudo-terminal (drivers/virtual/pty_link.py, POSIX): the client opens a path such as
  ``/dev/pts/3`` as if it were ``/dev/ttyUSB0``;
* ``socket``: a loopback TCP server (:class:`SocketLineServer`, every OS): the client opens pyserial's URL
  ``socket://127.0.0.1:PORT`` (``serial.serial_for_url``, as the drivers do).

drivers.virtual.transport.line_server picks the pty where the OS has one and the socket elsewhere (Windows); the
environment variable ``DUALRGB_VIRTUAL_TRANSPORT`` (``pty`` or ``socket``) or a ``transport`` argument chooses on
any OS.
"""
from __future__ import annotations

import logging
import select
import socket
import threading
import time
from collections.abc import Callable

log = logging.getLogger(__name__)

OnLine = Callable[[bytes, bool], None]
TICK_S = 0.05                           # the serving thread wakes at least this often (on_tick, delayed replies)
SEND_TIMEOUT_S = 1.0                    # a client that stops reading loses a reply instead of holding the thread


class LineServer:
    """Serve ``on_line(line, too_long)`` on a transport (module docstring); subclasses open and serve it."""

    transport = ""

    def __init__(self, name: str, on_line: OnLine, *, max_line: int = 96,
                 on_tick: Callable[[], None] | None = None):
        self.name = name
        self._on_line = on_line
        self._on_tick = on_tick
        self.max_line = max_line
        self._port = ""
        self._thread: threading.Thread | None = None
        self._stop = threading.Event()
        self._pending: list[tuple[float, bytes, object]] = []     # (due, reply, the client it answers)
        self._pending_lock = threading.Lock()
        self._replying_to: object = None                         # the client whose line is being handled

    @property
    def port(self) -> str:
        """What a serial client opens: a pty path, or a ``socket://`` URL (``serial.serial_for_url``)."""
        return self._port

    @property
    def running(self) -> bool:
        return self._thread is not None and self._thread.is_alive()

    def start(self) -> str:
        """Open the transport and serve it; returns the port a serial client opens."""
        if self.running:
            return self._port
        self._port = self._open()
        self._stop.clear()
        self._thread = threading.Thread(target=self._serve, name=f"{self.name} {self._port}", daemon=True)
        self._thread.start()
        return self._port

    def close(self) -> None:
        """Stop serving and close the transport."""
        self._stop.set()
        self._wake()
        if self._thread is not None and self._thread is not threading.current_thread():
            self._thread.join(timeout=5)
        self._thread = None
        self._close_transport()
        with self._pending_lock:
            self._pending.clear()

    def respond(self, data: bytes, delay_s: float = 0.0) -> None:
        """Send ``data`` to the client now, or ``delay_s`` seconds (real time) from now."""
        to = self._replying_to
        if delay_s <= 0:
            self._send(data, to)
            return
        with self._pending_lock:
            self._pending.append((time.monotonic() + delay_s, data, to))
            self._pending.sort(key=lambda p: p[0])

    # ---- the transport: what a subclass provides ----
    def _open(self) -> str:
        raise NotImplementedError

    def _serve(self) -> None:
        raise NotImplementedError

    def _send(self, data: bytes, to: object) -> None:
        raise NotImplementedError

    def _wake(self) -> None:
        """Wake the serving thread from its wait (close())."""

    def _close_transport(self) -> None:
        raise NotImplementedError

    # ---- shared by the transports ----
    def _after_wake(self) -> None:
        """Every wake-up of the serving thread: delayed replies that are due, then the tick."""
        now = time.monotonic()
        while True:
            with self._pending_lock:
                if not self._pending or self._pending[0][0] > now:
                    break
                _, data, to = self._pending.pop(0)
            self._send(data, to)
        if self._on_tick is not None:
            self._on_tick()

    def _wait_s(self) -> float:
        with self._pending_lock:
            if self._pending:
                return max(0.0, min(TICK_S, self._pending[0][0] - time.monotonic()))
        return TICK_S

    def _split_lines(self, buf: bytearray, discarding: bool, client: object = None) -> bool:
        """Hand every complete line in ``buf`` to ``on_line`` (consuming it); returns the new discarding state."""
        self._replying_to = client
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


class _Client:
    """One connected client: its socket and its partial line."""

    def __init__(self, conn: socket.socket):
        self.conn = conn
        self.buf = bytearray()
        self.discarding = False


class SocketLineServer(LineServer):
    """The line server on a loopback TCP port (every OS): ``socket://127.0.0.1:PORT`` for pyserial. Each client
    that connects is served (a reply goes to the client whose line it answers); one that disconnects is dropped,
    and closing the server disconnects them all (an unplugged cable)."""

    transport = "socket"

    def __init__(self, name: str, on_line: OnLine, *, max_line: int = 96,
                 on_tick: Callable[[], None] | None = None):
        super().__init__(name, on_line, max_line=max_line, on_tick=on_tick)
        self._listener: socket.socket | None = None
        self._wake_pair: tuple[socket.socket, socket.socket] | None = None
        self._clients: list[_Client] = []
        self._send_lock = threading.Lock()

    def _open(self) -> str:
        listener = socket.create_server(("127.0.0.1", 0))
        listener.setblocking(False)
        self._listener = listener
        self._wake_pair = socket.socketpair()        # select() on Windows takes sockets only: a socket wakes it
        return f"socket://127.0.0.1:{listener.getsockname()[1]}"

    def _wake(self) -> None:
        if self._wake_pair is not None:
            try:
                self._wake_pair[1].send(b"x")
            except OSError:
                pass

    def _serve(self) -> None:
        listener, wake = self._listener, self._wake_pair
        if listener is None or wake is None:
            return
        while not self._stop.is_set():
            clients = list(self._clients)
            try:
                ready, _, _ = select.select([listener, wake[0], *(c.conn for c in clients)], [], [], self._wait_s())
            except (OSError, ValueError):
                break
            if self._stop.is_set():
                break
            if listener in ready:
                self._accept(listener)
            for client in clients:
                if client.conn in ready:
                    self._receive(client)
            self._after_wake()

    def _accept(self, listener: socket.socket) -> None:
        try:
            conn, _ = listener.accept()
        except OSError as exc:
            log.debug("%s: accept: %s", self.name, exc)
            return
        conn.settimeout(SEND_TIMEOUT_S)
        conn.setsockopt(socket.IPPROTO_TCP, socket.TCP_NODELAY, 1)     # a reply line goes out at once
        with self._send_lock:
            self._clients.append(_Client(conn))

    def _receive(self, client: _Client) -> None:
        try:
            data = client.conn.recv(4096)
        except OSError as exc:
            log.debug("%s: receive: %s", self.name, exc)
            data = b""
        if not data:                                  # the client closed its port
            self._drop(client)
            return
        client.buf += data
        client.discarding = self._split_lines(client.buf, client.discarding, client)

    def _drop(self, client: _Client) -> None:
        with self._send_lock:
            if client in self._clients:
                self._clients.remove(client)
        try:
            client.conn.close()
        except OSError:
            pass

    def _send(self, data: bytes, to: object) -> None:
        with self._send_lock:       # to the client that asked; one that has gone gets nothing (a reopened port
            clients = [c for c in self._clients if c is to] if to is not None else self._clients[-1:]   # is clean)
        for client in clients:
            try:
                client.conn.sendall(data)
            except OSError as exc:                    # the client stopped reading or went away: the reply is lost
                log.warning("%s: reply %r dropped (%s)", self.name, data, exc)

    def _close_transport(self) -> None:
        with self._send_lock:
            clients, self._clients = self._clients, []
        socks = [c.conn for c in clients] + [s for s in (self._listener, *(self._wake_pair or ())) if s is not None]
        for s in socks:
            try:
                s.close()
            except OSError:
                pass
        self._listener = self._wake_pair = None
