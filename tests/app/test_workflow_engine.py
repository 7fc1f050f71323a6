"""The one run engine (core.engine): plans yield typed messages (core.messages) and the engine alone
applies them to the devices; one RunControl per run owns cancel and pause; one cancel exception
(common.progress.Cancelled); every run starts and ends dark, read back, whichever front end starts it (a CopyStand
call for the CLI and the demo, a Run for the window, a light plan), and an error gets the read-back as a note;
one run at a time acts on a device; the manual light, the framing light and the dark are plans with their caps."""
from __future__ import annotations

import threading
import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import pytest

import dualrgb.app.sequences as sequences
from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent, Sequence
from dualrgb.app.workflow.stand.light_plans import MAX_FRAMING_LEVEL, Dark, FramingLight, HeldLight, framing_light
from dualrgb.common.progress import Cancelled, CancelToken
from dualrgb.core import messages as M
from dualrgb.core.engine import Run, RunControl, RunEngine, StandDevices
from dualrgb.core.vocabulary import EventKind
from dualrgb.drivers.led_sphere.errors import LightReport, SphereError
from dualrgb.drivers.led_sphere.supervisor import LitPeriod
from dualrgb.simulation.lightsource import LightSource

LIGHT = LightSource((1, 6, 8), (0.5, 0.5, 0.5))


@dataclass
class Sphere:
    """Records every call; ``off`` is what ensure_off answers; lit while on."""

    confirm_off: bool = True
    calls: list = field(default_factory=list)
    lit: bool = False
    channels: int = 10

    def apply(self, light) -> list[float]:
        self.calls.append("apply")
        return list(light.weights(self.channels))

    def on(self, max_on_s: float | None = None) -> LitPeriod:
        self.calls.append(f"on {max_on_s:g}")
        self.lit = True
        self.period = LitPeriod(time.monotonic(), float(max_on_s or 10.0))
        return self.period

    def off(self) -> None:
        self.calls.append("off")
        self.lit = False
        self.period.off_at = time.monotonic()

    def ensure_off(self) -> LightReport:
        self.calls.append("ensure_off")
        self.lit = not self.confirm_off and self.lit
        return LightReport(self.confirm_off, "all LEDs and the light were switched off" if self.confirm_off
                           else "the sphere did not confirm it is off")

    def keepalive(self) -> None:
        self.calls.append("keepalive")


class Frames(Sequence):
    """A plan of ``n`` steps; ``on_step(i)`` runs before step i is reported; it may fail at ``fail_at``."""

    name = "frames"

    def __init__(self, n: int, on_step=None, fail_at: int | None = None):
        super().__init__()
        self.n, self.on_step, self.fail_at = n, on_step, fail_at
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


def dark_at_both_ends(sphere: Sphere) -> bool:
    return sphere.calls[0] == "ensure_off" and sphere.calls[-1] == "ensure_off" and not sphere.lit


def test_one_cancel_exception():
    assert not hasattr(sequences, "SequenceCancelled")
    control = RunControl()
    control.cancel()
    with pytest.raises(Cancelled):
        control.checkpoint()


def test_a_cancelled_plan_stops_between_steps_and_ends_dark():
    sphere = Sphere()
    engine = RunEngine("job", StandDevices(sphere=sphere))
    seq = Frames(5, on_step=lambda i: engine.control.cancel() if i == 1 else None)
    with pytest.raises(Cancelled):
        engine.run_plan(seq)
    assert seq.taken == 2 and dark_at_both_ends(sphere)         # frame 2 was in progress: finished, nothing more


def test_plans_of_a_run_share_its_control():
    """A CopyStand-like run: the second plan never starts once the first was cancelled."""
    token = CancelToken()
    engine = RunEngine("job", control=RunControl(token))
    first = Frames(3, on_step=lambda i: token.cancel() if i == 0 else None)
    second = Frames(3)
    with pytest.raises(Cancelled):
        engine.run(lambda: (engine.run_plan(first), engine.run_plan(second)))
    assert first.control is engine.control and second.taken == 0


def test_an_error_gets_the_light_state_as_a_note():
    sphere = Sphere()
    seq = Frames(3, fail_at=1)
    with pytest.raises(RuntimeError) as info:
        RunEngine("job", StandDevices(sphere=sphere)).run_plan(seq)
    assert "switched off" in " ".join(info.value.__notes__) and dark_at_both_ends(sphere)


def test_stepwise_a_cancel_ends_with_a_cancelled_event():
    sphere = Sphere()
    engine = RunEngine("job", StandDevices(sphere=sphere))
    seq = Frames(4)
    it = engine.steps(seq)
    assert next(it).kind is EventKind.FRAME
    seq.cancel()
    rest = list(it)
    assert [e.kind for e in rest] == [EventKind.CANCELLED] and seq.taken == 1 and dark_at_both_ends(sphere)


def test_pause_waits_between_steps_and_cancel_wakes_it():
    seq = Frames(3)
    run = Run.of(seq, lambda hooks: hooks.engine("job", StandDevices()))
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


def test_a_window_run_starts_dark_and_ends_with_the_light_read_back():
    """The window's Run (a one-plan run, or a CopyStand call that fails) goes through the engine: dark at its start
    and end, read back; an error gets the read-back as a note."""
    sphere = Sphere()
    run = Run.of(Frames(2), lambda hooks: hooks.engine("job", StandDevices(sphere=sphere)))
    run.execute(lambda ev: None)
    assert dark_at_both_ends(sphere) and run.outcome == "done"

    def work(hooks):
        return hooks.engine("job", StandDevices(sphere=sphere)).run(lambda: (_ for _ in ()).throw(ValueError("x")))
    sphere.calls.clear()
    with pytest.raises(ValueError) as info:
        Run("job", [], work).execute(lambda ev: None)
    assert dark_at_both_ends(sphere) and "switched off" in " ".join(info.value.__notes__)


def test_a_run_is_not_started_when_the_light_is_not_confirmed_off():
    seq = Frames(2)
    with pytest.raises(SphereError, match="not started: the sphere did not confirm"):
        RunEngine("job", StandDevices(sphere=Sphere(confirm_off=False))).run_plan(seq)
    assert seq.taken == 0


def test_nested_calls_are_one_run():
    sphere = Sphere()
    engine = RunEngine("job", StandDevices(sphere=sphere))
    engine.run(lambda: [engine.run_plan(Frames(1)) for _ in range(3)])
    # one read-back at the start and the end of the run, one after each plan
    assert sphere.calls == ["ensure_off"] * 5


def test_copy_stand_runs_its_plans_through_its_engine():
    """CopyStand's cancel token and control are its engine's (one owner), whichever it was given; its devices
    are the engine's."""
    from dualrgb.app.workflow.stand.copystand import CopyStand

    camera, sphere = SimpleNamespace(latency_s=0.0), Sphere()
    token = CancelToken()
    stand = CopyStand(camera, sphere, None, cancel=token)           # type: ignore[arg-type]
    assert stand.cancel is token and stand.engine.token is token and stand.engine.devices.sphere is sphere
    control = RunControl()
    stand = CopyStand(camera, sphere, None, control=control)          # type: ignore[arg-type]
    seq = Frames(4, on_step=lambda i: control.cancel() if i == 2 else None)
    with pytest.raises(Cancelled):
        stand.run_sequence(seq)
    assert seq.taken == 3 and stand.cancel is control.token and dark_at_both_ends(sphere)


def test_prompts_go_to_a_person_or_say_one_is_needed():
    asked = []

    def plan():
        yield M.Prompt("Check the focus, then continue")
        yield M.Place("lens-cap", ask="Put the lens cap on, then continue")
        yield M.Place("lens-cap", ask="Put the lens cap on, then continue")      # placed already: not asked again
        yield M.Place("open-gate")
    RunEngine("job", prompt=asked.append).drive(plan())
    assert asked == ["Check the focus, then continue", "Put the lens cap on, then continue",
                     "Place the open-gate, then continue"]
    with pytest.raises(ValueError, match="Check the focus.*a person must do this"):
        RunEngine("job").drive(plan())
    placed, asked[:] = [], []
    RunEngine("job", StandDevices(stand=lambda what, nd: placed.append(what)), prompt=asked.append).drive(plan())
    assert placed == ["lens-cap", "open-gate"] and asked == ["Check the focus, then continue"]   # the stand places


def test_a_message_the_engine_does_not_know_is_refused():
    def plan():
        yield "switch the light on"
    with pytest.raises(TypeError, match="no action for str"):
        RunEngine("job").drive(plan())


def test_every_lit_period_counts_in_the_dose_and_new_levels_split_it():
    sphere = Sphere()
    engine = RunEngine("job", StandDevices(sphere=sphere))

    def plan():
        yield M.SetLight(LIGHT)
        yield M.LightOn(5.0)
        yield M.Wait(0.05)
        yield M.SetLight(LightSource((2,), (0.25,)))
        yield M.Wait(0.05)
        yield M.LightOff()
    engine.drive(plan())
    dose = engine.actions.shooter.dose
    assert 0.09 < dose.on_s < 2.0 and dose.level_s[0] > 0 and dose.level_s[1] > 0
    assert sphere.calls[1:5] == ["apply", "on 5", "apply", "off"] and dark_at_both_ends(sphere)


def test_a_light_on_without_levels_is_refused_before_switching_on():
    sphere = Sphere()

    def plan():
        yield M.LightOn(5.0)
    with pytest.raises(ValueError, match="needs a SetLight first"):
        RunEngine("job", StandDevices(sphere=sphere)).drive(plan())
    assert not any(c.startswith("on") for c in sphere.calls)


# ---------------------------------------------------------------------------------------------- the light by hand
def test_the_manual_light_is_a_plan_held_within_its_cap():
    sphere = Sphere()
    held = HeldLight(LIGHT, 0.3, tick_s=0.02)
    t0 = time.monotonic()
    RunEngine("manual light", StandDevices(sphere=sphere)).run_plan(held)
    assert 0.25 < time.monotonic() - t0 < 5.0                   # held until its cap, then off
    assert "on 0.3" in sphere.calls and dark_at_both_ends(sphere) and sphere.calls.count("on 0.3") == 1


def test_the_manual_light_ends_at_once_when_cancelled_and_new_levels_keep_its_period():
    sphere = Sphere()
    held = HeldLight(LIGHT, 5.0, tick_s=0.02)
    engine = RunEngine("manual light", StandDevices(sphere=sphere), control=held.control)
    threading.Timer(0.2, lambda: held.change(LightSource((2,), (0.3,)))).start()
    threading.Timer(0.5, held.cancel).start()
    t0 = time.monotonic()
    with pytest.raises(Cancelled):
        engine.run_plan(held)
    assert time.monotonic() - t0 < 3.0 and dark_at_both_ends(sphere)
    assert sphere.calls.count("on 5") == 1 and sphere.calls.count("apply") == 2     # one lit period, new levels


@pytest.mark.parametrize("cap", [0.0, 10.5])
def test_the_manual_light_refuses_a_cap_over_ten_seconds(cap):
    with pytest.raises(ValueError, match="a lit period of"):
        HeldLight(LIGHT, cap)


def test_the_framing_light_is_renewed_never_extended_and_stays_low():
    sphere = Sphere()
    light = framing_light(LIGHT, 0.5)                              # asked for 50 %: held at 5 %
    assert max(light.levels) == pytest.approx(MAX_FRAMING_LEVEL)
    plan = FramingLight(light, 0.4, max_s=1.3, margin_s=0.1, tick_s=0.02)
    RunEngine("framing light", StandDevices(sphere=sphere)).run_plan(plan)
    assert len(plan.periods) >= 3 and all(p.max_on_s == 0.4 for p in plan.periods)
    assert sphere.calls.count("on 0.4") == len(plan.periods) and dark_at_both_ends(sphere)
    assert "stopped after" in plan.ended and plan.level_seconds() <= MAX_FRAMING_LEVEL * (1.3 + 0.5)
    with pytest.raises(ValueError, match="above 5 %"):
        FramingLight(LightSource((1,), (0.2,)), 1.0)


def test_light_off_is_a_run_that_reads_the_light_back():
    sphere = Sphere(lit=True)
    RunEngine("light off", StandDevices(sphere=sphere)).run_plan(Dark())
    assert set(sphere.calls) == {"ensure_off"} and not sphere.lit


def test_one_run_at_a_time_acts_on_a_device():
    """A second run on the same sphere waits until the first (a held light) has ended dark."""
    sphere = Sphere()
    held = HeldLight(LIGHT, 5.0, tick_s=0.02)
    first = RunEngine("manual light", StandDevices(sphere=sphere), control=held.control)
    t = threading.Thread(target=lambda: pytest.raises(Cancelled, first.run_plan, held))
    t.start()
    deadline = time.monotonic() + 10
    while "on 5" not in sphere.calls and time.monotonic() < deadline:
        time.sleep(0.01)
    threading.Timer(0.3, held.cancel).start()
    RunEngine("capture", StandDevices(sphere=sphere)).run_plan(Frames(1))
    t.join(5)
    off_of_the_held_light = max(i for i, c in enumerate(sphere.calls) if c == "on 5")
    assert all(c == "ensure_off" for c in sphere.calls[off_of_the_held_light + 1:])   # nothing lit after it
    assert sphere.calls.count("ensure_off") >= 4 and not sphere.lit
