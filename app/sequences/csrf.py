"""The camera's spectral sensitivity (CSRF) measured with a monochromator (thesis 4.2): a sweep of monochromatic
frames, then darks at every exposure the sweep used.

    seq = CsrfSweep(engine.facts, CsrfSettings(380, 780, 10))
    engine.run_plan(seq)                 # core.engine; a hand-set monochromator's prompts go to ``prompt``
    seq.exposures                        # wavelength -> exposure

Per wavelength: the monochromator is set (a Tune message; the engine asks the person first for a
:class:`drivers.monochromator.ManualMonochromator`), the exposure is metered on metering frames so that the
brightest channel sits at ``target_fraction`` of the sensor's linear limit (app.sequences.calibration's
converge_exposure, the auto-exposure of the calibration; snapped down to a full stop, so it is at most that and at
least half of it, and never clipped), then ``frames`` frames are taken. After the sweep the shutter is closed and
``dark_frames`` darks are taken at every exposure used (exposures are only known once metered; one closed-shutter
period, one prompt for a hand-set instrument). Light safety: the shutter is opened for each exposure and closed as
soon as the camera reports it over, before the download (a ShutterShot: core.shutter_shooter); on every
error, cancel and at the end the engine closes it. Every frame is in the session before the next step; a resumed
sweep skips wavelengths already done.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Generator
from dataclasses import dataclass
from typing import Any

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.calibration import LINEAR_LIMIT_DN, converge_exposure, metered_level, snap_down
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import CloseShutter, Entries, Instrument, PlanSteps, ReadFrame, ShutterShot, Tune
from dualrgb.core.vocabulary import EventKind, Role, format_exposure, monochromatic_light, step_id

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


class CsrfSweep(BaseSequence):
    """See the module docstring."""

    name = "CSRF sweep"

    def __init__(self, facts: StandFacts, settings: CsrfSettings):
        super().__init__()
        self.settings = settings
        self.usable = settings.usable_exposures(facts.shutter_speeds())
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

    def _steps(self) -> PlanSteps:
        wavelengths = self.settings.wavelengths()
        total = len(wavelengths) + 1
        self.instrument = yield Instrument()
        done: dict[float, list[Any]] = {}
        for e in (yield Entries(Role.CSRF.value)):
            done.setdefault(e.meta.get("wavelength_nm"), []).append(e)
        t = snap_down(self.usable, self.settings.start_exposure_s)
        for i, nm in enumerate(wavelengths, start=1):
            if len(done.get(nm, [])) >= self.settings.frames:
                t = self.exposures[nm] = done[nm][0].exposure()
                yield ProgressEvent(i, total, f"{nm:g} nm: kept ({len(done[nm])} frames)", kind=EventKind.KEPT,
                                    data={"wavelength_nm": nm, "exposure_s": t})
                continue
            t = yield from self._one_wavelength(i, total, nm, t)
        yield from self._darks(total)
        yield ProgressEvent(total, total, f"CSRF sweep: {len(wavelengths)} wavelengths, "
                                          f"{len(set(self.exposures.values()))} exposures", kind=EventKind.DONE,
                            data={"exposures": dict(self.exposures)})

    def _one_wavelength(self, i: int, total: int, nm: float, start_s: float
                        ) -> Generator[Any, Any, float]:
        reached = yield Tune(nm)
        light = monochromatic_light(nm)
        t = yield from converge_exposure(lambda te: self._meter(nm, light, te), self.usable, start_s,
                                         self.settings.target_fraction * LINEAR_LIMIT_DN, what=light)
        taken = None
        for k in range(self.settings.frames):
            step = step_id(Role.CSRF, light=light, exposure_s=t, frame=k)
            taken = yield ShutterShot(Role.CSRF.value, step, t, True,
                                      {"wavelength_nm": nm, "reached_nm": reached, "light_name": light})
        self.exposures[nm] = t
        assert taken is not None
        yield ProgressEvent(i, total, f"{nm:g} nm: {self.settings.frames} frame(s) at {format_exposure(t)}",
                            kind=EventKind.FRAME, data={"entry": taken.seq, "wavelength_nm": nm, "exposure_s": t})
        return t

    def _meter(self, nm: float, light: str, exposure_s: float) -> PlanSteps:
        step = step_id(Role.METERING, light=light, exposure_s=exposure_s)
        taken = yield ShutterShot(Role.METERING.value, step, exposure_s, True,
                                  {"wavelength_nm": nm, "light_name": light})
        return metered_level((yield ReadFrame(taken.entry, keep=False)))

    def _darks(self, total: int) -> PlanSteps:
        yield CloseShutter()
        exposures = sorted(set(self.exposures.values()))
        taken = None
        for t in exposures:
            for k in range(self.settings.dark_frames):
                taken = yield ShutterShot(Role.DARK.value, step_id(Role.DARK, exposure_s=t, frame=k), t, False)
        yield ProgressEvent(total, total, f"darks: {self.settings.dark_frames} at each of {len(exposures)} "
                                          "exposures, shutter closed", kind=EventKind.FRAME,
                            data={"entry": taken.seq if taken else None, "exposures": exposures})
