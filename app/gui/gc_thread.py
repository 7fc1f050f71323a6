"""Python's cyclic garbage collection on the GUI thread only, while a window is open.

A collection runs in whichever thread happens to allocate. When it frees a Qt object's wrapper (a widget held in a
reference cycle) on a worker thread, the object is destroyed there: Qt's ``~QObject`` takes its connection lock and
then waits for the GIL to look for Python overrides, while the GUI thread, holding the GIL, waits for that lock in
its own ``~QObject`` - both threads hang for good (found in tests/gui: a worker collected inside matplotlib while
the GUI deleted a menu; the window froze with a calibration half processed). pyqtgraph's ``GarbageCollector``
turns automatic collection off and collects from a GUI-thread timer instead; this starts it with the first window
and gives automatic collection back when the last one closes (the tests open and close many windows in one
process).
"""
from __future__ import annotations

import gc
import logging
from dataclasses import dataclass
from typing import Any

log = logging.getLogger(__name__)

COLLECT_EVERY_S = 0.5          # as often as generation 0 would fill up in a busy GUI


@dataclass
class _Collection:
    windows: int = 0            # open windows that asked for it
    collector: Any = None       # pyqtgraph's GarbageCollector (the library has no type information)
    was_enabled: bool = True    # automatic collection before the first window


_now = _Collection()


def start() -> None:
    """A window opens: collect on the GUI thread from now on (call on the GUI thread)."""
    from pyqtgraph.util.garbage_collector import GarbageCollector

    _now.windows += 1
    if _now.windows == 1:
        _now.was_enabled = gc.isenabled()
        _now.collector = GarbageCollector(interval=COLLECT_EVERY_S)
        log.debug("garbage collection moved to the GUI thread")


def stop() -> None:
    """A window closed: the last one gives automatic collection back (as it was before the first)."""
    _now.windows = max(_now.windows - 1, 0)
    if _now.windows == 0 and _now.collector is not None:
        _now.collector.timer.stop()
        _now.collector = None
        if _now.was_enabled:
            gc.enable()        # no gc.collect() here: inside closeEvent it freed wrappers of widgets mid-destruction
        log.debug("garbage collection back to automatic")                      # (a segfault in tests/gui)
