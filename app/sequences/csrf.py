"""The camera's spectral sensitivity (CSRF) measured with a monochromator (thesis 4.2): a sweep of monochromatic
frames, then darks at every exposure the sweep used.

    seq = CsrfSweep(camera, monochromator, session, CsrfSettings(380, 780, 10))
    for event in seq.run(): ...          # prompts (a hand-set monochromator) come as EventKind.PROMPT
    seq.exposures                        # wavelength -> exposure

Per wavelength: the monochromator is set (``goto``; a :class:`drivers.monochromator.ManualMonochromator` asks the
person first, a prompt event), the exposure is metered on metering frames so that the brightest channel sits at
``target_fraction`` of the sensor's linear limit (app.sequences.calibration.converge_exposure, the auto-exposure
of the calibration; snapped down to a full stop, so it is at most that and at least half of it, and never
clipped), then ``frames`` frames are taken. After the sweep the shutter is closed and ``dark_frames`` darks are
taken at every exposure used (exposures are only known once metered; one closed-shutter period, one prompt for a
hand-set instrument). Light safety: the shutter is opened for each exposure and closed as soon as the camera
reports it over, before the download (:class:`MonoShooter`); on every error, cancel and at the end it is closed
(``_cleanup``). Every frame is in the session before the next step; a resumed sweep skips wavelengths already done.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Generator, Iterator
from dataclasses import dataclass
from typing import Any

from dualrgb.app.protocols import Monochromator, Session
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.calibration import LINEAR_LIMIT_DN, converge_exposure, snap_down
from dualrgb.app.sequences.shooter import channel_levels
from dualrgb.app.session.manifest import SessionEntry
from dualrgb.app.workflow.vocabulary import EventKind, Role, format_exposure, monochromatic_light, step_id
from dualrgb.drivers.camera.base import Camera, CameraError, Exposure, RawCapture, call_with_deadline
from dualrgb.drivers.monochromator.errors import MonochromatorError, ShutterReport
from dualrgb.drivers.raw import RawFrame, load_raw

log = logging.getLogger(__name__)

FULL_STOP_TOLERANCE = 0.1          # an offered exposure within 10 % of a power of two is a full stop (1/60 ~ 2^-6)
DARK_EXPOSURES_ESTIMATE = 8        # the plan's guess of distinct exposures (for the free-space check)


@dataclass(frozen=True)
class CsrfSettings:
    """What the sweep does (stored as the session's definition, so a resume with other settings is refused)."""

    start_nm: float = 380.0
    end_nm: float = 780.0
    step_nm: float = 10.0
    frames: int = 2                    # per wavelength: their spread is the frame repeatability
    dark_frames: int = 5               # per exposure used
    target_fraction: float = 0.6       # the brightest channel's goal, of the linear limit (LINEAR_LIMIT_DN)
    max_exposure_s: float = 30.0       # the longest exposure (where the camera barely responds)
    min_exposure_s: float = 1 / 4000
    full_stops: bool = True            # exposures on a ladder of whole stops (fewer darks)
    start_exposure_s: float = 0.25     # the first wavelength's first metering exposure (then the previous one's)
    region: float = 0.3                # the central fraction of each side averaged by the processing
    expose_timeout_s: float = 30.0     # host-side deadline of an exposure beyond its exposure time
    fetch_timeout_s: float = 120.0

    def __post_init__(self) -> None:
        checks = [
            (0 < self.start_nm <= self.end_nm <= 2500,
             f"range {self.start_nm:g}-{self.end_nm:g} nm: expected 0 < start <= end <= 2500 nm"),
            (self.step_nm > 0, f"step {self.step_nm:g} nm: expected more than 0"),
            (self.frames >= 1 and self.dark_frames >= 1, "frames and dark frames: expected at least 1 each"),
            (0.05 <= self.target_fraction <= 0.9,
             f"target fraction {self.target_fraction:g}: expected 0.05..0.9 of the linear limit"),
            (0 < self.min_exposure_s <= self.max_exposure_s,
             f"exposures {self.min_exposure_s:g}-{self.max_exposure_s:g} s: expected 0 < min <= max"),
            (0.02 <= self.region <= 1.0, f"region {self.region:g}: expected 0.02..1 of each side")]
        for ok, problem in checks:
            if not ok:
                raise ValueError(problem)
        if len(self.wavelengths()) > 2000:
            raise ValueError(f"{len(self.wavelengths())} wavelengths: use a coarser step (at most 2000)")

    def wavelengths(self) -> list[float]:
        """start, start + step, ... up to end (inclusive, to 1e-6 nm), rounded to 3 decimals (the drive's)."""
        n = int(math.floor((self.end_nm - self.start_nm) / self.step_nm + 1e-6)) + 1
        return [round(self.start_nm + i * self.step_nm, 3) for i in range(n)]

    def definition(self) -> dict[str, Any]:
        return {"workflow": "csrf", "start_nm": self.start_nm, "end_nm": self.end_nm, "step_nm": self.step_nm,
                "frames": self.frames, "dark_frames": self.dark_frames, "target_fraction": self.target_fraction,
                "max_exposure_s": self.max_exposure_s, "min_exposure_s": self.min_exposure_s,
                "full_stops": self.full_stops}

    def usable_exposures(self, offered: list[float]) -> list[float]:
        """The camera's exposures within the limits (whole stops only with ``full_stops``), shortest first."""
        usable = sorted(t for t in offered if self.min_exposure_s * (1 - 1e-6) <= t <= self.max_exposure_s * (1 + 1e-6))
        if self.full_stops:
            stops = [t for t in usable if abs(2 ** round(math.log2(t)) / t - 1) <= FULL_STOP_TOLERANCE]
            usable = stops or usable
        if not usable:
            raise ValueError(f"the camera offers no exposure within {self.min_exposure_s:g}-{self.max_exposure_s:g} s")
        return usable


def restate(error: BaseException, report: ShutterReport) -> BaseException:
    """``error`` with what is known about the shutter appended to its one-line message (same type where possible)."""
    text = f"{error}; {report.message}"
    if isinstance(error, MonochromatorError):
        return MonochromatorError(text, kind=error.kind, code=error.code,
                                  shutter="closed" if report.closed else "unknown")
    if isinstance(error, CameraError):
        return CameraError(text, error.code)
    error.add_note(report.message)
    return error


class MonoShooter:
    """One frame done safely under the monochromator: the shutter open only for the exposure, closed before the
    download, the frame written to the session first thing (resume: a step already there is not shot again)."""

    def __init__(self, camera: Camera, monochromator: Monochromator, session: Session, settings: CsrfSettings):
        self.camera = camera
        self.monochromator = monochromator
        self.session = session
        self.settings = settings
        self._frames: dict[int, RawFrame] = {}

    def shoot(self, role: Role, step: str, exposure_s: float, *, lit: bool, **meta: Any) -> SessionEntry:
        if self.session.has_step(step):
            log.info("step %s already in the session: not shot again", step)
            return self.session.entry(step)
        report: ShutterReport | None = None
        if lit:
            exposure, report = self._lit_exposure(exposure_s)
        else:
            exposure = self._expose(exposure_s)
        raw = self._fetch(exposure, report)
        settings = {k: v for k, v in self.camera.settings().__dict__.items() if v is not None}
        entry = self.session.record(raw, role.value, step_id=step, settings=settings, shutter_open=lit, **meta)
        if report is not None and not report.closed:
            raise MonochromatorError(f"{step}: the frame was saved (#{entry.seq}); {report.message}",
                                     kind=report.error.kind if report.error else "device", shutter="unknown")
        return entry

    def _lit_exposure(self, exposure_s: float) -> tuple[Exposure, ShutterReport]:
        """Shutter open, expose, shutter closed; a failure is raised after the shutter was closed, saying so."""
        self.monochromator.open_shutter()             # a failed open has closed it and says so
        exposure: Exposure | None = None
        failure: BaseException | None = None
        try:
            exposure = self._expose(exposure_s)
        except BaseException as exc:  # noqa: BLE001 - any failure, Ctrl-C too: the shutter closes first, then it is raised
            failure = exc
        report = self._close()
        if failure is not None:
            raise restate(failure, report) from failure
        assert exposure is not None
        return exposure, report

    def _close(self) -> ShutterReport:
        try:
            self.monochromator.close_shutter()
        except MonochromatorError as exc:
            log.warning("closing the shutter after the exposure: %s", exc)
            return self.monochromator.ensure_closed()
        return ShutterReport(True, "the monochromator's shutter was closed")

    def _expose(self, exposure_s: float) -> Exposure:
        return call_with_deadline(lambda: self.camera.expose(exposure_s),
                                  float(exposure_s) + self.settings.expose_timeout_s, "capture: the exposure")

    def _fetch(self, exposure: Exposure, report: ShutterReport | None) -> RawCapture:
        try:
            return call_with_deadline(lambda: self.camera.fetch(exposure), self.settings.fetch_timeout_s,
                                      "capture: the download")
        except CameraError as exc:
            raise (restate(exc, report) if report is not None else exc) from exc

    def frame(self, entry: SessionEntry) -> RawFrame:
        if entry.seq not in self._frames:
            self._frames = {entry.seq: load_raw(self.session.file_path(entry))}     # keep one: metering only
        return self._frames[entry.seq]


class CsrfSweep(BaseSequence):
    """See the module docstring."""

    name = "CSRF sweep"

    def __init__(self, camera: Camera, monochromator: Monochromator, session: Session, settings: CsrfSettings):
        super().__init__()
        self.settings = settings
        self.monochromator = monochromator
        self.shooter = MonoShooter(camera, monochromator, session, settings)
        self.usable = settings.usable_exposures(list(camera.shutter_speeds()))
        self.exposures: dict[float, float] = {}
        self.instrument: dict[str, str] = {}

    def plan(self) -> list[PlannedFrame]:
        s = self.settings
        out = []
        for nm in s.wavelengths():
            light = monochromatic_light(nm)
            out.append(PlannedFrame(Role.METERING.value, 0.0, light, "metering (1 to 5 frames)"))
            out += [PlannedFrame(Role.CSRF.value, 0.0, light, "shutter open, exposure metered")] * s.frames
        return out + [PlannedFrame(Role.DARK.value, 0.0, "", "shutter closed, at each exposure used")] * (
            s.dark_frames * DARK_EXPOSURES_ESTIMATE)

    def _done(self, nm: float) -> list[SessionEntry]:
        return [e for e in self.shooter.session.entries(Role.CSRF.value) if e.meta.get("wavelength_nm") == nm]

    def _steps(self) -> Iterator[ProgressEvent]:
        wavelengths = self.settings.wavelengths()
        total = len(wavelengths) + 1
        self.monochromator.prepare()
        self.instrument = self.monochromator.describe()
        t = snap_down(self.usable, self.settings.start_exposure_s)
        for i, nm in enumerate(wavelengths, start=1):
            done = self._done(nm)
            if len(done) >= self.settings.frames:
                t = self.exposures[nm] = done[0].exposure()
                yield ProgressEvent(i, total, f"{nm:g} nm: kept ({len(done)} frames)", kind=EventKind.KEPT,
                                    data={"wavelength_nm": nm, "exposure_s": t})
                continue
            prompt = self.monochromator.prompt_to_set(nm)
            if prompt:
                yield ProgressEvent(i - 1, total, prompt, kind=EventKind.PROMPT, data={"wavelength_nm": nm})
            t = yield from self._one_wavelength(i, total, nm, t)
        yield from self._darks(total)
        yield ProgressEvent(total, total, f"CSRF sweep: {len(wavelengths)} wavelengths, "
                                          f"{len(set(self.exposures.values()))} exposures", kind=EventKind.DONE,
                            data={"exposures": dict(self.exposures)})

    def _one_wavelength(self, i: int, total: int, nm: float, start_s: float
                        ) -> Generator[ProgressEvent, None, float]:
        reached = self.monochromator.goto(nm)
        light = monochromatic_light(nm)
        t = converge_exposure(lambda te: self._meter(nm, light, te), self.usable, start_s,
                              self.settings.target_fraction * LINEAR_LIMIT_DN, what=light)
        entry = None
        for k in range(self.settings.frames):
            step = step_id(Role.CSRF, light=light, exposure_s=t, frame=k)
            entry = self.shooter.shoot(Role.CSRF, step, t, lit=True, wavelength_nm=nm, reached_nm=reached,
                                       light_name=light)
        self.exposures[nm] = t
        assert entry is not None
        yield ProgressEvent(i, total, f"{nm:g} nm: {self.settings.frames} frame(s) at {format_exposure(t)}",
                            kind=EventKind.FRAME, data={"entry": entry.seq, "wavelength_nm": nm, "exposure_s": t})
        return t

    def _meter(self, nm: float, light: str, exposure_s: float) -> tuple[float, float]:
        step = step_id(Role.METERING, light=light, exposure_s=exposure_s)
        entry = self.shooter.shoot(Role.METERING, step, exposure_s, lit=True, wavelength_nm=nm, light_name=light)
        frame = self.shooter.frame(entry)
        return float(channel_levels(frame).max()), float(frame.white_level - max(frame.black_levels))

    def _darks(self, total: int) -> Iterator[ProgressEvent]:
        prompt = self.monochromator.prompt_to_close()
        if prompt:
            yield ProgressEvent(total - 1, total, prompt, kind=EventKind.PROMPT, data={"place": "shutter closed"})
        else:
            self.monochromator.close_shutter()
        exposures = sorted(set(self.exposures.values()))
        entry = None
        for t in exposures:
            for k in range(self.settings.dark_frames):
                entry = self.shooter.shoot(Role.DARK, step_id(Role.DARK, exposure_s=t, frame=k), t, lit=False)
        yield ProgressEvent(total, total, f"darks: {self.settings.dark_frames} at each of {len(exposures)} "
                                          "exposures, shutter closed", kind=EventKind.FRAME,
                            data={"entry": entry.seq if entry else None, "exposures": exposures})

    def _cleanup(self) -> None:
        report = self.monochromator.ensure_closed()
        if not report.closed and not self.monochromator.manual:
            log.error("monochromator: %s", report.message)
