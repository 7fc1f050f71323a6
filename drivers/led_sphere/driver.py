"""LedSphere: the host side of the 10-LED integrating sphere over a serial port (pyserial).

Every exchange is one request line and one reply line (drivers/led_sphere/protocol.py), bounded by ``timeout``;
a request that gets no matching reply in time is sent once more (every command is idempotent: it sets absolute
values), then :class:`SphereError` is raised. Replies to an earlier request that arrive late are recognised by
their keyword/echo and skipped. Anything else that goes wrong is a :class:`SphereError` too, with a one-line
message saying what happened and what to do.

Safety (artworks under the light): every lit period has a limit (``max_on_s``, default 10 s). ``on()`` sends it
with the switch-on (``ON <ms>``: the firmware switches off by itself at the limit, even if this host dies) and
arms an :class:`~drivers.led_sphere.supervisor.OnTimeSupervisor` that switches the light off at the limit from its
own thread, whatever the caller is doing. One lock serialises the port between threads, and every wait for it
is bounded. Used as a context manager the sphere is left with every LED at 0 and the light off on exit, also
when an exception leaves the block (``close()`` switches off too). :meth:`LedSphere.ensure_off` switches off,
reads the state back and says truthfully what is known afterwards (off, or unknown and what the firmware
guarantees); it never raises (drivers/led_sphere/switch_off.py).
Firmware 1.0 answers ``ON`` with ``ERR 1``: the driver then sets the watchdog to the limit before ``LIGHT 1``.
"""
from __future__ import annotations

import logging
import math
import threading
import time
from collections.abc import Iterable
from typing import Any

import serial

from dualrgb.drivers.led_sphere import open_spheres
from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.led_sphere.errors import SphereError
from dualrgb.drivers.led_sphere.limits import DEFAULT_MAX_ON_S, DEFAULT_TIMEOUT_S, MAX_ON_RANGE_S
from dualrgb.drivers.led_sphere.supervisor import LitPeriod, OnTimeSupervisor
from dualrgb.drivers.led_sphere.switch_off import SwitchOff
from dualrgb.simulation.lightsource import N_SPHERE_LEDS, LightSource

log = logging.getLogger(__name__)

_TERMIOS_ERRORS: tuple[type[Exception], ...]
try:                                    # pyserial's POSIX backend lets termios.error (not an OSError) through
    from termios import error as _termios_error
    _TERMIOS_ERRORS = (_termios_error,)
except ImportError:                     # pragma: no cover - Windows
    _TERMIOS_ERRORS = ()

_IO_ERRORS: tuple[type[Exception], ...] = (serial.SerialException, OSError, *_TERMIOS_ERRORS)
_MAX_LINES_PER_ATTEMPT = 8     # stale replies skipped per attempt before giving up (a chattering line)


class LedSphere(SwitchOff):
    """The LED sphere on ``port``: a pyserial URL (``/dev/ttyUSB0``, a pty path, ``loop://``) or an already
    open serial-like object (``write``, ``read_until``; optional ``reset_input_buffer``, ``flush``, ``close``).

    >>> with LedSphere("/dev/ttyACM0") as sphere:          # doctest: +SKIP
    ...     sphere.apply(LightSource((1, 6, 8)))
    ...     sphere.on()
    ...     ...                                             # capture
    # every LED off and the light off here, whatever happened in the block
    """

    def __init__(self, port: Any, timeout: float = DEFAULT_TIMEOUT_S, channels: int = N_SPHERE_LEDS,
                 clock=time.monotonic):
        self._timeout = DEFAULT_TIMEOUT_S
        self._ser: Any = None                # not yet: the timeout setter configures an open port
        self._io_errors = _IO_ERRORS
        self.timeout = timeout
        self.channels = int(channels)
        self._clock = clock
        self._lock = threading.RLock()
        self._owns_port = isinstance(port, str)
        self._url = port if isinstance(port, str) else getattr(port, "port", None) or type(port).__name__
        self._ser = None if isinstance(port, str) else port     # a name: opened by open()
        self._light_on_since: float | None = None
        self._last_exchange: float | None = None
        self._max_on_s = DEFAULT_MAX_ON_S
        self._answered: bool | None = None   # did the port answer like a sphere? (None: not asked yet)
        self._device_limit: bool | None = None   # ON <ms> works (True), firmware 1.0 (False), not tried (None)
        self._watchdog_ms = P.DEFAULT_WATCHDOG_MS   # as far as this host knows
        self._supervisor = OnTimeSupervisor(self._switch_off_at_limit, name=f"LED sphere {self._url} on-time limit")
        if self._ser is not None:
            self._configure(self._ser)
            open_spheres.register(self)

    # ------------------------------------------------------------------------------------------- port
    @property
    def timeout(self) -> float:
        """Seconds to wait for each reply (and for each write); a timed-out request is sent once more."""
        return self._timeout

    @timeout.setter
    def timeout(self, seconds: float) -> None:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) \
                or seconds <= 0:
            raise SphereError(f"timeout {seconds!r} must be a positive number of seconds", kind="argument")
        self._timeout = float(seconds)
        if self._ser is not None:
            self._configure(self._ser)

    @property
    def max_on_s(self) -> float:
        """The default limit of a lit period (``on()`` without ``max_on_s``), 0.1..3600 s."""
        return self._max_on_s

    @max_on_s.setter
    def max_on_s(self, seconds: float) -> None:
        self._max_on_s = self._check_limit(seconds)

    @staticmethod
    def _check_limit(seconds: Any) -> float:
        lo, hi = MAX_ON_RANGE_S
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) \
                or not lo <= seconds <= hi:
            raise SphereError(f"light-on limit {seconds!r} s is outside {lo:g}..{hi:g} s", kind="argument")
        return float(seconds)

    def _lock_wait_s(self) -> float:
        """How long a request waits for the port while another thread's exchange finishes (two attempts)."""
        return 2.5 * self.timeout + 0.5

    @property
    def port(self) -> str:
        return str(self._url)

    @property
    def is_open(self) -> bool:
        return self._ser is not None

    def open(self) -> LedSphere:
        """Open the serial port (a no-op for an object passed in already open)."""
        if self._ser is None:
            try:
                self._ser = serial.serial_for_url(
                    self._url, baudrate=P.BAUDRATE, bytesize=P.BYTESIZE, parity=P.PARITY, stopbits=P.STOPBITS,
                    timeout=self.timeout, write_timeout=self.timeout)
            except (serial.SerialException, OSError, ValueError) as exc:
                raise SphereError(f"cannot open LED sphere port {self._url}: {exc}; check the cable and the "
                                  "port name (ls /dev/ttyACM* /dev/ttyUSB*) and that no other program uses it; "
                                  "nothing was sent, so the light's state is unknown (a lit sphere switches off "
                                  "by itself at its on-time limit, or when its watchdog hears no request)",
                                  kind="port", light="unknown") from None
            self._configure(self._ser)
            log.info("opened LED sphere port %s", self._url)
        open_spheres.register(self)             # what a signal switches off (app.interrupts)
        return self

    def _configure(self, ser: Any) -> None:
        for name in ("timeout", "write_timeout"):
            if hasattr(ser, name):
                try:
                    setattr(ser, name, self.timeout)
                except (AttributeError, ValueError, serial.SerialException):
                    log.debug("could not set %s on %r", name, ser)

    def close(self, leave_on: bool = False) -> None:
        """Switch every LED and the light off (best effort: :meth:`ensure_off`, what it could not confirm is
        logged), then close the port (only if this object opened it). ``leave_on=True`` closes without switching
        off (the command line's ``set``/``on``, whose effect must outlast the process; a lit sphere still goes
        off at its on-time limit)."""
        if self._ser is not None and not leave_on:
            report = self.ensure_off()
            if not report.off or report.error is not None:
                log.warning("closing LED sphere %s: %s", self._url, report.message)
        self._supervisor.stop()
        ser, self._ser = self._ser, None
        open_spheres.unregister(self)
        if ser is not None and self._owns_port:
            try:
                ser.close()
            except _IO_ERRORS as exc:
                log.warning("closing %s: %s", self._url, exc)

    def __enter__(self) -> LedSphere:
        return self.open()

    def __exit__(self, exc_type, exc, tb) -> None:
        try:
            report = self.ensure_off()
            if report.error is not None:
                if exc is None:
                    raise SphereError(report.message, kind=report.error.kind, code=report.error.code,
                                      light="off" if report.off else "unknown")
                log.error("after an error, the LED sphere: %s", report.message)
                exc.add_note(f"and the LED sphere could not be switched off completely: {report.message}")
        finally:
            self.close(leave_on=True)           # ensure_off() was just tried

    # ------------------------------------------------------------------------------------------- exchanges
    def exchange(self, name: str, **args: Any) -> Any:
        """Send command ``name`` of protocol.TABLE with ``args`` (wire units); return its reply's value."""
        cmd = P.COMMANDS[name]
        try:
            request = cmd.encode(**args)
        except (ValueError, TypeError) as exc:
            raise SphereError(f"invalid {name} request: {exc}", kind="argument") from None
        if not self._lock.acquire(timeout=self._lock_wait_s()):
            raise SphereError(f"LED sphere {self._url}: the port stayed busy with another request for "
                              f"{self._lock_wait_s():.1f} s; {cmd.keyword} was not sent", kind="timeout")
        try:
            return self._exchange_locked(cmd, args, request)
        except SphereError as exc:
            if exc.kind in ("timeout", "garbled") and self._answered is None:
                self._answered = False          # asked, and nothing on this port answered like a sphere
            raise
        finally:
            self._lock.release()

    def _exchange_locked(self, cmd: P.Command, args: dict, request: bytes) -> Any:
        if self._ser is None:
            raise SphereError(f"LED sphere port {self._url} is not open; use 'with LedSphere(port) as s:' "
                              "or call open()", kind="port")
        shown = request.decode("ascii").strip()
        skipped: list[str] = []
        for attempt in (1, 2):
            self._send(request, shown)
            try:
                fields = self._receive(cmd, args, shown, skipped)
            except TimeoutError:
                log.info("LED sphere %s: no reply to %r within %.2f s (attempt %d)",
                     self._url, shown, self.timeout, attempt)
                continue
            self._last_exchange = self._clock()
            return cmd.value(fields)
        extra = f"; skipped unrelated replies {', '.join(skipped[:2])}" if skipped else ""
        raise SphereError(f"LED sphere {self._url}: no reply to {shown!r} within {self.timeout:.2f} s "
                          f"(sent twice){extra}; check that the sphere is powered and connected and that "
                          "the port is the sphere's", kind="timeout")

    def _send(self, request: bytes, shown: str) -> None:
        ser = self._ser
        try:
            reset = getattr(ser, "reset_input_buffer", None)
            if reset is not None:
                reset()             # drop late replies to earlier requests
            ser.write(request)
            flush = getattr(ser, "flush", None)
            if flush is not None:
                flush()
        except serial.SerialTimeoutException:
            raise SphereError(f"LED sphere {self._url}: could not send {shown!r} within {self.timeout:.2f} s; "
                              "check the cable and that the sphere is powered", kind="timeout") from None
        except _IO_ERRORS as exc:
            raise SphereError(f"LED sphere {self._url} disconnected while sending {shown!r} ({exc}); reconnect "
                              "it (the sphere's watchdog switches the LEDs off)", kind="disconnected") from None
        log.debug("-> %r", request)

    def _receive(self, cmd: P.Command, args: dict, shown: str, skipped: list[str]) -> dict:
        """Read lines until the reply to ``cmd``; TimeoutError when none arrives before the deadline."""
        deadline = time.monotonic() + self.timeout
        for _ in range(_MAX_LINES_PER_ATTEMPT):
            if time.monotonic() >= deadline:
                break
            try:
                line = self._ser.read_until(P.TERMINATOR, P.MAX_REPLY_BYTES)
            except _IO_ERRORS as exc:
                raise SphereError(f"LED sphere {self._url} disconnected while waiting for the reply to {shown!r} "
                                  f"({exc}); reconnect it (the sphere's watchdog switches the LEDs off)",
                                  kind="disconnected") from None
            line = bytes(line or b"")
            log.debug("<- %r", line)
            if not line.endswith(P.TERMINATOR):
                if len(line) >= P.MAX_REPLY_BYTES:
                    raise SphereError(f"LED sphere {self._url}: overlong reply {P._show(line)} to {shown!r}; "
                                      "check baud rate 115200 and that the port is the sphere's", kind="garbled")
                if line:
                    skipped.append(P._show(line))      # a fragment: the rest never came in time
                raise TimeoutError
            try:
                fields = cmd.decode(line, args)
                self._answered = True
                return fields
            except P.StaleReply as exc:
                self._answered = True
                log.info("LED sphere %s: skipping late reply (%s)", self._url, exc)
                skipped.append(P._show(line))
                continue
            except P.DeviceReply as exc:
                self._answered = True
                try:
                    advice = P.ERROR_ADVICE[P.ErrorCode(exc.code)]
                except ValueError:
                    advice = "unknown error code; check the firmware version (identify)"
                raise SphereError(f"LED sphere {self._url} refused {shown!r}: {exc.message} (error {exc.code}); "
                                  f"{advice}", kind="device", code=exc.code) from None
            except P.ReplyError as exc:
                raise SphereError(f"LED sphere {self._url}: garbled answer to {shown!r}: {exc}; check baud rate "
                                  "115200, the cable, and that no other program uses the port",
                                  kind="garbled") from None
        raise TimeoutError

    # ------------------------------------------------------------------------------------------- validation
    def _check_led(self, led: Any) -> int:
        if isinstance(led, bool) or not isinstance(led, (int, float)) or not float(led).is_integer() \
                or not 1 <= led <= self.channels:
            raise SphereError(f"LED {led!r} does not exist: use 1..{self.channels}", kind="argument")
        return int(led)

    @staticmethod
    def _check_level(level: Any, what: str = "level") -> float:
        try:
            value = float(level)
        except (TypeError, ValueError):
            raise SphereError(f"{what} {level!r} is not a number: use 0..1", kind="argument") from None
        if isinstance(level, bool) or not math.isfinite(value) or not 0.0 <= value <= 1.0:
            raise SphereError(f"{what} {level!r} is outside 0..1", kind="argument")
        return value

    # ------------------------------------------------------------------------------------------- commands
    def identify(self) -> dict[str, str]:
        """{'model', 'firmware', 'serial'}."""
        return self.exchange("identify")

    def channel_count(self) -> int:
        return self.exchange("channels")

    def set_level(self, led: int, level: float) -> float:
        """One LED's level 0..1 (sent as 16-bit PWM); returns the level the sphere took (PWM-quantised)."""
        led = self._check_led(led)
        pwm = P.level_to_pwm(self._check_level(level, f"LED {led} level"))
        return P.pwm_to_level(self.exchange("set_level", led=led, pwm=pwm))

    def level(self, led: int) -> float:
        return P.pwm_to_level(self.exchange("get_level", led=self._check_led(led)))

    def set_levels(self, levels: Iterable[float]) -> list[float]:
        """Every channel's level in one exchange (``channels`` values, LED 1 first); returns what was taken."""
        levels = list(levels)
        if len(levels) != self.channels:
            raise SphereError(f"{len(levels)} levels given, the sphere has {self.channels} LEDs", kind="argument")
        pwms = tuple(P.level_to_pwm(self._check_level(v, f"LED {i} level")) for i, v in enumerate(levels, 1))
        taken = self.exchange("set_levels", pwms=pwms)
        if self._light_on_since is not None:
            self._check_faults()
        return [P.pwm_to_level(p) for p in taken]

    def levels(self) -> list[float]:
        return [P.pwm_to_level(p) for p in self.exchange("get_levels")]

    def apply(self, light: LightSource) -> list[float]:
        """Set all channels to ``light`` in one exchange (LEDs not in it to 0); the light switch is unchanged."""
        if not isinstance(light, LightSource):
            raise SphereError(f"apply() takes a LightSource, not {type(light).__name__}", kind="argument")
        taken = self.set_levels(light.weights(self.channels))
        log.info("LED sphere %s: applied %s", self._url, light.label())
        return taken

    def all_off(self) -> None:
        """Every LED's level to 0 (the light switch is unchanged)."""
        self.exchange("all_off")

    def on(self, max_on_s: float | None = None) -> LitPeriod:
        """Light on (master enable) for at most ``max_on_s`` seconds (default :attr:`max_on_s`); then checks that
        no driven LED reports a fault.

        The limit is enforced twice, independently of the caller: the firmware switches off by itself
        (``ON <ms>``; firmware 1.0: the watchdog set to the limit, which requests restart) and this driver's
        supervisor thread switches off at the deadline. Switching on again before the light was confirmed off
        never extends the lit period. Returns the :class:`LitPeriod` (mark the exposure done with
        :meth:`exposure_done`). On failure the light is switched off and the SphereError says in what state it
        is (``.light``; ``.period`` is the lit period, for the light dose)."""
        limit = self._check_limit(self._max_on_s if max_on_s is None else max_on_s)
        period = self._supervisor.arm(limit)      # before sending: the sphere may obey a request whose reply is lost
        try:
            try:
                self._switch_on(limit, period)
            finally:
                period.switched_at = time.monotonic()
            if self._light_on_since is None:
                self._light_on_since = self._clock()
            self._check_faults()
        except SphereError as exc:
            raise self._failed_on(exc, period) from None
        return period

    def _switch_on(self, limit_s: float, period: LitPeriod) -> None:
        ms = min(max(int(math.ceil(limit_s * 1000)), P.ON_LIMIT_MIN_MS), P.ON_LIMIT_MAX_MS)
        if self._device_limit is not False:
            try:
                self.exchange("light_on_for", ms=ms)
                self._device_limit = period.device_limit = True
                return
            except SphereError as exc:
                if exc.kind != "device" or exc.code != P.ErrorCode.UNKNOWN_COMMAND:
                    raise
            self._device_limit = False
            log.warning("LED sphere %s: the firmware does not know ON <ms> (before %s): the watchdog, set to the "
                        "light-on limit, is the sphere's own backstop", self._url, P.COMMANDS["light_on_for"].since)
        wd_ms = min(max(ms, P.WATCHDOG_MIN_MS), P.WATCHDOG_MAX_MS)
        self._watchdog_ms = self.exchange("set_watchdog", ms=wd_ms)
        self.exchange("set_light", state=1)

    def _failed_on(self, exc: SphereError, period: LitPeriod) -> SphereError:
        if exc.light is None:
            report = self.ensure_off()
            exc = SphereError(f"{exc}; {report.message}", kind=exc.kind, code=exc.code,
                              light="off" if report.off else "unknown")
        exc.period = period
        return exc

    def exposure_done(self, period: LitPeriod) -> bool:
        """Mark the exposure of a lit period finished; False when its limit had already switched the light off
        (the frame was not lit all through)."""
        return self._supervisor.exposure_done(period)

    def tripped(self) -> bool:
        """Whether the sphere switched its light off by itself - its ``ON <ms>`` limit or its watchdog - since the
        light was last switched on (``STATUS?``'s ``trip``, cleared by every switch-on); one exchange."""
        asked = time.monotonic()
        s = self.exchange("status")
        if not s["light"]:
            self._confirmed_off(asked)
        return bool(s["trip"])

    @property
    def lit_period(self) -> LitPeriod | None:
        """The lit period not yet confirmed off, if any (its deadline: when the light goes off at the latest)."""
        return self._supervisor.current()

    def light_on(self) -> bool:
        asked = time.monotonic()
        lit = bool(self.exchange("get_light"))
        if not lit:
            self._confirmed_off(asked)
        return lit

    def _check_faults(self) -> None:
        mask = self.exchange("faults")
        if mask:
            leds = [i + 1 for i in range(P.MAX_CHANNELS) if mask >> i & 1]
            report = self.ensure_off()
            raise SphereError(f"LED sphere {self._url}: LED {', '.join(map(str, leds))} reports a fault (open "
                              f"circuit / driver) and emits nothing; {report.message}; check the LED's "
                              "connector and driver, or use a preset without it", kind="fault",
                              light="off" if report.off else "unknown")

    def faulty_leds(self) -> list[int]:
        mask = self.exchange("faults")
        return [i + 1 for i in range(P.MAX_CHANNELS) if mask >> i & 1]

    def temperature_c(self) -> float:
        return float(self.exchange("temperature"))

    def on_time_s(self) -> float:
        """Seconds since this driver switched the light on (host clock); 0.0 while off."""
        return 0.0 if self._light_on_since is None else max(0.0, self._clock() - self._light_on_since)

    def device_on_time_s(self) -> float:
        """Seconds since the light was switched on, as the sphere counts them (0.0 while off)."""
        return float(self.exchange("on_time"))

    def led_on_time_s(self, led: int) -> float:
        """Seconds the LED has been emitting continuously, as the sphere counts them (thesis 4.3.2: the
        peak wavelength does not drift in the first 10 s)."""
        return float(self.exchange("led_on_time", led=self._check_led(led)))

    def keepalive(self) -> None:
        """Restart the sphere's watchdog (any request does; this one does nothing else)."""
        self.exchange("ping")

    def set_watchdog(self, seconds: float) -> float:
        if isinstance(seconds, bool) or not isinstance(seconds, (int, float)) or not math.isfinite(seconds) \
                or not P.WATCHDOG_MIN_MS <= seconds * 1000 <= P.WATCHDOG_MAX_MS:
            raise SphereError(f"watchdog {seconds!r} s is outside {P.WATCHDOG_MIN_MS / 1000:g}.."
                              f"{P.WATCHDOG_MAX_MS / 1000:g} s", kind="argument")
        self._watchdog_ms = self.exchange("set_watchdog", ms=int(round(seconds * 1000)))
        return self._watchdog_ms / 1000

    def watchdog_s(self) -> float:
        self._watchdog_ms = self.exchange("get_watchdog")
        return self._watchdog_ms / 1000

    @property
    def seconds_since_last_exchange(self) -> float | None:
        return None if self._last_exchange is None else self._clock() - self._last_exchange

    def status(self, adopt: bool = True) -> dict[str, Any]:
        """Light, levels, temperature, on-times (host: None when this object did not switch the light on; device),
        watchdog, trip flag, faulty LEDs (2 exchanges), and when a lit period ends at the latest: ``off_in_s`` and
        what ends it, ``off_by`` ("limit": this object's on-time limit, held by its supervisor and the limit sent
        with ON; "watchdog": the sphere's watchdog, that long after this request, sooner if whoever switched it on
        set a shorter limit; None while off).

        ``adopt``: a light found on that this object did not switch on gets this object's limit (its supervisor
        switches it off then: only true while this object stays open; a one-shot command passes False)."""
        asked = time.monotonic()
        s = self.exchange("status")
        self._watchdog_ms = s["wdog"]
        if not s["light"]:
            self._confirmed_off(asked)
        elif adopt and self._supervisor.adopt(s["ontime"], self._max_on_s, asked) is not None:
            # lit, but not by this host (another program, a restart): the limit applies to it too
            log.warning("LED sphere %s is lit (%.1f s) and this program did not switch it on: it goes off at the "
                        "%g s limit", self._url, s["ontime"], self._max_on_s)
        period = self._supervisor.current() if s["light"] else None
        levels = self.levels()              # this request restarts the watchdog: its bound counts from here
        off_by = None if not s["light"] else "limit" if period is not None else "watchdog"
        off_in_s = (None if off_by is None else s["wdog"] / 1000 if period is None
                    else max(0.0, period.deadline - time.monotonic()))
        return {
            "port": self.port,
            "light_on": bool(s["light"]),
            "levels": levels,
            "temperature_c": s["temp"],
            # None: the light was switched on by someone else (another process), the host has no start time
            "on_time_s": None if self._light_on_since is None else self.on_time_s(),
            "device_on_time_s": s["ontime"],
            "watchdog_s": s["wdog"] / 1000,
            "watchdog_tripped": bool(s["trip"]),
            "faulty_leds": [i + 1 for i in range(P.MAX_CHANNELS) if s["fault"] >> i & 1],
            "off_in_s": off_in_s,           # seconds until it goes off at the latest (None while off)
            "off_by": off_by,
            "max_on_s": None if period is None else period.max_on_s,
        }
