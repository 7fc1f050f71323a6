"""The normal path, guarded (issue 9, "Must show"): over every sequence on the virtual lab (dark series, flats,
auto-exposure, target capture, HDR metering + bracket, CRF sweep) the sphere emulator's own record shows light
only while a frame is exposed (per frame at most exposure + settle + 0.2 s), dark between frames and at the end.
Deleting the switch-off after each shot (core/shooter.py) makes this test fail."""
from __future__ import annotations

import pytest
from light_record import LS1, LS2, lit_spans

from dualrgb.app.sequences.calibration import DarkSeries, FlatSeries, auto_exposure
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.sequences.crf_sweep import CrfSweep
from dualrgb.app.sequences.hdr import meter_and_plan
from dualrgb.core.engine import RunEngine, StandDevices
from dualrgb.core.light_safety import SafetySettings
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import Subject

SETTLE_S = 0.05
SLACK_S = 0.2           # issue 9: per frame, light on at most exposure + settle + 0.2 s


def run_every_sequence(lab, engine: RunEngine) -> None:
    facts = engine.facts
    engine.run_plan(DarkSeries(facts, [1 / 60], frames=2))
    exposures = {nl.name: engine.drive(auto_exposure(facts, nl))[0] for nl in (LS1, LS2)}
    engine.run_plan(FlatSeries(facts, [LS1, LS2], {k: [t] for k, t in exposures.items()}, frames=1))
    engine.run_plan(SubjectCapture(facts, [LS1, LS2], {k: [t] for k, t in exposures.items()}, Subject.target("test")))
    boxes = lab.scene_for("test", nd=True).patch_boxes()
    plans = engine.drive(meter_and_plan(facts, [LS1, LS2], exposures, Subject.target("test", nd=True), boxes))
    engine.run_plan(SubjectCapture(facts, [LS1, LS2], {k: p.exposures for k, p in plans.items()},
                                   Subject.target("test", nd=True)))
    engine.run_plan(CrfSweep(facts, LS1.light, levels=(1.0,), exposures=[1 / 500, 1 / 125, 1 / 30]))


@pytest.mark.fault("light safety")
def test_light_only_while_a_frame_is_exposed_over_every_sequence(lab, tmp_path):
    session = CaptureSession.create(tmp_path / "s", {"test": "normal path"})
    engine = RunEngine("test", StandDevices(lab.camera, lab.sphere, session, lab.place),
                       safety=SafetySettings(settle_s=SETTLE_S))
    t0 = lab.emulator.clock()
    first = len(lab.camera.exposure_log)
    run_every_sequence(lab, engine)
    spans = lit_spans(lab.emulator, t0)
    exposures = lab.camera.exposure_log[first:]
    lit = [e for e in exposures if e.lit]
    roles = {e.role for e in session.entries()}
    assert {"dark", "metering", "flat", "target", "crf"} <= roles, roles
    assert len(lit) == len(exposures) - 2 and len(spans) == len(lit), (len(spans), len(lit), len(exposures))
    assert all(s.t_off is not None for s in spans), "the light is still on at the end"
    worst = 0.0
    for span, frame in zip(spans, lit, strict=True):                 # one lit span per lit frame, in order, around it
        assert span.t_on <= frame.t_open and frame.t_close <= span.t_off, (span, frame)
        over = span.duration(0) - (frame.exposure_s + SETTLE_S)
        worst = max(worst, over)
        assert over <= SLACK_S, f"lit {span.duration(0):.3f} s for a {frame.exposure_s:g} s exposure"
    for frame in exposures:                             # dark frames (lens cap) saw no light at all
        inside = [s for s in spans if s.t_on <= frame.t_open <= s.t_off]
        assert bool(inside) == frame.lit
    print(f"[light safety] normal path: {len(lit)} lit frames, worst light-on beyond exposure + settle "
          f"{worst:+.3f} s")
