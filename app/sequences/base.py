"""The sequence contract shared by every capture workflow (dark series, flats, dual-RGB, HDR, CRF ...).

    seq = DarkSeries(engine.facts, exposures=[1/60, 1/500])
    print(seq.plan())                 # frames and estimated time, before anything moves
    engine.run_plan(seq)              # the run engine applies its messages to the devices (core.engine)
    seq.cancel() / seq.pause() / seq.resume() from any thread

A sequence is a *plan* of the one run engine: ``_steps()`` is a generator of messages (core.messages:
a frame, a placement, a prompt, a checkpoint, ...) and progress events; it holds no device and calls none. What
it knows of the stand (the camera's shutter speeds, the light-on rule) comes as core.light_safety's
StandFacts. Guarantees (the engine's): before the first message the free space of the session's disk is checked
against the plan (frames x the camera's bytes per raw file) and a shortfall is refused up front; the run's control
is checked after every progress event (never in the middle of a download) and a cancel raises the one cancel
exception, common.progress.Cancelled; the LEDs are off, read back, after cancel, error or completion, and every
frame is saved to the session before the next message.
"""
from __future__ import annotations

import logging

from dualrgb.core.engine import Controlled, RunControl, states_light
from dualrgb.core.messages import PlannedFrame, PlanSteps, ProgressEvent

log = logging.getLogger(__name__)

__all__ = ["PlannedFrame", "ProgressEvent", "Sequence", "states_light"]


class Sequence(Controlled):
    """Base class: subclasses implement ``plan()`` and ``_steps()`` (a generator of messages and ProgressEvents);
    the run engine (core.engine) runs them."""

    name = "sequence"

    def __init__(self) -> None:
        self.control = RunControl()             # cancel / pause / resume (Controlled); a run shares its own

    # ---- to implement ----
    def plan(self) -> list[PlannedFrame]:
        raise NotImplementedError

    def _steps(self) -> PlanSteps:
        raise NotImplementedError
