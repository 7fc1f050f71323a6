"""Cancel within a second wherever work runs (issue 30 item 4), measured in work units, never in wall-clock time:
how much work started after the cancel was set. A search checks its cancel token before every slice of
simulation.search.CANCEL_SLICE light sets (a few ms each: bench/cancel_latency.py times one); a calibration's
processing and an original's delivery check it between frames and bands, and a cancelled calibration never
replaces the current one."""
from __future__ import annotations

import threading

import pytest

from dualrgb.simulation.search import CANCEL_SLICE
from tests.gui.conftest import HANG_GUARD_MS, click, wait_idle
from tests.gui.test_copystand_gui import start as start_stand

LONG = HANG_GUARD_MS


class WorkAfterCancel:
    """Wraps a cost function: the largest call (the work between two cancel checks) and the light sets costed by
    calls that began after ``token`` was set."""

    def __init__(self, monkeypatch, cls, name: str):
        self.token = None
        self.after = 0
        self.calls_after = 0
        self.before = 0
        self.largest = 0
        self.lock = threading.Lock()
        inner = getattr(cls, name)

        def counted(obj, idx, w):
            late = self.token is not None and self.token.cancelled
            out = inner(obj, idx, w)
            with self.lock:
                self.largest = max(self.largest, len(w))
                if late:
                    self.after += len(w)
                    self.calls_after += 1
                else:
                    self.before += len(w)
            return out
        monkeypatch.setattr(cls, name, counted)


@pytest.mark.parametrize("method", ["pso", "ga", "halving"])
def test_a_search_stops_within_one_slice_of_cancel(qtbot, make_window, monkeypatch, method):
    """Simulate & optimise: Cancel during a long search. The search checks the token before every cost call, no
    call costs more than one slice (so the work in flight when Cancel is pressed is at most one slice), and at most
    one call (one slice) begins after the cancel was set."""
    from dualrgb.app.gui.viewmodel import ConvergenceTap

    w = make_window()
    sim = w.simulate
    counter = WorkAfterCancel(monkeypatch, ConvergenceTap, "cost_indexed")
    sim.mode.setCurrentText("reflective")
    sim.method.setCurrentText(method)
    sim.objective.setCurrentText("noise-free")
    sim.iterations.setValue(1000)                       # far longer than the test waits: the cancel lands mid-run
    sim.population.setValue(200)
    click(qtbot, sim.run_button)
    counter.token = sim.handle.cancel_token
    qtbot.waitUntil(lambda: len(sim.live) >= 3, timeout=LONG)     # the search proper is running
    click(qtbot, sim.cancel_button)
    wait_idle(qtbot, w, LONG)
    print(f"[cancel latency] {method}: {counter.before} light sets before the cancel, {counter.after} after "
          f"({counter.calls_after} calls), largest call {counter.largest} (one slice = {CANCEL_SLICE})")
    assert counter.before > 0 and sim.handle.cancel_token.cancelled
    assert counter.largest <= CANCEL_SLICE
    assert counter.after <= CANCEL_SLICE and counter.calls_after <= 1
    assert "cancelled" in sim.status.text() or "partial" in sim.status.text(), sim.status.text()


def test_the_kernel_compile_is_said_as_such(qtbot, make_window, monkeypatch):
    """The one-off kernel compile at start-up is said in the progress line, not shown as a stuck search."""
    from dualrgb.common.progress import COMPILING
    from dualrgb.simulation import warmup

    monkeypatch.setattr(warmup, "kernels_cached", lambda: False)          # as on a first run
    w = make_window()
    sim = w.simulate
    seen: list[str] = []
    original = sim._progress
    monkeypatch.setattr(sim, "_progress", lambda f, m: (seen.append(m), original(f, m)))
    sim.method.setCurrentText("pso")
    sim.iterations.setValue(1)
    sim.population.setValue(4)
    click(qtbot, sim.run_button)
    qtbot.waitUntil(lambda: sim.result is not None, timeout=LONG)
    wait_idle(qtbot, w, LONG)
    assert COMPILING == "compiling kernels (first run only)" and COMPILING in seen, seen[:5]


def wait_for_cancel(token) -> None:
    """In the worker: wait until the window's Cancel set ``token`` (a hang guard only bounds it)."""
    waited = 0.0
    while not token.cancelled and waited < LONG / 1000:
        threading.Event().wait(0.01)
        waited += 0.01


class BlockAtFirstCall:
    """Wraps ``owner.name``: its first call (in the worker) waits until ``token_of()`` is cancelled (by a click
    in the window), then goes on; later calls begun after the cancel are counted (work units after it)."""

    def __init__(self, monkeypatch, owner, name: str, token_of):
        self.started = threading.Event()
        self.after = 0
        inner = getattr(owner, name)

        def wrapped(*args, **kwargs):
            if not self.started.is_set():
                self.started.set()
                wait_for_cancel(token_of())
            elif token_of().cancelled:
                self.after += 1
            return inner(*args, **kwargs)
        monkeypatch.setattr(owner, name, wrapped)


def _start(qtbot, w):
    cap = start_stand(qtbot, w)
    box = cap.calibration
    box.dark_frames.setValue(1)
    box.flat_frames.setValue(1)
    box.de_fit.setChecked(False)
    box.hdr_auto.setChecked(False)
    return cap, box


def _finish(qtbot, w, view):
    qtbot.waitUntil(lambda: view.outcome != "", timeout=LONG)
    wait_idle(qtbot, w, LONG)
    return view.outcome


def test_cancel_in_processing_keeps_the_calibration_and_a_delivery(qtbot, make_window, monkeypatch, tmp_path):
    """Calibrate & capture: Cancel during a calibration's processing stops it at the next work unit and never
    replaces the current calibration; Cancel during an original's delivery stops before the next band and delivers
    nothing. Measured as work units begun after the cancel (the first unit waits inside for the click)."""
    import dualrgb.app.workflow.stand.copystand as copystand
    from dualrgb.app.processing.encode import DeliveryEncoder
    from dualrgb.app.workflow.day.day import OriginalState

    w = make_window(frame_size=(96, 200))                  # 200 rows: four delivery bands of 64
    cap, box = _start(qtbot, w)
    ws = w.ctx.workspace
    click(qtbot, box.calibrate_button)
    assert _finish(qtbot, w, cap.view) == "done", w.errors.history
    current = ws.calibration
    assert current is not None
    saved = sorted((w.lab.session.path / "calibration").glob("*.json"))

    real, started, after = copystand.process_session, threading.Event(), []

    def processing(*args, progress=None, cancel=None, **kwargs):   # a progress report: a unit of processing done
        def counted(f, m):
            if not started.is_set():
                started.set()
                wait_for_cancel(cancel)
            elif cancel.cancelled:
                after.append(m)
            if progress is not None:
                progress(f, m)
        return real(*args, progress=counted, cancel=cancel, **kwargs)
    monkeypatch.setattr(copystand, "process_session", processing)
    w.asker.scripted = ["Keep"]                      # calibrate again: asked; keep the frames, compute it again
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(started.is_set, timeout=LONG)
    click(qtbot, cap.view.cancel_button)
    assert _finish(qtbot, w, cap.view) == "cancelled", (cap.view.message.text(), w.errors.history)
    print(f"[cancel latency] calibration processing: {len(after)} units after the cancel {after}")
    assert ws.calibration is current and len(after) <= 1
    assert sorted((w.lab.session.path / "calibration").glob("*.json")) == saved
    # a cancel after the last unit of processing: the calibration is still neither saved nor made current
    done = threading.Event()

    def processed(*args, cancel=None, **kwargs):
        result = real(*args, cancel=cancel, **kwargs)
        done.set()
        wait_for_cancel(cancel)
        return result
    monkeypatch.setattr(copystand, "process_session", processed)
    w.asker.scripted = ["Keep"]
    click(qtbot, box.calibrate_button)
    qtbot.waitUntil(done.is_set, timeout=LONG)
    click(qtbot, cap.view.cancel_button)
    assert _finish(qtbot, w, cap.view) == "cancelled", (cap.view.message.text(), w.errors.history)
    assert ws.calibration is current
    assert sorted((w.lab.session.path / "calibration").glob("*.json")) == saved

    org = w.originals
    org.identifier.setText("PAINT-1")
    org.title_edit.setText("PAINT-1 title")
    org.stand_in.setCurrentText("painting")
    click(qtbot, org.add_button)
    bands = BlockAtFirstCall(monkeypatch, DeliveryEncoder, "encode_mosaic",      # full resolution: a band each
                            lambda: org.run.control.token)
    click(qtbot, org.capture_all_button)
    qtbot.waitUntil(bands.started.is_set, timeout=LONG)
    click(qtbot, org.view.cancel_button)
    wait_idle(qtbot, w, LONG)
    print(f"[cancel latency] delivery: {bands.after} bands encoded after the cancel")
    assert bands.after == 0 and ws.queue.row("PAINT-1").state is not OriginalState.DELIVERED
    assert not list(tmp_path.rglob("PAINT-1*.tif"))


def test_cancel_during_the_compile_says_it_waits_for_it(make_window):
    """Numba's one-off compile cannot be interrupted: a Cancel then says the search stops after it."""
    from types import SimpleNamespace

    from dualrgb.common.progress import COMPILING

    sim = make_window().simulate
    cancelled = []
    sim.handle = SimpleNamespace(running=True, cancel=lambda: cancelled.append(True))
    sim._progress(0.0, COMPILING)
    sim.cancel_running()
    assert cancelled and "after the kernels' one-off compile" in sim.status.text()
    sim._progress(0.5, "PSO: 10/630 light sets")
    sim.cancel_running()
    assert sim.status.text() == "cancelling …"
    sim.handle = None
