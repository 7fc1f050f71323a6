"""An event-loop watchdog that measures stalls of the GUI thread itself.

A QTimer ticks every 10 ms on the GUI thread. Between two ticks the GUI thread is either idle in the event loop or
busy in a slot; ``time.thread_time()`` (the GUI thread's own CPU clock) grows only while it is busy, so the CPU
time between two ticks is how long the GUI thread kept the event loop from running. Unlike the wall-clock gap
it does not grow when the shared machine schedules other processes, so a loaded machine does not fail the test,
while a slow slot, a big redraw or a processEvents() loop does. The wall-clock gap is recorded too (printed).

Python's garbage collection runs on the GUI thread (app.gui.gc_thread); its pauses grow with everything the test
process holds (every earlier test's objects: a full collection took 0.56 s late in the suite, 0.04 s alone), not
with what the window does, so they are measured apart (``max_gc``, printed) and left out of ``max_stall``.

No test asserts these figures (issue 41: a CPU-time figure still grows on a busy host, 111.8 ms at load 36): the
tests print them and, when ``DUALRGB_STALL_JSON`` names a file, :meth:`StallWatchdog.record` adds them to it;
``make bench`` (bench/gui_stall.py) runs the two window days that way and writes the figures with their target.
"""
from __future__ import annotations

import gc
import json
import os
import threading
import time
from pathlib import Path

from PySide6.QtCore import QObject, QTimer


class StallWatchdog(QObject):
    def __init__(self, interval_ms: int = 10):
        super().__init__()
        self.timer = QTimer(self)
        self.timer.setInterval(interval_ms)
        self.timer.timeout.connect(self._tick)
        self.active = False
        self.ticks = 0
        self.max_stall = 0.0          # GUI-thread CPU seconds between two ticks, garbage collection left out
        self.max_gap = 0.0            # wall-clock seconds between two ticks (informative)
        self.max_gc = 0.0             # the longest garbage collection on the GUI thread, CPU seconds (informative)
        self.worst_at = ""
        self.worst_gap_at = ""
        self.phase = ""
        self._last: tuple[float, float] | None = None
        self._thread = threading.get_ident()
        self._gc_started: float | None = None
        self._gc_cpu = 0.0            # GUI-thread CPU seconds spent collecting since the last tick

    def start(self) -> None:
        self.active = True
        self._last = None
        if self._on_gc not in gc.callbacks:
            gc.callbacks.append(self._on_gc)
        self.timer.start()

    def stop(self) -> None:
        self.active = False
        self.timer.stop()
        if self._on_gc in gc.callbacks:
            gc.callbacks.remove(self._on_gc)

    def _on_gc(self, phase: str, _info: dict) -> None:
        if threading.get_ident() != self._thread:
            return
        now = time.thread_time()
        if phase == "start":
            self._gc_started = now
        elif self._gc_started is not None:
            spent, self._gc_started = now - self._gc_started, None
            self._gc_cpu += spent
            self.max_gc = max(self.max_gc, spent)

    def _tick(self) -> None:
        now = (time.perf_counter(), time.thread_time())
        collecting, self._gc_cpu = self._gc_cpu, 0.0
        if self.active and self._last is not None:
            gap, cpu = now[0] - self._last[0], now[1] - self._last[1] - collecting
            self.ticks += 1
            if gap > self.max_gap:
                self.max_gap, self.worst_gap_at = gap, self.phase
            if cpu > self.max_stall:
                self.max_stall, self.worst_at = cpu, self.phase
        self._last = now

    def summary(self) -> str:
        return (f"{self.ticks} ticks; longest GUI-thread stall {1000 * self.max_stall:.1f} ms (during "
                f"{self.worst_at or '?'}); longest wall-clock gap {1000 * self.max_gap:.1f} ms (during "
                f"{self.worst_gap_at or '?'}); longest garbage collection {1000 * self.max_gc:.1f} ms")

    def record(self, name: str) -> None:
        """Print the figures and, when ``DUALRGB_STALL_JSON`` is set, add them to that JSON file under ``name``."""
        print("watchdog:", self.summary())
        target = os.environ.get("DUALRGB_STALL_JSON")
        if not target:
            return
        path = Path(target)
        figures = json.loads(path.read_text()) if path.is_file() else {}
        figures[name] = {"ticks": self.ticks, "max_stall_ms": round(1000 * self.max_stall, 1),
                         "worst_at": self.worst_at, "max_gap_ms": round(1000 * self.max_gap, 1),
                         "worst_gap_at": self.worst_gap_at, "max_gc_ms": round(1000 * self.max_gc, 1)}
        path.write_text(json.dumps(figures, indent=2) + "\n")
