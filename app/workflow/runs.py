"""A CopyStand call run like a sequence: a plan first, then events, pause between frames, cancel, prompts.

A front end that shows sequences (the GUI's sequence view: plan table, progress, time left, Pause, Cancel,
Continue) runs a whole calibration or an original's capture the same way:

    run = StandRun("calibration", plan, lambda hooks: CopyStand(..., **hooks.stand_kwargs()).calibrate(preset))
    run.execute(emit)          # in a worker thread; every ProgressEvent goes to ``emit``
    run.pause() / run.resume() / run.cancel()   # from any thread
    run.result                 # what the call returned (None when cancelled or failed)

Pause takes effect after the frame in progress (the Shooter has already switched the light off before the
download); cancel stops before the next frame (CopyStand checks its token at every event) and the sequence's
clean-up switches the LEDs off. A prompt (place the target, cap the lens) pauses until ``resume``.
"""
from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Generic, TypeVar

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.workflow.vocabulary import EventKind
from dualrgb.common.progress import Cancelled, CancelToken

log = logging.getLogger(__name__)

T = TypeVar("T")
RUN_PROGRESS = "run_progress"     # data key of the events that carry the whole run's progress
Emit = Callable[[ProgressEvent], None]


@dataclass
class RunHooks:
    """The callbacks a CopyStand gets from a :class:`StandRun` (all called in the worker thread)."""

    progress: Callable[[float, str], None]
    cancel: CancelToken
    prompt: Callable[[str], None]
    on_event: Callable[[ProgressEvent], None]

    def stand_kwargs(self) -> dict[str, Any]:
        return {"progress": self.progress, "cancel": self.cancel, "prompt": self.prompt, "on_event": self.on_event}


class StandRun(Generic[T]):
    """``work(hooks)`` run in the caller's (worker) thread with sequence-like control; see the module docstring.

    Progress of the whole run comes as 'progress' events marked ``data[RUN_PROGRESS]`` whose ``step``/``total``
    are per mille of the run; the events of the sequences inside come as they are (their step counts that
    sequence)."""

    progress_events = True            # a progress bar follows the RUN_PROGRESS events only

    def __init__(self, name: str, plan: list[PlannedFrame], work: Callable[[RunHooks], T]):
        self.name = name
        self._plan = list(plan)
        self._work = work
        self._token = CancelToken()
        self._running = threading.Event()
        self._running.set()
        self.result: T | None = None

    # ---- control (thread-safe) ----
    def plan(self) -> list[PlannedFrame]:
        return list(self._plan)

    def cancel(self) -> None:
        self._token.cancel()
        self._running.set()

    def pause(self) -> None:
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

    @property
    def cancelled(self) -> bool:
        return self._token.cancelled

    # ---- worker side ----
    def _gate(self) -> None:
        """Between frames: wait while paused (a cancel wakes it; CopyStand stops at its next check)."""
        self._running.wait()

    def execute(self, emit: Emit) -> T | None:
        """Run ``work``; a cancel ends with a 'cancelled' event (never an error), anything else propagates."""
        def progress(fraction: float, message: str) -> None:
            emit(ProgressEvent(int(round(1000 * fraction)), 1000, message, data={RUN_PROGRESS: True}))

        def on_event(ev: ProgressEvent) -> None:
            if ev.kind is not EventKind.PROMPT:       # prompts are announced by ``prompt``
                emit(ev)
                self._gate()

        def prompt(message: str) -> None:
            self.pause()
            emit(ProgressEvent(0, 0, message, kind=EventKind.PROMPT))
            self._gate()

        hooks = RunHooks(progress, self._token, prompt, on_event)
        try:
            self.result = self._work(hooks)
        except Cancelled:
            log.info("%s cancelled", self.name)
            emit(ProgressEvent(0, 0, f"{self.name} cancelled; lights off", kind=EventKind.CANCELLED))
            return None
        return self.result
