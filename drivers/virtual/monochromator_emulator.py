"""MonochromatorEmulator: a Cornerstone 130 speaking drivers/monochromator/protocol.py on a real serial transport.

``start()`` serves a port (drivers.virtual.line_server: a pseudo-terminal, or pyserial's ``socket://`` URL where
there is none or when chosen) and returns it; the Cornerstone driver (or pyserial) opens it as if it were
/dev/ttyUSB0. The emulator holds the instrument's state - wavelength (the drive
stops on a motor step), grating, shutter, filter wheel, units, status byte and error code - echoes every statement
as the RS-232 instrument does, answers queries, and sets the status byte and error code for what it refuses
(unknown statement 1, bad parameter 2, a wavelength outside the grating's range 3, error 7 for a filter or grating
already in place). Its light (:meth:`output`) is the narrow band of drivers/virtual/monochromator_light.py at the
current wavelength, grating and filter, and nothing while the shutter is closed; every open period is recorded on
the emulator's clock (:meth:`shutter_record`) for tests that bound how long light came out.

Faults (:meth:`inject`), like the sphere emulator's: ``no_reply`` (nothing comes back, not even the echo;
``execute=False``: the statement is not carried out either), ``ignore`` (the same as no_reply with
execute=False), ``garbled`` (the echo and answer bytes corrupted), ``slow`` (everything comes ``delay_s`` late),
``error`` (the statement is echoed but refused with error ``code``); each takes ``keywords=("GOWAVE", ...)`` to
hit only those statements. ``disconnect`` closes the port (an unplugged cable; the instrument keeps its state).
``inject(None)`` clears them. ``motion_s_per_nm`` (default 0) makes the drive take time to slew: statements after a
GOWAVE are answered when it has arrived.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualrgb.drivers.monochromator import protocol as P
from dualrgb.drivers.virtual.monochromator_light import MonochromatorOptics
from dualrgb.drivers.virtual.transport import line_server

log = logging.getLogger(__name__)

FAULTS = ("no_reply", "ignore", "garbled", "slow", "error", "disconnect")
MODEL_INFO = "CS130 VER 1.01 EMULATOR"


@dataclass
class ShutterInterval:
    """The shutter open from ``t_open`` to ``t_close`` (None: still open) on the emulator's clock, at
    ``wavelength_nm``; ``closed_by``: the statement or event that closed it."""

    t_open: float
    t_close: float | None
    wavelength_nm: float
    closed_by: str = ""


class MonochromatorEmulator:
    """A Cornerstone 130 on a pty; see the module docstring."""

    def __init__(self, optics: MonochromatorOptics | None = None, *, clock: Callable[[], float] = time.monotonic,
                 motion_s_per_nm: float = 0.0, seed: int = 0, transport: str | None = None):
        self.optics = optics or MonochromatorOptics()
        self._clock = clock
        self.motion_s_per_nm = float(motion_s_per_nm)
        self._lock = threading.RLock()
        self._steps = int(round(500.0 * self.optics.grating(1).steps_per_nm))     # homed at 500 nm
        self._grating = 1
        self._filter = 1
        self._units = "NM"
        self._shutter_open = False
        self._status = P.STATUS_OK
        self._error: int | None = None
        self._record: list[ShutterInterval] = []
        self._faults: dict[str, dict[str, Any]] = {}
        self._busy_until = 0.0                     # real time when the drive stops (motion_s_per_nm > 0)
        self._rng = np.random.default_rng(seed)
        self._server = line_server("monochromator-emulator", self._on_line, max_line=P.MAX_LINE_BYTES,
                                   transport=transport)
        self.statements: list[bytes] = []          # every statement received, for tests and logs

    # ------------------------------------------------------------------------------------------ serving
    def start(self) -> str:
        """Serve the port; returns what a serial client opens (a pty path or a ``socket://`` URL)."""
        port = self._server.start()
        log.info("monochromator emulator serving on %s", port)
        return port

    @property
    def port(self) -> str:
        return self._server.port

    def stop(self) -> None:
        """Stop serving (the instrument is switched off: the shutter closes)."""
        self._server.close()
        with self._lock:
            self._set_shutter(False, "power off")

    def __enter__(self) -> MonochromatorEmulator:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _active_faults(self, line: bytes) -> dict[str, dict[str, Any]]:
        with self._lock:
            faults = dict(self._faults)
        keyword = line.split(b" ", 1)[0].strip().upper().decode("ascii", "replace")
        return {n: p for n, p in faults.items() if p.get("keywords") is None or keyword in p["keywords"]}

    def _on_line(self, line: bytes, too_long: bool) -> None:
        busy_s = self._busy_until - time.monotonic()      # a moving drive answers once it has stopped
        faults = self._active_faults(line)
        hung = "ignore" in faults or ("no_reply" in faults and not faults["no_reply"].get("execute", True))
        if hung:
            return
        if too_long:
            with self._lock:
                self._fail(P.ErrorCode.NOT_UNDERSTOOD)
            reply = b""
        elif "error" in faults:
            with self._lock:
                self._fail(P.ErrorCode(int(faults["error"].get("code", P.ErrorCode.SYSTEM))))
            reply = line + P.TERMINATOR
        else:
            reply = self.handle(line)
        if "no_reply" in faults or not reply:
            return
        if "garbled" in faults:
            reply = self._garble(reply)
        delay = float(faults["slow"].get("delay_s", 1.0)) if "slow" in faults else 0.0
        self._server.respond(reply, max(delay, busy_s))

    def _garble(self, reply: bytes) -> bytes:
        body = bytearray(reply.rstrip(b"\r\n") or b"00")
        hits = self._rng.random(len(body)) < 0.35
        hits[0] = True
        body = bytearray(int(self._rng.integers(0x80, 0x100)) if h else b for b, h in zip(body, hits, strict=True))
        return bytes(body) + P.TERMINATOR

    # ------------------------------------------------------------------------------------------ faults
    def inject(self, fault: str | None, **params: Any) -> None:
        """Start a fault (module docstring), or clear them all with ``None``."""
        if fault is None:
            with self._lock:
                self._faults.clear()
            return
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; expected one of {', '.join(FAULTS)} or None")
        log.info("monochromator emulator: inject %s %s", fault, params)
        if fault == "disconnect":
            self._server.close()
            return
        params = dict(params)
        if params.get("keywords") is not None:
            params["keywords"] = frozenset(str(k).upper() for k in params["keywords"])
            unknown = params["keywords"] - set(P.BY_KEYWORD)
            if unknown:
                raise ValueError(f"{fault}: unknown keywords {sorted(unknown)}")
        if fault == "error":
            params["code"] = P.ErrorCode(int(params.get("code", P.ErrorCode.SYSTEM)))
        with self._lock:
            self._faults[fault] = params

    # ------------------------------------------------------------------------------------------ firmware
    def handle(self, line: bytes) -> bytes:
        """One statement (no terminator) -> what the instrument sends back: the echo, then a query's answer."""
        with self._lock:
            self.statements.append(line)
            echo = line + P.TERMINATOR
            try:
                stmt, value = P.parse_statement(line)
                answer = getattr(self, f"_do_{stmt.name}")(value)
            except P.RequestError as exc:
                log.debug("monochromator emulator: %r refused: %s", line, exc.message)
                self._fail(exc.code)
                return echo
            return echo + (stmt.render_answer(answer) if stmt.is_query else b"")

    def _fail(self, code: P.ErrorCode) -> None:
        self._status = P.STATUS_ERROR
        self._error = int(code)

    @property
    def wavelength_nm(self) -> float:
        with self._lock:
            return self._steps / self.optics.grating(self._grating).steps_per_nm

    def _move(self, nm: float) -> None:
        g = self.optics.grating(self._grating)
        lo, hi = g.range_nm
        if not lo <= nm <= hi:
            raise P.RequestError(P.ErrorCode.DESTINATION_NOT_ALLOWED, f"{nm:g} nm outside {lo:g}-{hi:g} nm")
        before = self.wavelength_nm
        self._steps = int(round(nm * g.steps_per_nm))
        if self.motion_s_per_nm > 0:
            self._busy_until = time.monotonic() + abs(nm - before) * self.motion_s_per_nm
        if self._shutter_open:                   # light of another colour from now on: a new interval
            self._set_shutter(False, "GOWAVE")
            self._set_shutter(True, "")

    def _do_info(self, _value: None) -> str:
        return MODEL_INFO

    def _do_goto(self, nm: float) -> None:
        self._move(nm if self._units == "NM" else _to_nm(nm, self._units))

    def _do_wavelength(self, _value: None) -> float:
        nm = self.wavelength_nm
        return nm if self._units == "NM" else _from_nm(nm, self._units)

    def _do_shutter(self, state: str) -> None:
        self._set_shutter(state == "O", f"SHUTTER {state}")

    def _do_shutter_state(self, _value: None) -> bool:
        return self._shutter_open

    def _do_set_grating(self, number: int) -> None:
        if number not in [g.number for g in self.optics.gratings]:
            raise P.RequestError(P.ErrorCode.BAD_PARAMETER, f"no grating {number}")
        if number == self._grating:
            raise P.RequestError(P.ErrorCode.ALREADY_THERE, f"grating {number} already in place")
        nm = self.wavelength_nm
        self._grating = number
        self._steps = int(round(nm * self.optics.grating(number).steps_per_nm))

    def _do_grating(self, _value: None) -> P.GratingInfo:
        g = self.optics.grating(self._grating)
        return P.GratingInfo(g.number, g.lines_per_mm, g.label)

    def _do_set_filter(self, position: int) -> None:
        if position == self._filter:
            raise P.RequestError(P.ErrorCode.ALREADY_THERE, f"filter {position} already in place")
        self._filter = position

    def _do_filter(self, _value: None) -> int:
        return self._filter

    def _do_set_units(self, units: str) -> None:
        self._units = units

    def _do_units(self, _value: None) -> str:
        return self._units

    def _do_step(self, _value: None) -> int:
        return self._steps

    def _do_status_byte(self, _value: None) -> int:
        status, self._status = self._status, P.STATUS_OK
        return status

    def _do_error(self, _value: None) -> int | None:
        code, self._error = self._error, None
        self._status = P.STATUS_OK
        return code

    # ------------------------------------------------------------------------------------------ the light
    def _set_shutter(self, opened: bool, cause: str) -> None:
        now = self._clock()
        current = self._record[-1] if self._record and self._record[-1].t_close is None else None
        if opened and current is None:
            self._record.append(ShutterInterval(now, None, self.wavelength_nm))
        elif not opened and current is not None:
            current.t_close, current.closed_by = now, cause
        self._shutter_open = opened

    def set_by_hand(self, wavelength_nm: float | None = None, shutter_open: bool | None = None) -> None:
        """A person at the instrument (manual mode): turn the drive, open or close the shutter (no statement)."""
        with self._lock:
            if wavelength_nm is not None:
                self._move(float(wavelength_nm))
            if shutter_open is not None:
                self._set_shutter(bool(shutter_open), "by hand")

    @property
    def shutter_open(self) -> bool:
        with self._lock:
            return self._shutter_open

    @property
    def grating_number(self) -> int:
        with self._lock:
            return self._grating

    @property
    def filter_position(self) -> int:
        with self._lock:
            return self._filter

    def output(self) -> tuple[np.ndarray, np.ndarray]:
        """(wavelengths nm, spectral radiance W sr-1 m-2 nm-1) coming out now: the band at the current wavelength,
        grating and filter; all zero while the shutter is closed."""
        with self._lock:
            nm, grating, position, lit = self.wavelength_nm, self._grating, self._filter, self._shutter_open
        wl, radiance = self.optics.band(nm, grating, position)
        return wl, radiance if lit else np.zeros_like(radiance)

    def shutter_record(self) -> list[ShutterInterval]:
        """Every open period since the emulator was made, oldest first (copies; the last has ``t_close=None``
        while the shutter is open)."""
        with self._lock:
            return [ShutterInterval(i.t_open, i.t_close, i.wavelength_nm, i.closed_by) for i in self._record]

    @property
    def clock(self) -> Callable[[], float]:
        return self._clock


def _to_nm(value: float, units: str) -> float:
    return value * 1000.0 if units == "UM" else 1e7 / value if value else float("inf")


def _from_nm(nm: float, units: str) -> float:
    return nm / 1000.0 if units == "UM" else 1e7 / nm
