"""Test doubles for the LED sphere: a scripted serial port that asserts the exact bytes written (in the spirit of
pymeasure's ``expected_protocol``), a fast fuzz transport, and a settable clock for the emulator's physics."""
from __future__ import annotations

import contextlib
import threading
from collections.abc import Iterator, Sequence

import serial

from dualrgb.drivers.led_sphere import LedSphere


class ScriptedSerial:
    """A serial-like object: each ``write`` must equal the next expected request; its scripted reply (bytes,
    possibly several lines, or None for silence) then becomes readable. ``read_until`` returns one line, a
    fragment without terminator when that is all there is (as a real port does at its timeout), or b"".
    ``reset_input_buffer`` drops unread bytes, like the real port."""

    def __init__(self, pairs: Sequence[tuple[bytes, bytes | None]]):
        self.pairs = list(pairs)
        self.index = 0
        self.buffer = bytearray()
        self.written: list[bytes] = []
        self.timeout: float | None = None
        self.write_timeout: float | None = None
        self.port = "scripted"

    def write(self, data: bytes) -> int:
        self.written.append(bytes(data))
        assert self.index < len(self.pairs), f"unexpected extra request {data!r}"
        expected, reply = self.pairs[self.index]
        assert bytes(data) == expected, f"request {self.index}: wrote {data!r}, expected {expected!r}"
        self.index += 1
        if reply:
            self.buffer += reply
        return len(data)

    def flush(self) -> None:
        pass

    def reset_input_buffer(self) -> None:
        self.buffer.clear()

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        nl = self.buffer.find(expected)
        end = len(self.buffer) if nl < 0 else nl + len(expected)
        if size is not None:
            end = min(end, size)
        out = bytes(self.buffer[:end])
        del self.buffer[:end]
        return out

    def close(self) -> None:
        pass

    @property
    def done(self) -> bool:
        return self.index == len(self.pairs)


@contextlib.contextmanager
def expected_protocol(pairs: Sequence[tuple[bytes, bytes | None]], timeout: float = 0.05,
                      **kwargs) -> Iterator[LedSphere]:
    """A LedSphere on a ScriptedSerial; on leaving the block every scripted exchange must have happened."""
    port = ScriptedSerial(pairs)
    sphere = LedSphere(port, timeout=timeout, **kwargs)
    try:
        yield sphere
    finally:
        sphere.close(leave_on=True)         # stops the on-time supervisor: no requests after the script
    assert port.done, f"only {port.index} of {len(port.pairs)} scripted exchanges happened: {port.written}"


class FrameSerial:
    """Fuzz transport: every read returns the next frame (cut at its first newline and at ``size``); writes are
    accepted and counted. When the frames run out it stays silent (b"")."""

    def __init__(self, frames: Sequence[bytes]):
        self.frames = list(frames)
        self.next = 0
        self.writes = 0
        self.timeout = None
        self.port = "fuzz"

    def write(self, data: bytes) -> int:
        self.writes += 1
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        if self.next >= len(self.frames):
            return b""
        frame = self.frames[self.next]
        self.next += 1
        nl = frame.find(expected)
        if nl >= 0:
            frame = frame[:nl + 1]
        return frame[:size] if size is not None else frame


class BrokenSerial(ScriptedSerial):
    """Raises on read or write like an unplugged USB port."""

    def __init__(self, fail_on: str = "read"):
        super().__init__([])
        self.fail_on = fail_on

    def write(self, data: bytes) -> int:
        if self.fail_on == "write":
            raise serial.SerialException("write failed: [Errno 5] Input/output error")
        if self.fail_on == "write_timeout":
            raise serial.SerialTimeoutException("Write timeout")
        return len(data)

    def read_until(self, expected: bytes = b"\n", size: int | None = None) -> bytes:
        raise serial.SerialException("device reports readiness to read but returned no data")


class FakeClock:
    """A monotonic clock the test moves by hand (thread-safe: the emulator's serve thread reads it too)."""

    def __init__(self, t: float = 1000.0):
        self._t = t
        self._lock = threading.Lock()

    def __call__(self) -> float:
        with self._lock:
            return self._t

    def advance(self, dt: float) -> None:
        with self._lock:
            self._t += dt
