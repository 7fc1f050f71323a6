"""The sequence contract shared by every capture workflow (dark series, flats, dual-RGB, HDR, CRF ...).

    seq = DarkSeries(lab.camera, lab.sphere, session, exposures=[1/60, 1/500])
    print(seq.plan())                 # frames and estimated time, before anything moves
    for event in seq.run():           # generator: one event per step; the GUI runs this in a worker thread
        show(event.fraction, event.message, event.time_left_s)
    seq.cancel() / seq.pause() / seq.resume() from any thread

Guarantees: before the first step the free space of the session's disk is checked against the plan (frames x
the camera's bytes per raw file) and a shortfall is refused up front; the cancel flag is checked between steps
(never in the middle of a download), the LEDs are off after cancel, error or completion, and every frame is
saved to the session before the next step starts.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Generator, Iterator
from dataclasses import dataclass, field
from typing import Any

from dualrgb.app.workflow.vocabulary import EventKind
from dualrgb.common.atomic_files import require_free_space

log = logging.getLogger(__name__)


class SequenceCancelled(Exception):
    """Raised inside ``run()`` when the user cancels; the generator cleans up (LEDs off) and ends."""


@dataclass
class PlannedFrame:
    role: str                    # 'dark', 'flat', 'target', 'hdr', 'crf', ...
    exposure_s: float
    light: str = ""              # light source label ('' = lights off)
    note: str = ""


@dataclass
class ProgressEvent:
    step: int                    # steps completed so far
    total: int                   # steps planned
    message: str
    kind: EventKind = EventKind.PROGRESS     # a frame saved or kept, a prompt for the user, done, cancelled
    time_left_s: float | None = None
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def fraction(self) -> float:
        return 0.0 if self.total <= 0 else min(1.0, self.step / self.total)


class Sequence:
    """Base class: subclasses implement ``plan()`` and ``_steps()`` (a generator of ProgressEvents).

    ``run()`` wraps ``_steps()`` with pause/cancel handling between steps, time-left estimates and a
    guaranteed ``_cleanup()`` (lights off) whatever happens.
    """

    name = "sequence"

    def __init__(self) -> None:
        self._cancel = threading.Event()
        self._running = threading.Event()
        self._running.set()
        self._t0: float | None = None

    # ---- control (thread-safe) ----
    def cancel(self) -> None:
        self._cancel.set()
        self._running.set()          # a paused sequence must wake up to notice the cancel

    def pause(self) -> None:
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    @property
    def cancelled(self) -> bool:
        return self._cancel.is_set()

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

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
        """Call between steps: blocks while paused, raises SequenceCancelled when cancelled."""
        self._running.wait()
        if self._cancel.is_set():
            raise SequenceCancelled(f"{self.name} cancelled")

    def estimate_left(self, step: int, total: int) -> float | None:
        if self._t0 is None or step <= 0:
            return None
        return (time.monotonic() - self._t0) / step * max(total - step, 0)

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
        self.check_free_space()
        self._t0 = time.monotonic()
        failed: BaseException | None = None
        try:
            for event in self._steps():
                if event.time_left_s is None:
                    event.time_left_s = self.estimate_left(event.step, event.total)
                yield event
                self.checkpoint()
        except SequenceCancelled:
            log.info("%s cancelled", self.name)
            yield ProgressEvent(0, 0, f"{self.name} cancelled; lights off", kind=EventKind.CANCELLED)
        except BaseException as exc:
            failed = exc
            raise
        finally:
            self._run_cleanup(failed)

    def _run_cleanup(self, failed: BaseException | None) -> None:
        """``_cleanup()``; an error being raised that does not say what state the light is in gets it as a note."""
        try:
            report = self._cleanup()
        except Exception:  # cleanup must never mask the original error; it is logged loudly
            log.exception("%s cleanup failed", self.name)
            return
        message = getattr(report, "message", None)
        if failed is not None and message and not states_light(failed):
            failed.add_note(message)


def states_light(error: BaseException) -> bool:
    """Whether an error's message already says what state the light (or the shutter) was left in."""
    if getattr(error, "light", None) is not None or getattr(error, "shutter", None) is not None:
        return True
    text = str(error)
    return any(words in text for words in ("switched off", "light's state", "did not confirm it is off", "shutter"))
