"""When the stand was busy and when it waited for the computer: the exposures' trigger and end times and the
stand's own busy spans (a placement or a prompt, the light's settle time, a frame's download), on one clock.

    timeline = StandTimeline()
    with timeline.busy("download"):
        raw = camera.fetch(exposure)
    timeline.exposed(trigger_at, end_at)
    wait = timeline.stand_wait(last_end, first_trigger)       # the gap less the stand's own busy time

The run engine's hands (core.device_actions, core.shooter) fill it; the queue
(app.workflow.day.queue_run) reads each original's ``stand_wait_s`` from it: the time between the end of one
original's last exposure and the trigger of the next one's first exposure during which the stand did nothing but
wait for the computer (placement, prompts, settle and downloads excluded: those are the stand's and the camera's).
"""
from __future__ import annotations

import contextlib
import logging
import time
from collections import deque
from collections.abc import Callable, Iterator

log = logging.getLogger(__name__)

KEEP = 4096          # spans kept (a long day's are dropped oldest first; a queue reads only the last few)


class StandTimeline:
    """Exposures and the stand's busy spans on ``clock`` (module docstring); thread-safe enough for one writer."""

    def __init__(self, clock: Callable[[], float] = time.monotonic):
        self.clock = clock
        self.exposures: deque[tuple[float, float]] = deque(maxlen=KEEP)      # (trigger, end)
        self.spans: deque[tuple[float, float, str]] = deque(maxlen=KEEP)     # (start, end, what)

    @contextlib.contextmanager
    def busy(self, what: str) -> Iterator[None]:
        """The stand (or its camera, or a person at it) is busy for the duration of the block."""
        t0 = self.clock()
        try:
            yield
        finally:
            self.spans.append((t0, self.clock(), what))

    def exposed(self, trigger_at: float, end_at: float) -> None:
        self.exposures.append((trigger_at, end_at))

    def last_end(self) -> float | None:
        """The end of the latest exposure (None: none yet)."""
        return self.exposures[-1][1] if self.exposures else None

    def first_trigger_after(self, t: float) -> float | None:
        """The trigger of the first exposure at or after ``t`` (None: none)."""
        return next((trig for trig, _end in self.exposures if trig >= t), None)

    def stand_wait(self, since: float, until: float) -> float:
        """The seconds in ``since``..``until`` not covered by a busy span (overlapping spans counted once)."""
        covered = 0.0
        edge = since
        for start, end, _what in sorted(self.spans):
            start, end = max(start, edge), min(end, until)
            if end > start:
                covered += end - start
                edge = end
        return max(0.0, until - since - covered)
