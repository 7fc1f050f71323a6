"""Every sequence end to end on the virtual lab (sphere emulator on a real pty + virtual camera writing DNGs), run by
the one run engine: the plans yield messages, the engine alone acts on the devices."""
import threading

import numpy as np
import pytest

from dualrgb.app.sequences.calibration import DarkSeries, FlatSeries, NamedLight, auto_exposure, channel_levels
from dualrgb.app.sequences.capture import SubjectCapture
from dualrgb.app.sequences.crf_sweep import CrfSweep
from dualrgb.core.engine import RunEngine, StandDevices
from dualrgb.core.light_safety import LightSafetyError, SafetySettings
from dualrgb.core.messages import Shot
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.session.manifest import SessionError
from dualrgb.core.vocabulary import Subject
from dualrgb.drivers.camera.base import CameraError
from dualrgb.drivers.led_sphere import SphereError
from dualrgb.drivers.virtual.lab import VirtualLab
from dualrgb.simulation.lightsource import LightSource

LS1 = NamedLight("LS1", LightSource((1, 6, 8)))
LS2 = NamedLight("LS2", LightSource((3, 5, 9)))


@pytest.fixture()
def lab():
    with VirtualLab(frame_size=(240, 160), timeout_s=0.3, bumps=True) as lab:
        yield lab


def engine_on(lab, session) -> RunEngine:
    return RunEngine("test", StandDevices(lab.camera, lab.sphere, session, lab.place),
                     safety=SafetySettings(settle_s=0.0))


@pytest.fixture()
def engine(lab, tmp_path):
    return engine_on(lab, CaptureSession.create(tmp_path / "s", {"test": True}))


def shot(engine, role, light, t, step):
    def plan():
        return (yield Shot(role, light, t, step))
    return engine.drive(plan()).entry


def lights_off(lab) -> bool:
    snap = lab.emulator.snapshot()
    return not snap.light_on and not np.any(snap.levels)


def test_auto_exposure_hits_80_percent_of_the_linear_limit(engine, lab):
    t, seqs = engine.drive(auto_exposure(engine.facts, LS1))
    assert t in lab.camera.shutter_speeds() and seqs
    lab.place("open-gate")
    e = shot(engine, "check", LS1.light, t, "check")
    level = channel_levels(engine.actions.shooter.frame(e)).max()
    assert 0.55 * 11000 <= level <= 0.9 * 11000          # within a third of a stop below the 80 % goal
    assert lights_off(lab)


def test_dark_series_and_flats_record_everything_with_lights_off(engine, lab):
    seq = DarkSeries(engine.facts, [1 / 60, 1 / 500], frames=3)
    assert len(seq.plan()) == 6
    events = engine.run_plan(seq)
    assert [e.kind for e in events].count("frame") == 6
    session, shooter = engine.devices.session, engine.actions.shooter
    darks = session.entries("dark")
    assert len(darks) == 6 and all(e.light is None for e in darks)
    mean = shooter.frame(darks[0]).mosaic.mean()
    assert 598 < mean < 606                                 # lens cap: black level + noise
    flats = FlatSeries(engine.facts, [LS1, LS2], {"LS1": [1 / 80], "LS2": [1 / 200]}, frames=2)
    engine.run_plan(flats)
    assert len(session.entries("flat")) == 4
    assert shooter.dose.on_s > 0 and shooter.dose.lux_s > 0
    assert lights_off(lab)


def test_cancel_mid_sequence_leaves_lights_off_and_resume_finishes(engine, lab):
    seq = SubjectCapture(engine.facts, [LS1, LS2], {"LS1": [1 / 80, 1 / 40], "LS2": [1 / 200]},
                         Subject.target("train"))
    it = engine.steps(seq)
    first = next(it)
    assert first.kind == "frame"
    seq.cancel()
    rest = list(it)
    assert rest[-1].kind == "cancelled"
    assert lights_off(lab)
    session = engine.devices.session
    done = len(session.entries("target"))
    assert done == 1
    again = SubjectCapture(engine.facts, [LS1, LS2], {"LS1": [1 / 80, 1 / 40], "LS2": [1 / 200]},
                           Subject.target("train"))
    events = engine_on(lab, session).run_plan(again)
    assert len(session.entries("target")) == 3        # the first frame was not shot again
    assert [e.kind for e in events] == ["kept", "frame", "frame"]


def test_pause_and_resume_from_another_thread(engine, lab):
    seq = DarkSeries(engine.facts, [1 / 100], frames=4)
    it = engine.steps(seq)
    next(it)
    seq.pause()
    assert seq.paused
    threading.Timer(0.2, seq.resume).start()
    rest = list(it)
    assert len([e for e in rest if e.kind == "frame"]) == 3


def test_light_on_limit_refuses_long_exposures_before_switching_on(engine, lab):
    with pytest.raises(LightSafetyError, match="over the 10 s limit"):
        shot(engine, "target", LS1.light, 15.0, "too-long")
    with pytest.raises(LightSafetyError, match="over the 10 s limit"):      # the plan itself, before a run
        SubjectCapture(engine.facts, [LS1], {"LS1": [15.0]}, Subject.target("train"))
    assert lights_off(lab) and len(engine.devices.session) == 0


@pytest.mark.parametrize("fault", ["no_reply", "disconnect", "garbled"])
def test_sphere_fault_stops_cleanly_with_session_valid(engine, lab, fault):
    seq = SubjectCapture(engine.facts, [LS1, LS2], {"LS1": [1 / 80], "LS2": [1 / 200]}, Subject.target("train"))
    it = engine.steps(seq)
    next(it)
    lab.emulator.inject(fault)
    with pytest.raises(SphereError):
        list(it)
    lab.emulator.inject(None)
    assert not lab.emulator.snapshot().light_on or fault != "no_reply"
    session = engine.devices.session
    assert session.verify().valid and len(session.entries("target")) == 1


def test_camera_gone_mid_sequence_turns_lights_off(engine, lab, monkeypatch):
    def gone(*_a, **_k):
        raise CameraError("[-52] camera disappeared: reconnect it", code=-52)
    monkeypatch.setattr(lab.camera, "expose", gone)
    seq = SubjectCapture(engine.facts, [LS1], {"LS1": [1 / 80]}, Subject.target("test"))
    with pytest.raises(CameraError, match="camera disappeared.*; the light was switched off$"):
        engine.run_plan(seq)
    assert lights_off(lab) and engine.devices.session.verify().valid


def test_disk_full_stops_cleanly(engine, lab, monkeypatch):
    import errno

    def full(*_a, **_k):
        raise SessionError(errno.ENOSPC, "disk full while writing the raw file")
    monkeypatch.setattr(engine.devices.session, "record", full)
    with pytest.raises(SessionError, match="disk full"):
        engine.run_plan(SubjectCapture(engine.facts, [LS1], {"LS1": [1 / 80]}, Subject.target("test")))
    assert lights_off(lab)


def test_crf_sweep_finds_linear_limit_and_flags_the_shutter_bump(engine, lab):
    seq = CrfSweep(engine.facts, LightSource((2, 5, 9)), levels=(1.0, 0.25))
    events = engine.run_plan(seq)
    summary = events[-1].data["result"]
    assert 9500 < summary["linear_limit_dn"] < 12500           # thesis 4.1: ~11 000 DN
    assert any(abs(t - 1 / 60) < 1e-9 for t in summary["flagged_exposures"])   # +3 % bump at 1/60 s
    assert lights_off(lab)


def test_session_reopens_after_the_lab_is_gone(engine, lab, tmp_path):
    engine.run_plan(DarkSeries(engine.facts, [1 / 100], frames=2))
    engine.devices.session.close()
    reopened = CaptureSession.open(engine.devices.session.path)
    assert len(reopened.entries("dark")) == 2 and reopened.verify().valid


def test_crf_without_bumps_flags_nothing(lab, tmp_path):
    lab.camera.bumps_enabled = False
    engine = engine_on(lab, CaptureSession.create(tmp_path / "nb", {}))
    seq = CrfSweep(engine.facts, LightSource((2, 5, 9)), levels=(1.0, 0.25))
    summary = engine.run_plan(seq)[-1].data["result"]
    assert summary["flagged_exposures"] == []                  # the knee onset is not a shutter bump
