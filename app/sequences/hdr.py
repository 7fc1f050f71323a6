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
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import Checkpoint, Place, PlanSteps, ProgressEvent, ReadFrame, Shot
from dualrgb.core.vocabulary import NamedLight, Role, Subject, step_id
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


def meter_light(facts: StandFacts, nl: NamedLight, base_s: float, subject: Subject,
                boxes: Sequence[tuple[int, int, int, int]], *, take: int = 1, max_frames: int = 5) -> PlanSteps:
    """A plan answering ``nl``'s HDR plan (``plan_hdr``) and its metering frame (Taken): one frame of ``subject``
    at the light's open-gate exposure ``base_s``, kept in the session (role 'metering')."""
    sid = step_id(Role.METERING, subject=subject, light=nl.name, exposure_s=base_s, take=take)
    taken = yield Shot(Role.METERING.value, nl.light, base_s, sid, {"light_name": nl.name, "subject": subject.key})
    frame = yield ReadFrame(taken.entry)
    plan = plan_hdr(frame, base_s, boxes, facts.shutter_speeds(), max_exposure_s=facts.max_exposure_s,
                    max_frames=max_frames)
    return plan, taken


def meter_and_plan(facts: StandFacts, lights: Sequence[NamedLight], base_exposures: dict[str, float],
                   subject: Subject, boxes: Sequence[tuple[int, int, int, int]], *, take: int = 1,
                   max_frames: int = 5) -> PlanSteps:
    """A plan answering each light's HDR plan: one metering frame per light at its open-gate exposure (kept in the
    session, role 'metering'), then ``plan_hdr`` for each; checkpoints between lights (the engine switches the
    light off after the plan). Darks and flats can then be taken at the planned exposures before the bracket itself
    is shot with app.sequences.capture.SubjectCapture (app.workflow.stand.metering.HdrMetering wraps this as a plan)."""
    plans: dict[str, HdrPlan] = {}
    yield Place(subject.place, subject.nd, f"Place the {subject.label}, then continue")
    for i, nl in enumerate(lights):
        yield Checkpoint()
        t0 = base_exposures[nl.name]
        yield ProgressEvent(i, len(lights), f"HDR metering frame under {nl.name} at {t0:g} s")
        plans[nl.name], _taken = yield from meter_light(facts, nl, t0, subject, boxes, take=take,
                                                        max_frames=max_frames)
    return plans
