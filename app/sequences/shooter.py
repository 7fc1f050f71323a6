"""Shooter: one exposure done safely, the building block of every sequence.

For each frame: skip it if the session already has its step (resume); switch on only the light it needs, for at
most settle + exposure + the camera's latency allowance (refused before anything is switched on when that
exceeds ``max_on_s``, default 10 s: the thesis found no LED drift in the first 10 s, 4.3.2); let it settle;
expose; switch the light off as soon as the camera reports the shutter closed, *before* the download; then fetch
the frame and write it to the session first thing; the light dose of the lit period is logged on every path.

The limit does not depend on this thread: the sphere driver's supervisor thread and the sphere's firmware switch
the light off at it (drivers.led_sphere), so a camera that hangs never holds the light on. Camera calls run with
host-side deadlines (drivers.camera.base.call_with_deadline): a hung one is a one-line CameraError. A frame
whose light was cut at the limit before the shutter closed is kept as 'rejected' (never used, shot again on
resume). Every error says truthfully what state the light was left in, and an unconfirmed switch-off is reported
together with the camera's error.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from dualrgb.app.protocols import Session, Sphere
from dualrgb.app.session.light_dose import LightDose
from dualrgb.app.session.manifest import SessionEntry
from dualrgb.app.workflow.defaults import SETTLE_S
from dualrgb.common.errors import ReportedError
from dualrgb.drivers.camera.base import DEFAULT_LATENCY_S, Camera, CameraError, Exposure, RawCapture, call_with_deadline
from dualrgb.drivers.led_sphere import LightReport, SphereError
from dualrgb.drivers.raw import RawFrame, load_raw
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

Stand = Callable[[str, bool], object]     # (what, nd) -> places 'train'/'test'/'open-gate'/'lens-cap'
REJECTED_ROLE = "rejected"                # frames kept aside, never used (e.g. lit for less than the exposure)


class LightSafetyError(ReportedError, RuntimeError):
    """A capture the light-on limit does not allow (refused before anything was switched on), or a frame whose
    light was cut at its limit before the shutter closed (kept aside as 'rejected')."""


@dataclass(frozen=True)
class SafetySettings:
    max_on_s: float = 10.0          # per capture, light on at most (settle + exposure + latency)
    settle_s: float = SETTLE_S      # after switching on, before the shutter opens (app.workflow.defaults)
    # the camera's allowance beyond the exposure (trigger, shutter lag, reporting the shutter closed); None: what
    # the camera reports (Camera.latency_for, filled in by for_camera), DEFAULT_LATENCY_S without a camera
    latency_s: float | None = None
    expose_timeout_s: float = 30.0  # host-side deadline of an exposure beyond its exposure time
    fetch_timeout_s: float = 120.0  # host-side deadline of a download
    camera_latency: Callable[[float], float] | None = field(default=None, repr=False, compare=False)

    def for_camera(self, camera: Camera | None) -> SafetySettings:
        """These settings with the camera's own latency allowance (unless one was given, or the camera - a
        stand-in - reports none)."""
        latency_for = getattr(camera, "latency_for", None)
        if self.latency_s is not None or latency_for is None:
            return self
        return replace(self, camera_latency=latency_for)

    def latency_for(self, exposure_s: float) -> float:
        if self.latency_s is not None:
            return self.latency_s
        return float(self.camera_latency(exposure_s)) if self.camera_latency else DEFAULT_LATENCY_S

    @property
    def max_exposure_s(self) -> float:
        """The longest exposure the light-on limit allows (the allowance may grow with the exposure)."""
        budget = self.max_on_s - self.settle_s
        if self.latency_s is not None or self.camera_latency is None:
            return budget - self.latency_for(0.0)
        lo, hi = 0.0, max(budget, 0.0)
        if self.light_limit_s(hi) <= self.max_on_s:
            return hi
        for _ in range(50):             # bisection: the light limit grows with the exposure
            mid = (lo + hi) / 2
            lo, hi = (mid, hi) if self.light_limit_s(mid) <= self.max_on_s else (lo, mid)
        return lo

    def light_limit_s(self, exposure_s: float) -> float:
        """How long the light may stay on for one exposure."""
        return self.settle_s + float(exposure_s) + self.latency_for(float(exposure_s))

    def check(self, exposure_s: float) -> None:
        idle = self.settle_s + self.latency_for(0.0)
        if idle >= self.max_on_s:
            raise LightSafetyError(
                f"the camera's latency allowance ({self.latency_for(0.0):g} s) plus settle ({self.settle_s:g} s) "
                f"leaves no exposure within the {self.max_on_s:g} s light limit: this camera cannot be used with "
                "the light as set; measure its latency (docs/first-session-d610.md) or raise the limit")
        on = self.light_limit_s(exposure_s)
        if on > self.max_on_s:
            raise LightSafetyError(
                f"exposure {exposure_s:g} s would keep the light on up to {on:.1f} s (settle {self.settle_s:g} s, "
                f"camera latency {self.latency_for(exposure_s):g} s), over the {self.max_on_s:g} s limit (LEDs "
                "drift after 10 s); use a brighter light, a higher ISO or raise the limit")


def restate(error: BaseException, light: LightReport) -> BaseException:
    """``error`` with what is known about the light appended to its one-line message (same type where possible:
    SphereError, CameraError, LightSafetyError), so the camera's error and an unconfirmed switch-off are both
    reported."""
    text = f"{error}; {light.message}"
    if isinstance(error, SphereError):
        return SphereError(text, kind=error.kind, code=error.code, light="off" if light.off else "unknown")
    if isinstance(error, CameraError):
        return CameraError(text, error.code)
    if isinstance(error, LightSafetyError):
        return LightSafetyError(text)
    error.add_note(light.message)
    return error


class Shooter:
    """Frames shot safely (module docstring) with ``camera`` and ``sphere`` into ``session``. A shooter made
    without a camera or a session (a plan's, nothing shot) says so in one line when asked for them; without a
    sphere it takes only unlit frames."""

    def __init__(self, camera: Camera | None, sphere: Sphere | None, session: Session | None,
                 stand: Stand | None = None, safety: SafetySettings = SafetySettings(),
                 sleep: Callable[[float], None] = time.sleep, clock: Callable[[], float] = time.monotonic):
        self._camera = camera
        self.sphere = sphere
        self._session = session
        self.stand = stand
        self.safety = safety.for_camera(camera)
        self.dose = LightDose()
        self._sleep = sleep
        self._clock = clock
        self.placed: tuple[str, bool] | None = None
        self._frames: dict[int, RawFrame] = {}

    @property
    def camera(self) -> Camera:
        if self._camera is None:
            raise ValueError("no camera is connected (connect one: Devices, or --camera)")
        return self._camera

    @property
    def session(self) -> Session:
        if self._session is None:
            raise ValueError("no capture session is open (a plan only: nothing can be shot)")
        return self._session

    def _lit_sphere(self) -> Sphere:
        if self.sphere is None:
            raise ValueError("no LED sphere is connected: a lit frame needs one (connect it: Devices, or --port)")
        return self.sphere

    def place(self, what: str, nd: bool = False) -> bool:
        """Ask the stand to hold ``what``; returns False when a person must do it (no stand callback)."""
        if self.placed == (what, nd):
            return True
        if self.stand is None:
            return False
        self.stand(what, nd)
        self.placed = (what, nd)
        return True

    def check_light_time(self, exposure_s: float) -> None:
        self.safety.check(exposure_s)

    def lights_off(self) -> LightReport | None:
        """Every LED and the light off (a sequence's start and cleanup); never raises (it runs in ``finally``
        blocks, where it must not hide the error being handled): what it could not confirm is logged and returned.
        Each shot has confirmed its own switch-off already."""
        if self.sphere is None:
            return None
        report = self.sphere.ensure_off()
        if not report.off:
            log.error("LED sphere: %s", report.message)
        return report

    def shoot(self, role: str, light: LightSource | None, exposure_s: float, step_id: str,
              **meta) -> SessionEntry:
        if self.session.has_step(step_id):
            log.info("step %s already in the session: not shot again", step_id)
            return self.session.entry(step_id)
        lit = light if light is not None and not light.is_dark else None
        off: LightReport | None = None
        if lit is not None:
            self.check_light_time(exposure_s)
            exposure, off, complete = self._lit_exposure(lit, exposure_s, step_id)
            if not complete:
                self._reject(exposure, lit, step_id, off)
        else:
            exposure = self._expose(exposure_s)
        raw = self._fetch(exposure, off)
        entry = self._record(raw, role, step_id, lit, meta)
        if off is not None and not off.off:
            raise SphereError(f"{step_id}: the frame was saved (#{entry.seq}); {off.message}",
                              kind=off.error.kind if off.error else "port", light="unknown")
        return entry

    # ------------------------------------------------------------------------------------------ phases
    def _lit_exposure(self, light: LightSource, exposure_s: float,
                      step_id: str) -> tuple[Exposure, LightReport, bool]:
        """Light on, settle, expose, light off: (the exposure, what is known about the light, whether the light
        stayed on all through the exposure). A failure is raised after the light was switched off, saying so."""
        sphere = self._lit_sphere()
        try:
            sphere.apply(light)
        except SphereError as exc:          # nothing was switched on by this shot; say what the light is now
            raise (exc if exc.light is not None else restate(exc, sphere.ensure_off())) from None
        try:
            period = sphere.on(max_on_s=self.safety.light_limit_s(exposure_s))
        except SphereError as exc:          # it says what state the light is in; its lit period (if any) counts
            if exc.period is not None:
                self._add_dose(light, exc.period.lit_s(), step_id)
            raise
        exposure: Exposure | None = None
        failure: BaseException | None = None
        complete = False
        try:
            self._sleep(self.safety.settle_s)
            exposure = self._expose(exposure_s)
            complete = sphere.exposure_done(period)
        except BaseException as exc:  # noqa: BLE001 - any failure, Ctrl-C too: the light goes off first, then it is raised
            failure = exc
        off = self._switch_off(sphere)
        self._add_dose(light, period.lit_s(), step_id)
        if failure is not None:
            raise restate(failure, off) from failure
        assert exposure is not None                 # set whenever nothing was caught
        return exposure, off, complete

    def _switch_off(self, sphere: Sphere) -> LightReport:
        """The light off right after the exposure (one LIGHT 0); when that is not confirmed, ALLOFF + LIGHT 0 again,
        and what is known then."""
        try:
            sphere.off()
        except SphereError as exc:
            log.warning("switching the light off after the exposure: %s", exc)
            return sphere.ensure_off()
        return LightReport(True, "the light was switched off")

    def _expose(self, exposure_s: float) -> Exposure:
        return call_with_deadline(lambda: self.camera.expose(exposure_s),
                                  float(exposure_s) + self.safety.expose_timeout_s, "capture: the exposure")

    def _fetch(self, exposure: Exposure, off: LightReport | None) -> RawCapture:
        try:
            return call_with_deadline(lambda: self.camera.fetch(exposure), self.safety.fetch_timeout_s,
                                      "capture: the download")
        except CameraError as exc:
            raise (restate(exc, off) if off is not None else exc) from exc

    def _reject(self, exposure: Exposure, light: LightSource, step_id: str, off: LightReport) -> None:
        """The light was cut at its limit before the shutter closed: keep the frame aside, then refuse, saying in
        one line how late the camera was and, when it keeps missing, that it cannot meet the limit as set."""
        limit = self.safety.light_limit_s(exposure.exposure_s)
        kept = "not downloaded"
        try:
            raw = self._fetch(exposure, off)
            entry = self.session.record(raw, REJECTED_ROLE, light=light, rejected_step=step_id,
                                        reason="light cut at its limit before the shutter closed")
            kept = f"kept aside as {REJECTED_ROLE} #{entry.seq}"
        except (CameraError, OSError) as exc:
            log.error("%s: the rejected frame could not be kept: %s", step_id, exc)
        allowance = self.safety.latency_for(exposure.exposure_s)
        late = exposure.ended - exposure.started - exposure.exposure_s
        misses = sum(1 for e in self.session.entries(REJECTED_ROLE) if e.meta.get("rejected_step") == step_id)
        advice = (f"the camera has missed its {allowance:g} s latency allowance {misses} times on this step, so it "
                  "cannot meet the light limit as set: measure its latency (docs/first-session-d610.md) and set it, "
                  "or check the camera" if misses >= 2 else
                  f"check the camera, or allow it more latency than {allowance:g} s")
        raise LightSafetyError(
            f"{step_id}: the light reached its {limit:.2f} s limit and was switched off before the camera reported "
            f"the end of the {exposure.exposure_s:g} s exposure ({exposure.ended - exposure.started:.2f} s after it "
            f"was triggered, {late:.2f} s beyond it), so the frame was not lit all through ({kept}; the step is shot "
            f"again); {off.message}; {advice}")

    def _record(self, raw: RawCapture, role: str, step_id: str, light: LightSource | None,
                meta: dict) -> SessionEntry:
        temperature = None
        if self.sphere is not None:
            try:
                temperature = self.sphere.temperature_c()
            except Exception as exc:  # noqa: BLE001 - a temperature read failure must not lose the downloaded frame
                log.warning("could not read the sphere temperature: %s", exc)
        settings = {k: v for k, v in self.camera.settings().__dict__.items() if v is not None}
        return self.session.record(raw, role, step_id=step_id, light=light, sphere_temperature_c=temperature,
                                   settings=settings, placed=list(self.placed) if self.placed else None, **meta)

    def _add_dose(self, light: LightSource, on_s: float, step_id: str) -> None:
        """The light dose of one lit period (every path: success, camera error, unconfirmed switch-off), also in
        the session's manifest as it happens."""
        self.dose.add(light, on_s)
        self.session.record_dose(light, on_s, step_id=step_id)

    def frame(self, entry: SessionEntry) -> RawFrame:
        """The raw frame of a session entry, read back from the session folder (cached)."""
        if entry.seq not in self._frames:
            self._frames[entry.seq] = load_raw(self.session.file_path(entry))
        return self._frames[entry.seq]

    def forget(self) -> None:
        self._frames.clear()


def channel_levels(frame: RawFrame, percentile: float = 99.5, region: float = 0.6) -> np.ndarray:
    """Per-CFA-channel bright level above black (DN) in the central ``region`` of the frame."""
    h, w = frame.mosaic.shape
    r0, r1 = int(h * (1 - region) / 2) // 2 * 2, int(h * (1 + region) / 2) // 2 * 2
    c0, c1 = int(w * (1 - region) / 2) // 2 * 2, int(w * (1 + region) / 2) // 2 * 2
    out = []
    for _name, (r, c), idx in frame.channels():
        plane = frame.mosaic[r0 + r:r1:2, c0 + c:c1:2].astype(np.float32) - frame.black_levels[idx]
        out.append(float(np.percentile(plane, percentile)))
    return np.array(out)
