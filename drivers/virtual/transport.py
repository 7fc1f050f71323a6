"""Which transport the virtual instruments serve (drivers/virtual/line_server.py): a pseudo-terminal where the OS
has them (Linux, macOS), pyserial's ``socket://127.0.0.1:PORT`` elsewhere (Windows); ``DUALRGB_VIRTUAL_TRANSPORT``
(``pty`` or ``socket``) or a ``transport`` argument chooses on any OS."""
from __future__ import annotations

import os
from collections.abc import Callable

from dualrgb.drivers.virtual.line_server import LineServer, OnLine, SocketLineServer

TRANSPORT_ENV = "DUALRGB_VIRTUAL_TRANSPORT"
TRANSPORTS = ("pty", "socket")


def pty_available() -> bool:
    """Whether this OS serves pseudo-terminals (POSIX: ``os.openpty`` and the ``tty`` module)."""
    if not hasattr(os, "openpty"):
        return False
    try:
        import tty  # noqa: F401 - only whether it imports
    except ImportError:
        return False
    return True


def chosen_transport(transport: str | None = None) -> str:
    """``transport``, else ``$DUALRGB_VIRTUAL_TRANSPORT``, else the pty where there is one and the socket elsewhere;
    ValueError naming the value for anything else (or a pty on an OS without one)."""
    wanted = (transport or os.environ.get(TRANSPORT_ENV, "")).strip().lower()
    if wanted and wanted not in TRANSPORTS:
        source = "transport" if transport else TRANSPORT_ENV
        raise ValueError(f"{source}={wanted!r}: expected one of {', '.join(TRANSPORTS)}")
    if wanted == "pty" and not pty_available():
        raise ValueError(f"{TRANSPORT_ENV}=pty: this OS has no pseudo-terminals; use socket")
    return wanted or ("pty" if pty_available() else "socket")


def line_server(name: str, on_line: OnLine, *, max_line: int = 96, on_tick: Callable[[], None] | None = None,
                transport: str | None = None) -> LineServer:
    """The line server on the chosen transport (:func:`chosen_transport`)."""
    if chosen_transport(transport) == "pty":
        from dualrgb.drivers.virtual.pty_link import PtyLineServer

        return PtyLineServer(name, on_line, max_line=max_line, on_tick=on_tick)
    return SocketLineServer(name, on_line, max_line=max_line, on_tick=on_tick)
