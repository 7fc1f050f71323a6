"""The one run engine: every device action of every run goes through it (bluesky's RunEngine is the model).

A *plan* yields typed messages (core.messages: set light, light on with its cap, a frame, read back,
prompt, checkpoint, ...) and progress events; the engine alone applies the messages to the devices
(core.device_actions) and sends each answer back into the plan. A plan is a generator function
(``engine.drive(auto_exposure(facts, light))``) or an :class:`app.sequences.base.Sequence` (``plan()`` lists its
frames before anything moves, ``_steps()`` is the generator: ``engine.run_plan(DarkSeries(facts, [1/60], 10))``).
What the engine owns:

* **one entry point**, :meth:`RunEngine.run`: the CLI (app.workflow.stand.copystand.CopyStand's calls), the window (a
  :class:`Run` executed in the runner's sequences thread, and the light held by hand: app.workflow.stand.light_plans)
  and the demo all run through it. A run starts from dark (every LED 0 and the light off, read back; a light that
  is not confirmed off refuses the run) and ends with the light off, read back; an error that does not say what
  state the light is in gets the read-back as a note. Nested calls (a calibration's plans) are one run, and one
  run at a time acts on a device (a second waits until the first has ended);
* **the devices**: only the engine's DeviceActions call the sphere, the camera, the monochromator and the
  spectroradiometer; every lit period's light dose is counted and appended to the session's manifest as it ends;
* **cancel** and **pause**: one :class:`RunControl` per run (a CancelToken plus a pause gate), checked after every
  progress event and at every Checkpoint; a cancel raises the one cancel exception, ``common.progress.Cancelled``;
* **progress**: each plan fills its share ``lo..hi`` of the run's ``progress(fraction, message)``; time left;
* **prompts**: a message for a person goes to ``prompt`` (the CLI asks on the terminal; a Run pauses until
  Continue); without one, one line says a person is needed;
* **clean-up**: after every plan (completion, cancel or error) every LED 0 and the light off, read back, and the
  monochromator's shutter closed; the free space a plan's frames need is checked before its first message.

    engine = RunEngine("calibration", StandDevices(camera, sphere, session), progress=print_progress)
    engine.run(lambda: [engine.run_plan(seq) for seq in plans])      # one run: dark at start and end
    run = Run("calibration", plan, lambda hooks: lab.copy_stand(settings, hooks).calibrate(preset))
    run.execute(emit)                                               # a worker thread; events go to ``emit``
    run.pause() / run.resume() / run.cancel()                       # from any thread
"""
from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from dualrgb.common.progress import Cancelled, CancelToken, ProgressCallback, report
from dualrgb.core.device_actions import DeviceActions, StandDevices
from dualrgb.core.light_safety import SafetySettings, StandFacts
from dualrgb.core.messages import (
    Checkpoint,
    PlannedFrame,
    PlanSteps,
    ProgressEvent,
    Prompt,
)
from dualrgb.core.vocabulary import EventKind
from dualrgb.drivers.led_sphere.errors import SphereError

if TYPE_CHECKING:
    from dualrgb.drivers.camera.base import Camera

log = logging.getLogger(__name__)

T = TypeVar("T")
RUN_PROGRESS = "run_progress"     # data key of the events that carry the whole run's progress
Prompter = Callable[[str], None]
Emit = Callable[[ProgressEvent], None]

__all__ = ["RUN_PROGRESS", "Controlled", "Plan", "PlannedFrame", "ProgressEvent", "Run", "RunClock", "RunControl",
           "RunEngine", "RunHooks", "StandDevices", "facts_of", "owning", "states_light"]


def states_light(error: BaseException) -> bool:
    """Whether an error's message already says what state the light (or the shutter) was left in."""
    if getattr(error, "light", None) is not None or getattr(error, "shutter", None) is not None:
        return True
    text = " ".join([str(error), *getattr(error, "__notes__", ())])      # a note already added says it too
    return any(words in text for words in ("switched off", "light's state", "did not confirm it is off", "shutter"))


class RunControl:
    """Cancel and pause of one run, from any thread: a CancelToken and a gate. ``checkpoint()`` between steps
    waits while paused and raises :class:`~dualrgb.common.progress.Cancelled` once cancelled."""

    def __init__(self, token: CancelToken | None = None):
        self.token = token if token is not None else CancelToken()
        self._running = threading.Event()
        self._running.set()

    def cancel(self) -> None:
        self.token.cancel()
        self._running.set()          # a paused run must wake up to notice the cancel

    def pause(self) -> None:
        self._running.clear()

    def resume(self) -> None:
        self._running.set()

    @property
    def cancelled(self) -> bool:
        return self.token.cancelled

    @property
    def paused(self) -> bool:
        return not self._running.is_set()

    def wait(self) -> None:
        """Block while paused (a cancel wakes it)."""
        self._running.wait()

    def checkpoint(self, what: str = "run") -> None:
        self._running.wait()
        if self.token.cancelled:
            raise Cancelled(f"{what} cancelled")


class Controlled:
    """Cancel / pause / resume of whatever holds a ``control`` (a plan, a run), from any thread."""

    control: RunControl

    def cancel(self) -> None:
        self.control.cancel()

    def pause(self) -> None:
        self.control.pause()

    def resume(self) -> None:
        self.control.resume()

    @property
    def cancelled(self) -> bool:
        return self.control.cancelled

    @property
    def paused(self) -> bool:
        return self.control.paused


class Plan(Protocol):
    """What :meth:`RunEngine.run_plan` runs (app.sequences.base.Sequence): its frames listed before anything
    moves, and the generator of its messages and events."""

    name: str
    control: RunControl

    def plan(self) -> list[PlannedFrame]: ...

    def _steps(self) -> Iterator[Any]: ...


_OWNERS: dict[int, threading.RLock] = {}       # id(device) -> the lock a run holds while it acts on it
_OWNERS_LOCK = threading.Lock()


@contextlib.contextmanager
def owning(devices: StandDevices, name: str) -> Iterator[None]:
    """Hold every device of a run: one run at a time acts on a device (another run on it waits here)."""
    present = sorted((d for d in (devices.sphere, devices.camera, devices.monochromator) if d is not None), key=id)
    with _OWNERS_LOCK:
        locks = [_OWNERS.setdefault(id(d), threading.RLock()) for d in present]
    with contextlib.ExitStack() as held:
        for lock in locks:
            if not lock.acquire(blocking=False):
                log.info("%s waits for the run on its devices to end", name)
                lock.acquire()
            held.callback(lock.release)
        yield


def facts_of(camera: Camera | None, safety: SafetySettings) -> StandFacts:
    """What plans shown before a run know of the stand (the camera alone, nothing lit or shot)."""
    return StandFacts(tuple(camera.shutter_speeds()) if camera is not None else (), safety.for_camera(camera))


class RunEngine:
    """Runs plans on ``devices`` under one :class:`RunControl` (see the module docstring)."""

    def __init__(self, name: str = "run", devices: StandDevices | None = None, *,
                 safety: SafetySettings = SafetySettings(), control: RunControl | None = None,
                 progress: ProgressCallback | None = None, prompt: Prompter | None = None,
                 on_event: Emit | None = None):
        self.name = name
        self.devices = devices if devices is not None else StandDevices()
        self.control = control if control is not None else RunControl()
        self.progress, self.prompt, self.on_event = progress, prompt, on_event
        self.actions = DeviceActions(self.devices, safety, self.control, self._ask, self._notice)
        self._depth = 0
        self._fraction = 0.0
        self._facts: StandFacts | None = None

    @property
    def token(self) -> CancelToken:
        return self.control.token

    @property
    def facts(self) -> StandFacts:
        """What plans know of the stand (the camera's shutter speeds, read once; the light-on rule)."""
        if self._facts is None:
            self._facts = self.actions.facts()
        return self._facts

    def check(self) -> None:
        """Between computations: raise Cancelled once the run is cancelled (and wait while paused)."""
        self.control.checkpoint(self.name)

    # ------------------------------------------------------------------------------------------ runs
    def run(self, job: Callable[[], T]) -> T:
        """``job()`` as one run: from dark, read back (refused when the light is not confirmed off) to dark, read
        back, on every path; an error that does not say the light's state gets the read-back as a note. Inside a
        run it is part of that run."""
        with self._one_run():
            return job()

    @contextlib.contextmanager
    def _one_run(self) -> Iterator[None]:
        if self._depth:
            yield
            return
        with owning(self.devices, self.name):
            self._start_dark()
            self._depth = 1
            failed: BaseException | None = None
            try:
                yield
            except BaseException as exc:
                failed = exc
                raise
            finally:
                self._depth = 0
                self._end_dark(failed)

    def run_plan(self, seq: Plan, lo: float = 0.0, hi: float = 1.0) -> list[ProgressEvent]:
        """Run a Sequence under this run's control (its free space checked first): prompts to ``prompt``,
        progress to ``lo``..``hi`` of the run, every event to ``on_event``; a cancel raises Cancelled after the
        clean-up (LEDs off, read back). Returns its events."""
        seq.control = self.control
        self.actions.check_free_space(len(seq.plan()), seq.name)      # before the run touches a device

        def job() -> list[ProgressEvent]:
            events: list[ProgressEvent] = []
            self._drive(seq._steps(), seq.name, lo, hi, events)
            return events
        return self.run(job)

    def drive(self, steps: PlanSteps, lo: float = 0.0, hi: float = 1.0, name: str = "plan") -> Any:
        """Run a generator plan to its end (one run unless inside one); its return value."""
        return self.run(lambda: self._drive(steps, name, lo, hi, []))

    def steps(self, seq: Plan, lo: float = 0.0, hi: float = 1.0) -> Iterator[ProgressEvent]:
        """A Sequence run step by step: its events as they happen (one run unless inside one, ended when the
        iterator is exhausted or closed); a cancel ends with a 'cancelled' event instead of Cancelled."""
        seq.control = self.control

        def events() -> Iterator[ProgressEvent]:
            self.actions.check_free_space(len(seq.plan()), seq.name)
            with self._one_run():
                try:
                    yield from self._events(seq._steps(), seq.name, lo, hi)
                except Cancelled:
                    yield ProgressEvent(0, 0, f"{seq.name} cancelled; lights off", kind=EventKind.CANCELLED)
        return events()

    def _drive(self, steps: Iterator[Any], name: str, lo: float, hi: float, events: list[ProgressEvent]) -> Any:
        it = self._events(steps, name, lo, hi)
        with contextlib.closing(it):
            while True:
                try:
                    events.append(next(it))
                except StopIteration as stop:
                    return stop.value

    def _events(self, steps: Iterator[Any], name: str, lo: float, hi: float) -> Generator[ProgressEvent, None, Any]:
        """The plan driven: each message applied and its answer sent back, each progress event yielded (then the
        run's control checked); the clean-up after completion, cancel or error."""
        gen: Any = steps
        t0 = time.monotonic()
        failed: BaseException | None = None
        reply: Any = None
        try:
            while True:
                try:
                    item = gen.send(reply)
                except StopIteration as stop:
                    return stop.value
                reply = None
                if isinstance(item, ProgressEvent):
                    self._event(item, lo, hi, t0)
                    yield item
                    self.control.checkpoint(name)
                else:
                    reply = self._answer(item, name)
        except Cancelled:
            log.info("%s cancelled", name)
            raise
        except BaseException as exc:
            failed = exc
            raise
        finally:
            gen.close()
            self._clean_up(name, failed)

    def _answer(self, item: Any, name: str) -> Any:
        if isinstance(item, Checkpoint):
            self.control.checkpoint(item.what or name)
            return None
        if isinstance(item, Prompt):
            with self.actions.shooter.timeline.busy("prompt"):      # a person's time (the queue's stand wait)
                self._ask(item.message, dict(item.data))
            return None
        return self.actions.apply(item)

    def _event(self, ev: ProgressEvent, lo: float, hi: float, t0: float) -> None:
        if ev.time_left_s is None and ev.step > 0:
            ev.time_left_s = (time.monotonic() - t0) / ev.step * max(ev.total - ev.step, 0)
        self._fraction = lo + (hi - lo) * ev.fraction
        report(self.progress, self._fraction, ev.message)
        if self.on_event is not None:
            self.on_event(ev)

    def _ask(self, message: str, data: dict) -> None:
        if self.prompt is None:
            raise ValueError(f"{message}: a person must do this (no stand and no prompt)")
        log.info("asking: %s", message)
        self.prompt(message)

    def _notice(self, line: str, data: dict) -> None:
        """One line the run must say (a frame set aside and shot again): the log, the progress, the events."""
        log.warning("%s", line)
        report(self.progress, self._fraction, line)
        if self.on_event is not None:
            self.on_event(ProgressEvent(0, 0, line, kind=EventKind.REJECTED, data=data))

    # ------------------------------------------------------------------------------------------ the light
    def _clean_up(self, name: str, failed: BaseException | None) -> None:
        """After a plan: every LED 0 and the light off (read back), the shutter closed; an error being raised that
        does not say what state the light is in gets the read-back as a note."""
        try:
            light = self.actions.lights_off()
            self.actions.shutter_closed()
        except Exception:  # clean-up must never mask the original error; it is logged loudly
            log.exception("%s clean-up failed", name)
            return
        if failed is not None and light is not None and not states_light(failed):
            failed.add_note(light.message)

    def _start_dark(self) -> None:
        """A run starts from dark: a light left on (by hand, by another program) is switched off and read back,
        else the run does not start."""
        light = self.actions.lights_off()
        if light is not None and not light.off:
            raise SphereError(f"{self.name} not started: {light.message}", kind="unconfirmed", light="unknown")

    def _end_dark(self, failed: BaseException | None) -> None:
        """The run's last word on the light: switched off and read back; an error that does not say the light's
        state gets the read-back as a note; a light not confirmed off after a clean run is logged loudly."""
        try:
            light = self.actions.lights_off()
        except Exception:  # the run's own error (if any) must reach the user; this one is logged loudly
            log.exception("%s: switching the light off at the end failed", self.name)
            return
        if light is None:
            return
        if failed is not None and not states_light(failed):
            failed.add_note(light.message)
        elif not light.off:
            log.error("%s ended: %s", self.name, light.message)


@dataclass
class RunHooks:
    """The callbacks a CopyStand (its engine) gets from a :class:`Run` (all called in the worker thread)."""

    progress: Callable[[float, str], None]
    cancel: CancelToken
    prompt: Callable[[str], None]
    on_event: Callable[[ProgressEvent], None]
    control: RunControl | None = None

    def stand_kwargs(self) -> dict[str, Any]:
        return {"progress": self.progress, "cancel": self.cancel, "prompt": self.prompt, "on_event": self.on_event,
                "control": self.control}

    def engine(self, name: str, devices: StandDevices, safety: SafetySettings = SafetySettings()) -> RunEngine:
        """A run engine on ``devices`` with these callbacks and the run's control."""
        return RunEngine(name, devices, safety=safety, control=self.control or RunControl(self.cancel),
                         progress=self.progress, prompt=self.prompt, on_event=self.on_event)


class RunClock(Protocol):
    """What times a run's progress (app.workflow.phase_costs.PhaseClock: the time left from measured phase costs):
    told when the run begins, asked the time left at each fraction, shown the run's events (a new plan), told how
    it ended."""

    def begin(self) -> None: ...

    def time_left(self, fraction: float) -> float | None: ...

    def saw(self, event: ProgressEvent) -> None: ...

    def finish(self, outcome: str) -> None: ...


class Run(Controlled, Generic[T]):
    """One front-end run: ``work(hooks)`` (a CopyStand call, or one plan: :meth:`of`) with sequence-like control.
    Its devices are acted on by the engine ``work`` makes from the hooks (RunEngine.run: dark at start and end).
    Progress comes as 'progress' events marked ``data[RUN_PROGRESS]`` whose ``step``/``total`` are per mille of the
    run (their time left from ``clock`` when there is one); the events of the plans inside come as they are."""

    progress_events = True           # a progress bar follows the RUN_PROGRESS events only

    def __init__(self, name: str, plan: list[PlannedFrame], work: Callable[[RunHooks], T], *, source: Any = None,
                 clock: RunClock | None = None):
        self.name = name
        self._plan = list(plan)
        self._work = work
        self.source = source          # the plan object of a one-plan run (its results, its summary)
        self.clock = clock
        self.control = RunControl()
        self.result: T | None = None
        self.outcome = ""

    @classmethod
    def of(cls, seq: Plan, engine: Callable[[RunHooks], RunEngine]) -> Run[list[ProgressEvent]]:
        """A run of one plan on the engine ``engine(hooks)`` makes."""
        return Run(seq.name, seq.plan(), lambda hooks: engine(hooks).run_plan(seq), source=seq)

    def plan(self) -> list[PlannedFrame]:
        return list(self._plan)

    def summary(self) -> str:
        """The plan's own one-line summary (a one-plan run), else ''."""
        summary = getattr(self.source, "summary", None)
        text = summary() if callable(summary) else ""
        return text if isinstance(text, str) else ""

    # ---- worker side ----
    def execute(self, emit: Emit) -> T | None:
        """Run it in the calling (worker) thread. A cancel ends with a 'cancelled' event (never an error) and no
        result; anything else propagates. The clock (if any) hears how it ended."""
        clock = self.clock
        if clock is not None:
            clock.begin()
        try:
            return self._execute(emit)
        finally:
            if clock is not None:
                try:
                    clock.finish(self.outcome if self.outcome in ("done", "cancelled") else "failed")
                except Exception:  # a time estimate never masks the run's own outcome; logged loudly
                    log.exception("%s: its phase times were not recorded", self.name)

    def _execute(self, emit: Emit) -> T | None:
        clock = self.clock

        def progress(fraction: float, message: str) -> None:
            left = clock.time_left(fraction) if clock is not None else None
            emit(ProgressEvent(int(round(1000 * fraction)), 1000, message, time_left_s=left,
                               data={RUN_PROGRESS: True}))

        def on_event(ev: ProgressEvent) -> None:
            if clock is not None:
                clock.saw(ev)
            if ev.kind is EventKind.CANCELLED:        # a plan inside stopped at the cancel and said so
                self.outcome = "cancelled"
            if ev.kind is not EventKind.PROMPT:       # prompts are announced by ``prompt``
                emit(ev)
                self.control.wait()

        def prompt(message: str) -> None:
            self.pause()
            emit(ProgressEvent(0, 0, message, kind=EventKind.PROMPT))
            self.control.wait()

        hooks = RunHooks(progress, self.control.token, prompt, on_event, self.control)
        try:
            self.result = self._work(hooks)
        except Cancelled:
            log.info("%s cancelled", self.name)
            self.outcome = "cancelled"
            emit(ProgressEvent(0, 0, f"{self.name} cancelled; lights off", kind=EventKind.CANCELLED))
            return None
        self.outcome = self.outcome or "done"
        return self.result
