"""The one run engine: every capture plan, every CopyStand call and every front end's run goes through it.

A *plan* is a generator of *steps* (``app.sequences.base.Sequence``: ``plan()`` lists its frames before anything
moves, ``_steps()`` yields one ProgressEvent per frame saved or kept, per prompt). The engine iterates plans and
is the one owner of what happens between steps:

* **cancel** and **pause**: one :class:`RunControl` per run (a CancelToken plus a pause gate), shared by every plan
  and every computation the run starts; a cancel raises the one cancel exception, ``common.progress.Cancelled``;
* **progress**: each plan fills its share of the run's ``progress(fraction, message)``; time left per plan;
* **prompts**: a step that needs a person goes to ``prompt`` (or pauses the run until Continue, in a front end);
* **light-off clean-up, read back**: every plan's clean-up after completion, cancel or error, and, for a whole
  run on a sphere, ``sphere.ensure_off()`` at the start and at the end; an error that does not say what state the
  light is in gets the read-back as a note.

    engine = RunEngine("calibration", progress=print_progress, prompt=ask_person)
    engine.run_plan(DarkSeries(shooter, [1/60], 10), 0.1, 0.35)      # steps, progress 10..35 %, clean-up
    run = Run("calibration", plan, lambda hooks: CopyStand(..., **hooks.stand_kwargs()).calibrate(preset))
    run.execute(emit, sphere=sphere)                                # a worker thread; events go to ``emit``
    run.pause() / run.resume() / run.cancel()                       # from any thread

Used by the CLI and the demo (CopyStand's ``progress`` / ``cancel`` / ``prompt``) and by the GUI (a :class:`Run`
per Start, executed in the runner's sequences thread by app.gui.sequence_view).
"""
from __future__ import annotations

import contextlib
import logging
import threading
import time
from collections.abc import Callable, Generator, Iterator
from dataclasses import dataclass, field
from typing import TYPE_CHECKING, Any, Generic, Protocol, TypeVar

from dualrgb.app.workflow.vocabulary import EventKind
from dualrgb.common.progress import Cancelled, CancelToken, ProgressCallback, report

if TYPE_CHECKING:
    from dualrgb.app.protocols import Sphere

log = logging.getLogger(__name__)

T = TypeVar("T")
RUN_PROGRESS = "run_progress"     # data key of the events that carry the whole run's progress
Prompt = Callable[[str], None]


@dataclass
class PlannedFrame:
    role: str                    # 'dark', 'flat', 'target', 'hdr', 'crf', ...
    exposure_s: float
    light: str = ""              # light source label ('' = lights off)
    note: str = ""


@dataclass
class ProgressEvent:
    """One step of a plan (a frame saved or kept, a prompt for the user, done, cancelled) or of a run."""

    step: int                    # steps completed so far
    total: int                   # steps planned
    message: str
    kind: EventKind = EventKind.PROGRESS
    time_left_s: float | None = None
    data: dict[str, Any] = field(default_factory=dict)

    @property
    def fraction(self) -> float:
        return 0.0 if self.total <= 0 else min(1.0, self.step / self.total)


Emit = Callable[[ProgressEvent], None]


def states_light(error: BaseException) -> bool:
    """Whether an error's message already says what state the light (or the shutter) was left in."""
    if getattr(error, "light", None) is not None or getattr(error, "shutter", None) is not None:
        return True
    text = str(error)
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
    """What the engine runs (app.sequences.base.Sequence): frames listed before anything moves, steps, a
    clean-up that switches the light off and may return the read-back (drivers.led_sphere.LightReport)."""

    name: str
    control: RunControl

    def plan(self) -> list[PlannedFrame]: ...

    def check_free_space(self) -> None: ...

    def _steps(self) -> Iterator[ProgressEvent]: ...

    def _cleanup(self) -> Any: ...


def steps(seq: Plan) -> Generator[ProgressEvent, None, None]:
    """A plan's steps with the engine's guarantees: free space checked before the first step, time left on every
    event, the run's control checked between steps (a cancel ends with a 'cancelled' event), the plan's clean-up
    (lights off, read back) after completion, cancel or error."""
    seq.check_free_space()
    control = seq.control
    t0 = time.monotonic()
    failed: BaseException | None = None
    try:
        for event in seq._steps():
            if event.time_left_s is None and event.step > 0:
                event.time_left_s = (time.monotonic() - t0) / event.step * max(event.total - event.step, 0)
            yield event
            control.checkpoint(seq.name)
    except Cancelled:
        log.info("%s cancelled", seq.name)
        yield ProgressEvent(0, 0, f"{seq.name} cancelled; lights off", kind=EventKind.CANCELLED)
    except BaseException as exc:
        failed = exc
        raise
    finally:
        clean_up(seq, failed)


def clean_up(seq: Plan, failed: BaseException | None) -> None:
    """``seq._cleanup()``; an error being raised that does not say what state the light is in gets it as a note."""
    try:
        light = seq._cleanup()
    except Exception:  # clean-up must never mask the original error; it is logged loudly
        log.exception("%s clean-up failed", seq.name)
        return
    message = getattr(light, "message", None)
    if failed is not None and message and not states_light(failed):
        failed.add_note(message)


class RunEngine:
    """Runs plans for one run under one :class:`RunControl` (see the module docstring)."""

    def __init__(self, name: str = "run", *, control: RunControl | None = None,
                 progress: ProgressCallback | None = None, prompt: Prompt | None = None,
                 on_event: Emit | None = None):
        self.name = name
        self.control = control if control is not None else RunControl()
        self.progress, self.prompt, self.on_event = progress, prompt, on_event

    @property
    def token(self) -> CancelToken:
        return self.control.token

    def check(self) -> None:
        """Between computations: raise Cancelled once the run is cancelled (and wait while paused)."""
        self.control.checkpoint(self.name)

    def run_plan(self, seq: Plan, lo: float = 0.0, hi: float = 1.0) -> list[ProgressEvent]:
        """Iterate ``seq`` under this run's control: prompts to ``prompt``, progress to ``lo``..``hi`` of the
        run, every event to ``on_event``; a cancel raises Cancelled after the plan's clean-up (LEDs off)."""
        seq.control = self.control
        events = []
        with contextlib.closing(steps(seq)) as plan:     # an error in a callback cleans up at once (lights off)
            for ev in plan:
                if ev.kind is EventKind.CANCELLED:
                    raise Cancelled(ev.message)
                if ev.kind is EventKind.PROMPT:
                    if self.prompt is None:
                        raise ValueError(f"{ev.message}: a person must do this (no stand and no prompt)")
                    self.prompt(ev.message)
                report(self.progress, lo + (hi - lo) * ev.fraction, ev.message)
                if self.on_event is not None:
                    self.on_event(ev)
                events.append(ev)
        return events


@dataclass
class RunHooks:
    """The callbacks a CopyStand gets from a :class:`Run` (all called in the worker thread)."""

    progress: Callable[[float, str], None]
    cancel: CancelToken
    prompt: Callable[[str], None]
    on_event: Callable[[ProgressEvent], None]
    control: RunControl | None = None

    def stand_kwargs(self) -> dict[str, Any]:
        return {"progress": self.progress, "cancel": self.cancel, "prompt": self.prompt, "on_event": self.on_event,
                "control": self.control}


class Run(Controlled, Generic[T]):
    """One front-end run: a bare plan (a Sequence) or ``work(hooks)`` (a CopyStand call), with sequence-like
    control. Progress of a ``work`` run comes as 'progress' events marked ``data[RUN_PROGRESS]`` whose
    ``step``/``total`` are per mille of the run; the events of the plans inside come as they are."""

    def __init__(self, name: str, plan: list[PlannedFrame], work: Callable[[RunHooks], T] | None = None, *,
                 seq: Plan | None = None):
        if (work is None) == (seq is None):
            raise ValueError("a run is either a plan (seq) or a CopyStand call (work)")
        self.name = name
        self._plan = list(plan)
        self._work = work
        self.seq = seq
        self.control = seq.control if seq is not None else RunControl()
        self.result: T | None = None
        self.outcome = ""

    @classmethod
    def of(cls, seq: Plan) -> Run[None]:
        return Run(seq.name, seq.plan(), seq=seq)

    @property
    def progress_events(self) -> bool:
        """Whether a progress bar follows the RUN_PROGRESS events only (a CopyStand call) or every event."""
        return self._work is not None

    def plan(self) -> list[PlannedFrame]:
        return list(self._plan)

    # ---- worker side ----
    def execute(self, emit: Emit, sphere: Sphere | None = None) -> T | None:
        """Run it in the calling (worker) thread. With ``sphere`` the run starts from dark (a light left on by
        hand is switched off first, read back) and ends with the light off, read back. A cancel ends with a
        'cancelled' event (never an error) and no result; anything else propagates."""
        if sphere is not None:
            light = sphere.ensure_off()
            if not light.off:
                raise RuntimeError(f"{self.name} not started: {light.message}")
        failed: BaseException | None = None
        try:
            if self.seq is not None:
                self._iterate(emit)
            else:
                self.result = self._call(emit)
        except BaseException as exc:
            failed = exc
            raise
        finally:
            if sphere is not None:
                _light_off(sphere, self.name, failed)
        self.outcome = self.outcome or "done"
        return self.result

    def _iterate(self, emit: Emit) -> None:
        assert self.seq is not None
        with contextlib.closing(steps(self.seq)) as plan:   # an error in ``emit`` cleans up at once
            for event in plan:
                if event.kind is EventKind.PROMPT:
                    self.pause()                       # the next step waits for Continue
                elif event.kind is EventKind.CANCELLED:
                    self.outcome = "cancelled"
                emit(event)

    def _call(self, emit: Emit) -> T | None:
        assert self._work is not None

        def progress(fraction: float, message: str) -> None:
            emit(ProgressEvent(int(round(1000 * fraction)), 1000, message, data={RUN_PROGRESS: True}))

        def on_event(ev: ProgressEvent) -> None:
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
            result = self._work(hooks)
        except Cancelled:
            log.info("%s cancelled", self.name)
            self.outcome = "cancelled"
            emit(ProgressEvent(0, 0, f"{self.name} cancelled; lights off", kind=EventKind.CANCELLED))
            return None
        return result


def _light_off(sphere: Sphere, name: str, failed: BaseException | None) -> None:
    """The run's last word on the light: switched off and read back; an error that does not say the light's
    state gets the read-back as a note; a light not confirmed off after a clean run is logged loudly."""
    try:
        light = sphere.ensure_off()
    except Exception:  # the run's own error (if any) must reach the user; this one is logged loudly
        log.exception("%s: switching the light off at the end failed", name)
        return
    if failed is not None and not states_light(failed):
        failed.add_note(light.message)
    elif not light.off:
        log.error("%s ended: %s", name, light.message)
