"""SphereEmulator: the LED sphere's firmware, speaking drivers/led_sphere/protocol.py on a real serial transport.

``start()`` serves a port from a background thread (drivers.virtual.line_server: a pseudo-terminal on Linux and
macOS, pyserial's ``socket://127.0.0.1:PORT`` on Windows or when ``transport='socket'`` /
``DUALRGB_VIRTUAL_TRANSPORT=socket``); any serial client (the LedSphere driver, pyserial, ``screen`` on a pty) opens
the returned port as if it were /dev/ttyACM0. The emulator keeps the
physical state the virtual camera needs, readable at any time with the thread-safe :meth:`snapshot`:

* levels (16-bit PWM per LED), the master switch, what each LED actually emits now;
* per-LED continuous on-time, and the light dose (emitted level x seconds, artwork exposure);
* temperature, rising with emitted power towards ambient + ``HEAT_C_PER_LED`` per LED at full level
  (first order, ``THERMAL_TAU_S``), over-temperature protection at ``OVER_TEMPERATURE_C``;
* peak-wavelength drift with continuous on-time as measured in thesis 4.3.2 (Fig. 4.10; the model is in
  drivers/virtual/led_physics.py): none during the first 10 s, then growing towards a per-LED maximum reached
  after about an hour (LED 4 ~7 nm, LED 7 none, the others a few nm); LED 10 also fades after ~40 min on and does
  not recover (it "died" in the thesis run). Drift depends on continuous on-time only, not on the level (the
  thesis measured at full level), and starts over when the LED goes dark;
* the watchdog: no request for ``watchdog_s`` -> every LED to 0 and the light off, ``trip`` set;
* the on-time limit of ``ON <ms>`` (firmware 1.1): the light goes off by itself ``ms`` after it came on, whatever
  the host sends meanwhile (``firmware="1.0.0"`` emulates the old firmware that answers ``ON`` with ERR 1);
* a record of every lit period on the emulator's own clock (:meth:`light_record`: when light came on, when it
  went off, the emitted levels and what ended it), for tests that bound how long an object was lit.

Physics is evaluated lazily against the injectable ``clock`` (exact, piecewise-constant levels), so tests can
move a fake clock by an hour instead of sleeping. Wire delays (fault "slow") use real time.

Faults (:meth:`inject`): ``no_reply`` (reply lost; ``execute=False``: firmware hung), ``ignore`` (requests
neither executed nor answered), ``disobey`` (answered as if done, not executed: a stuck relay, a firmware
bug), ``garbled`` (reply bytes corrupted), ``slow`` (reply after ``delay_s``); each of
these five takes ``keywords=("ON", ...)`` to hit only those requests. ``disconnect`` (port closed, as if unplugged;
the sphere keeps its own power, so its watchdog and on-time limit switch the LEDs off), ``led_fail`` (``led=N``,
``mode="dark"``: takes levels but emits nothing, FAULT? reports it while driven; ``mode="error"``: a non-zero
level for it gets ERR 6).
``inject(None)`` clears every fault (except a disconnect: start() again for a new pty).
"""
from __future__ import annotations

import collections
import dataclasses
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import numpy as np

from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.virtual.led_physics import (
    AMBIENT_C,
    FADE_LED,
    HEAT_C_PER_LED,
    MAX_SHIFT_NM,
    OVER_TEMPERATURE_C,
    THERMAL_TAU_S,
    fade_factor,
    peak_shift_nm,
)
from dualrgb.drivers.virtual.transport import line_server

log = logging.getLogger(__name__)

FAULTS = ("no_reply", "ignore", "disobey", "garbled", "slow", "disconnect", "led_fail")
_WIRE_FAULTS = ("no_reply", "ignore", "disobey", "garbled", "slow")   # these take keywords=(...) to pick requests


@dataclass
class LightInterval:
    """One lit period on the emulator's clock: something emitted from ``t_on`` to ``t_off`` (None: still lit)
    at constant ``levels``; ``ended_by`` names what ended it (a request keyword, 'on-time limit', 'watchdog',
    'over-temperature', 'power off', 'fault'). A level change while lit ends one interval and starts the next
    at the same instant."""

    t_on: float
    t_off: float | None
    levels: tuple[float, ...]
    ended_by: str = ""

    @property
    def duration_s(self) -> float | None:
        return None if self.t_off is None else self.t_off - self.t_on


@dataclass(frozen=True)
class SphereSnapshot:
    levels: np.ndarray          # (10,) float 0..1 actually emitted now (0 when master off, LED failed or off)
    on_time_s: np.ndarray       # (10,) seconds each LED has been continuously on
    peak_shift_nm: np.ndarray   # (10,) current peak-wavelength drift per LED (thesis 4.3.2)
    temperature_c: float
    light_on: bool


def _cause_of(line: bytes) -> str:
    """How a request is named in the light record: its keyword ('LIGHT 0' with its state)."""
    tokens = line.decode("ascii", "replace").upper().split()
    return " ".join(tokens[:2] if tokens[:1] == ["LIGHT"] else tokens[:1])


class SphereEmulator:
    """The sphere's firmware on a serial port (a pty or a socket); see the module docstring."""

    model = "DRGB-SPHERE10-EMU"
    serial = "EMU-0001"

    def __init__(self, n_leds: int = 10, watchdog_s: float = 30.0, clock: Callable[[], float] = time.monotonic,
                 firmware: str = P.FIRMWARE_VERSION, transport: str | None = None):
        if P.version_tuple(firmware) == (0,):
            raise ValueError(f"firmware {firmware!r}: expected a version such as 1.1.0")
        self.firmware = firmware
        if not 1 <= n_leds <= P.MAX_CHANNELS:
            raise ValueError(f"n_leds {n_leds} outside 1..{P.MAX_CHANNELS}")
        wd_ms = int(round(watchdog_s * 1000))
        if not P.WATCHDOG_MIN_MS <= wd_ms <= P.WATCHDOG_MAX_MS:
            raise ValueError(f"watchdog {watchdog_s} s outside "
                             f"{P.WATCHDOG_MIN_MS / 1000}..{P.WATCHDOG_MAX_MS / 1000} s")
        self.n_leds = n_leds
        self._clock = clock
        self._lock = threading.RLock()
        self.max_shift_nm = np.resize(MAX_SHIFT_NM, n_leds) if n_leds > 10 else MAX_SHIFT_NM[:n_leds].copy()
        self.ambient_c = AMBIENT_C
        self.over_temperature_c = OVER_TEMPERATURE_C
        # physical state
        self._t = clock()
        self._pwm = np.zeros(n_leds, dtype=np.int64)
        self._light = False
        self._light_since: float | None = None
        self._off_at: float | None = None            # ON <ms>: when the light goes off by itself
        self._record: list[LightInterval] = []
        self._cause = ""
        self._on_time = np.zeros(n_leds)
        self._dose = np.zeros(n_leds)
        self._health = np.ones(n_leds)
        self._temp = self.ambient_c
        self._watchdog_ms = wd_ms
        self._last_rx = self._t
        self._trip = False
        # faults and wire
        self._faults: dict[str, dict[str, Any]] = {}
        self._failed: dict[int, str] = {}
        self._rng = np.random.default_rng(0)
        self._server = line_server("sphere-emulator", self._on_line, max_line=P.MAX_REQUEST_BYTES,
                                   on_tick=self._tick, transport=transport)
        self.requests: collections.deque[bytes] = collections.deque(maxlen=1000)   # recent request lines (log)

    # ------------------------------------------------------------------------------------------ serving
    def start(self) -> str:
        """Serve the port in a background thread; returns what a serial client opens (a pty path or a
        ``socket://`` URL: drivers.virtual.line_server)."""
        if self._server.running:
            return self._server.port
        with self._lock:
            self._advance(self._clock())
            self._last_rx = self._t
        port = self._server.start()
        log.info("sphere emulator serving on %s (watchdog %.1f s)", port, self._watchdog_ms / 1000)
        return port

    @property
    def port(self) -> str:
        return self._server.port

    @property
    def running(self) -> bool:
        return self._server.running

    def stop(self) -> None:
        """Stop serving and close the port; the sphere is powered off (every LED off, light off)."""
        self._server.close()
        with self._lock:
            self._advance(self._clock())
            self._pwm[:] = 0
            self._set_light(False)
            self._settle("power off")

    def __enter__(self) -> SphereEmulator:
        self.start()
        return self

    def __exit__(self, *exc) -> None:
        self.stop()

    def _tick(self) -> None:
        """Every wake-up of the serving thread: the physics runs on (watchdog, on-time limit) without requests."""
        with self._lock:
            self._advance(self._clock())

    def _active_faults(self, line: bytes) -> dict[str, dict[str, Any]]:
        """The wire faults that apply to this request line (those with ``keywords`` only for their keywords)."""
        with self._lock:
            faults = dict(self._faults)
        keyword = line.split(b" ", 1)[0].strip().upper().decode("ascii", "replace")
        return {name: params for name, params in faults.items()
                if params.get("keywords") is None or keyword in params["keywords"]}

    def _on_line(self, line: bytes, too_long: bool = False) -> None:
        faults = self._active_faults(line)
        hung = "ignore" in faults or ("no_reply" in faults and not faults["no_reply"].get("execute", True))
        if hung:
            log.debug("emulator hung: ignoring %r", line)
            return
        if too_long:
            with self._lock:
                self._advance(self._clock())
                self._last_rx = max(self._clock(), self._t)
            reply = P.render_error(P.ErrorCode.LINE_TOO_LONG, f"line longer than {P.MAX_REQUEST_BYTES} bytes")
        elif "disobey" in faults:
            reply = self._acknowledge(line)
        else:
            reply = self.handle(line)
        if "no_reply" in faults:
            return
        if "garbled" in faults:
            reply = self._garble(reply)
        self._respond(reply, float(faults["slow"].get("delay_s", 1.0)) if "slow" in faults else 0.0)

    def _acknowledge(self, line: bytes) -> bytes:
        """The reply ``line`` would get, without doing what it asks (the request still restarts the watchdog)."""
        with self._lock:
            self._advance(self._clock())
            self._last_rx = max(self._clock(), self._t)
            self.requests.append(line)
        try:
            cmd, args = P.parse_request(line)
            return cmd.render_reply(**args)
        except (P.RequestError, KeyError) as exc:       # a query has no echo to fake: answer it truly
            log.debug("emulator: cannot fake a reply to %r (%s)", line, exc)
            return self.handle(line)

    def _garble(self, reply: bytes) -> bytes:
        body = bytearray(reply[:-1] or b"OK")
        hits = self._rng.random(len(body)) < 0.35
        hits[0] = True
        body = bytearray(int(self._rng.integers(0x80, 0x100)) if h else b for b, h in zip(body, hits, strict=True))
        return bytes(body) + b"\n"

    def _respond(self, reply: bytes, delay_s: float = 0.0) -> None:
        self._server.respond(reply, delay_s)

    # ------------------------------------------------------------------------------------------ faults
    def inject(self, fault: str | None, **params: Any) -> None:
        """Start a fault (see the module docstring), or clear them all with ``None``."""
        if fault is None:
            with self._lock:
                self._advance(self._clock())
                self._faults.clear()
                self._failed.clear()
                self._settle("fault cleared")
            log.info("sphere emulator: faults cleared")
            return
        if fault not in FAULTS:
            raise ValueError(f"unknown fault {fault!r}; expected one of {', '.join(FAULTS)} or None")
        log.info("sphere emulator: inject %s %s", fault, params)
        if fault == "disconnect":
            self._server.close()
            return
        if fault == "led_fail":
            led = int(params.get("led", 1))
            mode = params.get("mode", "dark")
            if not 1 <= led <= self.n_leds or mode not in ("dark", "error"):
                raise ValueError(f"led_fail needs led=1..{self.n_leds} and mode='dark' or 'error'")
            with self._lock:
                self._advance(self._clock())
                self._failed[led] = mode
                self._settle("fault")
            return
        if fault == "slow" and float(params.get("delay_s", 1.0)) <= 0:
            raise ValueError("slow needs delay_s > 0")
        params = dict(params)
        if params.get("keywords") is not None:
            params["keywords"] = frozenset(str(k).upper() for k in params["keywords"])
            unknown = params["keywords"] - set(P.BY_KEYWORD)
            if unknown:
                raise ValueError(f"{fault}: unknown keywords {sorted(unknown)}")
        with self._lock:
            self._faults[fault] = params

    # ------------------------------------------------------------------------------------------ physics
    def _emitting(self) -> np.ndarray:
        on = (self._pwm > 0) & self._light
        for led, _mode in self._failed.items():
            on[led - 1] = False
        return on

    def _emitted(self) -> np.ndarray:
        return np.where(self._emitting(), self._pwm / P.PWM_MAX * self._health, 0.0)

    def _settle(self, cause: str = "") -> None:
        """After a state change (at clock time ``self._t``): LEDs that stopped emitting have no continuous on-time
        any more, and the light record follows what is emitted now."""
        self._on_time[~self._emitting()] = 0.0
        self._record_light(cause or self._cause)

    def _record_light(self, cause: str) -> None:
        emitting = self._emitting()
        levels = tuple(float(p) / P.PWM_MAX if on else 0.0 for p, on in zip(self._pwm, emitting, strict=True))
        current = self._record[-1] if self._record and self._record[-1].t_off is None else None
        if current is not None and current.levels == levels:
            return
        if current is not None:
            current.t_off = self._t
            current.ended_by = "levels changed" if any(levels) else cause
        if any(levels):
            self._record.append(LightInterval(self._t, None, levels))

    def _advance(self, now: float) -> None:
        """Bring the physical state to clock time ``now`` (watchdog trip and on-time limit at their exact moment)."""
        if now <= self._t:
            return
        while True:
            due = []
            if self._light or self._pwm.any():
                due.append((self._last_rx + self._watchdog_ms / 1000, self._trip_watchdog))
            if self._light and self._off_at is not None:
                due.append((self._off_at, self._limit_reached))
            due = [d for d in due if d[0] < now]
            if not due:
                break
            at, event = min(due, key=lambda d: d[0])
            if at > self._t:
                self._integrate(at)
            event()
        self._integrate(now)
        if self._light and self._temp > self.over_temperature_c:
            log.warning("sphere emulator: over temperature (%.1f C): light off", self._temp)
            self._set_light(False)
            self._settle("over-temperature")

    def _limit_reached(self) -> None:
        log.warning("sphere emulator: on-time limit reached: light off")
        self._set_light(False)
        self._trip = True
        self._settle("on-time limit")

    def _integrate(self, t1: float) -> None:
        dt = t1 - self._t
        emitted = self._emitted()
        on = self._emitting()
        self._dose += emitted * dt
        self._on_time = np.where(on, self._on_time + dt, 0.0)
        if FADE_LED <= self.n_leds and on[FADE_LED - 1]:
            i = FADE_LED - 1
            self._health[i] = min(self._health[i], fade_factor(self._on_time[i]))
        target = self.ambient_c + HEAT_C_PER_LED * float(emitted.sum())
        self._temp = target + (self._temp - target) * math.exp(-dt / THERMAL_TAU_S)
        self._t = t1

    def _trip_watchdog(self) -> None:
        log.warning("sphere emulator: watchdog (%.1f s without a request): all LEDs off", self._watchdog_ms / 1000)
        self._pwm[:] = 0
        self._set_light(False)
        self._trip = True
        self._settle("watchdog")

    def _set_light(self, on: bool) -> None:
        if on and not self._light:
            self._light_since = self._t
        if not on:
            self._light_since = None
            self._off_at = None
        self._light = on

    def _fault_mask(self) -> int:
        mask = 0
        for led in self._failed:            # current sensing: only a driven channel can show its fault
            if self._light and self._pwm[led - 1] > 0:
                mask |= 1 << (led - 1)
        return mask

    # ------------------------------------------------------------------------------------------ views
    def snapshot(self) -> SphereSnapshot:
        """What the sphere physically does right now (thread-safe; the virtual camera reads this)."""
        with self._lock:
            self._advance(self._clock())
            return SphereSnapshot(levels=self._emitted(), on_time_s=self._on_time.copy(),
                                  peak_shift_nm=peak_shift_nm(self._on_time, self.max_shift_nm),
                                  temperature_c=float(self._temp), light_on=bool(self._light))

    def light_dose(self) -> np.ndarray:
        """(n_leds,) emitted level x seconds per LED since the emulator was made (artwork light exposure)."""
        with self._lock:
            self._advance(self._clock())
            return self._dose.copy()

    def output_health(self) -> np.ndarray:
        """(n_leds,) permanent output factor per LED (1 = as new; LED 10 fades after long on-time)."""
        with self._lock:
            return self._health.copy()

    def commanded_levels(self) -> np.ndarray:
        """(n_leds,) levels as set by the host (PWM / 65535), whatever the master switch and faults."""
        with self._lock:
            self._advance(self._clock())
            return self._pwm / P.PWM_MAX

    def light_record(self) -> list[LightInterval]:
        """Every lit period since the emulator was made, oldest first, on its own clock (copies; the last one
        has ``t_off=None`` while the sphere is lit)."""
        with self._lock:
            self._advance(self._clock())
            return [dataclasses.replace(i) for i in self._record]

    @property
    def clock(self) -> Callable[[], float]:
        """The emulator's clock (light_record times; the virtual camera can share it)."""
        return self._clock

    @property
    def watchdog_s(self) -> float:
        return self._watchdog_ms / 1000

    @property
    def watchdog_tripped(self) -> bool:
        with self._lock:
            self._advance(self._clock())
            return self._trip

    # ------------------------------------------------------------------------------------------ firmware
    def handle(self, line: bytes) -> bytes:
        """One request line (no terminator) -> one reply line; the firmware's command interpreter."""
        with self._lock:
            now = self._clock()
            self._advance(now)
            self._last_rx = max(now, self._t)
            self.requests.append(line)
            try:
                cmd, args = P.parse_request(line)
                if not P.supports(cmd, self.firmware):
                    raise P.RequestError(P.ErrorCode.UNKNOWN_COMMAND, f"unknown command {cmd.keyword}")
                values = getattr(self, f"_cmd_{cmd.name}")(**args)
            except P.RequestError as exc:
                log.debug("emulator: %r -> ERR %d %s", line, exc.code, exc.message)
                return P.render_error(exc.code, exc.message)
            self._settle(_cause_of(line))
            return cmd.render_reply(**(values or {}))

    def _led(self, led: int) -> int:
        if led > self.n_leds:
            raise P.RequestError(P.ErrorCode.OUT_OF_RANGE, f"led outside 1..{self.n_leds}")
        return led - 1

    def _refuse_failed(self, pwms: dict[int, int]) -> None:
        for led, pwm in pwms.items():
            if pwm > 0 and self._failed.get(led) == "error":
                raise P.RequestError(P.ErrorCode.LED_FAULT, f"LED {led} driver fault")

    def _cmd_identify(self) -> dict:
        return {"model": self.model, "firmware": self.firmware, "serial": self.serial}

    def _cmd_channels(self) -> dict:
        return {"count": self.n_leds}

    def _cmd_set_level(self, led: int, pwm: int) -> dict:
        i = self._led(led)
        self._refuse_failed({led: pwm})
        self._pwm[i] = pwm
        return {"led": led, "pwm": pwm}

    def _cmd_get_level(self, led: int) -> dict:
        return {"led": led, "pwm": int(self._pwm[self._led(led)])}

    def _cmd_set_levels(self, pwms: tuple[int, ...]) -> dict:
        if len(pwms) != self.n_leds:
            raise P.RequestError(P.ErrorCode.ARGUMENT_COUNT, f"LEVELS takes exactly {self.n_leds} values")
        self._refuse_failed({i + 1: p for i, p in enumerate(pwms)})
        self._pwm[:] = pwms
        return {"pwms": pwms}

    def _cmd_get_levels(self) -> dict:
        return {"pwms": tuple(int(p) for p in self._pwm)}

    def _cmd_all_off(self) -> None:
        self._pwm[:] = 0

    def _cmd_set_light(self, state: int) -> dict:
        if state and self._temp > self.over_temperature_c:
            raise P.RequestError(P.ErrorCode.OVER_TEMPERATURE, f"temperature {self._temp:.1f} C, light stays off")
        if state:
            self._trip = False
        self._set_light(bool(state))
        return {"state": state}

    def _cmd_light_on_for(self, ms: int) -> dict:
        self._cmd_set_light(1)
        assert self._light_since is not None                  # on since now, or since earlier
        self._off_at = self._light_since + ms / 1000         # counted from when it came on: never extended
        return {"ms": ms}

    def _cmd_get_light(self) -> dict:
        return {"state": int(self._light)}

    def _cmd_temperature(self) -> dict:
        return {"celsius": round(self._temp, 2)}

    def _light_on_time(self) -> float:
        return 0.0 if self._light_since is None else self._t - self._light_since

    def _cmd_on_time(self) -> dict:
        return {"seconds": self._light_on_time()}

    def _cmd_led_on_time(self, led: int) -> dict:
        return {"led": led, "seconds": float(self._on_time[self._led(led)])}

    def _cmd_set_watchdog(self, ms: int) -> dict:
        self._watchdog_ms = ms
        return {"ms": ms}

    def _cmd_get_watchdog(self) -> dict:
        return {"ms": self._watchdog_ms}

    def _cmd_ping(self) -> None:
        return None

    def _cmd_faults(self) -> dict:
        return {"mask": self._fault_mask()}

    def _cmd_status(self) -> dict:
        return {"light": int(self._light), "ontime": self._light_on_time(), "temp": round(self._temp, 2),
                "wdog": self._watchdog_ms, "trip": int(self._trip), "fault": self._fault_mask()}
