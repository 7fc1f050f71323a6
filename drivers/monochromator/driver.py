"""Cornerstone: the host side of a Newport / Oriel Cornerstone 130 / 260 monochromator over RS-232 (pyserial).

Every exchange is one statement and its echo (plus, for a query, one answer line), bounded by ``timeout``
(drivers/monochromator/protocol.py). A statement that gets no echo in time is sent once more (every statement the
driver sends is absolute: a wavelength, a shutter state, a grating, so resending is harmless), then
:class:`MonochromatorError` is raised. Every command is followed by ``STB?`` (and ``ERROR?`` when the status byte
is not ``00``), so a refused wavelength is an error here and not a silent no-op; after a motion (``GOWAVE``,
``GRAT``, ``FILTER``) that ``STB?`` waits up to ``motion_timeout`` for the motor to stop.

Light safety: the output shutter is open only while a frame is exposed. :meth:`Cornerstone.ensure_closed` closes
it and says truthfully what is known afterwards (closed, confirmed by ``SHUTTER?``; or unknown, and what to do);
it never raises. Used as a context manager the shutter is closed on exit, also when an exception leaves the
block, and :meth:`Cornerstone.close` closes it too. A failed :meth:`Cornerstone.open_shutter` closes it before
raising.
"""
from __future__ import annotations

import collections
import logging
import math
import threading
import time
from typing import Any

import serial

from dualrgb.drivers.monochromator import protocol as P
from dualrgb.drivers.monochromator.errors import MonochromatorError, ShutterReport

log = logging.getLogger(__name__)

DEFAULT_TIMEOUT_S = 2.0           # per echo / answer
DEFAULT_MOTION_TIMEOUT_S = 30.0   # a wavelength slew across the range, a grating change
WAVELENGTH_TOLERANCE_NM = 0.5     # WAVE? after GOWAVE must be this close (the drive stops on a motor step)
_MAX_STALE_LINES = 4              # late echoes of earlier statements skipped per attempt

_TERMIOS_ERRORS: tuple[type[Exception], ...]
try:                                    # pyserial's POSIX backend lets termios.error (not an OSError) through
    from termios import error as _termios_error
    _TERMIOS_ERRORS = (_termios_error,)
except ImportError:                     # pragma: no cover - Windows
    _TERMIOS_ERRORS = ()
_IO_ERRORS: tuple[type[Exception], ...] = (serial.SerialException, OSError, *_TERMIOS_ERRORS)
CLOSE_BY_HAND = "close the monochromator's shutter on its front panel (or cap the lens) before going on"


class Cornerstone:
    """The monochromator on ``port``: a pyserial URL (``/dev/ttyUSB0``, a pty path, ``loop://``) or an already open
    serial-like object (``write``, ``read_until``; optional ``reset_input_buffer``, ``flush``, ``close``).

    >>> with Cornerstone("/dev/ttyUSB0") as mono:           # doctest: +SKIP
    ...     mono.prepare()                                  # units NM, errors cleared, shutter closed
    ...     mono.goto(550); mono.open_shutter(); ...; mono.close_shutter()
    # the shutter is closed here, whatever happened in the block
    """

    manual = False

    def __init__(self, port: Any, timeout: float = DEFAULT_TIMEOUT_S,
                 motion_timeout: float = DEFAULT_MOTION_TIMEOUT_S):
        self.timeout = self._check_time(timeout, "timeout")
        self.motion_timeout = self._check_time(motion_timeout, "motion timeout")
        self._lock = threading.RLock()
        self._owns_port = isinstance(port, str)
        self._url = port if isinstance(port, str) else getattr(port, "port", None) or type(port).__name__
        self._ser: Any = None if isinstance(port, str) else port
        self._answered: bool | None = None      # did the port answer like a monochromator? (None: not asked yet)
        self._info: str | None = None
        self._recent: collections.deque[bytes] = collections.deque(maxlen=4)    # the last statements sent

    @staticmethod
    def _check_time(seconds: Any, what: str) -> float:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) \
                or seconds <= 0:
            raise MonochromatorError(f"{what} {seconds!r} must be a positive number of seconds", kind="argument")
        return float(seconds)

    # ------------------------------------------------------------------------------------------- port
    @property
    def port(self) -> str:
        return str(self._url)

    @property
    def is_open(self) -> bool:
        return self._ser is not None

    def open(self) -> Cornerstone:
        """Open the serial port (a no-op for an object passed in already open)."""
        if self._ser is None:
            try:
                self._ser = serial.serial_for_url(
                    self._url, baudrate=P.BAUDRATE, bytesize=P.BYTESIZE, parity=P.PARITY, stopbits=P.STOPBITS,
                    timeout=min(self.timeout, 0.2), write_timeout=self.timeout)
            except (serial.SerialException, OSError, ValueError) as exc:
                raise MonochromatorError(f"cannot open monochromator port {self._url}: {exc}; check the cable and "
                                         "the port name (ls /dev/ttyUSB* /dev/ttyS*) and that no other program uses "
                                         "it", kind="port") from None
            log.info("opened monochromator port %s", self._url)
        return self

    def close(self, leave_open: bool = False) -> None:
        """Close the shutter (best effort: :meth:`ensure_closed`, what it could not confirm is logged), then the
        port (only if this object opened it). ``leave_open=True`` leaves the shutter as it is."""
        if self._ser is not None and not leave_open:
            report = self.ensure_closed()
            if not report.closed:
                log.warning("closing monochromator %s: %s", self._url, report.message)
        ser, self._ser = self._ser, None
        if ser is not None and self._owns_port:
            try:
                ser.close()
            except _IO_ERRORS as exc:
                log.warning("closing %s: %s", self._url, exc)

    def __enter__(self) -> Cornerstone:
        return self.open()

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            report = self.ensure_closed()
            if not report.closed:
                if exc is None:
                    raise MonochromatorError(report.message, kind=report.error.kind if report.error else "port",
                                             shutter="unknown")
                log.error("after an error, the monochromator: %s", report.message)
                exc.add_note(f"and the monochromator's shutter could not be confirmed closed: {report.message}")
        finally:
            self.close(leave_open=True)          # ensure_closed() was just tried

    # ------------------------------------------------------------------------------------------- exchanges
    def exchange(self, name: str, value: Any = None, *, wait_s: float | None = None) -> Any:
        """Send statement ``name`` of protocol.TABLE with ``value``; returns a query's answer (None for a command).
        ``wait_s``: how long to wait for the echo (default ``timeout``; after a motion, the motion timeout)."""
        stmt = P.COMMANDS[name]
        try:
            request = stmt.encode(value)
        except ValueError as exc:
            raise MonochromatorError(f"invalid {stmt.keyword} statement: {exc}", kind="argument") from None
        lock_wait = 2.5 * max(self.timeout, wait_s or 0.0) + 0.5
        if not self._lock.acquire(timeout=lock_wait):
            raise MonochromatorError(f"monochromator {self._url}: the port stayed busy for {lock_wait:.1f} s; "
                                     f"{stmt.keyword} was not sent", kind="timeout")
        try:
            return self._exchange_locked(stmt, request, wait_s or self.timeout)
        except MonochromatorError as exc:
            if exc.kind in ("timeout", "garbled") and self._answered is None:
                self._answered = False          # asked, and nothing on this port answered like a monochromator
            raise
        finally:
            self._lock.release()

    def _exchange_locked(self, stmt: P.Statement, request: bytes, wait_s: float) -> Any:
        if self._ser is None:
            raise MonochromatorError(f"monochromator port {self._url} is not open; use 'with Cornerstone(port) as "
                                     "m:' or call open()", kind="port")
        shown = request.decode("ascii").strip()
        for attempt in (1, 2):
            self._send(request, shown)
            try:
                value = self._receive(stmt, request, shown, wait_s)
            except TimeoutError:
                log.info("monochromator %s: no echo of %r within %.2f s (attempt %d)", self._url, shown, wait_s,
                         attempt)
                continue
            self._answered = True
            return value
        raise MonochromatorError(f"monochromator {self._url}: no echo of {shown!r} within {wait_s:.2f} s (sent "
                                 "twice); check that it is switched on, the cable (RS-232, 9600 baud) and that the "
                                 "port is the monochromator's", kind="timeout")

    def _send(self, request: bytes, shown: str) -> None:
        ser = self._ser
        try:
            reset = getattr(ser, "reset_input_buffer", None)
            if reset is not None:
                reset()                          # drop a late echo or answer of an earlier statement
            ser.write(request)
            self._recent.append(request)
            flush = getattr(ser, "flush", None)
            if flush is not None:
                flush()
        except serial.SerialTimeoutException:
            raise MonochromatorError(f"monochromator {self._url}: could not send {shown!r} within "
                                     f"{self.timeout:.2f} s; check the cable", kind="timeout") from None
        except _IO_ERRORS as exc:
            raise MonochromatorError(f"monochromator {self._url} disconnected while sending {shown!r} ({exc}); "
                                     f"reconnect it and {CLOSE_BY_HAND}", kind="disconnected") from None
        log.debug("-> %r", request)

    def _receive(self, stmt: P.Statement, request: bytes, shown: str, wait_s: float) -> Any:
        """The echo (TimeoutError when it does not come in ``wait_s``), then a query's answer. A late echo of an
        earlier statement (it came after its timeout) is skipped."""
        deadline = time.monotonic() + wait_s
        for _ in range(_MAX_STALE_LINES + 1):
            echo = self._read_line(deadline, shown)
            if P.is_echo(echo, request):
                break
            if not any(P.is_echo(echo, earlier) for earlier in self._recent):
                raise MonochromatorError(f"monochromator {self._url}: expected the echo of {shown!r}, got "
                                         f"{P.show(echo)}; check baud rate 9600 and that no other program uses the "
                                         "port", kind="garbled")
            log.info("monochromator %s: skipping a late echo %s", self._url, P.show(echo))
        else:
            raise TimeoutError
        if not stmt.is_query:
            return None
        try:
            answer = self._read_line(time.monotonic() + self.timeout, shown)
        except TimeoutError:
            raise MonochromatorError(f"monochromator {self._url}: echoed {shown!r} but sent no answer within "
                                     f"{self.timeout:.2f} s", kind="timeout") from None
        try:
            return stmt.decode(answer)
        except P.ReplyError as exc:
            raise MonochromatorError(f"monochromator {self._url}: garbled answer to {shown!r}: {exc}",
                                     kind="garbled") from None

    def _read_line(self, deadline: float, shown: str) -> bytes:
        """One line ending in LF (TimeoutError at ``deadline``; an overlong line is garbled)."""
        buf = bytearray()
        while True:
            try:
                chunk = bytes(self._ser.read_until(b"\n", P.MAX_LINE_BYTES - len(buf)) or b"")
            except _IO_ERRORS as exc:
                raise MonochromatorError(f"monochromator {self._url} disconnected while waiting for the reply to "
                                         f"{shown!r} ({exc}); reconnect it and {CLOSE_BY_HAND}",
                                         kind="disconnected") from None
            buf += chunk
            if buf.endswith(b"\n"):
                log.debug("<- %r", bytes(buf))
                return bytes(buf)
            if len(buf) >= P.MAX_LINE_BYTES:
                raise MonochromatorError(f"monochromator {self._url}: overlong reply {P.show(bytes(buf))} to "
                                         f"{shown!r}; check baud rate 9600", kind="garbled")
            if time.monotonic() >= deadline:
                raise TimeoutError
            if not chunk:
                time.sleep(0.002)                # a port object without a read timeout returns at once

    def command(self, name: str, value: Any = None) -> None:
        """A command, then its status: ``STB?`` (and ``ERROR?`` when not 00); MonochromatorError when refused."""
        stmt = P.COMMANDS[name]
        self.exchange(name, value)
        status = self.exchange("status_byte", wait_s=self.motion_timeout if stmt.motion else None)
        if status == P.STATUS_OK:
            return
        code = self.exchange("error")
        if code == P.ErrorCode.ALREADY_THERE and stmt.motion:
            log.info("monochromator %s: %s: already in position", self._url, stmt.keyword)
            return
        shown = stmt.encode(value).decode("ascii").strip()
        if code is None:
            raise MonochromatorError(f"monochromator {self._url} flagged an error after {shown!r} (status "
                                     f"{status:02X}) but ERROR? gave no code", kind="device")
        try:
            what = P.ErrorCode(code)
            text = f"{what.name.lower().replace('_', ' ')} (error {code}); {P.ERROR_ADVICE[what]}"
        except ValueError:
            text = f"error {code}, unknown to this driver; check the model (INFO?)"
        raise MonochromatorError(f"monochromator {self._url} refused {shown!r}: {text}", kind="device", code=code)

    # ------------------------------------------------------------------------------------------- shutter
    def open_shutter(self) -> None:
        """Open the output shutter; when that fails it is closed again and the error says in what state it is."""
        try:
            self.command("shutter", "O")
        except MonochromatorError as exc:
            report = self.ensure_closed()
            raise MonochromatorError(f"{exc}; {report.message}", kind=exc.kind, code=exc.code,
                                     shutter="closed" if report.closed else "unknown") from None

    def close_shutter(self) -> None:
        """Close the output shutter (MonochromatorError when the monochromator refuses or does not answer)."""
        self.command("shutter", "C")

    def shutter_is_open(self) -> bool:
        return bool(self.exchange("shutter_state"))

    def ensure_closed(self) -> ShutterReport:
        """Close the shutter and say what is known afterwards (confirmed by ``SHUTTER?``); never raises.

        On a port that never answered like a monochromator, ``SHUTTER C`` is written without waiting for replies
        that would not come, and the report says the state is unknown."""
        if self._ser is None:
            return ShutterReport(False, f"the monochromator port {self._url} is closed, so the shutter's state is "
                                        f"unknown; {CLOSE_BY_HAND}")
        if self._answered is False:
            sent = self._send_blind(P.COMMANDS["shutter"].encode("C"))
            what = "SHUTTER C was sent without waiting for a reply" if sent else "SHUTTER C could not even be sent"
            return ShutterReport(False, f"the port never answered like a monochromator, so the shutter's state is "
                                        f"unknown ({what}); {CLOSE_BY_HAND}")
        first: MonochromatorError | None = None
        try:
            self.close_shutter()
        except MonochromatorError as exc:
            first = exc
        try:
            still_open = self.shutter_is_open()
        except MonochromatorError as exc:
            return ShutterReport(False, f"{first or exc}; the shutter's state is unknown: {CLOSE_BY_HAND}",
                                 first or exc)
        if still_open:
            return ShutterReport(False, f"the shutter still reports open after SHUTTER C; {CLOSE_BY_HAND}",
                                 first or MonochromatorError("shutter reports open", kind="device"))
        log.info("monochromator %s: shutter closed", self._url)
        return ShutterReport(True, "the monochromator's shutter was closed", first)

    def _send_blind(self, request: bytes) -> bool:
        if not self._lock.acquire(timeout=2.5 * self.timeout + 0.5):
            return False
        try:
            self._ser.write(request)
            flush = getattr(self._ser, "flush", None)
            if flush is not None:
                flush()
            return True
        except _IO_ERRORS + (AttributeError,) as exc:
            log.info("monochromator %s: could not send the shutter close: %s", self._url, exc)
            return False
        finally:
            self._lock.release()

    # ------------------------------------------------------------------------------------------- wavelength etc.
    def identify(self) -> str:
        """``INFO?``: model and firmware, as the monochromator words it."""
        self._info = str(self.exchange("info"))
        return self._info

    def prepare(self) -> None:
        """Before a sweep: units NM, any stale error read (and so cleared), the shutter closed (confirmed)."""
        self.command("set_units", "NM")
        if self.exchange("status_byte") != P.STATUS_OK:
            log.info("monochromator %s: clearing a stale error %s", self._url, self.exchange("error"))
        report = self.ensure_closed()
        if not report.closed:
            raise MonochromatorError(report.message, kind=report.error.kind if report.error else "device",
                                     shutter="unknown")

    def goto(self, wavelength_nm: float) -> float:
        """Move to ``wavelength_nm`` (waiting for the drive); returns the wavelength it reports (``WAVE?``)."""
        try:
            nm = P.NM.check(wavelength_nm)
        except ValueError as exc:
            raise MonochromatorError(f"wavelength: {exc}", kind="argument") from None
        self.command("goto", nm)
        reached = self.wavelength()
        if abs(reached - nm) > WAVELENGTH_TOLERANCE_NM:
            raise MonochromatorError(f"monochromator {self._url}: asked for {nm:g} nm, the drive reports "
                                     f"{reached:g} nm; check the units (UNITS NM) and the grating", kind="device")
        return reached

    def wavelength(self) -> float:
        return float(self.exchange("wavelength"))

    def grating(self) -> P.GratingInfo:
        return self.exchange("grating")

    def set_grating(self, number: int) -> P.GratingInfo:
        self.command("set_grating", number)
        return self.grating()

    def filter(self) -> int:
        """Filter wheel position 1..6 (0: out of position or no wheel)."""
        return int(self.exchange("filter"))

    def set_filter(self, position: int) -> int:
        self.command("set_filter", position)
        return self.filter()

    def units(self) -> str:
        return str(self.exchange("units"))

    def set_units(self, units: str) -> None:
        self.command("set_units", units)

    def step_position(self) -> int:
        return int(self.exchange("step"))

    def status_byte(self) -> int:
        return int(self.exchange("status_byte"))

    def last_error(self) -> int | None:
        return self.exchange("error")

    # ------------------------------------------------------------------------------------------- for sequences
    def describe(self) -> dict[str, str]:
        """Provenance for a measurement's header: the instrument, its INFO? text, port and grating."""
        info = self._info if self._info is not None else self.identify()
        g = self.grating()
        return {"instrument": "Newport / Oriel Cornerstone monochromator", "model": info, "port": self.port,
                "grating": f"{g.number} ({g.lines_per_mm} l/mm, {g.label})"}

    def prompt_to_set(self, wavelength_nm: float) -> str | None:
        """Motorised: nobody has to do anything (a ManualMonochromator returns what to ask the person)."""
        return None

    def prompt_to_close(self) -> str | None:
        return None
