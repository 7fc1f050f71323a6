"""The virtual instruments' two transports (drivers.virtual.transport), for parametrised tests: the pty where
the OS has one, pyserial's socket:// everywhere."""
from __future__ import annotations

import os

import pytest

from dualrgb.drivers.virtual.transport import pty_available

TRANSPORTS = [pytest.param("pty", marks=pytest.mark.skipif(not pty_available(), reason="no pseudo-terminals here")),
              "socket"]


def assert_port(port: str, transport: str) -> None:
    """``port`` is what ``transport`` serves: a pty path that exists, or a loopback socket URL."""
    if transport == "pty":
        assert port.startswith("/dev/") and os.path.exists(port), port
    else:
        assert port.startswith("socket://127.0.0.1:") and int(port.rsplit(":", 1)[1]) > 0, port
