"""Progress reporting and cancellation shared by every long computation (Qt-free)."""
from __future__ import annotations

import threading
from collections.abc import Callable

ProgressCallback = Callable[[float, str], None]
# the message simulation.warmup reports while numba compiles the kernels (front ends show it even when quiet)
COMPILING = "compiling kernels (first run only)"


class Cancelled(Exception):
    """Raised between steps when the caller's cancel token is set."""


class CancelToken:
    """A thread-safe flag checked between steps; ``cancel()`` from any thread."""

    def __init__(self) -> None:
        self._event = threading.Event()

    def cancel(self) -> None:
        self._event.set()

    @property
    def cancelled(self) -> bool:
        return self._event.is_set()

    def wait(self, timeout: float) -> bool:
        """Sleep up to ``timeout`` seconds, woken at once by a cancel; whether it was cancelled."""
        return self._event.wait(timeout)

    def check(self) -> None:
        if self._event.is_set():
            raise Cancelled("cancelled by the user")


def report(progress: ProgressCallback | None, fraction: float, message: str) -> None:
    if progress is not None:
        progress(min(max(fraction, 0.0), 1.0), message)


def scaled(progress: ProgressCallback | None, start: float, end: float) -> ProgressCallback | None:
    """``progress`` for a sub-task that fills ``start``..``end`` of the whole (its 0..1 mapped there)."""
    if progress is None:
        return None
    return lambda fraction, message: report(progress, start + (end - start) * fraction, message)


def check(cancel: CancelToken | None) -> None:
    if cancel is not None:
        cancel.check()
