"""Running device calls, computations and capture sequences off the GUI thread.

Everything slow goes through a :class:`TaskRunner`: ``submit(fn, ...)`` runs ``fn`` on a QThreadPool and
delivers its result, error, progress and generator events back on the GUI thread through queued signals
(the receiving slots belong to a QObject that lives in the GUI thread, so Qt posts them as events; no
``processEvents()`` loops anywhere).

Four pools keep the work apart:
* ``devices``   one thread: every device call from the panels that is not a run (connect, status, camera
                settings, live view), in order (gphoto2 is not re-entrant);
* ``compute``   one thread: simulations, processing, figure data;
* ``sequences`` one thread: the runs of the run engine (core.engine.Run.execute), one at a time;
* ``light``     one thread: the light held by hand (app.workflow.stand.light_plans: the manual and the framing light),
                a run of the engine too; a state more than work: ``busy()`` without a pool leaves it out. The
                engine lets one run at a time act on a device, so a sequence starting waits for it to end.
"""
from __future__ import annotations

import itertools
import logging
import threading
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

from PySide6.QtCore import QObject, QRunnable, Qt, QThreadPool, Signal, Slot

from dualrgb.common.progress import CancelToken

log = logging.getLogger(__name__)

POOLS = ("devices", "compute", "sequences", "light")
STATE_POOLS = ("light",)          # held lights: not counted by busy() unless asked by name


class _Bridge(QObject):
    """Signals emitted from worker threads; connected (queued) to the runner's slots in the GUI thread."""

    progress = Signal(int, float, str)
    run_event = Signal(int, object)     # not "event": that would hide QObject.event()
    result = Signal(int, object)
    error = Signal(int, object, str)
    finished = Signal(int)


@dataclass
class TaskHandle:
    """What ``submit`` returns: cancel it (cooperative), ask whether it is still running."""

    id: int
    name: str
    pool: str
    cancel_token: CancelToken = field(default_factory=CancelToken)
    on_cancel: Callable[[], None] | None = None
    done: bool = False

    def cancel(self) -> None:
        self.cancel_token.cancel()
        if self.on_cancel is not None:
            self.on_cancel()

    @property
    def running(self) -> bool:
        return not self.done


@dataclass
class _Callbacks:
    on_result: Callable[[Any], None] | None
    on_error: Callable[[BaseException], None] | None
    on_progress: Callable[[float, str], None] | None
    on_event: Callable[[Any], None] | None
    on_finished: Callable[[], None] | None


class _Job(QRunnable):
    def __init__(self, task_id: int, bridge: _Bridge, fn: Callable[..., Any], handle: TaskHandle,
                 pass_progress: bool, pass_cancel: bool, iterate: bool, pass_emit: bool = False):
        super().__init__()
        self.setAutoDelete(True)
        self._id = task_id
        self._bridge = bridge
        self._fn = fn
        self._handle = handle
        self._pass_progress = pass_progress
        self._pass_cancel = pass_cancel
        self._iterate = iterate
        self._pass_emit = pass_emit

    def run(self) -> None:  # worker thread
        kwargs: dict[str, Any] = {}
        if self._pass_progress:
            kwargs["progress"] = lambda f, m: self._bridge.progress.emit(self._id, float(f), str(m))
        if self._pass_cancel:
            kwargs["cancel"] = self._handle.cancel_token
        if self._pass_emit:
            kwargs["emit"] = lambda item: self._bridge.run_event.emit(self._id, item)
        try:
            out = self._fn(**kwargs)
            if self._iterate:
                for item in out:                 # e.g. Sequence.run(): one event per step
                    self._bridge.run_event.emit(self._id, item)
                out = None
            self._bridge.result.emit(self._id, out)
        except Exception as exc:  # noqa: BLE001 - delivered to the GUI as an actionable dialog, never swallowed
            self._bridge.error.emit(self._id, exc, traceback.format_exc())
        finally:
            self._bridge.finished.emit(self._id)


class TaskRunner(QObject):
    """Submit callables to named thread pools; callbacks run on the GUI thread."""

    busyChanged = Signal(str, bool)          # pool name, busy

    def __init__(self, parent: QObject | None = None):
        super().__init__(parent)
        self._pools: dict[str, QThreadPool] = {}
        for name in POOLS:
            pool = QThreadPool(self)
            pool.setMaxThreadCount(1)
            pool.setExpiryTimeout(-1)
            self._pools[name] = pool
        self._bridge = _Bridge()
        self._bridge.progress.connect(self._on_progress, Qt.ConnectionType.QueuedConnection)
        self._bridge.run_event.connect(self._on_event, Qt.ConnectionType.QueuedConnection)
        self._bridge.result.connect(self._on_result, Qt.ConnectionType.QueuedConnection)
        self._bridge.error.connect(self._on_error, Qt.ConnectionType.QueuedConnection)
        self._bridge.finished.connect(self._on_finished, Qt.ConnectionType.QueuedConnection)
        self._ids = itertools.count(1)
        self._callbacks: dict[int, _Callbacks] = {}
        self._handles: dict[int, TaskHandle] = {}
        self._lock = threading.Lock()

    def submit(self, fn: Callable[..., Any], *, pool: str = "compute", name: str = "",
               on_result: Callable[[Any], None] | None = None,
               on_error: Callable[[BaseException], None] | None = None,
               on_progress: Callable[[float, str], None] | None = None,
               on_event: Callable[[Any], None] | None = None,
               on_finished: Callable[[], None] | None = None,
               pass_progress: bool = False, pass_cancel: bool = False, iterate: bool = False,
               pass_emit: bool = False, on_cancel: Callable[[], None] | None = None) -> TaskHandle:
        """Run ``fn()`` on ``pool``. With ``pass_progress``/``pass_cancel`` it gets ``progress=`` (a
        ``(fraction, message)`` callable) and ``cancel=`` (a CancelToken); with ``pass_emit`` an ``emit=``
        callable whose items go to ``on_event``. With ``iterate`` its return value is iterated in the worker and
        every item goes to ``on_event``."""
        if pool not in self._pools:
            raise ValueError(f"pool {pool!r}: expected one of {', '.join(POOLS)}")
        task_id = next(self._ids)
        handle = TaskHandle(task_id, name or getattr(fn, "__name__", "task"), pool, on_cancel=on_cancel)
        self._callbacks[task_id] = _Callbacks(on_result, on_error, on_progress, on_event, on_finished)
        self._handles[task_id] = handle
        was_busy = self.busy(pool)
        self._pools[pool].start(_Job(task_id, self._bridge, fn, handle, pass_progress, pass_cancel, iterate,
                                           pass_emit))
        if not was_busy:
            self.busyChanged.emit(pool, True)
        log.debug("submitted %s to %s", handle.name, pool)
        return handle

    def busy(self, pool: str | None = None) -> bool:
        """Whether a task runs in ``pool`` (None: in any pool but the held light's)."""
        return any(not h.done and (h.pool == pool if pool is not None else h.pool not in STATE_POOLS)
                   for h in self._handles.values())

    def running(self, pool: str | None = None) -> list[TaskHandle]:
        return [h for h in self._handles.values() if not h.done and (pool is None or h.pool == pool)]

    def cancel_all(self) -> None:
        for h in list(self._handles.values()):
            h.cancel()

    def wait(self, msecs: int = 30000) -> bool:
        """Block until every pool is idle (shutdown only; never called while the window runs)."""
        ok = True
        for pool in self._pools.values():
            ok = pool.waitForDone(msecs) and ok
        return ok

    # ---- GUI-thread side ----
    @Slot(int, float, str)
    def _on_progress(self, task_id: int, fraction: float, message: str) -> None:
        cb = self._callbacks.get(task_id)
        if cb and cb.on_progress:
            cb.on_progress(fraction, message)

    @Slot(int, object)
    def _on_event(self, task_id: int, item: object) -> None:
        cb = self._callbacks.get(task_id)
        if cb and cb.on_event:
            cb.on_event(item)

    @Slot(int, object)
    def _on_result(self, task_id: int, value: object) -> None:
        cb = self._callbacks.get(task_id)
        if cb and cb.on_result:
            cb.on_result(value)

    @Slot(int, object, str)
    def _on_error(self, task_id: int, exc: object, tb: str) -> None:
        cb = self._callbacks.get(task_id)
        handle = self._handles.get(task_id)
        log.debug("task %s failed:\n%s", handle.name if handle else task_id, tb)
        if cb and cb.on_error and isinstance(exc, BaseException):     # _Job emits only exceptions
            cb.on_error(exc)
        else:
            log.error("%s failed: %s", handle.name if handle else task_id, exc)

    @Slot(int)
    def _on_finished(self, task_id: int) -> None:
        cb = self._callbacks.pop(task_id, None)
        handle = self._handles.pop(task_id, None)
        if handle is not None:
            handle.done = True
        if cb and cb.on_finished:
            cb.on_finished()
        if handle is not None and not self.busy(handle.pool):
            self.busyChanged.emit(handle.pool, False)

