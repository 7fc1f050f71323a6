"""Switching the LED sphere off and saying truthfully what is known afterwards (a mixin of
:class:`drivers.led_sphere.driver.LedSphere`, kept apart so that each module reads at once).

Every switch-off is read back: after ``LIGHT 0`` (and ``ALLOFF``) answered, ``LIGHT?`` (and, when the switch still
reads on, ``LEVELS?``) must say that nothing emits. A sphere that acknowledges a switch-off but does not carry it
out (a stuck relay, a firmware bug) is therefore reported as "the sphere did not confirm it is off", never as off.
"""
from __future__ import annotations

import logging
import threading
import time
from typing import Any

from dualrgb.drivers.led_sphere import protocol as P
from dualrgb.drivers.led_sphere.errors import LightReport, SphereError
from dualrgb.drivers.led_sphere.supervisor import OnTimeSupervisor

log = logging.getLogger(__name__)

NOT_CONFIRMED = "the sphere did not confirm it is off"


class SwitchOff:
    """Shutdown, ensure_off, off and their read-back; the attributes are LedSphere's."""

    _ser: Any
    _url: Any
    _lock: threading.RLock
    _answered: bool | None
    _light_on_since: float | None
    _device_limit: bool | None
    _watchdog_ms: int
    _supervisor: OnTimeSupervisor
    _io_errors: tuple[type[Exception], ...]

    def exchange(self, name: str, **args: Any) -> Any:      # LedSphere's
        raise NotImplementedError

    def _lock_wait_s(self) -> float:                       # LedSphere's
        raise NotImplementedError

    def shutdown(self) -> None:
        """Every LED to 0, then the light off, read back. Tries both even if the first fails; raises the first
        error (or the read-back's refusal), its message saying truthfully what state the light is in."""
        report = self._switch_off()
        if report.error is not None:
            raise SphereError(report.message, kind=report.error.kind, code=report.error.code,
                              light="off" if report.off else "unknown")

    def ensure_off(self) -> LightReport:
        """Switch every LED and the light off and say what is known afterwards (read back); never raises.

        On a port that has never answered like a sphere (silent, or speaking garbage), ALLOFF and LIGHT 0 are
        written without waiting for replies that would not come (so a wrong port is reported within one request's
        two timeouts)."""
        if self._ser is None:
            return LightReport(False, f"the LED sphere port {self._url} is closed, so the light's state is unknown; "
                                      f"{self._guarantee()}")
        if self._answered is False:
            sent = self._send_blind(("all_off", {}), ("set_light", {"state": 0}))
            what = "ALLOFF and LIGHT 0 were sent without waiting for replies" if sent else \
                "ALLOFF and LIGHT 0 could not even be sent"
            return LightReport(False, f"the port never answered like an LED sphere, so the light's state is "
                                      f"unknown ({what}); {self._guarantee()}")
        return self._switch_off()

    def off(self) -> None:
        """Light off (master enable; levels are kept), read back: SphereError (kind 'unconfirmed') when the sphere
        answered but still reports light."""
        asked = time.monotonic()
        self.exchange("set_light", state=0)
        unconfirmed = self._read_back()
        if unconfirmed is not None:
            raise SphereError(f"LED sphere {self._url}: {NOT_CONFIRMED}: it answered LIGHT 0 but {unconfirmed}; "
                              f"{self._guarantee()}", kind="unconfirmed", light="unknown")
        self._confirmed_off(asked)

    def _read_back(self) -> str | None:
        """None when the sphere reports that nothing emits (the switch off, or every level 0); else what it says."""
        try:
            if not self.exchange("get_light"):
                return None
            pwms = self.exchange("get_levels")
        except SphereError as exc:
            return f"reading its state back failed ({exc})"
        if not any(pwms):
            return None
        lit = [str(i + 1) for i, p in enumerate(pwms) if p]
        return f"still reports the light on with LED {', '.join(lit)} above 0"

    def _switch_off(self) -> LightReport:
        """ALLOFF then LIGHT 0 (both tried), then read back; either answered and the read-back saying nothing
        emits means off (a level is emitted only while the light is on, and ALLOFF zeroes every level)."""
        failed: dict[str, SphereError] = {}
        asked = time.monotonic()
        for name, args in (("all_off", {}), ("set_light", {"state": 0})):
            if failed and self._answered is False:
                self._send_blind((name, args))
                failed[name] = next(iter(failed.values()))
                continue
            try:
                self.exchange(name, **args)
            except SphereError as exc:
                failed[name] = exc
        if len(failed) < 2:
            unconfirmed = self._read_back()
            if unconfirmed is not None:
                error = SphereError(f"LED sphere {self._url}: {NOT_CONFIRMED}: it answered "
                                    f"{' and '.join(n for n in ('ALLOFF', 'LIGHT 0') if _key(n) not in failed)} "
                                    f"but {unconfirmed}", kind="unconfirmed")
                return LightReport(False, f"{error}; {self._guarantee()}", error)
            self._confirmed_off(asked)
        return self._switch_off_report(failed)

    def _switch_off_report(self, failed: dict[str, SphereError]) -> LightReport:
        first = next(iter(failed.values()), None)
        if first is None:
            log.info("LED sphere %s: all LEDs off, light off (read back)", self._url)
            return LightReport(True, "all LEDs and the light were switched off")
        if "set_light" not in failed:
            return LightReport(True, f"the light was switched off (LIGHT 0 answered) but the LED levels were not "
                                     f"zeroed: {first}", first)
        if "all_off" not in failed:
            return LightReport(True, f"every LED was set to 0 (ALLOFF answered), so nothing is lit, but the light "
                                     f"switch did not answer: {first}", first)
        if self._answered is False:
            return LightReport(False, f"{first}; the port never answered like an LED sphere, so the light's state is "
                                      f"unknown (LIGHT 0 was sent without waiting for a reply); {self._guarantee()}",
                               first)
        return LightReport(False, f"{first}; switching off was not confirmed, so the light's state is unknown: "
                                  f"{self._guarantee()}", first)

    def _confirmed_off(self, asked_at: float) -> None:
        """The sphere answered that the light is off to a request sent at ``asked_at`` (monotonic)."""
        self._light_on_since = None
        self._supervisor.confirm_off(asked_at)

    def _switch_off_at_limit(self) -> None:
        """The supervisor's switch-off (its own thread): raises unless the sphere confirmed the light off."""
        report = self.ensure_off()
        if not report.off:
            raise SphereError(report.message, kind=report.error.kind if report.error else "port", light="unknown")

    def _guarantee(self) -> str:
        """What switches a lit sphere off without this host (for messages where the light's state is unknown)."""
        period = self._supervisor.current()
        watchdog = f"its watchdog switches every LED off {self._watchdog_ms / 1000:g} s after the last request " \
                   "it hears"
        if period is None:
            return f"if it is lit, {watchdog}"
        left = period.deadline - time.monotonic()
        when = f"at most {period.max_on_s:.3g} s after it came on" + (f" (in {left:.1f} s)" if left > 0 else "")
        if self._device_limit:
            return f"the sphere switches it off by itself {when}, the limit sent with ON; and {watchdog}"
        if self._device_limit is None:
            return f"if the sphere received ON, it switches it off by itself {when}; this program keeps trying to " \
                   f"switch it off, and {watchdog}"
        return f"this program keeps trying to switch it off ({when}), and {watchdog} (firmware without ON)"

    def _send_blind(self, *requests: tuple[str, dict]) -> bool:
        """Write requests without waiting for replies (a port that never answered); False if even that failed."""
        if not self._lock.acquire(timeout=self._lock_wait_s()):
            return False
        try:
            for name, args in requests:
                self._ser.write(P.COMMANDS[name].encode(**args))
            flush = getattr(self._ser, "flush", None)
            if flush is not None:
                flush()
            return True
        except self._io_errors + (AttributeError,) as exc:
            log.info("LED sphere %s: could not send the switch-off: %s", self._url, exc)
            return False
        finally:
            self._lock.release()


def _key(request: str) -> str:
    return {"ALLOFF": "all_off", "LIGHT 0": "set_light"}[request]
