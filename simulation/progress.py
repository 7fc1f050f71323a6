"""Progress reporting and cancellation shared by every long computation (Qt-free)."""
from __future__ import annotations

import threading
from typing import Callable, Optional

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

    def check(self) -> None:
        if self._event.is_set():
            raise Cancelled("cancelled by the user")


def report(progress: Optional[ProgressCallback], fraction: float, message: str) -> None:
    if progress is not None:
        progress(min(max(fraction, 0.0), 1.0), message)


def scaled(progress: Optional[ProgressCallback], start: float, end: float) -> Optional[ProgressCallback]:
    """``progress`` for a sub-task that fills ``start``..``end`` of the whole (its 0..1 mapped there)."""
    if progress is None:
        return None
    return lambda fraction, message: report(progress, start + (end - start) * fraction, message)


def check(cancel: Optional[CancelToken]) -> None:
    if cancel is not None:
        cancel.check()
