"""The sequence contract shared by every capture workflow (dark series, flats, dual-RGB, HDR, CRF ...).

    seq = DarkSeries(lab.camera, lab.sphere, session, exposures=[1/60, 1/500])
    print(seq.plan())                 # frames and estimated time, before anything moves
    for event in seq.run():           # generator: one event per step; the GUI runs this in a worker thread
        show(event.fraction, event.message, event.time_left_s)
    seq.cancel() / seq.pause() / seq.resume() from any thread

A sequence is a *plan* of the one run engine (app.workflow.engine): ``run()`` is the engine's ``steps(seq)``, and
``cancel`` / ``pause`` / ``resume`` act on the sequence's RunControl, which a run shares with every plan in it.
Guarantees (the engine's): before the first step the free space of the session's disk is checked against the plan
(frames x the camera's bytes per raw file) and a shortfall is refused up front; the cancel flag is checked between
steps (never in the middle of a download) and raises the one cancel exception, common.progress.Cancelled; the
LEDs are off after cancel, error or completion, and every frame is saved to the session before the next step
starts.
"""
from __future__ import annotations

import logging
from collections.abc import Generator, Iterator
from typing import Any

from dualrgb.app.workflow.engine import Controlled, PlannedFrame, ProgressEvent, RunControl, states_light, steps
from dualrgb.common.atomic_files import require_free_space

log = logging.getLogger(__name__)

__all__ = ["PlannedFrame", "ProgressEvent", "Sequence", "states_light"]


class Sequence(Controlled):
    """Base class: subclasses implement ``plan()`` and ``_steps()`` (a generator of ProgressEvents) and
    ``_cleanup()`` (lights off); the run engine (app.workflow.engine) drives them."""

    name = "sequence"

    def __init__(self) -> None:
        self.control = RunControl()             # cancel / pause / resume (Controlled); a run shares its own

    # ---- to implement ----
    def plan(self) -> list[PlannedFrame]:
        raise NotImplementedError

    def _steps(self) -> Iterator[ProgressEvent]:
        raise NotImplementedError

    def _cleanup(self) -> Any:
        """Turn lights off etc.; called after completion, cancel and error. It may return what is known about the
        light afterwards (drivers.led_sphere.LightReport): an error that does not say it gets it as a note."""

    # ---- driver ----
    def checkpoint(self) -> None:
        """Call between steps: blocks while paused, raises common.progress.Cancelled when cancelled."""
        self.control.checkpoint(self.name)

    def estimated_bytes(self) -> int:
        """Disk space the planned frames need: frames x the camera's bytes per raw file (0 without a camera)."""
        camera = getattr(getattr(self, "shooter", None), "camera", None)
        frame_bytes = getattr(camera, "frame_bytes", None)
        return len(self.plan()) * int(frame_bytes()) if callable(frame_bytes) else 0

    def check_free_space(self) -> None:
        """Refuse up front (InsufficientSpaceError, one line) a sequence whose frames cannot fit on the disk
        of its session folder; nothing has been switched on or shot when it is raised."""
        session = getattr(getattr(self, "shooter", None), "session", None)
        needed = self.estimated_bytes()
        if session is not None and needed:
            require_free_space(session.path, needed, f"the {self.name} ({len(self.plan())} frames)")

    def run(self) -> Generator[ProgressEvent, None, None]:
        """The steps under the engine's guarantees (app.workflow.engine.steps)."""
        return steps(self)
