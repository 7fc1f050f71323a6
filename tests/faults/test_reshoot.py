"""A frame whose light went off before the camera reported the end of its exposure is never used (issue 38 item 8):
cut at the limit by the host's supervisor, or switched off by the sphere itself (it reports ``trip=1``: its own
on-time limit or watchdog), it is kept aside as 'rejected', the step is shot again once, and the run says so in
one line with the rejected frame's light dose; only a second such frame stops the run
(tests/faults/test_light_limits.py)."""
from __future__ import annotations

import pytest
from light_record import FAST, LS1, assert_dark_within, lit_spans

from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.core.engine import RunEngine, StandDevices
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import EventKind, Role, Subject


def run_capture(lab, tmp_path, exposure_s, on_notice):
    """A target under LS1 at ``exposure_s`` through the run engine; ``on_notice`` is called at the run's notice
    (the line the engine says); returns (session, progress lines, events, plan)."""
    session = CaptureSession.create(tmp_path / "s", {"test": "re-shoot"})
    lines, events = [], []

    def on_event(ev):
        events.append(ev)
        if ev.kind is EventKind.REJECTED:
            on_notice()
    engine = RunEngine("test", StandDevices(lab.camera, lab.sphere, session, lab.place), safety=FAST,
                       progress=lambda _f, line: lines.append(line), on_event=on_event)
    seq = SubjectCapture(engine.facts, [LS1], {LS1.name: [exposure_s]}, Subject.target("test"))
    engine.run_plan(seq)
    return session, lines, events, seq


def assert_set_aside_once(session, lines, events, seq, t0, lab, why):
    step = seq.steps()[0]
    rejected = session.entries(Role.REJECTED.value)
    assert len(rejected) == 1 and rejected[0].meta["rejected_step"] == step and why in rejected[0].meta["reason"]
    assert session.has_step(step) and [e.role for e in session.entries(Role.TARGET.value)] == ["target"]
    said = [line for line in lines if "shooting it again once" in line]
    assert len(said) == 1 and "\n" not in said[0] and why in said[0], lines
    assert f"kept aside as rejected #{rejected[0].seq}, never used" in said[0] and "lux.s)" in said[0]
    assert [e.kind for e in events].count(EventKind.REJECTED) == 1 and seq.new == 1
    assert len(lit_spans(lab.emulator, t0)) == 2 and not lab.emulator.snapshot().light_on
    doses = [d for d in session.doses() if d.step_id == step]
    assert len(doses) == 2 and all(d.on_s > 0 for d in doses)     # both lit periods are in the dose


@pytest.mark.fault("light safety")
def test_a_frame_cut_at_the_limit_is_set_aside_and_shot_again_once(lab, tmp_path):
    lab.camera.inject("latency", delay_s=0.8)          # late once: the light is cut at its limit before the end
    t0 = lab.emulator.clock()
    session, lines, events, seq = run_capture(lab, tmp_path, 1 / 60, lambda: lab.camera.inject(None))
    assert_dark_within(lab.emulator, t0, FAST.light_limit_s(1 / 60), "a late camera, shot again")
    assert_set_aside_once(session, lines, events, seq, t0, lab, "switched off before the camera reported the end")


@pytest.mark.fault("light safety")
def test_the_sphere_switching_itself_off_during_an_exposure_is_set_aside_and_shot_again(lab, tmp_path):
    """trip=1 alone: the sphere's watchdog (0.15 s, no request during the exposure) darkens it mid-exposure while
    the host's supervisor saw nothing; the camera reported a complete exposure. Only the sphere's trip flag says
    the frame was not lit all through."""
    lab.sphere.set_watchdog(0.15)
    t0 = lab.emulator.clock()
    session, lines, events, seq = run_capture(lab, tmp_path, 0.3, lambda: lab.sphere.set_watchdog(30.0))
    spans = lit_spans(lab.emulator, t0)
    assert spans[0].ended_by == "watchdog" and spans[1].ended_by in ("LIGHT 0", "ALLOFF")
    assert_set_aside_once(session, lines, events, seq, t0, lab, "trip=1")
