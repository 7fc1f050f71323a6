"""The camera bridge protocol (docs/camera-bridge-protocol.md): a camera served over TCP by a tethering bridge.

One place for what both ends share: the address form ``tcp://HOST:PORT``, the framing (one line of UTF-8 JSON per
message, ``\\n``-terminated, at most :data:`MAX_HEADER` bytes, followed by exactly ``bytes`` bytes of payload
when the header has that key), the operations and the reply shape. The client is
:class:`drivers.camera.network.NetworkCamera`, the server :class:`drivers.camera.bridge.CameraBridge`.
"""
from __future__ import annotations

import json
import socket
from typing import Any, BinaryIO

PROTOCOL = 1
SCHEME = "tcp://"
MAX_HEADER = 64 * 1024                 # a header line (settings, identity) is a few hundred bytes
MAX_PAYLOAD = 1 << 31                  # a raw file: ~30 MB for a D610 NEF; a 150 MP back's DNG stays below
OPS = ("hello", "settings", "apply", "shutter_speeds", "expose", "fetch", "preview", "frame_shape", "image_area",
       "frame_bytes", "latency", "config")
SETTING_FIELDS = ("iso", "shutter_s", "aperture", "image_quality", "capture_target")


class ProtocolError(ValueError):
    """A message that is not the protocol's (bad JSON, too long, a payload cut short): one line."""


def is_address(text: str) -> bool:
    """Whether ``text`` names a camera bridge (``tcp://HOST:PORT``)."""
    return str(text).strip().lower().startswith(SCHEME)


def parse_address(address: str) -> tuple[str, int]:
    """``tcp://HOST:PORT`` -> (host, port); a one-line ValueError naming the address otherwise."""
    text = str(address).strip()
    host, _, port = text[len(SCHEME):].rpartition(":") if is_address(text) else ("", "", "")
    if not host or not port.isdigit() or not 0 < int(port) < 65536:
        raise ValueError(f"camera address {address!r}: expected {SCHEME}HOST:PORT (e.g. {SCHEME}127.0.0.1:5050)")
    return host.strip("[]"), int(port)


def send(sock: socket.socket, header: dict[str, Any], payload: bytes = b"") -> None:
    """Send one message: ``header`` as a JSON line (with ``bytes`` set when there is a payload), then the payload."""
    if payload:
        header = {**header, "bytes": len(payload)}
    line = json.dumps(header, separators=(",", ":"), allow_nan=False).encode() + b"\n"
    if len(line) > MAX_HEADER:
        raise ProtocolError(f"message header of {len(line)} bytes: at most {MAX_HEADER}")
    sock.sendall(line + payload if len(payload) < 1 << 20 else line)
    if len(payload) >= 1 << 20:
        sock.sendall(payload)


def receive(stream: BinaryIO) -> tuple[dict[str, Any], bytes] | None:
    """One message from ``stream`` (a socket's ``makefile('rb')``): (header, payload); None at a clean end of the
    stream (the peer closed between messages); ProtocolError for anything that is not a message."""
    line = stream.readline(MAX_HEADER + 1)
    if not line:
        return None
    if not line.endswith(b"\n"):
        raise ProtocolError(f"a message header longer than {MAX_HEADER} bytes, or cut short" if len(line) > MAX_HEADER
                            else "the connection closed in the middle of a message")
    try:
        header = json.loads(line)
    except (UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise ProtocolError(f"not a JSON message line ({exc})") from None
    if not isinstance(header, dict):
        raise ProtocolError(f"a message must be a JSON object, not {type(header).__name__}")
    n = header.get("bytes", 0)
    if not isinstance(n, int) or isinstance(n, bool) or not 0 <= n <= MAX_PAYLOAD:
        raise ProtocolError(f"payload size {n!r}: expected an integer 0..{MAX_PAYLOAD}")
    payload = stream.read(n) if n else b""
    if len(payload) != n:
        raise ProtocolError(f"the connection closed after {len(payload)} of {n} payload bytes")
    return header, payload


def error_reply(message: str, kind: str = "camera", code: int | None = None) -> dict[str, Any]:
    """A failed request's reply: one line ``error`` saying what to do, ``kind`` (camera, protocol, internal), the
    camera's ``code`` where it has one (libgphoto2's)."""
    return {"ok": False, "error": str(message).splitlines()[0] if message else kind, "kind": kind, "code": code}
