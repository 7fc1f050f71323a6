"""The virtual instruments' transports (drivers.virtual.transport, line_server): which one is chosen, and the
socket server's own rules (each reply to the client that asked, a late reply to a client gone is dropped, close()
unplugs all)."""
from __future__ import annotations

import time

import pytest
import serial

from dualrgb.drivers.virtual import line_server as ls
from dualrgb.drivers.virtual import transport


def test_the_transport_is_chosen_by_argument_then_environment_then_os(monkeypatch):
    monkeypatch.delenv(transport.TRANSPORT_ENV, raising=False)
    assert transport.chosen_transport() == ("pty" if transport.pty_available() else "socket")
    assert transport.chosen_transport("socket") == "socket"
    monkeypatch.setenv(transport.TRANSPORT_ENV, "Socket")
    assert transport.chosen_transport() == "socket"
    with pytest.raises(ValueError, match="DUALRGB_VIRTUAL_TRANSPORT='usb': expected one of pty, socket"):
        monkeypatch.setenv(transport.TRANSPORT_ENV, "usb")
        transport.chosen_transport()
    monkeypatch.setattr(transport, "pty_available", lambda: False)          # Windows
    monkeypatch.delenv(transport.TRANSPORT_ENV)
    assert transport.chosen_transport() == "socket"
    with pytest.raises(ValueError, match="no pseudo-terminals"):
        transport.chosen_transport("pty")


@pytest.fixture
def echo():
    """A socket line server that answers 'ECHO <line>' at once, and 'LATE' lines after 0.3 s."""
    def on_line(line: bytes, too_long: bool) -> None:
        server.respond(b"ECHO " + line + b"\n", 0.3 if line == b"LATE" else 0.0)
    server = ls.SocketLineServer("echo", on_line, max_line=16)
    port = server.start()
    yield server, port
    server.close()


def test_each_client_gets_its_own_replies(echo):
    _, port = echo
    with serial.serial_for_url(port, timeout=2) as a, serial.serial_for_url(port, timeout=2) as b:
        a.write(b"one\r\n")
        b.write(b"two\n")
        assert b.readline() == b"ECHO two\n" and a.readline() == b"ECHO one\n"
        a.write(b"X" * 40 + b"\nthree\n")                      # too long: passed once, then the next line
        assert a.readline().startswith(b"ECHO XXXXXXXXXXXXXXXX") and a.readline() == b"ECHO three\n"


def test_a_late_reply_to_a_client_gone_is_dropped_and_close_unplugs(echo):
    server, port = echo
    with serial.serial_for_url(port, timeout=2) as a:
        a.write(b"LATE\n")
        time.sleep(0.05)
    with serial.serial_for_url(port, timeout=0.6) as b:
        b.write(b"now\n")
        assert b.readline() == b"ECHO now\n"
        assert b.readline() == b""                             # the first client's late reply never reaches it
        server.close()
        with pytest.raises(serial.SerialException):
            b.write(b"after\n")
            b.readline()
            b.readline()
