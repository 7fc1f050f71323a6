"""Auto-exposure and HDR metering as sequences: planned, paused between lights, cancelled with the LEDs off.

The generator plans app.sequences.calibration.auto_exposure and app.sequences.hdr.meter_light wrapped as
:class:`app.sequences.base.Sequence` s: the GUI's sequence view shows their plan, progress and time left, Esc
cancels between lights, and the engine switches the LEDs off (read back) after completion, cancel or error.
:class:`app.workflow.stand.copystand.CopyStand` runs them too, so the CLI, the demo and the GUI meter the same way.

    seq = AutoExposure(engine.facts, lights)
    engine.run_plan(seq)     # core.engine
    seq.exposures            # light name -> open-gate exposure (80 % of the linear limit, thesis 4.1)
"""
from __future__ import annotations

import logging
from collections.abc import Sequence

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.sequences.base import Sequence as BaseSequence
from dualrgb.app.sequences.calibration import OPEN_GATE, auto_exposure
from dualrgb.app.sequences.hdr import HdrPlan, meter_light
from dualrgb.core.light_safety import StandFacts
from dualrgb.core.messages import Checkpoint, Place, PlanSteps
from dualrgb.core.vocabulary import NamedLight, Role, Subject, format_exposure

log = logging.getLogger(__name__)

AUTO_EXPOSURE_START_S = 1 / 60        # app.sequences.calibration.auto_exposure's first metering exposure
Box = tuple[int, int, int, int]


class AutoExposure(BaseSequence):
    """Per light, the exposure that puts the open gate's brightest channel at 80 % of the linear limit.

    Each light takes up to five metering frames (kept in the session, role 'metering'); cancel and pause act
    between lights. ``exposures`` holds the result of every light done so far."""

    name = "auto-exposure"

    def __init__(self, facts: StandFacts, lights: Sequence[NamedLight]):
        super().__init__()
        self.facts = facts
        self.lights = list(lights)
        self.exposures: dict[str, float] = {}

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.METERING.value, AUTO_EXPOSURE_START_S, nl.light.label(),
                             "open gate; metering, up to 5 frames") for nl in self.lights]

    def _steps(self) -> PlanSteps:
        total = len(self.lights)
        yield Place("open-gate", ask=OPEN_GATE)
        for i, nl in enumerate(self.lights, start=1):
            yield Checkpoint()
            t, seqs = yield from auto_exposure(self.facts, nl)
            self.exposures[nl.name] = t
            yield ProgressEvent(i, total, f"auto-exposure: {nl.name} {format_exposure(t)}",
                                data={"entry": seqs[-1], "light": nl.name, "exposure_s": t, "role": "metering"})

    def summary(self) -> str:
        return "auto-exposure: " + ", ".join(f"{n} {format_exposure(t)}" for n, t in self.exposures.items())


class HdrMetering(BaseSequence):
    """One metering frame per light at its base exposure, then the fewest exposures that bring every region into
    the linear range (app.sequences.hdr.plan_hdr, thesis 8). ``plans`` holds each light's bracket."""

    name = "HDR metering"

    def __init__(self, facts: StandFacts, lights: Sequence[NamedLight], base_exposures: dict[str, float],
                 subject: Subject, boxes: Sequence[Box], *, take: int = 1, max_frames: int = 5):
        super().__init__()
        missing = [nl.name for nl in lights if nl.name not in base_exposures]
        if missing:
            raise ValueError(f"no base exposure for {', '.join(missing)}: run auto-exposure first")
        self.facts = facts
        self.lights = list(lights)
        self.base = {k: float(v) for k, v in base_exposures.items()}
        self.subject = subject
        self.boxes = list(boxes)
        self.take = take
        self.max_frames = max_frames
        self.plans: dict[str, HdrPlan] = {}

    def plan(self) -> list[PlannedFrame]:
        return [PlannedFrame(Role.METERING.value, self.base[nl.name], nl.light.label(),
                             f"metering {self.subject.label}") for nl in self.lights]

    def _steps(self) -> PlanSteps:
        total = len(self.lights)
        yield Place(self.subject.place, self.subject.nd, f"Place the {self.subject.label}, then continue")
        for i, nl in enumerate(self.lights, start=1):
            yield Checkpoint()
            plan, taken = yield from meter_light(self.facts, nl, self.base[nl.name], self.subject, self.boxes,
                                                 take=self.take, max_frames=self.max_frames)
            self.plans[nl.name] = plan
            yield ProgressEvent(i, total, f"HDR metering {nl.name}: {len(plan.exposures)} exposure(s)",
                                data={"entry": taken.seq, "light": nl.name, "exposures": list(plan.exposures),
                                      "role": "metering"})

    def summary(self) -> str:
        return "; ".join(f"{n}: {', '.join(format_exposure(t) for t in p.exposures)} (range {p.dynamic_range:.0f}:1"
                         + (", limited by the light-on time" if p.limited_by_light_time else "") + ")"
                         for n, p in self.plans.items())
