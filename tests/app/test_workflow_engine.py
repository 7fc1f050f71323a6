"""The one run engine (app.workflow.engine): plans yield steps; one RunControl per run owns cancel and pause; one
cancel exception (common.progress.Cancelled); the clean-up switches the light off after completion, cancel and
error, and a run on a sphere ends with the light off, read back."""
from __future__ import annotations

import threading

import pytest

import dualrgb.app.sequences as sequences
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent, Sequence
from dualrgb.app.workflow.engine import Run, RunControl, RunEngine
from dualrgb.app.workflow.vocabulary import EventKind
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.drivers.led_sphere.errors import LightReport


class Frames(Sequence):
    """A plan of ``n`` frames; ``on_step(i)`` runs before frame i is reported; its clean-up is recorded."""

    name = "frames"

    def __init__(self, n: int, on_step=None, fail_at: int | None = None):
        super().__init__()
        self.n, self.on_step, self.fail_at = n, on_step, fail_at
        self.cleaned = 0
        self.taken = 0

    def plan(self):
        return [PlannedFrame("dark", 0.01) for _ in range(self.n)]

    def _steps(self):
        for i in range(self.n):
            if self.on_step is not None:
                self.on_step(i)
            if i == self.fail_at:
                raise RuntimeError("camera gone")
            self.taken += 1
            yield ProgressEvent(i + 1, self.n, f"frame {i + 1}", kind=EventKind.FRAME)

    def _cleanup(self):
        self.cleaned += 1
        return LightReport(True, "the light was switched off (confirmed)")


class Sphere:
    """Counts ensure_off calls; ``off`` is what it answers."""

    def __init__(self, off: bool = True):
        self.off, self.calls = off, 0

    def ensure_off(self) -> LightReport:
        self.calls += 1
        return LightReport(self.off, "the light was switched off (confirmed)" if self.off
                           else "the sphere did not confirm it is off")


def test_one_cancel_exception():
    assert not hasattr(sequences, "SequenceCancelled")
    control = RunControl()
    control.cancel()
    with pytest.raises(Cancelled):
        control.checkpoint()


def test_a_cancelled_plan_stops_between_steps_and_cleans_up():
    engine = RunEngine("job")
    seq = Frames(5, on_step=lambda i: engine.control.cancel() if i == 1 else None)
    with pytest.raises(Cancelled):
        engine.run_plan(seq)
    assert seq.taken == 2 and seq.cleaned == 1          # frame 2 was in progress: finished, then nothing more


def test_plans_of_a_run_share_its_control():
    """A CopyStand-like run: the second plan never starts once the first was cancelled."""
    token = CancelToken()
    engine = RunEngine("job", control=RunControl(token))
    first = Frames(3, on_step=lambda i: token.cancel() if i == 0 else None)
    second = Frames(3)
    with pytest.raises(Cancelled):
        engine.run_plan(first)
        engine.run_plan(second)
    assert first.control is engine.control and second.taken == 0


def test_an_error_gets_the_light_state_as_a_note():
    seq = Frames(3, fail_at=1)
    with pytest.raises(RuntimeError) as info:
        list(seq.run())
    assert seq.cleaned == 1 and "switched off" in " ".join(info.value.__notes__)


def test_pause_waits_between_steps_and_cancel_wakes_it():
    seq = Frames(3)
    run = Run.of(seq)
    seen: list[ProgressEvent] = []
    reached = threading.Event()

    def emit(ev):
        seen.append(ev)
        if ev.kind is EventKind.FRAME and ev.step == 1:
            run.pause()
            reached.set()
    t = threading.Thread(target=lambda: run.execute(emit))
    t.start()
    assert reached.wait(5)
    t.join(0.3)
    assert t.is_alive() and seq.taken == 1               # paused after frame 1
    run.cancel()
    t.join(5)
    assert not t.is_alive() and seq.taken == 1 and run.outcome == "cancelled"
    assert seen[-1].kind is EventKind.CANCELLED


def test_a_run_on_a_sphere_starts_dark_and_ends_with_the_light_read_back():
    sphere = Sphere()
    run = Run.of(Frames(2))
    run.execute(lambda ev: None, sphere=sphere)
    assert sphere.calls == 2 and run.outcome == "done"

    def work(hooks):
        raise ValueError("no flats")
    sphere = Sphere()
    with pytest.raises(ValueError) as info:
        Run("job", [], work).execute(lambda ev: None, sphere=sphere)
    assert sphere.calls == 2 and "switched off" in " ".join(info.value.__notes__)


def test_a_run_not_started_when_the_light_is_not_confirmed_off():
    seq = Frames(2)
    with pytest.raises(RuntimeError, match="not started: the sphere did not confirm"):
        Run.of(seq).execute(lambda ev: None, sphere=Sphere(off=False))
    assert seq.taken == 0


def test_copy_stand_runs_its_plans_through_its_engine():
    """CopyStand's cancel token and control are its engine's (one owner), whichever it was given."""
    from types import SimpleNamespace

    from dualrgb.app.workflow.copystand import CopyStand

    camera = SimpleNamespace(latency_s=0.0)
    token = CancelToken()
    stand = CopyStand(camera, None, None, cancel=token)           # type: ignore[arg-type]
    assert stand.cancel is token and stand.engine.token is token
    control = RunControl()
    stand = CopyStand(camera, None, None, control=control)          # type: ignore[arg-type]
    seq = Frames(4, on_step=lambda i: control.cancel() if i == 2 else None)
    with pytest.raises(Cancelled):
        stand.run_sequence(seq)
    assert seq.taken == 3 and seq.cleaned == 1 and stand.cancel is control.token
