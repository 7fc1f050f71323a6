"""The one error type the monochromator drivers raise, and what is known after closing the shutter."""
from __future__ import annotations

from dataclasses import dataclass

from dualrgb.common.errors import ReportedError

#: What went wrong, as ``MonochromatorError.kind``.
KINDS = (
    "argument",      # the caller passed an invalid wavelength / grating / filter (nothing was sent)
    "port",          # the serial port could not be opened, or is closed
    "timeout",       # no echo or answer within the timeout, after one retry
    "garbled",       # an echo or answer that is not what the statement expects
    "device",        # the monochromator reported an error code (STB? / ERROR?)
    "disconnected",  # the port went away (unplugged, emulator stopped)
)


class MonochromatorError(ReportedError, RuntimeError):
    """A monochromator problem, with a one-line message: what happened and what to do about it.

    ``kind`` is one of :data:`KINDS`; ``code`` is the device's error code (``kind == "device"``, see
    docs/monochromator-protocol.md), else None. ``shutter`` is ``"closed"`` or ``"unknown"`` when the message
    already says what state the shutter was left in, else None.
    """

    def __init__(self, message: str, kind: str = "device", code: int | None = None, shutter: str | None = None):
        if kind not in KINDS:
            raise ValueError(f"unknown MonochromatorError kind {kind!r}")
        super().__init__(" ".join(str(message).split()))       # one line, always: messages quote device bytes
        self.kind = kind
        self.code = code
        self.shutter = shutter


@dataclass(frozen=True)
class ShutterReport:
    """What is known after trying to close the shutter: ``closed`` only when the monochromator confirmed it
    (``SHUTTER?`` answered ``C``); ``message`` says so in words; ``error`` is the first failure, if any."""

    closed: bool
    message: str
    error: MonochromatorError | None = None
