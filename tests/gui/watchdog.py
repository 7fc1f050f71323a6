"""An event-loop watchdog that measures stalls of the GUI thread itself.

A QTimer ticks every 10 ms on the GUI thread. Between two ticks the GUI thread is either idle in the event loop or
busy in a slot; ``time.thread_time()`` (the GUI thread's own CPU clock) grows only while it is busy, so the CPU
time between two ticks is how long the GUI thread kept the event loop from running. Unlike the wall-clock gap
it does not grow when the shared machine schedules other processes, so a loaded machine does not fail the test,
while a slow slot, a big redraw or a processEvents() loop does. The wall-clock gap is recorded too (printed).
"""
from __future__ import annotations

import time

from PySide6.QtCore import QObject, QTimer


class StallWatchdog(QObject):
    def __init__(self, interval_ms: int = 10):
        super().__init__()
        self.timer = QTimer(self)
        self.timer.setInterval(interval_ms)
        self.timer.timeout.connect(self._tick)
        self.active = False
        self.ticks = 0
        self.max_stall = 0.0          # GUI-thread CPU seconds between two ticks
        self.max_gap = 0.0            # wall-clock seconds between two ticks (informative)
        self.worst_at = ""
        self.worst_gap_at = ""
        self.phase = ""
        self._last: tuple[float, float] | None = None

    def start(self) -> None:
        self.active = True
        self._last = None
        self.timer.start()

    def stop(self) -> None:
        self.active = False
        self.timer.stop()

    def _tick(self) -> None:
        now = (time.perf_counter(), time.thread_time())
        if self.active and self._last is not None:
            gap, cpu = now[0] - self._last[0], now[1] - self._last[1]
            self.ticks += 1
            if gap > self.max_gap:
                self.max_gap, self.worst_gap_at = gap, self.phase
            if cpu > self.max_stall:
                self.max_stall, self.worst_at = cpu, self.phase
        self._last = now

    def summary(self) -> str:
        return (f"{self.ticks} ticks; longest GUI-thread stall {1000 * self.max_stall:.1f} ms (during "
                f"{self.worst_at or '?'}); longest wall-clock gap {1000 * self.max_gap:.1f} ms (during "
                f"{self.worst_gap_at or '?'})")
