"""Dark series, open-gate flats and auto-exposure (thesis 7, 8.2.1, 8.2.2).

* DarkSeries: N frames (default 10) with the lens cap on at each exposure time that will be used; the master
  dark per exposure is computed by app.processing (mean with hot-outlier rejection).
* FlatSeries: open-gate frames per light source (and per exposure for HDR): the white images of eq 7.1.
* auto_exposure: from the open gate, the exposure that puts the brightest channel at ~80 % of the sensor's
  linear limit (default 11 000 DN of 14 bits, thesis 4.1), snapped to the camera's shutter list.
"""
from __future__ import annotations

import logging
import math
from collections.abc import Callable, Mapping, Sequence

import numpy as np

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.common.formatting import format_exposure
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import Place, PlanSteps, ReadBack, ReadFrame, Shot
from dualrgb.core.vocabulary import NamedLight, Role, step_id
from dualrgb.drivers.raw import RawFrame

log = logging.getLogger(__name__)

LINEAR_LIMIT_DN = 11000.0
OPEN_GATE = "Remove the target: open gate, then continue"


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


class DarkSeries(BaseSequence):
    name = "dark series"

    def __init__(self, facts: StandFacts, exposures: Sequence[float], frames: int = 10):
        super().__init__()
        if frames < 1:
            raise ValueError(f"dark frames {frames}: expected at least 1")
        self.facts = facts
        self.exposures = sorted({float(t) for t in exposures})
        self.frames = frames

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.DARK.value, t, "", "lens cap on") for t in self.exposures for _ in range(self.frames)]

    def _steps(self) -> PlanSteps:
        total = len(self.exposures) * self.frames
        yield Place("lens-cap", ask="Put the lens cap on, then continue")
        yield ReadBack()
        step = 0
        for t in self.exposures:
            for i in range(self.frames):
                entry = yield Shot(Role.DARK.value, None, t, step_id(Role.DARK, exposure_s=t, frame=i),
                                   {"frame_index": i})
                step += 1
                yield ProgressEvent(step, total, f"dark {i + 1}/{self.frames} at {format_exposure(t)}",
                                    kind=entry.kind, data={"entry": entry.seq, "exposure_s": t})


class FlatSeries(BaseSequence):
    """Open-gate frames: ``plan`` maps each light name to the exposures it needs."""

    name = "open-gate flats"

    def __init__(self, facts: StandFacts, lights: Sequence[NamedLight], exposures: Mapping[str, Sequence[float]],
                 frames: int = 3):
        super().__init__()
        self.facts = facts
        self.lights = list(lights)
        self.exposures = {k: sorted({float(t) for t in v}) for k, v in exposures.items()}
        self.frames = frames
        for nl in self.lights:
            for t in self.exposures.get(nl.name, []):
                facts.check_light_time(t)

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.FLAT.value, t, nl.light.label(), "open gate") for nl in self.lights
                for t in self.exposures.get(nl.name, []) for _ in range(self.frames)]

    def _steps(self) -> PlanSteps:
        total = len(self.plan())
        yield Place("open-gate", ask=OPEN_GATE)
        step = 0
        for nl in self.lights:
            for t in self.exposures.get(nl.name, []):
                for i in range(self.frames):
                    entry = yield Shot(Role.FLAT.value, nl.light, t, step_id(Role.FLAT, light=nl.name, exposure_s=t,
                                                                              frame=i),
                                       {"light_name": nl.name, "frame_index": i})
                    step += 1
                    yield ProgressEvent(step, total, f"flat {nl.name} {i + 1}/{self.frames} at {format_exposure(t)}",
                                        kind=entry.kind, data={"entry": entry.seq, "exposure_s": t})


def snap_down(shutters: Sequence[float], t: float) -> float:
    """The longest offered exposure not above ``t`` (the shortest if all are longer)."""
    ok = [s for s in shutters if s <= t * (1 + 1e-6)]
    return max(ok) if ok else min(shutters)


Meter = Callable[[float], PlanSteps]     # exposure_s -> a plan answering (brightest level above black, headroom), DN


def converge_exposure(meter: Meter, usable: Sequence[float], start_s: float, goal_dn: float, *,
                      max_tries: int = 5, what: str = "") -> PlanSteps:
    """A plan answering the offered exposure (``usable``) putting the brightest level at ``goal_dn`` (snapped
    down: at or below it).

    ``meter(t)`` is a plan that takes a frame at ``t`` and answers its brightest level and the headroom (white -
    black). A clipped frame (level >= 97 % of the headroom) cannot be scaled from: the next try is 3 stops shorter.
    Stops when the next exposure is the same or within a third of a stop of the last one (or after ``max_tries``).
    """
    t = snap_down(usable, start_s)
    for _ in range(max_tries):
        level, headroom = yield from meter(t)
        if level >= 0.97 * headroom:                 # clipped: cannot scale from it, step down 3 stops
            new_t = snap_down(usable, t / 8)
        else:
            new_t = snap_down(usable, t * goal_dn / max(level, 1.0))
        log.info("auto-exposure %s: %g s -> level %.0f DN; next %g s", what, t, level, new_t)
        if new_t == t or (level < 0.97 * headroom and abs(math.log2(new_t / t)) < 0.34):
            return new_t
        t = new_t
    return t


def metered_level(frame: RawFrame) -> tuple[float, float]:
    """A metering frame's brightest channel level above black and its headroom (white - black), DN."""
    return float(channel_levels(frame).max()), float(frame.white_level - max(frame.black_levels))


def auto_exposure(facts: StandFacts, nl: NamedLight, *, start_s: float = 1 / 60, target_fraction: float = 0.8,
                  linear_limit: float = LINEAR_LIMIT_DN, max_tries: int = 5) -> PlanSteps:
    """A plan answering the exposure putting the open gate's brightest channel at ``target_fraction`` of the
    linear limit, and the entry seqs of its metering frames (kept in the session, role 'metering')."""
    usable = [s for s in facts.shutter_speeds() if s <= facts.max_exposure_s]
    if not usable:
        raise ValueError(f"no shutter speed fits the {facts.safety.max_on_s:g} s light-on limit")
    yield Place("open-gate", ask=OPEN_GATE)
    seqs: list[int] = []

    def meter(t: float) -> PlanSteps:
        entry = yield Shot(Role.METERING.value, nl.light, t, step_id(Role.METERING, light=nl.name, exposure_s=t),
                           {"light_name": nl.name})
        seqs.append(entry.seq)
        return metered_level((yield ReadFrame(entry.entry)))

    t = yield from converge_exposure(meter, usable, start_s, target_fraction * linear_limit, max_tries=max_tries,
                                     what=nl.name)
    return t, seqs
