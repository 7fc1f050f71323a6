"""Every signal ends dark, said in one line: SIGINT (Ctrl-C), SIGTERM (``kill``, a service manager) and SIGHUP (the
terminal closed) while a command runs.

The handler, on the main thread at the signal, first switches every LED sphere this process has open off and reads
it back (drivers.led_sphere.open_spheres: the driver's ``ensure_off``, which never raises and bounds its waits),
then raises :class:`Interrupted` (a ``KeyboardInterrupt``, so every clean-up written for Ctrl-C runs: the shot's
light off, the session closed, staging folders removed). The command line then ends with one line saying what was
read back and how to resume (:func:`interrupted_line`), exit 128 + the signal's number::

    dualrgb: interrupted; light off (read back); run the same command again to resume

Switching off in the handler, before unwinding, is safe because every lock on the way is re-entrant (the sphere's
port lock, its supervisor's condition) and a reply the interrupted exchange was waiting for is skipped as stale;
what the unwinding then switches off again changes nothing. A second signal while the first is handled is ignored
(the clean-up it would cut short keeps frames and the session whole). Without the handler SIGTERM and SIGHUP would
end the process at once, leaving the light to the sphere's own on-time limit.
"""
from __future__ import annotations

import contextlib
import logging
import signal
import threading
from collections.abc import Iterator
from dataclasses import dataclass, field
from types import FrameType

from dualrgb.drivers.led_sphere.open_spheres import open_spheres

log = logging.getLogger(__name__)

SIGNALS = tuple(getattr(signal, name) for name in ("SIGINT", "SIGTERM", "SIGHUP") if hasattr(signal, name))
RESUME = "run the same command again to resume"


@dataclass
class LightRead:
    """One open sphere's switch-off at the signal: its port, whether it confirmed the light off, its words."""

    port: str
    off: bool
    message: str


class Interrupted(KeyboardInterrupt):
    """A signal ended the command; ``lights`` is what each open sphere said when it was switched off."""

    def __init__(self, signum: int, lights: list[LightRead]):
        super().__init__(signal.Signals(signum).name)
        self.signum = signum
        self.lights = lights


@dataclass
class _State:
    handling: bool = False
    received: list[Interrupted] = field(default_factory=list)


_STATE = _State()


def switch_off_open_spheres() -> list[LightRead]:
    """Every open sphere switched off and read back (its LightReport's ``off`` and words)."""
    out = []
    for sphere in open_spheres():
        report = sphere.ensure_off()
        out.append(LightRead(str(sphere.port), bool(getattr(report, "off", False)),
                             str(getattr(report, "message", report))))
    return out


def _handler(signum: int, frame: FrameType | None) -> None:
    if _STATE.handling or _STATE.received:
        log.warning("%s ignored: the command is already ending", signal.Signals(signum).name)
        return
    _STATE.handling = True
    try:
        exc = Interrupted(signum, switch_off_open_spheres())
        _STATE.received.append(exc)
    finally:
        _STATE.handling = False
    raise exc


@contextlib.contextmanager
def handled() -> Iterator[None]:
    """SIGINT, SIGTERM and SIGHUP handled as the module says while the block runs (main thread only; elsewhere, as
    in a test's worker thread, nothing changes); the previous handlers come back afterwards."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    _STATE.received.clear()
    previous = {sig: signal.signal(sig, _handler) for sig in SIGNALS}
    try:
        yield
    finally:
        for sig, old in previous.items():
            signal.signal(sig, old)


def received() -> Interrupted | None:
    """The signal that ended the command in the last :func:`handled` block, if any."""
    return _STATE.received[0] if _STATE.received else None


def interrupted_line(exc: Interrupted | None) -> str:
    """The command's last line after a signal (``exc`` None: a KeyboardInterrupt raised without the handler)."""
    if exc is None:
        return f"dualrgb: interrupted; the light's state was not read back; {RESUME}"
    if not exc.lights:
        return f"dualrgb: interrupted; no LED sphere was open, so this command had nothing lit; {RESUME}"
    unsure = [read for read in exc.lights if not read.off]
    if not unsure:
        return f"dualrgb: interrupted; light off (read back); {RESUME}"
    said = "; ".join(f"LED sphere {read.port}: {read.message}" for read in unsure)
    return f"dualrgb: interrupted; the light is NOT confirmed off: {said}; {RESUME}"


def exit_code(exc: BaseException) -> int:
    """128 + the signal's number (130 for Ctrl-C, 143 for SIGTERM, 129 for SIGHUP)."""
    return 128 + int(getattr(exc, "signum", signal.SIGINT))
