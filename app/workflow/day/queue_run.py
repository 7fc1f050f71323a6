"""A queue of originals captured and delivered in one run: the loop ``dualrgb capture --queue`` and the window's
Originals panel both run, and the frames an original will take, listed before anything moves.

    outcomes = capture_queue(stand, originals, profile, on_outcome=print)     # CLI: a delivered one is kept
    outcomes = capture_queue(stand, originals, profile, reshoot={"ACC-1": True, "ACC-2": False},
                             frames={"ACC-1": 2})                          # window: the technician's answers
    plan = original_plan(profile, "ACC-1", frames=2)                      # metering, then the original per light

Every original is checked first (app.workflow.stand.copystand.CopyStand.preflight: nothing is lit while one cannot be
delivered), then each is captured (metering, an HDR bracket when metering asks) and delivered, all in one run of
the stand's run engine (dark at its start and end, read back). The stand's ``on_event`` hears, per original, a
progress event when it starts and one with its outcome (``data[QUEUE_EVENT]``: 'start', 'delivered', 'kept' or
'failed'; ``data['original']``: its identifier), so a window follows the queue from its worker thread.

The day is pipelined (issue 41): while original N is delivered by a delivery worker (a thread that does no device
I/O and writes nothing in the session: app.workflow.stand.copystand.CopyStand.deliver_shot), the run's own thread - the
only one acting on the devices - meters and shoots N+1 (the operator's placement prompt between them as before).
At most two originals are in flight: N+1's delivery starts once N's has ended, before N+2 is shot. A delivery
that fails is reported against its original (state 'failed', its frames stay in the session: ``dualrgb process``
delivers them again) and never stops or loses the next one's frames; a cancel stops both (the worker sees the same
cancel token). ``pipelined=False`` delivers each original before the next is metered (the sequential day).

Each outcome carries ``capture_s`` (checks, metering and frames), ``deliver_s`` (its delivery) and
``stand_wait_s``: between the end of the previous original's last exposure and the trigger of this one's first,
the seconds the stand waited for the computer - placement and prompts, the light's settle time and the frames'
downloads excluded (core.stand_timeline).

Priority: the delivery worker lowers its own scheduling priority (nice +10 on Linux, where nice is per thread;
the threads it starts inherit it), so the run's thread that times the light and the camera does not share its core
evenly with the delivery; where that is not possible it says so once in the log and runs at the same priority.
"""
from __future__ import annotations

import logging
import os
import statistics
import threading
import time
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Future, ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from dualrgb.app.workflow.day.queue_clock import QueueClock
from dualrgb.app.workflow.delivery.delivery import Delivery, Original
from dualrgb.app.workflow.delivery.delivery_folder import sidecar_identifier
from dualrgb.app.workflow.stand.copystand import CaptureReport, CopyStand, ShotOriginal
from dualrgb.common.progress import Cancelled
from dualrgb.core.messages import PlannedFrame, ProgressEvent
from dualrgb.core.session.paths import deliverable
from dualrgb.core.vocabulary import Role

if TYPE_CHECKING:
    from dualrgb.app.workflow.calibration.profile import CalibrationProfile
    from dualrgb.core.protocols import Session

log = logging.getLogger(__name__)

QUEUE_EVENT = "queue"          # data key of the queue's own events: 'start', 'delivered', 'kept', 'failed'
WORKER_NICE = 10               # the delivery worker's niceness above the run's thread (Linux: per thread)


@dataclass
class QueueOutcome:
    """One original of a queue: captured and delivered (``report``), already delivered and kept (``kept``: its
    sidecar), or captured and not delivered (``error``: one line; its frames are in the session). Timings in
    seconds (module docstring; None where they do not apply)."""

    original: Original
    report: CaptureReport | None = None
    kept: Path | None = None
    error: str = ""
    capture_s: float | None = None
    deliver_s: float | None = None
    stand_wait_s: float | None = None

    def summary(self) -> str:
        if self.error:
            return (f"{self.original.identifier}: not delivered: {self.error} (its frames are in the session: "
                    "`dualrgb process` delivers them again)")
        if self.report is not None:
            return self.report.summary()
        return f"{self.original.identifier}: already delivered, kept"

    def timings(self) -> dict[str, float | None]:
        def r(v: float | None) -> float | None:
            return None if v is None else round(v, 3)
        return {"capture_s": r(self.capture_s), "deliver_s": r(self.deliver_s), "stand_wait_s": r(self.stand_wait_s)}


def median_stand_wait(outcomes: Sequence[QueueOutcome]) -> float | None:
    """The median stand wait of the originals that had one (None: fewer than two were shot)."""
    waits = [o.stand_wait_s for o in outcomes if o.stand_wait_s is not None]
    return statistics.median(waits) if waits else None


def delivered_sidecar(session: Session, original: Original) -> Path | None:
    """The sidecar of ``original``'s delivery in ``session`` (session.json 'originals'), when it exists and names
    the same identifier; None otherwise."""
    meta = (session.settings.get("originals") or {}).get(original.identifier) or {}
    sidecar = deliverable(Path(session.path), meta.get("sidecar"))
    if sidecar is None or not sidecar.is_file():
        return None
    try:
        return sidecar if sidecar_identifier(sidecar) == original.identifier else None
    except ValueError as exc:
        log.warning("%s: %s", original.identifier, exc)
        return None


def original_plan(profile: CalibrationProfile, identifier: str, frames: int = 1,
                  brackets: Mapping[str, Sequence[float]] | None = None) -> list[PlannedFrame]:
    """The frames of an original before anything moves: a metering frame per light, then the original under each
    light at its base exposure, or - once metering has planned how many exposures it needs (``brackets``: light
    name -> the exposures metering asked for) - the calibration's own exposures, as many as metering asks and the
    calibration covers (CopyStand.meter); ``frames`` per exposure."""
    brackets = brackets or {}
    plan = [PlannedFrame(Role.METERING.value, profile.base_exposures[nl.name], nl.light.label(),
                         f"metering {identifier}") for nl in profile.lights]
    for nl in profile.lights:
        have = profile.exposures.get(nl.name, [])
        times = have[:len(brackets[nl.name])] if nl.name in brackets else [profile.base_exposures[nl.name]]
        note = identifier + ("" if brackets else " (more exposures when metering asks for HDR)")
        plan += [PlannedFrame(Role.ORIGINAL.value, t, nl.light.label(), note) for t in times for _ in range(frames)]
    return plan


def capture_queue(stand: CopyStand, originals: Sequence[Original], profile: CalibrationProfile, *,
                  reshoot: bool | Mapping[str, bool] = False, out_dir: Path | None = None,
                  frames: Mapping[str, int] | None = None,
                  on_outcome: Callable[[QueueOutcome], None] | None = None,
                  pipelined: bool = True, clock: QueueClock | None = None) -> list[QueueOutcome]:
    """Capture and deliver ``originals`` in order, in one run (module docstring). ``reshoot`` True: every one is
    shot again; False: one already delivered in the session is kept and said so; a mapping (the technician's
    answers, by identifier): True shoots it again (a new take), False delivers its frames again (nothing lit for
    frames it has). ``frames``: frames per exposure by identifier (else the stand's setting). ``pipelined``:
    original N delivered while N+1 is shot (False: each delivered before the next is metered). ``clock``
    (app.workflow.day.queue_clock): the queue's one progress and its time left, its originals' phases recorded."""
    for original in originals:
        stand.preflight(original, out_dir, profile)
    stand.check_before_light(profile, out_dir, len(originals))
    if clock is not None:
        clock.pipelined = pipelined
        timed_by(stand, clock)
    day = _Day(stand, profile, reshoot, out_dir, frames or {}, on_outcome, len(originals), clock)
    if not pipelined:
        return stand.engine.run(lambda: day.run(originals, None))
    with ThreadPoolExecutor(1, thread_name_prefix="delivery", initializer=lower_priority) as worker:
        return stand.engine.run(lambda: day.run(originals, worker))


def timed_by(stand: CopyStand, clock: QueueClock) -> None:
    """The stand's progress as the whole queue's (QueueClock.fraction), the clock on the stand's timeline (a
    person's placements and prompts left out of the computer's time)."""
    clock.time.on_stand(stand)
    inner = stand.progress

    def progress(fraction: float, message: str) -> None:
        if inner is not None:
            inner(clock.fraction(fraction), message)
    stand.progress = stand.engine.progress = progress


def lower_priority() -> None:
    """The calling thread's niceness raised by WORKER_NICE (Linux: per thread; elsewhere, or when refused, it is
    logged and the thread runs at the run's priority)."""
    try:
        tid = threading.get_native_id()
        os.setpriority(os.PRIO_PROCESS, tid, os.getpriority(os.PRIO_PROCESS, tid) + WORKER_NICE)
    except (AttributeError, OSError) as exc:
        log.info("the delivery worker runs at the capture's priority (%s)", exc)


@dataclass
class _InFlight:
    """An original being delivered by the worker (or delivered already, sequentially)."""

    outcome: QueueOutcome
    shot: ShotOriginal
    future: Future[tuple[Delivery, float]]
    step: int


class _Day:
    """One queue's loop in the run's thread (module docstring)."""

    def __init__(self, stand: CopyStand, profile: CalibrationProfile, reshoot: bool | Mapping[str, bool],
                 out_dir: Path | None, frames: Mapping[str, int],
                 on_outcome: Callable[[QueueOutcome], None] | None, total: int, clock: QueueClock | None = None):
        self.stand, self.profile, self.reshoot, self.out_dir = stand, profile, reshoot, out_dir
        self.frames, self.on_outcome, self.total, self.clock = frames, on_outcome, total, clock
        self.timeline = stand.engine.actions.shooter.timeline
        self.last_end: float | None = None            # the end of the previous original's last exposure

    def run(self, originals: Sequence[Original], worker: ThreadPoolExecutor | None) -> list[QueueOutcome]:
        outcomes: list[QueueOutcome] = []
        flight: _InFlight | None = None
        try:
            for i, original in enumerate(originals):
                self.stand._check_cancel()
                _say(self.stand, i, self.total, original, "start", f"{original.identifier}: capturing")
                if self.clock is not None:
                    self.clock.started(i)
                outcome, shot = self._shoot(original)
                outcomes.append(outcome)
                if self.clock is not None and shot is None:
                    self.clock.kept(i)
                elif self.clock is not None:
                    self.clock.shot(i)
                if shot is None:
                    self._done(outcome, i + 1, "kept")
                    continue
                if flight is not None:                 # at most two in flight: N's delivery ends before N+1's
                    done, flight = flight, None
                    try:
                        self._collect(done)
                    except BaseException:
                        shot.builder.close()           # N+1's frames stay in the session, its channels go
                        raise
                flight = self._submit(outcome, shot, worker, i + 1)
                if worker is None:                     # the sequential day: delivered before the next is metered
                    done, flight = flight, None
                    self._collect(done)
            if flight is not None:
                done, flight = flight, None
                self._collect(done)
        finally:
            if flight is not None:                     # a cancel or an error while N+1 was shot: N's ends first
                self._settle(flight)
        return outcomes

    def _shoot(self, original: Original) -> tuple[QueueOutcome, ShotOriginal | None]:
        """Its frames (or it is kept), and its capture time and stand wait."""
        if isinstance(self.reshoot, Mapping):
            kept = None
            again: bool | None = self.reshoot.get(original.identifier)
        else:
            kept, again = (None if self.reshoot else delivered_sidecar(self.stand.session, original)), self.reshoot
        if kept is not None:
            return QueueOutcome(original, kept=kept), None
        since = time.monotonic()
        shot = self.stand.shoot(original, self.profile, again, self.out_dir, self.frames.get(original.identifier))
        outcome = QueueOutcome(original, capture_s=shot.capture_s)
        first = self.timeline.first_trigger_after(since)
        if self.last_end is not None and first is not None:
            outcome.stand_wait_s = self.timeline.stand_wait(self.last_end, first)
        self.last_end = self.timeline.last_end() if first is not None else self.last_end
        return outcome, shot

    def _submit(self, outcome: QueueOutcome, shot: ShotOriginal, worker: ThreadPoolExecutor | None,
                step: int) -> _InFlight:
        def job() -> tuple[Delivery, float]:
            t0 = time.monotonic()
            delivery = self.stand.deliver_shot(shot)
            return delivery, time.monotonic() - t0
        if worker is not None:
            return _InFlight(outcome, shot, worker.submit(job), step)
        future: Future[tuple[Delivery, float]] = Future()
        try:
            future.set_result(job())
        except Cancelled:
            raise
        except Exception as exc:  # noqa: BLE001 - a failed delivery is reported against its original
            future.set_exception(exc)
        return _InFlight(outcome, shot, future, step)

    def _collect(self, flight: _InFlight) -> None:
        """Wait for an original's delivery; record it in the session and report it (or its failure)."""
        outcome = flight.outcome
        try:
            delivery, outcome.deliver_s = flight.future.result()
        except Cancelled:
            raise
        except Exception as exc:  # noqa: BLE001 - reported against its original, the queue goes on
            log.error("%s: delivery failed: %s", outcome.original.identifier, exc)
            outcome.error = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
            self._timed(flight.step - 1, None)
            self._done(outcome, flight.step, "failed")
            return
        self._timed(flight.step - 1, outcome.deliver_s)
        outcome.report = self.stand.finish(flight.shot, delivery)
        self._done(outcome, flight.step, "delivered")

    def _timed(self, i: int, deliver_s: float | None) -> None:
        if self.clock is not None:
            self.clock.delivered(i, deliver_s)

    def _settle(self, flight: _InFlight) -> None:
        """After a cancel or an error in the run's thread: the delivery in flight ends (a cancel stops it too) and
        is reported unless it was cancelled; nothing here hides the run's own error."""
        try:
            self._collect(flight)
        except Cancelled:
            log.info("%s: delivery cancelled", flight.outcome.original.identifier)
        except Exception:  # the run's own error is being raised; this one is logged loudly
            log.exception("%s: recording the delivery failed", flight.outcome.original.identifier)

    def _done(self, outcome: QueueOutcome, step: int, what: str) -> None:
        _say(self.stand, step, self.total, outcome.original, what, outcome.summary(), outcome)
        if self.on_outcome is not None:
            self.on_outcome(outcome)


def _say(stand: CopyStand, step: int, total: int, original: Original, what: str, line: str,
         outcome: QueueOutcome | None = None) -> None:
    if stand.on_event is not None:
        stand.on_event(ProgressEvent(step, total, line, data={QUEUE_EVENT: what, "original": original.identifier,
                                                              "outcome": outcome}))
