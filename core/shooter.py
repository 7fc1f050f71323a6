"""Shooter: the run engine's hands for one frame (the :class:`core.messages.Shot` message). Only the engine
(core.engine) makes one; plans never see it.

For each frame: skip it if the session already has its step (resume); switch on only the light it needs, for at
most settle + exposure + the camera's latency allowance (refused before anything is switched on when that
exceeds ``max_on_s``: core.light_safety); let it settle; expose; switch the light off as soon as the
camera reports the shutter closed, *before* the download; then fetch the frame and write it to the session first
thing; the light dose of the lit period is recorded on every path.

The limit does not depend on this thread: the sphere driver's supervisor thread and the sphere's firmware switch
the light off at it (drivers.led_sphere), so a camera that hangs never holds the light on. Camera calls run with
host-side deadlines (drivers.camera.base.call_with_deadline): a hung one is a one-line CameraError.

A frame whose light went off before the camera reported the end of the exposure - cut at the limit by the
supervisor, or by the sphere itself (it reports ``trip=1``: its own ``ON <ms>`` limit or watchdog) - is never
used: it is kept aside as 'rejected' and the step is shot again once, said in one line with the rejected
frame's light dose (``notice``); a second such frame stops the run (LightSafetyError). Every error says
truthfully what state the light was left in, and an unconfirmed switch-off is reported together with the camera's
error (a step whose switch-off was not confirmed is never shot again).

Light gaps (issue 41): for every lit frame the host's clock gives the gap from the switch-on request to the camera's
trigger (``on_to_trigger_s``: settle + whatever the host was late) and from the camera's report of the exposure's
end to the confirmed switch-off (``end_to_off_s``); both are written in the manifest (the frame's entry
``meta.light_gaps`` and its lit period's dose line). A trigger later than settle + the slack
(SafetySettings.trigger_bound_s: the host was starved) is never sent: the light goes off at once, the step is
shot again once, said in one line with that lit period's dose, and a second late trigger stops the run.
"""
from __future__ import annotations

import logging
import time
from collections.abc import Callable
from dataclasses import dataclass

from dualrgb.core.light_safety import (
    NO_CAMERA,
    REJECTED_ROLE,
    LightSafetyError,
    SafetySettings,
    restate,
)
from dualrgb.core.protocols import Session, Sphere
from dualrgb.core.session.light_dose import LightDose
from dualrgb.core.session.manifest import SessionEntry
from dualrgb.core.stand_timeline import StandTimeline
from dualrgb.drivers.camera.base import Camera, CameraError, Exposure, RawCapture, call_with_deadline
from dualrgb.drivers.led_sphere import LightReport, SphereError
from dualrgb.drivers.raw import RawFrame, load_raw
from dualrgb.simulation.lightsource import LightSource

log = logging.getLogger(__name__)

Notice = Callable[[str, dict], None]       # one line for the run (what happened, said once) and its data


@dataclass
class LightGaps:
    """A lit frame's host-side gaps (module docstring), seconds; None where the step never got there."""

    on_to_trigger_s: float | None = None
    end_to_off_s: float | None = None
    bound_s: float = 0.0            # the trigger's bound (settle + slack)
    slack_s: float = 0.0            # the switch-off's bound after the exposure's end

    def to_dict(self) -> dict[str, float | bool | None]:
        def r(v: float | None) -> float | None:
            return None if v is None else round(v, 4)
        late = self.end_to_off_s is not None and self.end_to_off_s > self.slack_s
        return {"on_to_trigger_s": r(self.on_to_trigger_s), "end_to_off_s": r(self.end_to_off_s),
                "trigger_bound_s": r(self.bound_s), "off_bound_s": r(self.slack_s), "off_late": late}


@dataclass
class LitExposure:
    """One lit exposure: the camera's exposure (None: not triggered, the host was late), what is known about the
    light afterwards, the seconds the object may have been lit, why the frame was not lit all through ('' when
    it was) and its light gaps."""

    exposure: Exposure | None
    off: LightReport
    lit_s: float
    cut: str = ""
    gaps: LightGaps | None = None
    starved: bool = False


class Shooter:
    """Frames shot safely (module docstring) with ``camera`` and ``sphere`` into ``session``. Made by the run engine
    alone; without a camera or a session it says so in one line when asked for them; without a sphere it takes
    only unlit frames."""

    def __init__(self, camera: Camera | None, sphere: Sphere | None, session: Session | None,
                 safety: SafetySettings = SafetySettings(), sleep: Callable[[float], None] = time.sleep,
                 notice: Notice | None = None, timeline: StandTimeline | None = None):
        self._camera = camera
        self.sphere = sphere
        self._session = session
        self.safety = safety.for_camera(camera)
        self.dose = LightDose()
        self._sleep = sleep
        self.notice: Notice = notice or (lambda line, _data: log.warning("%s", line))
        self.placed: tuple[str, bool] | None = None       # what the stand holds (the engine's Place)
        self._frames: dict[int, RawFrame] = {}
        self.timeline = timeline or StandTimeline()    # its clock measures the light gaps (a test's may jump)

    @property
    def camera(self) -> Camera:
        if self._camera is None:
            raise ValueError(NO_CAMERA)
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

    def shoot(self, role: str, light: LightSource | None, exposure_s: float, step_id: str,
              **meta) -> SessionEntry:
        if self.session.has_step(step_id):
            log.info("step %s already in the session: not shot again", step_id)
            return self.session.entry(step_id)
        lit = light if light is not None and not light.is_dark else None
        if lit is None:
            return self._record(self._fetch(self._timed_expose(exposure_s), None), role, step_id, None, meta)
        self.safety.check(exposure_s)
        shot = self._lit_exposure(lit, exposure_s, step_id)
        if shot.cut:                                  # never used (or never shot): kept aside, shot again once
            self._set_aside(shot, lit, step_id, again=True)
            shot = self._lit_exposure(lit, exposure_s, step_id)
            if shot.cut:
                self._set_aside(shot, lit, step_id, again=False)
        assert shot.exposure is not None and shot.gaps is not None      # a shot without a cut was triggered
        entry = self._record(self._fetch(shot.exposure, shot.off), role, step_id, lit,
                             {**meta, "light_gaps": shot.gaps.to_dict()})
        if not shot.off.off:
            raise SphereError(f"{step_id}: the frame was saved (#{entry.seq}); {shot.off.message}",
                              kind=shot.off.error.kind if shot.off.error else "port", light="unknown")
        return entry

    # ------------------------------------------------------------------------------------------ phases
    def _lit_exposure(self, light: LightSource, exposure_s: float, step_id: str) -> LitExposure:
        """Light on, settle, expose (unless the host was late: then not triggered), light off, each gap measured.
        A failure is raised after the light was switched off, saying so."""
        sphere = self._lit_sphere()
        try:
            sphere.apply(light)
        except SphereError as exc:          # nothing was switched on by this shot; say what the light is now
            raise (exc if exc.light is not None else restate(exc, sphere.ensure_off())) from None
        clock = self.timeline.clock
        gaps = LightGaps(bound_s=self.safety.trigger_bound_s(exposure_s), slack_s=self.safety.slack_s(exposure_s))
        on_at = clock()
        try:
            period = sphere.on(max_on_s=self.safety.light_limit_s(exposure_s))
        except SphereError as exc:          # it says what state the light is in; its lit period (if any) counts
            if exc.period is not None:
                self._add_dose(light, exc.period.lit_s(), step_id)
            raise
        exposure: Exposure | None = None
        failure: BaseException | None = None
        complete = False
        end_at = 0.0
        try:
            with self.timeline.busy("settle"):
                self._sleep(self.safety.settle_s)
            gaps.on_to_trigger_s = clock() - on_at
            if gaps.on_to_trigger_s <= gaps.bound_s:          # else the host was starved: no trigger
                exposure = self._timed_expose(exposure_s)
                end_at = clock()
                complete = sphere.exposure_done(period)
        except BaseException as exc:  # noqa: BLE001 - any failure, Ctrl-C too: the light goes off first, then it is raised
            failure = exc
        off = self._switch_off(sphere)
        if exposure is not None:
            gaps.end_to_off_s = clock() - end_at
        lit_s = period.lit_s()
        self._add_dose(light, lit_s, step_id, light_gaps=gaps.to_dict())
        if failure is not None:
            raise restate(failure, off) from failure
        if exposure is None:
            return LitExposure(None, off, lit_s, self._late(gaps), gaps, starved=True)
        shot = LitExposure(exposure, off, lit_s, gaps=gaps)
        shot.cut = self._why_cut(shot, complete)
        if gaps.end_to_off_s is not None and gaps.end_to_off_s > gaps.slack_s:
            log.warning("%s: the light went off %.2f s after the exposure ended (bound %.2f s): the host was busy",
                        step_id, gaps.end_to_off_s, gaps.slack_s)
        return shot

    @staticmethod
    def _late(gaps: LightGaps) -> str:
        return (f"the host was ready to trigger the camera {gaps.on_to_trigger_s or 0.0:.2f} s after the light went "
                f"on, over its {gaps.bound_s:.2f} s bound (the computer was busy), so the camera was not triggered "
                "and the light was switched off at once")

    def _timed_expose(self, exposure_s: float) -> Exposure:
        """The exposure, its trigger and end on the timeline."""
        trigger_at = self.timeline.clock()
        exposure = self._expose(exposure_s)
        self.timeline.exposed(trigger_at, self.timeline.clock())
        return exposure

    def _why_cut(self, shot: LitExposure, complete: bool) -> str:
        """Why the light did not cover the whole exposure ('' when it did): the supervisor cut it at the limit
        before the camera reported the shutter closed, or the sphere switched off by itself (``trip=1``)."""
        e = shot.exposure
        assert e is not None
        took = f"{e.ended - e.started:.2f} s after it was triggered, {e.ended - e.started - e.exposure_s:.2f} s beyond"
        if not complete:
            return (f"the light reached its {self.safety.light_limit_s(e.exposure_s):.2f} s limit and was switched "
                    f"off before the camera reported the end of the {e.exposure_s:g} s exposure ({took} it)")
        if shot.off.off and self._tripped():
            return (f"the sphere switched the light off by itself during the {e.exposure_s:g} s exposure (it reports "
                    "trip=1: its own on-time limit or watchdog)")
        return ""

    def _tripped(self) -> bool:
        """Whether the sphere switched its light off by itself since this shot switched it on (the trip flag is
        cleared by every switch-on); False, logged, when it cannot be read."""
        try:
            return self._lit_sphere().tripped()
        except SphereError as exc:
            log.warning("could not read the sphere's trip flag after the exposure: %s", exc)
            return False

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
            with self.timeline.busy("download"):
                return call_with_deadline(lambda: self.camera.fetch(exposure), self.safety.fetch_timeout_s,
                                          "capture: the download")
        except CameraError as exc:
            raise (restate(exc, off) if off is not None else exc) from exc

    def _set_aside(self, shot: LitExposure, light: LightSource, step_id: str, *, again: bool) -> None:
        """The frame was not lit all through: keep it aside as 'rejected' (never used) and say so in one line with
        its light dose; ``again``: the step is shot once more (unless its switch-off was not confirmed), else the
        run stops here, saying how late the camera was and, when it keeps missing, that it cannot meet the limit."""
        kept = "not downloaded"
        if shot.exposure is not None:
            try:
                entry = self.session.record(self._fetch(shot.exposure, shot.off), REJECTED_ROLE, light=light,
                                            rejected_step=step_id, reason=shot.cut, lit_s=round(shot.lit_s, 4),
                                            light_gaps=shot.gaps.to_dict() if shot.gaps else None)
                kept = f"kept aside as {REJECTED_ROLE} #{entry.seq}"
            except (CameraError, OSError) as exc:
                log.error("%s: the rejected frame could not be kept: %s", step_id, exc)
        dose = LightDose()
        dose.add(light, shot.lit_s)
        spent = f"its light dose {shot.lit_s:.2f} s, {dose.lux_s:.3g} lux.s"
        line = (f"{step_id}: {shot.cut} (no frame was taken; {spent})" if shot.starved else
                f"{step_id}: {shot.cut}, so the frame was not lit all through ({kept}, never used; {spent})")
        if again and shot.off.off:
            self.notice(f"{line}; shooting it again once", {"step": step_id, "lit_s": shot.lit_s,
                                                            "lux_s": dose.lux_s, "rejected": kept})
            return
        advice = ("the computer is too busy to keep the light's timing: stop other work on it and resume (the step "
                  "is shot again on resume)" if shot.starved or shot.exposure is None
                  else self._advice(step_id, shot.exposure))
        raise LightSafetyError(f"{line}; {'the step was shot again and failed again; ' if not again else ''}"
                               f"{shot.off.message}; {advice}")

    def _advice(self, step_id: str, exposure: Exposure) -> str:
        allowance = self.safety.latency_for(exposure.exposure_s)
        misses = sum(1 for e in self.session.entries(REJECTED_ROLE) if e.meta.get("rejected_step") == step_id)
        if misses >= 2:
            return (f"the camera has missed its {allowance:g} s latency allowance {misses} times on this step, so it "
                    "cannot meet the light limit as set: measure its latency (docs/first-session-d610.md) and set "
                    "it, or check the camera; the step is shot again when the run is resumed")
        return f"check the camera, or allow it more latency than {allowance:g} s; the step is shot again on resume"

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

    def _add_dose(self, light: LightSource, on_s: float, step_id: str, **meta: object) -> None:
        """The light dose of one lit period (every path: success, camera error, unconfirmed switch-off), also in
        the session's manifest as it happens (with its light gaps, when measured)."""
        self.dose.add(light, on_s)
        self.session.record_dose(light, on_s, step_id=step_id, **meta)

    def frame(self, entry: SessionEntry, keep: bool = True) -> RawFrame:
        """The raw frame of a session entry, read back from the session folder (cached unless not ``keep``)."""
        if entry.seq not in self._frames:
            frame = load_raw(self.session.file_path(entry))
            if not keep:
                return frame
            self._frames[entry.seq] = frame
        return self._frames[entry.seq]

    def forget(self) -> None:
        self._frames.clear()
