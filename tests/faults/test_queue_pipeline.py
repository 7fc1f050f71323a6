"""The pipelined day (issue 41): original N is delivered by a worker while N+1 is metered and shot, in one run of the
run engine. The same bytes as the sequential day; at most two originals in flight; a failed delivery reported
against its original while the next is delivered; a cancel stops both; the timings of ``capture --queue --json``.
No wall-clock figure is asserted: the overlap is proven by a delivery that waits for the next original's first
frame (a sequential day would never give it one: the hang guard then fails the test)."""
from __future__ import annotations

import hashlib
import os
import sys
import threading
from pathlib import Path

import pytest
from light_record import lit_spans
from workflow_profiles import make_profile

from dualrgb.app.workflow.day.queue_run import QUEUE_EVENT, capture_queue, median_stand_wait
from dualrgb.app.workflow.stand.copystand import CopyStand, StandSettings
from dualrgb.common.progress import Cancelled
from dualrgb.core.metadata import Original
from dualrgb.core.session.capture_session import CaptureSession
from dualrgb.core.vocabulary import EventKind
from dualrgb.drivers.virtual.lab import VirtualLab

HANG_GUARD_S = 60.0           # far above a normal wait: only a broken pipeline reaches it
IDS = ("ACC-1", "ACC-2", "ACC-3")


def _stand(lab: VirtualLab, root: Path, events: list | None = None) -> tuple[CopyStand, object]:
    session = CaptureSession.create(root / "session", {"test": "pipelined queue"})

    def place(what: str, nd: bool = False):          # every original stands in as the virtual painting
        return lab.place("original:painting" if what.startswith("original:") else what, nd)
    stand = CopyStand(lab.camera, lab.sphere, session, stand=place,
                      settings=StandSettings(settle_s=0.0, force=True),
                      on_event=events.append if events is not None else None)
    return stand, make_profile(root / "cal", shape=(64, 96))


def _digests(folder: Path) -> dict[str, str]:
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(folder.rglob("*")) if p.is_file()}


def _frames_of(stand: CopyStand, identifier: str) -> list:
    marker = f"/{Original(identifier).subject.key}/"
    return [e for e in stand.session.entries() if marker in (e.step_id or "")]


def _framed(stand: CopyStand, ev) -> str | None:
    """The identifier of the original whose frame an event says landed (None: not a new frame)."""
    if ev.kind is not EventKind.FRAME or "entry" not in ev.data:
        return None
    return next((i for i in IDS if any(e.seq == ev.data["entry"] for e in _frames_of(stand, i))), None)


def test_the_pipelined_day_delivers_the_same_bytes_as_the_sequential_day(lab, tmp_path, monkeypatch):
    """The same frames (the session's), delivered by the worker while the next is shot, then again one by one."""
    monkeypatch.setenv("SOURCE_DATE_EPOCH", "1767225600")          # the time written into the files, fixed
    stand, profile = _stand(lab, tmp_path)
    originals = [Original(i) for i in IDS]
    outcomes = capture_queue(stand, originals, profile, out_dir=tmp_path / "pipelined")
    again = capture_queue(stand, originals, profile, out_dir=tmp_path / "sequential", pipelined=False,
                          reshoot=dict.fromkeys(IDS, False))      # its frames delivered again, nothing lit
    assert [o.original.identifier for o in outcomes] == list(IDS) and all(o.report for o in outcomes + again)
    assert all(o.report.new == 0 for o in again if o.report)
    pipelined, sequential = _digests(tmp_path / "pipelined"), _digests(tmp_path / "sequential")
    assert len(pipelined) >= 3 * 5 and pipelined == sequential          # every TIFF and sidecar, byte for byte
    first, *rest = outcomes                                             # capture --queue --json's timings
    assert first.stand_wait_s is None and all(o.stand_wait_s is not None and o.stand_wait_s >= 0 for o in rest)
    assert all(o.capture_s and o.capture_s > 0 and o.deliver_s and o.deliver_s > 0 for o in outcomes)
    assert set(first.timings()) == {"capture_s", "deliver_s", "stand_wait_s"}
    assert median_stand_wait(outcomes) is not None


def test_n_is_delivered_while_n_plus_1_is_shot_and_never_more_than_two_in_flight(lab, tmp_path, monkeypatch):
    log: list[tuple[str, str]] = []
    first_frame = {i: threading.Event() for i in IDS}

    stand, profile = _stand(lab, tmp_path, [])

    def on_event(ev) -> None:
        ident = _framed(stand, ev)
        if ident is not None:
            log.append(("frame", ident))
            first_frame[ident].set()
    stand.on_event = on_event
    real = stand.deliver_shot

    niceness: list[int] = []

    def deliver(shot):
        ident = shot.original.identifier
        log.append(("deliver", ident))
        if hasattr(os, "getpriority"):
            niceness.append(os.getpriority(os.PRIO_PROCESS, threading.get_native_id()))
        nxt = IDS.index(ident) + 1
        if nxt < len(IDS):          # the next original's first frame lands while this one is being delivered
            assert first_frame[IDS[nxt]].wait(HANG_GUARD_S), f"{IDS[nxt]} was not shot while {ident} was delivered"
        try:
            return real(shot)
        finally:
            log.append(("delivered", ident))
    monkeypatch.setattr(stand, "deliver_shot", deliver)
    outcomes = capture_queue(stand, [Original(i) for i in IDS], profile)
    assert all(o.report is not None for o in outcomes)
    for n, ident in enumerate(IDS[:-2]):                 # N delivered before N+2's first frame: two in flight
        assert log.index(("delivered", ident)) < log.index(("frame", IDS[n + 2])), log
    base = os.getpriority(os.PRIO_PROCESS, threading.get_native_id()) if hasattr(os, "getpriority") else 19
    if sys.platform == "linux" and base < 19:            # the worker below the run's thread (nice is per thread)
        assert niceness and min(niceness) > base


def test_a_failed_delivery_is_reported_against_its_original_and_the_next_is_delivered(lab, tmp_path, monkeypatch):
    events: list = []
    stand, profile = _stand(lab, tmp_path, events)
    real = stand.deliver_shot

    def deliver(shot):
        if shot.original.identifier == "ACC-1":
            raise OSError(28, "No space left on device (injected)")
        return real(shot)
    monkeypatch.setattr(stand, "deliver_shot", deliver)
    seen: list = []
    outcomes = capture_queue(stand, [Original(i) for i in IDS[:2]], profile, on_outcome=seen.append)
    failed, delivered = outcomes
    assert "No space left on device" in failed.error and failed.report is None
    assert "ACC-1: not delivered" in failed.summary() and "dualrgb process" in failed.summary()
    assert delivered.report is not None and delivered.report.delivery.sidecar.is_file()
    assert [o.original.identifier for o in seen] == ["ACC-1", "ACC-2"]
    said = [(ev.data[QUEUE_EVENT], ev.data["original"]) for ev in events if QUEUE_EVENT in ev.data]
    assert ("failed", "ACC-1") in said and ("delivered", "ACC-2") in said
    assert len(_frames_of(stand, "ACC-1")) == len(_frames_of(stand, "ACC-2")) > 0       # no frame lost
    assert "ACC-1" not in (stand.session.settings.get("originals") or {})               # never said delivered


def test_cancel_stops_the_shooting_and_the_delivery(lab, tmp_path, monkeypatch):
    stand, profile = _stand(lab, tmp_path, [])
    delivering, ended = threading.Event(), threading.Event()

    def deliver(shot):
        delivering.set()
        try:
            stand.cancel.wait(HANG_GUARD_S)                # a long delivery, until the cancel
            if stand.cancel.cancelled:
                raise Cancelled("delivery cancelled")
            raise AssertionError("the cancel never reached the delivery")
        finally:
            ended.set()

    def on_event(ev) -> None:                  # cancel once ACC-2's first frame is in, ACC-1 still delivering
        if _framed(stand, ev) == "ACC-2":
            assert delivering.wait(HANG_GUARD_S)
            stand.engine.control.cancel()
    stand.on_event = on_event
    monkeypatch.setattr(stand, "deliver_shot", deliver)
    since = lab.emulator.clock()
    with pytest.raises(Cancelled):
        capture_queue(stand, [Original(i) for i in IDS], profile)
    assert ended.is_set()                                         # the delivery stopped before the run returned
    assert not [t for t in threading.enumerate() if t.name.startswith("delivery")]
    assert _frames_of(stand, "ACC-3") == []                       # nothing shot after the cancel
    assert all(s.t_off is not None for s in lit_spans(lab.emulator, since))     # the light is off
    assert not (stand.session.settings.get("originals") or {})


def test_capture_json_says_a_failed_original_with_its_error_and_timings():
    from dualrgb.app.commands.capture import _outcome_json
    from dualrgb.app.workflow.day.queue_run import QueueOutcome

    failed = _outcome_json(QueueOutcome(Original("ACC-1"), error="No space left on device", capture_s=6.81,
                                        deliver_s=0.2, stand_wait_s=0.0612))
    assert failed["state"] == "failed" and failed["error"] == "No space left on device"
    assert (failed["capture_s"], failed["deliver_s"], failed["stand_wait_s"]) == (6.81, 0.2, 0.061)
    kept = _outcome_json(QueueOutcome(Original("ACC-2"), kept=Path("ACC-2.json")))
    assert kept["state"] == "kept" and "stand_wait_s" not in kept
