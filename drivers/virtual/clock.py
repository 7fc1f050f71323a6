"""A clock the virtual lab can move forward: real monotonic time plus the seconds skipped.

The sphere emulator evaluates its physics (LED drift, fade, heating, watchdog, on-time limit) lazily against its
clock, so skipping 60 s on this clock is, for the emulator and everything sharing the clock, exactly a minute
passing: an hour-long warm-up series (thesis 4.3.2) is measured in moments, never by waiting on the wall clock.
"""
from __future__ import annotations

import logging
import threading
import time
from collections.abc import Callable

log = logging.getLogger(__name__)


class SkippableClock:
    """``clock()`` -> seconds: ``base()`` plus every :meth:`skip` so far (monotonic, thread-safe)."""

    def __init__(self, base: Callable[[], float] = time.monotonic) -> None:
        self._base = base
        self._skipped = 0.0
        self._lock = threading.Lock()

    def __call__(self) -> float:
        with self._lock:
            return self._base() + self._skipped

    def skip(self, seconds: float) -> None:
        """Move the clock ``seconds`` (>= 0) forward at once."""
        if not seconds >= 0:
            raise ValueError(f"cannot skip {seconds!r} s: expected a non-negative number of seconds")
        with self._lock:
            self._skipped += float(seconds)

    @property
    def skipped_s(self) -> float:
        with self._lock:
            return self._skipped
