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
from collections.abc import Callable, Iterator, Mapping, Sequence
from typing import Any

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.shooter import Shooter, channel_levels
from dualrgb.app.workflow.vocabulary import EventKind, NamedLight, Role, step_id
from dualrgb.common.formatting import format_exposure

log = logging.getLogger(__name__)

LINEAR_LIMIT_DN = 11000.0


class DarkSeries(BaseSequence):
    name = "dark series"

    def __init__(self, shooter: Shooter, exposures: Sequence[float], frames: int = 10):
        super().__init__()
        if frames < 1:
            raise ValueError(f"dark frames {frames}: expected at least 1")
        self.shooter = shooter
        self.exposures = sorted({float(t) for t in exposures})
        self.frames = frames

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.DARK.value, t, "", "lens cap on") for t in self.exposures for _ in range(self.frames)]

    def _steps(self) -> Iterator[ProgressEvent]:
        total = len(self.exposures) * self.frames
        if not self.shooter.place("lens-cap"):
            yield ProgressEvent(0, total, "Put the lens cap on, then continue", kind=EventKind.PROMPT,
                                data={"place": "lens-cap"})
        self.shooter.lights_off()
        step = 0
        for t in self.exposures:
            for i in range(self.frames):
                step_ = step_id(Role.DARK, exposure_s=t, frame=i)
                kind = EventKind.KEPT if self.shooter.session.has_step(step_) else EventKind.FRAME
                entry = self.shooter.shoot(Role.DARK.value, None, t, step_, frame_index=i)
                step += 1
                yield ProgressEvent(step, total, f"dark {i + 1}/{self.frames} at {format_exposure(t)}", kind=kind,
                                    data={"entry": entry.seq, "exposure_s": t})

    def _cleanup(self) -> Any:
        return self.shooter.lights_off()


class FlatSeries(BaseSequence):
    """Open-gate frames: ``plan`` maps each light name to the exposures it needs."""

    name = "open-gate flats"

    def __init__(self, shooter: Shooter, lights: Sequence[NamedLight], exposures: Mapping[str, Sequence[float]],
                 frames: int = 3):
        super().__init__()
        self.shooter = shooter
        self.lights = list(lights)
        self.exposures = {k: sorted({float(t) for t in v}) for k, v in exposures.items()}
        self.frames = frames
        for nl in self.lights:
            for t in self.exposures.get(nl.name, []):
                shooter.check_light_time(t)

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.FLAT.value, t, nl.light.label(), "open gate") for nl in self.lights
                for t in self.exposures.get(nl.name, []) for _ in range(self.frames)]

    def _steps(self) -> Iterator[ProgressEvent]:
        total = len(self.plan())
        if not self.shooter.place("open-gate"):
            yield ProgressEvent(0, total, "Remove the target: open gate, then continue", kind=EventKind.PROMPT,
                                data={"place": "open-gate"})
        step = 0
        for nl in self.lights:
            for t in self.exposures.get(nl.name, []):
                for i in range(self.frames):
                    step_ = step_id(Role.FLAT, light=nl.name, exposure_s=t, frame=i)
                    kind = EventKind.KEPT if self.shooter.session.has_step(step_) else EventKind.FRAME
                    entry = self.shooter.shoot(Role.FLAT.value, nl.light, t, step_, light_name=nl.name, frame_index=i)
                    step += 1
                    yield ProgressEvent(step, total, f"flat {nl.name} {i + 1}/{self.frames} at {format_exposure(t)}",
                                        kind=kind, data={"entry": entry.seq, "exposure_s": t})

    def _cleanup(self) -> Any:
        return self.shooter.lights_off()


def snap_down(shutters: Sequence[float], t: float) -> float:
    """The longest offered exposure not above ``t`` (the shortest if all are longer)."""
    ok = [s for s in shutters if s <= t * (1 + 1e-6)]
    return max(ok) if ok else min(shutters)


Meter = Callable[[float], tuple[float, float]]     # exposure_s -> (brightest level above black, headroom), DN


def converge_exposure(meter: Meter, usable: Sequence[float], start_s: float, goal_dn: float, *,
                      max_tries: int = 5, what: str = "") -> float:
    """The offered exposure (``usable``) putting the brightest level at ``goal_dn`` (snapped down: at or below it).

    ``meter(t)`` takes a frame at ``t`` and returns its brightest level and the headroom (white - black). A
    clipped frame (level >= 97 % of the headroom) cannot be scaled from: the next try is 3 stops shorter. Stops
    when the next exposure is the same or within a third of a stop of the last one (or after ``max_tries``).
    """
    t = snap_down(usable, start_s)
    for _ in range(max_tries):
        level, headroom = meter(t)
        if level >= 0.97 * headroom:                 # clipped: cannot scale from it, step down 3 stops
            new_t = snap_down(usable, t / 8)
        else:
            new_t = snap_down(usable, t * goal_dn / max(level, 1.0))
        log.info("auto-exposure %s: %g s -> level %.0f DN; next %g s", what, t, level, new_t)
        if new_t == t or (level < 0.97 * headroom and abs(math.log2(new_t / t)) < 0.34):
            return new_t
        t = new_t
    return t


def auto_exposure(shooter: Shooter, nl: NamedLight, *, start_s: float = 1 / 60, target_fraction: float = 0.8,
                  linear_limit: float = LINEAR_LIMIT_DN, max_tries: int = 5) -> tuple[float, list[int]]:
    """Exposure putting the open gate's brightest channel at ``target_fraction`` of the linear limit.

    The metering frames are kept in the session (role 'metering'); returns (exposure_s, their entry seqs).
    """
    shutters = shooter.camera.shutter_speeds()
    usable = [s for s in shutters if s <= shooter.safety.max_exposure_s]
    if not usable:
        raise ValueError(f"no shutter speed fits the {shooter.safety.max_on_s:g} s light-on limit")
    shooter.place("open-gate")
    seqs: list[int] = []

    def meter(t: float) -> tuple[float, float]:
        entry = shooter.shoot(Role.METERING.value, nl.light, t, step_id(Role.METERING, light=nl.name, exposure_s=t),
                              light_name=nl.name)
        seqs.append(entry.seq)
        frame = shooter.frame(entry)
        return float(channel_levels(frame).max()), float(frame.white_level - max(frame.black_levels))

    t = converge_exposure(meter, usable, start_s, target_fraction * linear_limit, max_tries=max_tries, what=nl.name)
    return t, seqs
