"""The workflow layer's additions for the copy-stand GUI (issue 11), Qt-free: metering as sequences (cancel between
lights, LEDs off), a CopyStand call run like a sequence (pause, cancel, prompts), the day's checklist and queue,
coverage of a calibration, planned steps and takes, frame checks and the flats' uniformity map."""
from __future__ import annotations

import json
import threading
from pathlib import Path
from types import SimpleNamespace

import numpy as np
import pytest

from dualrgb.app.sequences.base import PlannedFrame, ProgressEvent
from dualrgb.app.workflow.calibration.coverage import plan_coverage
from dualrgb.app.workflow.calibration.frame_checks import DARK_FRACTION, check_frame
from dualrgb.app.workflow.day.day import DayState, DayStep, OriginalsQueue, OriginalState, StepState, day_checklist
from dualrgb.app.workflow.delivery.delivery import Original
from dualrgb.common.progress import Cancelled
from dualrgb.core.engine import RUN_PROGRESS, Run
from dualrgb.core.vocabulary import EventKind, NamedLight, Role, step_id
from dualrgb.drivers.raw import RawFrame
from dualrgb.simulation.lightsource import LightSource

FRAME = (96, 64)
LIGHTS = [NamedLight("p light 1", LightSource((1, 6, 8), name="p light 1")),
          NamedLight("p light 2", LightSource((3, 5, 9), name="p light 2"))]


# ---------------------------------------------------------------- metering sequences on the virtual lab
@pytest.fixture
def stand(tmp_path):
    from dualrgb.core.engine import RunEngine, StandDevices
    from dualrgb.core.light_safety import SafetySettings
    from dualrgb.core.session.capture_session import CaptureSession
    from dualrgb.drivers.virtual.lab import VirtualLab

    with VirtualLab(frame_size=FRAME) as lab:
        session = CaptureSession.create(tmp_path / "s", {})
        yield lab, session, RunEngine("test", StandDevices(lab.camera, lab.sphere, session, lab.place),
                                      safety=SafetySettings(settle_s=0.0))
        session.close()


def test_auto_exposure_sequence_meters_each_light(stand):
    from dualrgb.app.workflow.stand.metering import AutoExposure

    lab, session, engine = stand
    seq = AutoExposure(engine.facts, LIGHTS)
    assert [f.role for f in seq.plan()] == ["metering", "metering"]
    events = engine.run_plan(seq)
    assert set(seq.exposures) == {nl.name for nl in LIGHTS} and all(0 < t < 1 for t in seq.exposures.values())
    assert [e.data["light"] for e in events] == [nl.name for nl in LIGHTS]
    assert all(session.entries()[-1].role == "metering" for _ in events)
    assert not lab.emulator.snapshot().light_on


def test_metering_cancelled_between_lights_ends_dark(stand):
    from dualrgb.app.workflow.stand.metering import AutoExposure

    lab, _session, engine = stand
    seq = AutoExposure(engine.facts, LIGHTS)
    events = []
    for ev in engine.steps(seq):
        events.append(ev)
        seq.cancel()                                     # after the first light
    assert events[-1].kind is EventKind.CANCELLED and list(seq.exposures) == [LIGHTS[0].name]
    assert not lab.emulator.snapshot().light_on and np.allclose(lab.emulator.snapshot().levels, 0)


def test_hdr_metering_plans_a_bracket_for_the_nd_target(stand):
    from dualrgb.app.workflow.stand.metering import AutoExposure, HdrMetering
    from dualrgb.core.vocabulary import Subject

    lab, session, engine = stand
    auto = AutoExposure(engine.facts, LIGHTS)
    engine.run_plan(auto)
    subject = Subject.target("test", nd=True)
    seq = HdrMetering(engine.facts, LIGHTS, auto.exposures, subject, lab.scene_for("test", nd=True).patch_boxes())
    events = engine.run_plan(seq)
    assert all(len(p.exposures) >= 2 for p in seq.plans.values())        # ND 2.0: 100x darker half
    entry = next(e for e in session.entries() if e.seq == events[0].data["entry"])
    assert entry.role == "metering" and entry.meta.get("subject") == subject.key
    with pytest.raises(ValueError, match="run auto-exposure first"):
        HdrMetering(engine.facts, LIGHTS, {}, subject, [])


# ---------------------------------------------------------------- the run engine's Run
def test_stand_run_pauses_between_frames_and_cancels():
    """``work`` sees a frame event; while paused it waits there; a cancel then ends with a 'cancelled' event."""
    seen, reached = [], threading.Event()

    def work(hooks):
        hooks.progress(0.5, "half")
        hooks.on_event(ProgressEvent(1, 2, "frame 1", kind="frame"))     # blocks while paused
        reached.set()
        hooks.cancel.check()
        return "finished"

    run = Run("job", [PlannedFrame("dark", 0.1)], work)
    run.pause()
    t = threading.Thread(target=lambda: run.execute(seen.append))
    t.start()
    assert not reached.wait(0.3)                         # paused after the frame: not going on
    run.cancel()                                         # wakes it; the work stops at its next check
    t.join(5)
    assert reached.is_set() and run.result is None
    assert [e.kind for e in seen] == [EventKind.PROGRESS, EventKind.FRAME, EventKind.CANCELLED]
    assert seen[0].data[RUN_PROGRESS] and seen[0].step == 500 and seen[0].total == 1000


def test_stand_run_prompt_waits_for_resume():
    seen = []

    def work(hooks):
        hooks.prompt("Put the lens cap on")
        return 42

    run = Run("job", [], work)
    t = threading.Thread(target=lambda: run.execute(seen.append))
    t.start()
    t.join(0.3)
    assert t.is_alive() and run.paused and seen[-1].kind is EventKind.PROMPT
    run.resume()
    t.join(5)
    assert run.result == 42


def test_stand_run_errors_propagate():
    def work(_hooks):
        raise ValueError("no flats")

    with pytest.raises(ValueError, match="no flats"):
        Run("job", [], work).execute(lambda ev: None)

    def cancelled(_hooks):
        raise Cancelled("cancelled by the user")

    seen = []
    assert Run("job", [], cancelled).execute(seen.append) is None and seen[-1].kind is EventKind.CANCELLED


# ---------------------------------------------------------------- checklist and queue
def fake_session(entries=(), settings=None, path="/tmp/day"):
    return SimpleNamespace(path=Path(path), settings=settings or {}, entries=lambda *a, **k: list(entries),
                           has_step=lambda s: any(e.step_id == s for e in entries))


def entry(seq, role, step, exposure, light=""):
    return SimpleNamespace(seq=seq, role=role, step_id=step, meta={"light_name": light} if light else {},
                           light_name=light, exposure_s=exposure, file=f"{seq}.dng")


def test_queue_refuses_duplicates_and_restores_delivered(tmp_path):
    q = OriginalsQueue()
    q.add(Original("ACC-1"))
    with pytest.raises(ValueError, match="ACC-1 is already in the queue"):
        q.add(Original("ACC-1", title="again"))
    with pytest.raises(ValueError, match="identifier"):
        q.add(Original("   "))
    side = tmp_path / "ACC-1" / "ACC-1.json"
    side.parent.mkdir()
    side.write_text(json.dumps({"files": {"srgb": "ACC-1_srgb_16bit.tif"}, "qa": {"text": "ACC-1: ok",
                                                                                  "warnings": []}}))
    session = fake_session(settings={"originals": {"ACC-1": {"identifier": "ACC-1", "title": "T", "mode":
                                                             "reflective", "sidecar": str(side), "take": 1}}})
    restored = OriginalsQueue.from_session(session)
    row = restored.row("ACC-1")
    assert row.state is OriginalState.DELIVERED and row.qa == "ACC-1: ok" and row.original.title == "T"
    assert row.main_file == side.parent / "ACC-1_srgb_16bit.tif" and row.folder == side.parent


def test_checklist_walks_the_day():
    steps = day_checklist(DayState())
    assert [s.step for s in steps] == list(DayStep)
    assert [s.state for s in steps] == [StepState.ACTIVE, StepState.TODO, StepState.TODO, StepState.TODO]
    dark = entry(1, "dark", step_id(Role.DARK, exposure_s=0.01, frame=0), 0.01)
    flat = entry(2, "flat", step_id(Role.FLAT, light="p light 1", exposure_s=0.01, frame=0), 0.01, "p light 1")
    session = fake_session([dark, flat])
    state = DayState(sphere="/dev/pts/3", camera="virtual", session=session,
                     plan={"p light 1": [0.01, 0.5], "p light 2": [0.02]})
    steps = day_checklist(state)
    assert steps[0].state is StepState.DONE and steps[1].state is StepState.ACTIVE
    assert "darks 1/3 exposures, flats 1/3 light exposures" in steps[1].lines


def test_checklist_warns_when_a_new_hdr_plan_outgrows_the_calibration():
    profile = SimpleNamespace(id="cal-1", test_mean=0.4, exposures={"p light 1": [0.01, 0.5]}, age_h=lambda: 0.5)
    state = DayState(sphere="s", camera="c", session=fake_session(), profile=profile,
                     plan={"p light 1": [0.01, 0.5]})
    assert day_checklist(state)[1].state is StepState.DONE
    state.plan = {"p light 1": [0.01, 0.5, 4.0]}                        # metering asked for a longer exposure
    step = day_checklist(state)[1]
    assert step.state is StepState.WARNING
    assert "darks 2/3 exposures, flats 2/3 light exposures" in step.lines
    assert any("4 s" in line and "recalibrate" in line for line in step.lines)


def test_plan_coverage_against_a_calibration():
    cov = plan_coverage({"a": [0.01, 0.5], "b": [0.02]}, {"a": [0.01, 0.5, 2.0], "b": [0.02]})
    assert cov.summary() == "darks 3/4 exposures, flats 3/4 light exposures" and not cov.complete
    assert cov.darks_missing == [2.0] and cov.flats_missing == [("a", 2.0)]


# ---------------------------------------------------------------- planned steps and takes
def test_planned_steps_done_and_next_take():
    from dualrgb.app.sequences.calibration import DarkSeries
    from dualrgb.app.sequences.capture import SubjectCapture
    from dualrgb.app.workflow.stand.plans import next_take, planned_steps, steps_done
    from dualrgb.core.light_safety import StandFacts
    from dualrgb.core.vocabulary import Subject

    darks = DarkSeries(None, [0.01, 0.5], frames=2)
    steps = planned_steps(darks)
    assert steps == [step_id(Role.DARK, exposure_s=t, frame=i) for t in (0.01, 0.5) for i in range(2)]
    session = fake_session([entry(1, "dark", steps[0], 0.01), entry(2, "dark", steps[3], 0.5)])
    assert steps_done(session, steps) == [True, False, False, True]
    cap = SubjectCapture(StandFacts(), LIGHTS, {nl.name: [0.01] for nl in LIGHTS}, Subject.target("test"))
    taken = [entry(3, "target", s, 0.01) for s in cap.steps()] + [entry(4, "target", cap.steps()[0] + "#take2", 0.01)]
    assert next_take(fake_session(taken), cap.steps()) == 3


# ---------------------------------------------------------------- frame checks
def raw_frame(level: float, white: int = 15520, black: int = 600) -> RawFrame:
    mosaic = np.full((40, 60), black + level, dtype=np.uint16)
    return RawFrame(Path("x.dng"), mosaic, np.array([[0, 1], [3, 2]]), "RGBG", (black,) * 4, white)


def test_check_frame_dark_and_clipped():
    dark = check_frame(raw_frame(50))
    assert dark.dark and dark.level_pct == pytest.approx(100 * 50 / (11000 - 600))
    assert "frame is dark" in dark.warning() and "the light was off" in dark.warning(light_on=False)
    lit = check_frame(raw_frame(DARK_FRACTION * 10400 * 10))
    assert not lit.dark and lit.warning() == ""
    clipped = check_frame(raw_frame(15520 - 600))
    assert clipped.clipped_pct == pytest.approx(100.0) and "clipped" in clipped.warning()


def test_flat_uniformity_shows_the_vignetting(stand):
    from dualrgb.app.sequences.calibration import FlatSeries
    from dualrgb.app.workflow.calibration.frame_checks import flat_uniformity

    lab, session, engine = stand
    engine.run_plan(FlatSeries(engine.facts, LIGHTS[:1], {LIGHTS[0].name: [0.01]}, frames=2))
    m = flat_uniformity(session, LIGHTS[0].name)
    assert m.frames == 2 and m.exposure_s == pytest.approx(0.01)
    assert np.nanmean(m.percent) == pytest.approx(100.0, abs=0.5)
    rows, cols = m.percent.shape
    centre, corner = m.percent[rows // 2, cols // 2], m.percent[0, 0]
    assert centre > corner and m.range_pct > 1.0                 # the virtual lab's vignetting
    with pytest.raises(ValueError, match="no open-gate flats of nobody"):
        flat_uniformity(session, "nobody")


# ---------------------------------------------------------------- the day kept in its session (issue 30)
def test_the_day_file_keeps_waiting_rows_and_the_calibration(tmp_path):
    from dualrgb.app.workflow.day.day_file import DAY_FORMAT, day_path, restore_day, restored_line, save_day

    session_dir = tmp_path / "s"
    (session_dir / "calibration").mkdir(parents=True)
    old, cal = session_dir / "calibration" / "cal-1.json", session_dir / "calibration" / "cal-2.json"
    old.write_text("{}")
    cal.write_text("{}")
    q = OriginalsQueue()
    q.add(Original("W-1", title="Waiting", extra={"Inventory": "7"}), stand_in="painting", frames=2)
    q.add(Original("C-1")).state = OriginalState.CAPTURING            # the window closed while it was shot
    q.add(Original("F-1")).state, q.rows[-1].qa = OriginalState.FAILED, "not shot: transmissive"
    d = q.add(Original("D-1"))
    d.state = OriginalState.DELIVERED                                  # delivered: session.json has it, not the file
    save_day(session_dir, q, old)
    doc = json.loads(day_path(session_dir).read_text())
    assert doc["format"] == DAY_FORMAT and "software" in doc and doc["calibration"] == "calibration/cal-1.json"
    assert [r["original"]["identifier"] for r in doc["rows"]] == ["W-1", "C-1", "F-1"]
    queue, calibration, notes = restore_day(fake_session(path=session_dir))
    assert calibration == old and notes == []                          # the saved one, not the newest
    w = queue.row("W-1")
    assert (w.state, w.stand_in, w.frames, w.original.title, w.original.extra) == (
        OriginalState.WAITING, "painting", 2, "Waiting", {"Inventory": "7"})
    assert queue.row("C-1").state is OriginalState.WAITING and "interrupted" in queue.row("C-1").qa
    assert queue.row("F-1").state is OriginalState.FAILED and [r.identifier for r in queue.rows] == ["W-1", "C-1",
                                                                                                     "F-1"]
    assert restored_line("s", queue, "cal-1") == "restored session s, calibration cal-1, queue: 2 waiting, 1 failed"
    old.unlink()                                                       # gone: the session's newest, said
    _queue, calibration, notes = restore_day(fake_session(path=session_dir))
    assert calibration == cal and "gone" in notes[0]
    day_path(session_dir).write_text("{not json")
    queue, _cal, notes = restore_day(fake_session(path=session_dir))
    assert queue.rows == [] and "not restored" in notes[0]


def test_raw_frames_of_an_original_carry_its_file_stem(tmp_path):
    from dualrgb.core.session.capture_session import CaptureSession
    from dualrgb.core.vocabulary import Subject
    from dualrgb.drivers.camera.base import RawCapture

    with CaptureSession.create(tmp_path / "s", {}) as session:
        raw = RawCapture(b"raw", "VIRT_0001.DNG", exposure_s=0.01)
        original = session.record(raw, "original", step_id="o/1", subject=Subject.original("ACC 1").key)
        target = session.record(raw, "target", step_id="t/1", subject=Subject.target("test").key)
        dark = session.record(raw, "dark", step_id="d/1")
    stem = Original("ACC 1").file_stem
    assert original.file == f"0001_{stem}_original_VIRT_0001.DNG" and stem.startswith("ACC_1_")
    assert (target.file, dark.file) == ("0002_target_VIRT_0001.DNG", "0003_dark_VIRT_0001.DNG")
    reopened = CaptureSession.open(tmp_path / "s", readonly=True)          # names are read from the manifest
    assert [e.file for e in reopened.entries()] == [original.file, target.file, dark.file]
