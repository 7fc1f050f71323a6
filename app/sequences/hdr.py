"""HDR bracket planning (thesis 8): measure the scene's dynamic range from a first frame and plan the fewest
exposures that bring every region into the sensor's linear range — one when it already fits.

The first frame is taken at the light's open-gate exposure (brightest possible subject at ~80 % of the linear
limit). Each region (patch box) is measured above black; a region is well exposed when its signal lies between
``min_signal`` (default 100 DN: shot-noise SNR ~28 at ISO 50, 40x the read noise) and the linear limit. Longer
exposures are added by the largest factor that keeps the previous frame's well-exposed range overlapping (linear
limit x headroom / min_signal), until the darkest region reaches ``min_signal`` or the light-on limit stops it
(then the plan says so).
"""
from __future__ import annotations

import logging
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from dualrgb.app.sequences.calibration import LINEAR_LIMIT_DN, snap_down
from dualrgb.app.workflow.vocabulary import Role, Subject, step_id
from dualrgb.drivers.raw import RawFrame

log = logging.getLogger(__name__)


@dataclass
class HdrPlan:
    exposures: list[float]
    darkest_dn: float                 # darkest region's signal in the first frame (DN above black)
    brightest_dn: float
    dynamic_range: float              # brightest / darkest region
    limited_by_light_time: bool = False
    notes: list[str] = field(default_factory=list)

    def to_dict(self) -> dict:
        return {"exposures": self.exposures, "darkest_dn": round(self.darkest_dn, 2),
                "brightest_dn": round(self.brightest_dn, 2), "dynamic_range": round(self.dynamic_range, 2),
                "limited_by_light_time": self.limited_by_light_time, "notes": self.notes}


def region_levels(frame: RawFrame, boxes: Sequence[tuple[int, int, int, int]], shrink: float = 0.5) -> np.ndarray:
    """Per region: the mean of its brightest CFA channel above black (DN), over the central part of the box."""
    black = np.array(frame.black_levels, dtype=np.float64)
    out = np.empty(len(boxes))
    chans = frame.channels()
    for i, (r0, r1, c0, c1) in enumerate(boxes):
        dr, dc = (r1 - r0) * (1 - shrink) / 2, (c1 - c0) * (1 - shrink) / 2
        rr0, rr1, cc0, cc1 = int(r0 + dr) // 2 * 2, int(r1 - dr) // 2 * 2, int(c0 + dc) // 2 * 2, int(c1 - dc) // 2 * 2
        best = 0.0
        for _name, (r, c), idx in chans:
            plane = frame.mosaic[rr0 + r:rr1:2, cc0 + c:cc1:2]
            if plane.size:
                best = max(best, float(plane.mean()) - black[idx])
        out[i] = best
    return out


def plan_hdr(first: RawFrame, first_exposure_s: float, boxes: Sequence[tuple[int, int, int, int]],
             shutters: Sequence[float], *, max_exposure_s: float, linear_limit: float = LINEAR_LIMIT_DN,
             min_signal: float = 100.0, headroom: float = 0.8, max_frames: int = 5) -> HdrPlan:
    levels = np.maximum(region_levels(first, boxes), 1e-3)
    darkest, brightest = float(levels.min()), float(levels.max())
    plan = HdrPlan([first_exposure_s], darkest, brightest, brightest / darkest)
    usable = [s for s in shutters if s <= max_exposure_s]
    step = headroom * linear_limit / min_signal            # overlap: min_signal x step = headroom x limit
    t, dark = first_exposure_s, darkest
    while dark < min_signal and len(plan.exposures) < max_frames:
        wanted = t * min_signal / dark * 1.05
        longer = [x for x in usable if x >= wanted]
        nxt = min(longer) if longer else (max(usable) if usable else t)
        if nxt > t * step:                                   # keep consecutive frames overlapping
            nxt = snap_down(usable, t * step)
        if nxt <= t:
            plan.limited_by_light_time = True
            plan.notes.append(f"darkest region reaches only {dark:.0f} DN: the light-on limit caps exposure at "
                              f"{max_exposure_s:g} s")
            break
        dark *= nxt / t
        t = nxt
        plan.exposures.append(t)
    if len(plan.exposures) == 1:
        plan.notes.append("the scene fits the linear range: one exposure")
    log.info("HDR plan: %s (range %.0f:1)", plan.exposures, plan.dynamic_range)
    return plan


def meter_and_plan(shooter, lights, base_exposures: dict[str, float], subject: Subject,
                   boxes: Sequence[tuple[int, int, int, int]], progress=None, cancel=None, *, take: int = 1,
                   max_frames: int = 5) -> dict[str, HdrPlan]:
    """One metering frame per light at its open-gate exposure (kept in the session, role 'metering'), then
    ``plan_hdr`` for each; the lights end off. Darks and flats can then be taken at the planned exposures
    before the bracket itself is shot with app.sequences.capture.SubjectCapture."""
    plans: dict[str, HdrPlan] = {}
    try:
        shooter.place(subject.place, subject.nd)
        limit = shooter.safety.max_exposure_s
        for i, nl in enumerate(lights):
            if cancel is not None:
                cancel.check()
            t0 = base_exposures[nl.name]
            if progress is not None:
                progress(i / len(lights), f"HDR metering frame under {nl.name} at {t0:g} s")
            sid = step_id(Role.METERING, subject=subject, light=nl.name, exposure_s=t0, take=take)
            entry = shooter.shoot(Role.METERING.value, nl.light, t0, sid, light_name=nl.name, subject=subject.key)
            plans[nl.name] = plan_hdr(shooter.frame(entry), t0, boxes, shooter.camera.shutter_speeds(),
                                      max_exposure_s=limit, max_frames=max_frames)
    finally:
        shooter.lights_off()
    return plans
