"""The one error type the LED sphere driver raises, and what is known after switching the sphere off."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from dualrgb.common.errors import ReportedError

#: What went wrong, as ``SphereError.kind``.
KINDS = (
    "argument",      # the caller passed an invalid LED number / level / time (nothing was sent)
    "port",          # the serial port could not be opened
    "timeout",       # no (matching) reply within the timeout, after one retry
    "garbled",       # a reply that is not a well-formed answer to the command
    "device",        # the sphere answered ERR <code> <message>
    "fault",         # the sphere reports an LED channel fault (open circuit) while lit
    "disconnected",  # the port went away (unplugged, emulator stopped)
    "unconfirmed",   # the sphere answered a switch-off but reading its state back still shows light
)


class SphereError(ReportedError, RuntimeError):
    """An LED sphere problem, with a one-line message: what happened and what to do about it.

    ``kind`` is one of :data:`KINDS`; ``code`` is the device's error code for ``kind == "device"``
    (see docs/led-sphere-protocol.md) and ``None`` otherwise. ``light`` is ``"off"`` or ``"unknown"`` when the
    message already says what state the light was left in (the driver tried to switch it off), else ``None``.
    ``period`` is the lit period (drivers.led_sphere.supervisor.LitPeriod) a failed ``on()`` started, if any.
    """

    def __init__(self, message: str, kind: str = "device", code: int | None = None,
                 light: str | None = None, period: Any = None):
        if kind not in KINDS:
            raise ValueError(f"unknown SphereError kind {kind!r}")
        # One line, always: messages may quote device bytes.
        super().__init__(" ".join(str(message).split()))
        self.kind = kind
        self.code = code
        self.light = light
        self.period = period


@dataclass(frozen=True)
class LightReport:
    """What is known after trying to switch the sphere off: ``off`` is True only when the sphere confirmed that
    nothing is lit (``LIGHT 0`` or ``ALLOFF`` answered); ``message`` says so in words (one clause, for error
    messages); ``error`` is the first failure on the way, if any."""

    off: bool
    message: str
    error: SphereError | None = None
