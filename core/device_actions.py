"""The run engine's hands: the one place where a plan's messages act on the devices (core.messages).

:class:`StandDevices` names what a run may act on (each may be None: a light plan has only the sphere, the CSRF
sweep no sphere); :class:`DeviceActions` applies one message at a time to them (``apply``), counts every lit
period's light dose (in the session's manifest as it ends, when a session is open), and does the engine's light
work between plans and runs: every LED 0 and the light off, read back (``lights_off``), the monochromator's
shutter closed (``shutter_closed``), the free space a plan's frames need (``check_free_space``) and what plans
may know of the stand (``facts``). Only core.engine makes one.
"""
from __future__ import annotations

import logging
from collections.abc import Callable
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Protocol

from dualrgb.common.atomic_files import require_free_space
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.core import messages as M
from dualrgb.core.light_safety import SafetySettings, StandFacts, restate
from dualrgb.core.shooter import Notice, Shooter
from dualrgb.drivers.led_sphere.errors import LightReport, SphereError

if TYPE_CHECKING:
    from dualrgb.core.protocols import Monochromator, Radiometer, Session, Sphere
    from dualrgb.core.shutter_shooter import ShutterShooter
    from dualrgb.drivers.camera.base import Camera
    from dualrgb.drivers.led_sphere.supervisor import LitPeriod
    from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

Place = Callable[[str, bool], object]      # the stand as a device: (what, nd) -> places it
Ask = Callable[[str, dict], None]         # a person asked to do something; returns when done
KEEPALIVE_S = M.KEEPALIVE_S


class Control(Protocol):
    """What the actions need of the run's control (core.engine.RunControl): its cancel, to wake a Wait."""

    token: CancelToken

    @property
    def cancelled(self) -> bool: ...


@dataclass
class StandDevices:
    """What a run acts on; any may be None. ``stand`` places targets, the open gate, the lens cap and originals
    (the virtual lab's); without it a person is asked. ``sleep``: how time passes in a Wait (a virtual clock's
    skip); None: real time, cancellable at once."""

    camera: Camera | None = None
    sphere: Sphere | None = None
    session: Session | None = None
    stand: Place | None = None
    monochromator: Monochromator | None = None
    radiometer: Radiometer[Any] | None = None
    sleep: Callable[[float], None] | None = None


@dataclass
class _Lit:
    """A LightOn's lit period and the light on it; ``counted_s``: its seconds already in the dose."""

    light: LightSource
    period: LitPeriod
    what: str
    counted_s: float = 0.0

    def take(self) -> float:
        """The seconds lit since the last count (the whole period never exceeds its limit: LitPeriod.lit_s)."""
        seconds = self.period.lit_s() - self.counted_s
        self.counted_s += seconds
        return seconds


class DeviceActions:
    """Applies messages to ``devices`` for one engine (module docstring)."""

    def __init__(self, devices: StandDevices, safety: SafetySettings, control: Control, ask: Ask,
                 notice: Notice):
        self.devices = devices
        self.control = control
        self.ask = ask
        self.shooter = Shooter(devices.camera, devices.sphere, devices.session, safety, notice=notice)
        self._shutter: ShutterShooter | None = None
        self._light: LightSource | None = None       # the levels last set (what a LightOn lights)
        self._lit: _Lit | None = None                # a LightOn's lit period not yet counted in the dose
        self._unpinged_s = 0.0
        self._handlers: dict[type, Callable[[Any], Any]] = {
            M.Place: self._place, M.Entries: lambda m: self.shooter.session.entries(m.role),
            M.ReadFrame: self._read_frame, M.SetLight: self._set_light,
            M.LightOn: self._light_on, M.LightOff: lambda _m: self._light_off(),
            M.ReadBack: lambda _m: self.lights_off(), M.Wait: lambda m: self._wait(m.seconds),
            M.Shot: self._shot, M.Instrument: lambda _m: self._instrument(), M.Tune: self._tune,
            M.ShutterShot: self._shutter_shot, M.CloseShutter: lambda _m: self._close_shutter(),
            M.Measure: lambda m: self._radiometer().measure(m.sample_id),
            M.SaveReadings: lambda m: self._radiometer().save(m.readings, m.folder, m.stem)}

    def apply(self, message: M.Message) -> Any:
        handler = self._handlers.get(type(message))
        if handler is None:
            raise TypeError(f"the run engine has no action for {type(message).__name__}")
        return handler(message)

    # ------------------------------------------------------------------------------------------ the engine's own
    def facts(self) -> StandFacts:
        """The camera's shutter speeds (read once per engine) and the light-on rule with its latency."""
        camera = self.devices.camera
        return StandFacts(tuple(camera.shutter_speeds()) if camera is not None else (), self.shooter.safety)

    def check_free_space(self, frames: int, what: str) -> None:
        """Refuse up front (InsufficientSpaceError, one line) ``frames`` frames that cannot fit on the session's
        disk; nothing has been switched on or shot when it is raised."""
        camera, session = self.devices.camera, self.devices.session
        frame_bytes = getattr(camera, "frame_bytes", None)
        if session is None or not callable(frame_bytes) or frames <= 0:
            return
        require_free_space(session.path, frames * int(frame_bytes()), f"the {what} ({frames} frames)")

    def lights_off(self) -> LightReport | None:
        """Every LED and the light off, read back (None without a sphere); never raises. A LightOn's lit period
        still open is counted in the light dose."""
        sphere = self.devices.sphere
        if sphere is None:
            return None
        report = sphere.ensure_off()
        self._count_lit()
        if not report.off:
            log.error("LED sphere: %s", report.message)
        return report

    def shutter_closed(self) -> None:
        """The monochromator's shutter closed (a plan's clean-up); what could not be confirmed is logged."""
        mono = self.devices.monochromator
        if mono is None:
            return
        report = mono.ensure_closed()
        if not report.closed and not mono.manual:
            log.error("monochromator: %s", report.message)

    @property
    def placed(self) -> tuple[str, bool] | None:
        return self.shooter.placed

    # ------------------------------------------------------------------------------------------ the stand
    def _place(self, msg: M.Place) -> None:
        if self.shooter.placed == (msg.what, msg.nd):
            return
        with self.shooter.timeline.busy("place"):         # the stand's (or a person's) time, not the computer's
            if self.devices.stand is not None:
                self.devices.stand(msg.what, msg.nd)
            else:
                self.ask(msg.prompt(), {"place": msg.what, "nd": msg.nd})
        self.shooter.placed = (msg.what, msg.nd)

    def _read_frame(self, msg: M.ReadFrame) -> Any:
        return self.shooter.frame(msg.entry, keep=msg.keep)

    def _shot(self, msg: M.Shot) -> M.Taken:
        kept = self.shooter.session.has_step(msg.step_id)
        return M.Taken(self.shooter.shoot(msg.role, msg.light, msg.exposure_s, msg.step_id, **dict(msg.meta)), kept)

    # ------------------------------------------------------------------------------------------ the sphere
    def _sphere(self) -> Sphere:
        if self.devices.sphere is None:
            raise ValueError("no LED sphere is connected (connect it: Devices, or --port)")
        return self.devices.sphere

    def _set_light(self, msg: M.SetLight) -> list[float]:
        sphere = self._sphere()
        if self._lit is not None:           # new levels while lit: the dose so far is the old light's
            self._dose(self._lit.light, self._lit.take(), self._lit.what)
        try:
            taken = sphere.apply(msg.light)
        except SphereError as exc:          # say what the light is now
            raise (exc if exc.light is not None else restate(exc, sphere.ensure_off())) from None
        self._light = msg.light
        if self._lit is not None:
            self._lit.light = msg.light
        return taken

    def _light_on(self, msg: M.LightOn) -> LitPeriod:
        if self._light is None or self._light.is_dark:
            raise ValueError("no light is set: a LightOn needs a SetLight first")
        sphere = self._sphere()
        try:
            period = sphere.on(max_on_s=msg.cap_s)
        except SphereError as exc:          # it says what state the light is in; its lit period (if any) counts
            if exc.period is not None:
                self._dose(self._light, exc.period.lit_s(), msg.what)
            raise
        if self._lit is None or self._lit.period is not period:
            self._count_lit()
            self._lit = _Lit(self._light, period, msg.what)
        return period

    def _light_off(self) -> LightReport:
        sphere = self._sphere()
        try:
            sphere.off()
            report = LightReport(True, "the light was switched off")
        except SphereError as exc:
            log.warning("switching the light off: %s", exc)
            report = sphere.ensure_off()
        self._count_lit()
        if not report.off:
            raise SphereError(report.message, kind=report.error.kind if report.error else "port", light="unknown")
        return report

    def _count_lit(self) -> None:
        lit, self._lit = self._lit, None
        if lit is not None:
            self._dose(lit.light, lit.take(), lit.what)

    def _dose(self, light: LightSource, seconds: float, what: str) -> None:
        if seconds <= 0:
            return
        self.shooter.dose.add(light, seconds)
        if self.devices.session is not None:
            self.devices.session.record_dose(light, seconds, step_id=what)

    def _wait(self, seconds: float) -> None:
        """``seconds`` pass (a virtual clock's skip, or real time woken at once by a cancel), in steps of at most
        KEEPALIVE_S; the sphere hears from the host at least that often."""
        left = float(seconds)
        while left > 1e-9:
            step = min(left, KEEPALIVE_S)
            if self.devices.sleep is not None:
                self.devices.sleep(step)
                cancelled = self.control.cancelled
            else:
                cancelled = self.control.token.wait(step)
            if cancelled:
                raise Cancelled("cancelled while waiting")
            self._unpinged_s += step
            if self.devices.sphere is not None and self._unpinged_s >= 1.0:
                self.devices.sphere.keepalive()
                self._unpinged_s = 0.0
            left -= step

    # ------------------------------------------------------------------------------------------ monochromator
    def _mono(self) -> Monochromator:
        if self.devices.monochromator is None:
            raise ValueError("no monochromator is connected")
        return self.devices.monochromator

    def _instrument(self) -> dict[str, str]:
        mono = self._mono()
        mono.prepare()
        return mono.describe()

    def _tune(self, msg: M.Tune) -> float:
        mono = self._mono()
        prompt = mono.prompt_to_set(msg.wavelength_nm)
        if prompt:
            self.ask(prompt, {"wavelength_nm": msg.wavelength_nm})
        return mono.goto(msg.wavelength_nm)

    def shutter_shooter(self) -> ShutterShooter:
        """The frame action under the monochromator (made on first use, with the run's camera timeouts)."""
        if self._shutter is None:
            from dualrgb.core.shutter_shooter import ShutterShooter

            camera, session = self.shooter.camera, self.shooter.session
            safety = self.shooter.safety
            self._shutter = ShutterShooter(camera, self._mono(), session, expose_timeout_s=safety.expose_timeout_s,
                                           fetch_timeout_s=safety.fetch_timeout_s)
        return self._shutter

    def _shutter_shot(self, msg: M.ShutterShot) -> M.Taken:
        shooter = self.shutter_shooter()
        kept = shooter.session.has_step(msg.step_id)
        return M.Taken(shooter.shoot(msg.role, msg.step_id, msg.exposure_s, lit=msg.lit, **dict(msg.meta)), kept)

    def _close_shutter(self) -> None:
        mono = self._mono()
        prompt = mono.prompt_to_close()
        if prompt:
            self.ask(prompt, {"place": "shutter closed"})
        else:
            mono.close_shutter()

    # ------------------------------------------------------------------------------------------ radiometer
    def _radiometer(self) -> Radiometer[Any]:
        if self.devices.radiometer is None:
            raise ValueError("no spectroradiometer is connected")
        return self.devices.radiometer
